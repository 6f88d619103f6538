"""Analytic controllers: the experts the learned policies are measured against.

Each controller is batched (``act`` maps observations ``(N, obs_dim)`` to actions ``(N, act_dim)``
in one numpy expression) and honest: ``act`` reads only the observation. What it is given at
construction are the design constants a control engineer knows about the plant (inertia, torque
limit, observation scale), never state. :func:`for_env` builds the controller for an env id from
an env instance's constants.
"""

from __future__ import annotations

import numpy as np

__all__ = ["ReorientController", "for_env"]


class ReorientController:
    """Quaternion-feedback PD with gyroscopic compensation, saturated along the eigenaxis.

    Wie, Weiss & Arapostathis (1989), "Quaternion feedback regulator for spacecraft eigenaxis
    rotations", J. Guidance 12(3):375–380, control law (with Euler's equation
    ``I Ω̇ + Ω × IΩ = u`` in body axes, course notes)::

        u = −K q_vec − C Ω + Ω × IΩ,     K = k I,  C = c I

    Taking the gains proportional to the inertia (their "K = k I, C = c I" choice) makes the
    closed loop rotate about the eigenaxis; linearised (θ ≈ 2 |q_vec|) each axis obeys
    ``θ̈ + c θ̇ + (k/2) θ = 0``, so ``k = 2 ω_n²`` and ``c = 2 ζ ω_n``. The torque is limited per body
    axis; rather than clipping each axis (which turns the rotation off its eigenaxis) the whole
    command is scaled down until it fits, as in Wie & Lu (1995), "Feedback control logic for
    spacecraft eigenaxis rotations under slew rate and control constraints", J. Guidance
    18(6):1372–1379. A rate limit from the same paper keeps large slews from building up more
    speed than the torque can take out: the proportional term is written as a commanded body rate
    ``Ω_cmd = −(k/c) q_vec`` clipped to ``|Ω_cmd| ≤ max_rate``, then ``u = −C (Ω − Ω_cmd) + Ω × IΩ``
    (identical to the PD law while the clip is inactive).

    ``q_err`` in the observation is ``q_target⁻¹ ∘ q`` in body axes with ``w ≥ 0``, so
    ``q_vec`` already points along the shorter way round.
    """

    def __init__(
        self,
        inertia,
        max_torque,
        spin_scale: float,
        natural_frequency: float = 3.0,
        damping_ratio: float = 0.8,
        max_rate: float = 3.0,
        gyroscopic: bool = True,
    ):
        inertia = np.asarray(inertia, dtype=float)
        self.inertia = np.diag(inertia) if inertia.shape == (3,) else inertia
        self.max_torque = np.broadcast_to(np.asarray(max_torque, dtype=float), (3,)).copy()
        self.spin_scale = float(spin_scale)
        self.k = 2.0 * natural_frequency**2
        self.c = 2.0 * damping_ratio * natural_frequency
        self.max_rate = float(max_rate)
        self.gyroscopic = bool(gyroscopic)  # False: plain PD (for comparison)

    @classmethod
    def from_env(cls, env, **gains) -> ReorientController:
        """Read the design constants (inertia, torque limit, spin scale) off a Reorient env."""
        task = env.unwrapped.task
        return cls(task.body.inertia, task.max_torque, task.spin_scale, **gains)

    def act(self, obs: np.ndarray) -> np.ndarray:
        obs = np.asarray(obs, dtype=float)
        q_vec = obs[:, 0:3]
        omega = obs[:, 4:7] * self.spin_scale  # body rad/s (clipped obs only beyond 5× the scale)
        rate_cmd = -(self.k / self.c) * q_vec
        norm = np.linalg.norm(rate_cmd, axis=1, keepdims=True)
        rate_cmd *= np.minimum(1.0, self.max_rate / np.maximum(norm, 1e-12))
        momentum = omega @ self.inertia  # I Ω (I symmetric)
        torque = -self.c * (omega - rate_cmd) @ self.inertia
        if self.gyroscopic:
            torque += np.cross(omega, momentum)
        fraction = torque / self.max_torque
        # Keep the direction: scale the whole command by its worst axis.
        scale = np.maximum(1.0, np.max(np.abs(fraction), axis=1, keepdims=True))
        return (fraction / scale).astype(np.float32)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return self.act(obs)


def for_env(env_id: str, env, **kwargs):
    """The analytic controller for ``env_id``, with constants read off ``env`` (single or vector)."""
    if env_id.startswith("RigidEnv/Reorient"):
        return ReorientController.from_env(env, **kwargs)
    if env_id.startswith("RigidEnv/BoxLanding"):
        from .landing_controller import BoxLandingController

        return BoxLandingController.from_env(env, **kwargs)
    raise ValueError(f"env_id: no analytic controller for {env_id!r}")

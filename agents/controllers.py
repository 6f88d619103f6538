"""Analytic controllers: the experts the learned policies are measured against.

Each controller is batched (``act`` maps observations ``(N, obs_dim)`` to actions ``(N, act_dim)``
in one numpy expression) and honest: ``act`` reads only the observation. What it is given at
construction are the design constants a control engineer knows about the plant (inertia, torque
limit, observation scale, the observation's named parts), never state. :func:`for_env` builds
the controller for an env id from an env instance's constants.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from rigid_env.envs import split_observation
from rigid_env.envs.box_landing import BoxLandingTask
from rigid_env.envs.reorient import ReorientTask

__all__ = ["BoxLandingController", "Controller", "ReorientController", "for_env"]


def _constants(env: Any) -> tuple[np.ndarray, np.ndarray, float, dict[str, int]]:
    """Inertia, torque limit, spin scale and observation structure of a (vector) env."""
    unwrapped = env.unwrapped
    task = unwrapped.task
    return task.body.inertia, task.max_torque, task.spin_scale, unwrapped.observation_structure


class Controller:
    """A batched policy ``(N, obs_dim) -> (N, 3)`` built from the plant's design constants."""

    structure: Mapping[str, int]

    def __init__(
        self,
        inertia: ArrayLike,
        max_torque: ArrayLike,
        spin_scale: float,
        structure: Mapping[str, int],
    ):
        inertia = np.asarray(inertia, dtype=float)
        self.inertia = np.diag(inertia) if inertia.shape == (3,) else inertia
        self.max_torque = np.broadcast_to(np.asarray(max_torque, dtype=float), (3,)).copy()
        self.spin_scale = float(spin_scale)
        self.structure = dict(structure)

    def parts(self, obs: ArrayLike) -> dict[str, np.ndarray]:
        """The observation's named parts, as float64."""
        return split_observation(np.asarray(obs, dtype=float), self.structure)

    def act(self, obs: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return self.act(obs)


class ReorientController(Controller):
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
        inertia: ArrayLike,
        max_torque: ArrayLike,
        spin_scale: float,
        natural_frequency: float = 3.0,
        damping_ratio: float = 0.8,
        max_rate: float = 3.0,
        gyroscopic: bool = True,
        structure: Mapping[str, int] | None = None,
    ):
        super().__init__(
            inertia,
            max_torque,
            spin_scale,
            ReorientTask.structure() if structure is None else structure,
        )
        self.k = 2.0 * natural_frequency**2
        self.c = 2.0 * damping_ratio * natural_frequency
        self.max_rate = float(max_rate)
        self.gyroscopic = bool(gyroscopic)  # False: plain PD (for comparison)

    @classmethod
    def from_env(cls, env: Any, **gains: Any) -> ReorientController:
        """Read the design constants (inertia, torque limit, spin scale) off a Reorient env."""
        inertia, max_torque, spin_scale, structure = _constants(env)
        return cls(inertia, max_torque, spin_scale, structure=structure, **gains)

    def act(self, obs: np.ndarray) -> np.ndarray:
        parts = self.parts(obs)
        q_vec = parts["error_quaternion"][:, :3]
        # Body rad/s (the observation is clipped only beyond 5× the scale).
        omega = parts["angular_velocity"] * self.spin_scale
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


class BoxLandingController(Controller):
    """A hand-written landing strategy: face down in flight, kill the spin, damp the bounces.

    The observation gives, in body axes, the up direction ``u`` (an IMU's gravity), the target
    face's outward normal ``n`` and the body rate ``Ω``. The face is down when ``n = d = −u``; the
    body rotation that takes ``n`` onto ``d`` is about ``n × d`` by ``θ = atan2(|n × d|, n·d)``
    (a world-fixed ``d`` moves in body axes as ``ḋ = −Ω × d``, so ``Ω ∥ n × d`` closes the gap).
    The law is the eigenaxis PD of :class:`ReorientController` on that two-axis error
    (Wie et al. 1989), ``u = I (k θ â − c Ω) + Ω × IΩ``, scaled to the torque limit:

    * in flight it is stiff (``flight_frequency``), with a rate limit, so the face turns down
      before touchdown (a 1–2 m fall lasts about 0.5 s) and the spin about the other axes dies;
      the rate about the vertical is damped too, since success needs ``|Ω|`` small;
    * touching the ground it switches to a soft, well-damped hold (``ground_frequency``) whose
      torque stays below ``ground_torque``: enough to keep the face flat through the bounces
      (a flat landing spreads the impact over four corners and bounces low) but not to tip the
      box over an edge (which needs ``m g d`` ≈ 1 N m for the default box).
    """

    def __init__(
        self,
        inertia: ArrayLike,
        max_torque: ArrayLike,
        spin_scale: float,
        flight_frequency: float = 16.0,
        ground_frequency: float = 5.0,
        damping_ratio: float = 1.0,
        max_rate: float = 12.0,
        ground_torque: float = 0.5,
        structure: Mapping[str, int] | None = None,
    ):
        super().__init__(
            inertia,
            max_torque,
            spin_scale,
            BoxLandingTask.structure() if structure is None else structure,
        )
        self.flight = (2.0 * flight_frequency**2, 2.0 * damping_ratio * flight_frequency)
        self.ground = (2.0 * ground_frequency**2, 2.0 * damping_ratio * ground_frequency)
        self.max_rate = float(max_rate)
        self.ground_torque = float(ground_torque)

    @classmethod
    def from_env(cls, env: Any, **gains: Any) -> BoxLandingController:
        """Read the design constants (inertia, torque limit, spin scale) off a BoxLanding env."""
        inertia, max_torque, spin_scale, structure = _constants(env)
        return cls(inertia, max_torque, spin_scale, structure=structure, **gains)

    def act(self, obs: np.ndarray) -> np.ndarray:
        parts = self.parts(obs)
        down = -parts["up"]
        omega = parts["angular_velocity"] * self.spin_scale
        normal = parts["target_normal"]
        touching = parts["corner_contacts"].max(axis=1, keepdims=True) > 0.5
        axis = np.cross(normal, down)
        sin = np.linalg.norm(axis, axis=1, keepdims=True)
        cos = np.einsum("ij,ij->i", normal, down)[:, None]
        angle = np.arctan2(sin, cos)
        # Face straight up (sin ≈ 0, cos < 0): any horizontal axis will do; take one ⟂ n.
        fallback = np.cross(normal, np.roll(normal, 1, axis=1))
        axis = np.where(sin > 1e-6, axis, fallback)
        axis /= np.maximum(np.linalg.norm(axis, axis=1, keepdims=True), 1e-12)
        k = np.where(touching, self.ground[0], self.flight[0])
        c = np.where(touching, self.ground[1], self.flight[1])
        rate_cmd = (k / c) * 0.5 * angle * axis  # 0.5 θ plays the role of |q_vec|
        norm = np.linalg.norm(rate_cmd, axis=1, keepdims=True)
        rate_cmd *= np.minimum(1.0, self.max_rate / np.maximum(norm, 1e-12))
        torque = -c * (omega - rate_cmd) @ self.inertia + np.cross(omega, omega @ self.inertia)
        limit = np.where(touching, np.minimum(self.ground_torque, self.max_torque), self.max_torque)
        fraction = torque / self.max_torque
        scale = np.maximum(1.0, np.max(np.abs(torque) / limit, axis=1, keepdims=True))
        return (fraction / scale).astype(np.float32)


def for_env(env_id: str, env: Any, **kwargs: Any) -> Controller:
    """The analytic controller for ``env_id``, with constants read off ``env`` (single or vector)."""
    if env_id.startswith("RigidEnv/Reorient"):
        return ReorientController.from_env(env, **kwargs)
    if env_id.startswith("RigidEnv/BoxLanding"):
        return BoxLandingController.from_env(env, **kwargs)
    raise ValueError(f"env_id: no analytic controller for {env_id!r}")

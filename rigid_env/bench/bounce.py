"""The landing scene's first bounce against its impulse closed form.

A box (the landing scene's: half extents 0.1, 0.15, 0.2 m, 1 kg) is dropped from rest, without
spin, its lowest point ``h`` above the ground, onto a frictionless ground (μ = 0) of restitution
ε. Before the impact it falls freely: the impact comes at t* = √(2h/g) with v⁻ = −√(2gh) ẑ.

* ``flat``: face down. The four corners strike together, symmetrically about the centre of mass,
  so the total impulse is the particle's: v⁺ = −ε v⁻, ω⁺ = 0, and the bottom face rises to ε²h.
* ``corner``: tilted so one corner strikes first, alone. The notes' impulse ("Impacto") with the
  ground as an infinite mass, n = ẑ, arm r from the centre of mass to the corner:

      j = −(1 + ε) nᵀv⁻ / (1/m + nᵀ((M⁻¹(r × n)) × r)),   v⁺ = v⁻ + j n / m,   ω⁺ = M⁻¹(r × j n).

After the bounce the box flies ballistically: v(t) = v⁺ − g (t − t*) ẑ and its angular momentum
about the centre of mass, L = M ω, stays L⁺ = r × j n. These are compared with the simulator's
state at a check time after the bounce, before any other corner can touch the ground (found from
the exact torque-free rotation), so the comparison isolates the impulse and the time stepping
around it. Errors are relative to the impact's scale: |v⁻| for velocities, |r| m |v⁻| for L.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from rigid_env import sim
from rigid_env.sim.rotation import quat_exp, quat_rotate, quat_to_matrix

from . import reference

GRAVITY = 9.81
HALF_EXTENTS = (0.1, 0.15, 0.2)  # the landing scene's box (rigid_env.sim.scenes)
MASS = 1.0
RESTITUTION = 0.5
HEIGHT = 1.0


@dataclass(frozen=True)
class Drop:
    name: str
    orientation: tuple[float, ...]  # (x, y, z, w), constant during the fall
    height: float = HEIGHT
    restitution: float = RESTITUTION


def drops() -> list[Drop]:
    corner = quat_exp(np.array([0.35, -0.25, 0.1]))  # one corner clearly lowest
    return [Drop("flat", (0.0, 0.0, 0.0, 1.0)), Drop("corner", tuple(corner))]


def body() -> sim.Body:
    return sim.Body.box(HALF_EXTENTS, MASS)


def scene(integrator: str, dt: float, restitution: float = RESTITUTION) -> sim.Scene:
    return sim.Scene(
        body(),
        dt,
        integrator=integrator,
        gravity=(0.0, 0.0, -GRAVITY),
        ground=sim.Ground(restitution=restitution, friction=0.0),
    )


def _corners(q: ArrayLike) -> np.ndarray:
    """World arms of the eight corners at orientation(s) q, (..., 8, 3)."""
    return quat_rotate(np.asarray(q)[..., None, :], body().shape.vertices)


@lru_cache(maxsize=512)  # every integrator of a sweep asks for the same drops
def closed_form(drop: Drop, g: float = GRAVITY) -> dict[str, Any]:
    """Impact time, pre/post-impact velocities and angular momentum, start and check times."""
    b = body()
    q = np.asarray(drop.orientation, float)
    arms = _corners(q)
    lowest = arms[np.argmin(arms[:, 2])]
    z0 = drop.height - lowest[2]  # centre-of-mass height at t = 0
    t_hit = np.sqrt(2 * drop.height / g)
    v_minus = np.array([0.0, 0.0, -g * t_hit])
    n = np.array([0.0, 0.0, 1.0])
    rot = quat_to_matrix(q)
    inertia = rot @ b.inertia @ rot.T
    inv_inertia = np.linalg.inv(inertia)
    flat = np.ptp(np.sort(arms[:, 2])[:4]) < 1e-12  # a face down: four corners at once
    if flat:
        r = np.zeros(3)  # the four impulses' torques cancel about the centre of mass
        j = -(1 + drop.restitution) * b.mass * (n @ v_minus)
    else:
        r = lowest
        denom = 1 / b.mass + n @ np.cross(inv_inertia @ np.cross(r, n), r)
        j = -(1 + drop.restitution) * (n @ v_minus) / denom
    v_plus = v_minus + j * n / b.mass
    l_plus = np.cross(r, j * n)
    w_plus = inv_inertia @ l_plus
    t_check = t_hit + _clear_time(b, q, w_plus, v_plus, z0 - drop.height, g)
    return {
        "z0": z0,
        "t_hit": t_hit,
        "v_minus": v_minus,
        "v_plus": v_plus,
        "w_plus": w_plus,
        "L_plus": l_plus,
        "impulse": j,
        "arm": lowest,
        "flat": flat,
        "t_check": t_check,
        "apex_rise": v_plus[2] ** 2 / (2 * g),  # centre-of-mass rise after the bounce
    }


def _clear_time(
    b: sim.Body, q: np.ndarray, w_plus: np.ndarray, v_plus: np.ndarray, z_hit: float, g: float
) -> float:
    """Half the time until a corner next comes within 1 mm of the ground (exact flight), or
    half the time to the apex if that comes first: a safe check time after the bounce."""
    apex = v_plus[2] / g
    times = np.linspace(0.0, 2 * apex, 401)[1:]
    if np.allclose(w_plus, 0):
        qs = np.broadcast_to(q, (times.size, 4))
    else:
        qs, _ = reference.torque_free_exact(np.diag(b.inertia), q, w_plus, times)
    z = z_hit + v_plus[2] * times - 0.5 * g * times**2
    low = z + np.min(_corners(qs)[..., 2], axis=-1)
    # Ignore the instant after the impact, when the struck corner itself is still near 0.
    away = times > 0.25 * apex
    near = np.nonzero(away & (low < 1e-3))[0]
    limit = times[near[0]] if near.size else 2 * apex
    return 0.5 * min(limit, apex)


PHASES = 8  # impact instants spread over one step: the error depends on where t* falls


def heights(drop: Drop, dt: float, phases: int = PHASES) -> np.ndarray:
    """Drop heights whose impact times t*_i = t*_0 + (i / phases) dt cover one step."""
    t_hit = np.sqrt(2 * drop.height / GRAVITY) + dt * np.arange(phases) / phases
    return 0.5 * GRAVITY * t_hit**2


def initial_state(
    sc: sim.Scene, drop: Drop, forms: list[dict[str, Any]], batch: int | None = None
) -> sim.State:
    z0 = np.array([cf["z0"] for cf in forms])
    if batch is not None:  # identical copies of the first drop, for timing
        z0 = np.full(batch, z0[0])
    position = np.zeros((z0.size, 1, 3))
    position[:, 0, 2] = z0
    return sc.initial_state(position=position, orientation=drop.orientation)


def run(drop: Drop, integrator: str, dt: float, phases: int = PHASES) -> dict[str, Any]:
    """Simulate a batch of drops (impact phases spread over one step) past the bounce; the
    worst error over the batch of the post-bounce state against each drop's closed form."""
    forms = [
        closed_form(Drop(drop.name, drop.orientation, h, drop.restitution))
        for h in heights(drop, dt, phases)
    ]
    sc = scene(integrator, dt, drop.restitution)
    state = initial_state(sc, drop, forms)
    t_hit = np.array([cf["t_hit"] for cf in forms])
    n_check = max(int(min(cf["t_check"] for cf in forms) / dt), int(np.ceil(t_hit.max() / dt)) + 1)
    flat = forms[0]["flat"]
    n_apex = int((t_hit.max() + forms[0]["v_plus"][2] / GRAVITY) / dt) + 3
    steps = max(n_check, n_apex if flat else 0)
    v_prev = np.zeros(phases)
    hit_step = np.zeros(phases, int)  # 0 = not yet
    top = np.full(phases, -np.inf)
    checked = None
    for k in range(1, steps + 1):
        state = sc.step(state)
        vz = state.linear_velocity[:, 0, 2]
        # The first step whose velocity the contact raised (free fall only lowers it).
        hit_step = np.where((hit_step == 0) & (vz > v_prev), k, hit_step)
        v_prev = vz
        if k == n_check:
            checked = state
        top = np.where(hit_step > 0, np.maximum(top, state.position[:, 0, 2]), top)
    assert checked is not None  # steps >= n_check >= 1, so the loop passed the check step
    t = n_check * dt
    up = np.array([0.0, 0.0, 1.0])
    v_ref = np.stack([cf["v_plus"] - GRAVITY * (t - cf["t_hit"]) * up for cf in forms])
    l_ref = np.stack([cf["L_plus"] for cf in forms])
    speed = np.array([np.linalg.norm(cf["v_minus"]) for cf in forms])
    arm = np.linalg.norm(forms[0]["arm"])
    L = sc.angular_momentum(checked, about=checked.position)
    velocity_error = float(
        np.max(np.linalg.norm(checked.linear_velocity[:, 0] - v_ref, axis=-1) / speed)
    )
    momentum_error = float(np.max(np.linalg.norm(L - l_ref, axis=-1) / (arm * MASS * speed)))
    out: dict[str, Any] = {
        "impact_time_error": float(np.max(np.abs(hit_step * dt - t_hit)))
        if np.all(hit_step > 0)
        else None,
        "velocity_error": velocity_error,
        "momentum_error": momentum_error,
        "check_time_after_impact_s": float(t - t_hit.max()),
        "phases": phases,
        "steps": steps,
    }
    if flat:
        # Apex of the centre above its height at impact, against ε² h for each drop.
        rise = top - HALF_EXTENTS[2]
        want = drop.restitution**2 * np.array([cf["t_hit"] ** 2 * GRAVITY / 2 for cf in forms])
        out["apex_error"] = float(np.max(np.abs(rise - want) / want))
    out["error"] = max(velocity_error, momentum_error)
    return out


def batch_wall(drop: Drop, integrator: str, dt: float, batch: int, steps: int) -> float:
    """Wall seconds per simulated second of ``batch`` identical drops over ``steps`` steps
    centred on the impact (half in free fall, half in and after contact)."""
    sc = scene(integrator, dt, drop.restitution)
    z, vz = window_start(drop, dt, steps)
    state = sc.initial_state(
        position=(0.0, 0.0, z),
        orientation=drop.orientation,
        linear_velocity=(0.0, 0.0, vz),
        batch_shape=(batch,),
    )
    start = time.perf_counter()
    for _ in range(steps):
        state = sc.step(state)
    return (time.perf_counter() - start) / (steps * dt)


def window_start(drop: Drop, dt: float, steps: int) -> tuple[float, float]:
    """Free-fall height and velocity of the centre ``steps / 2`` steps before the impact."""
    cf = closed_form(drop)
    t0 = max(0.0, cf["t_hit"] - 0.5 * steps * dt)
    return cf["z0"] - 0.5 * GRAVITY * t0**2, -GRAVITY * t0


def integrators() -> tuple[str, ...]:
    return sim.CONTACT_CAPABLE

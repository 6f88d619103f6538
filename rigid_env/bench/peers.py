"""MuJoCo (3 or 4) on the same free-body scene, when the optional ``peers`` extra is installed.

The box of :mod:`rigid_env.bench.scenes` as one free joint (same mass, principal moments and
initial state, no gravity), stepped by ``mujoco.rollout.rollout`` with a single ``MjData``,
i.e. single-threaded, into a preallocated output array. MuJoCo's free-joint quaternion is
(w, x, y, z) and its angular velocity is in body axes (MuJoCo docs, "Floating objects").
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from rigid_env.sim.rotation import quat_angle, quat_rotate

from . import scenes

if TYPE_CHECKING:
    from .bounce import Drop
    from .problems import Problem
    from .report import Progress

# mujoco.MjModel: MuJoCo ships no type information, so its objects are Any to the checker.
MjModel = Any

INTEGRATORS = ("Euler", "RK4", "implicit", "implicitfast")
THEORETICAL_ORDER = {"Euler": 1, "RK4": 4, "implicit": 1, "implicitfast": 1}

try:
    import mujoco
    from mujoco import rollout as _rollout
except ImportError:  # optional extra "peers"
    mujoco = None


SUPPORTED_MAJOR = ("3", "4")  # mujoco.rollout and the state API are the same in both


def available() -> bool:
    return mujoco is not None and mujoco.__version__.split(".")[0] in SUPPORTED_MAJOR


def status() -> str:
    if mujoco is None:
        return "skipped (mujoco not installed; `pip install -e .[peers]`)"
    if not available():
        return f"skipped (mujoco {mujoco.__version__} is not MuJoCo 3 or 4)"
    return f"MuJoCo {mujoco.__version__}, mujoco.rollout single-thread"


def free_body_model(integrator: str, dt: float) -> MjModel:
    moments = np.diag(scenes.box().inertia)
    xml = f"""<mujoco><option gravity="0 0 0" timestep="{dt:.17g}" integrator="{integrator}"/>
      <worldbody><body><freejoint/>
        <inertial pos="0 0 0" mass="{scenes.BOX_MASS:.17g}" diaginertia="{" ".join(f"{m:.17g}" for m in moments)}"/>
      </body></worldbody></mujoco>"""
    return mujoco.MjModel.from_xml_string(xml)


def initial_state(
    model: MjModel, omega_world: ArrayLike, q: ArrayLike = (0.0, 0.0, 0.0, 1.0)
) -> np.ndarray:
    """Full physics state vector with the rigid_env orientation q (x, y, z, w) and world ω."""
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    data = mujoco.MjData(model)
    q = np.asarray(q, float)
    data.qpos[3:7] = (q[3], q[0], q[1], q[2])
    data.qvel[3:6] = quat_rotate(q * np.array([-1, -1, -1, 1.0]), np.asarray(omega_world, float))
    state = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state, spec)
    return state


def _run(
    model: MjModel, init: np.ndarray, nstep: int, batch: int, out: np.ndarray | None = None
) -> tuple[np.ndarray, float]:
    data = mujoco.MjData(model)
    init = np.tile(init, (batch, 1))
    out = np.empty((batch, nstep, init.shape[1])) if out is None else out
    start = time.perf_counter()
    _rollout.rollout(model, data, init, nstep=nstep, state=out)
    return out, time.perf_counter() - start


def speed(
    batches: Sequence[int], block_s: float, dt: float, progress: Progress | None = None
) -> list[dict[str, Any]]:
    """Body-steps per second of MuJoCo's integrators on the tumbling free body."""
    records = []
    for integrator in INTEGRATORS:
        model = free_body_model(integrator, dt)
        init = initial_state(model, scenes.TUMBLE_OMEGA)
        for batch in batches:
            if progress:
                progress(f"speed mujoco {integrator} batch={batch}")
            _, probe = _run(model, init, 4, batch)
            nstep = max(4, int(block_s / max(probe / 4, 1e-8)))
            out = np.empty((batch, nstep, init.size))
            best = min(_run(model, init, nstep, batch, out)[1] for _ in range(3)) / nstep
            records.append(
                {
                    "scene": "free_body",
                    "engine": "mujoco",
                    "integrator": integrator,
                    "dt": dt,
                    "batch": batch,
                    "bodies": batch,
                    "s_per_step": best,
                    "body_steps_per_s": batch / best,
                }
            )
    return records


def accuracy(
    problem: Problem,
    dts_by_order: Mapping[int, Sequence[float]],
    duration: float,
    checkpoints: int,
    batch: int,
) -> list[dict[str, Any]]:
    """MuJoCo's errors on a torque-free problem, scored like rigid_env's (max over checkpoints)."""
    omega = np.asarray(problem.initial["angular_velocity"], float)
    records = []
    for integrator in INTEGRATORS:
        for dt in dts_by_order[THEORETICAL_ORDER[integrator]]:
            model = free_body_model(integrator, dt)
            init = initial_state(model, omega)
            n = int(round(duration / dt))
            marks = np.unique(np.linspace(0, n, checkpoints + 1).round().astype(int))[1:]
            states, wall = _run(model, init, n, 1)
            s = states[0, marks - 1]  # row k is the state after k + 1 steps
            q = s[:, [5, 6, 7, 4]]  # (w, x, y, z) -> (x, y, z, w)
            w = quat_rotate(q, s[:, 11:14])
            ref = problem.reference(marks * dt)
            finite = bool(np.all(np.isfinite(s)))
            err = float(np.max(quat_angle(q, ref["orientation"]))) if finite else None
            base = {
                "scene": problem.name,
                "engine": "mujoco",
                "integrator": integrator,
                "dt": dt,
                "duration_s": duration,
                "error_kind": "orientation",
                "orientation_error": err,
                "error": err,
                "diverged": not finite,
                "angular_velocity_error": float(
                    np.max(np.linalg.norm(w - ref["angular_velocity"], axis=-1))
                )
                if finite
                else None,
            }
            records.append({**base, "batch": 1, "wall_s_per_sim_s": wall / (n * dt)})
            steps = min(n, max(10, 2000 // batch * 10))
            _, wb = _run(model, init, steps, batch)
            records.append({**base, "batch": batch, "wall_s_per_sim_s": wb / (steps * dt)})
    return records


# --- the landing scene's first bounce ------------------------------------------------------------


def restitution_damping_ratio(eps: float) -> float:
    """Damping ratio ζ of a linear spring–damper contact whose bounce keeps the fraction ε of
    the approach speed: ε = exp(−ζπ / √(1 − ζ²)), so ζ = −ln ε / √(π² + ln² ε)."""
    log = np.log(eps)
    return float(-log / np.sqrt(np.pi**2 + log**2))


def landing_model(
    integrator: str,
    dt: float,
    restitution: float,
    half_extents: Sequence[float],
    mass: float,
    friction: float = 0.0,
) -> MjModel:
    """The bounce box on a plane: frictionless (condim 1) soft contact, solref (τ, ζ(ε)).

    MuJoCo's contact is a damped spring of natural frequency ≈ 1/(τζ) (MuJoCo docs,
    "Solver parameters"); its own rule τ ≥ 2Δt assumes ζ = 1. At the small ζ a bounce needs,
    τ = 2Δt leaves ωΔt > 2 and the first contact step overshoots (a 4.4 m/s drop left at
    21 m/s), so τ = max(0.02 s (MuJoCo's default), 2Δt/ζ) keeps ωΔt ≤ 1/2."""
    from .bounce import GRAVITY

    moments = np.diag(scenes.sim.Body.box(half_extents, mass).inertia)
    hx = " ".join(f"{h:.17g}" for h in half_extents)
    zeta = restitution_damping_ratio(restitution)
    solref = f"{max(0.02, 2 * dt / zeta):.17g} {zeta:.17g}"
    # condim 1: frictionless normal contact only; 3: with sliding friction μ.
    contact = f'condim="{3 if friction else 1}" friction="{friction:.17g} 0.005 0.0001"'
    xml = f"""<mujoco><option gravity="0 0 {-GRAVITY:.17g}" timestep="{dt:.17g}"
        integrator="{integrator}"/>
      <worldbody><geom type="plane" size="50 50 0.1" {contact} solref="{solref}"/>
        <body><freejoint/>
        <inertial pos="0 0 0" mass="{mass:.17g}" diaginertia="{" ".join(f"{m:.17g}" for m in moments)}"/>
        <geom type="box" size="{hx}" {contact} solref="{solref}"/>
      </body></worldbody></mujoco>"""
    return mujoco.MjModel.from_xml_string(xml)


def bounce_accuracy(
    drops: Sequence[Drop], dts: Sequence[float], batch: int, batch_steps: int
) -> list[dict[str, Any]]:
    """MuJoCo's first bounce, scored like rigid_env's (:mod:`rigid_env.bench.bounce`): the
    same drops (impact phases spread over a step), errors at the same check time."""
    from . import bounce

    records = []
    for drop in drops:
        for integrator in INTEGRATORS:
            for dt in dts:
                model = landing_model(
                    integrator, dt, drop.restitution, bounce.HALF_EXTENTS, bounce.MASS
                )
                hs = bounce.heights(drop, dt)
                forms = [
                    bounce.closed_form(
                        bounce.Drop(drop.name, drop.orientation, h, drop.restitution)
                    )
                    for h in hs
                ]
                t_hit = np.array([cf["t_hit"] for cf in forms])
                n_check = max(
                    int(min(cf["t_check"] for cf in forms) / dt), int(np.ceil(t_hit.max() / dt)) + 1
                )
                inits = np.stack(
                    [_state_at(model, (0, 0, cf["z0"]), drop.orientation) for cf in forms]
                )
                # One rollout (fresh MjData) per drop: several initial states in one rollout
                # call share contact warm-start data and bounce wrongly (seen with 3.17).
                out = np.empty((len(forms), n_check, inits.shape[1]))
                start = time.perf_counter()
                for i, init in enumerate(inits):
                    _rollout.rollout(
                        model, mujoco.MjData(model), init[None], nstep=n_check, state=out[i : i + 1]
                    )
                wall = (time.perf_counter() - start) / len(forms)
                s = out[:, -1]
                q = s[:, [5, 6, 7, 4]]
                v = s[:, 8:11]
                L = quat_rotate(q, model.body_inertia[1] * s[:, 11:14])
                t = n_check * dt
                up = np.array([0.0, 0.0, 1.0])
                v_ref = np.stack(
                    [cf["v_plus"] - bounce.GRAVITY * (t - cf["t_hit"]) * up for cf in forms]
                )
                l_ref = np.stack([cf["L_plus"] for cf in forms])
                speed = np.array([np.linalg.norm(cf["v_minus"]) for cf in forms])
                arm = np.linalg.norm(forms[0]["arm"])
                finite = bool(np.all(np.isfinite(s)))
                verr = float(np.max(np.linalg.norm(v - v_ref, axis=-1) / speed)) if finite else None
                lerr = (
                    float(np.max(np.linalg.norm(L - l_ref, axis=-1) / (arm * bounce.MASS * speed)))
                    if finite
                    else None
                )
                base = {
                    "scene": f"first_bounce_{drop.name}",
                    "engine": "mujoco",
                    "integrator": integrator,
                    "dt": dt,
                    "error_kind": "post-bounce velocity",
                    "velocity_error": verr,
                    "momentum_error": lerr,
                    "error": None if verr is None or lerr is None else max(verr, lerr),
                    "diverged": not finite,
                }
                records.append({**base, "batch": 1, "wall_s_per_sim_s": wall / t})
                # Batch timing: the window of rigid_env's (bounce.batch_wall), around the impact.
                z, vz = bounce.window_start(drop, dt, batch_steps)
                init_b = np.tile(_state_at(model, (0, 0, z), drop.orientation, vz), (batch, 1))
                out_b = np.empty((batch, batch_steps, inits.shape[1]))
                start = time.perf_counter()
                _rollout.rollout(
                    model, mujoco.MjData(model), init_b, nstep=batch_steps, state=out_b
                )
                wb = time.perf_counter() - start
                records.append(
                    {**base, "batch": batch, "wall_s_per_sim_s": wb / (batch_steps * dt)}
                )
    return records


def _state_at(
    model: MjModel,
    position: ArrayLike,
    q: ArrayLike,
    vz: float = 0.0,
    omega_world: ArrayLike | None = None,
) -> np.ndarray:
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    data = mujoco.MjData(model)
    q = np.asarray(q, float)
    data.qpos[:3] = position
    data.qpos[3:7] = (q[3], q[0], q[1], q[2])
    data.qvel[2] = vz
    if omega_world is not None:  # MuJoCo's free-joint angular velocity is in body axes
        data.qvel[3:6] = quat_rotate(q * np.array([-1, -1, -1, 1.0]), np.asarray(omega_world))
    state = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state, spec)
    return state


def landing_speed(
    batches: Sequence[int], block_s: float, dt: float, progress: Progress | None = None
) -> list[dict[str, Any]]:
    """Body-steps per second of MuJoCo on rigid_env's landing scene: the same box (1 kg, half
    extents 0.1, 0.15, 0.2 m), restitution 0.3 and friction 0.5, dropped from 1 m with the
    same random tilts and spins, timed after the same 1 s pre-roll (boxes on the ground)."""
    from rigid_env.sim import scenes as sim_scenes

    from .scenes import LANDING_PREROLL_S

    records = []
    for integrator in INTEGRATORS:
        model = landing_model(integrator, dt, 0.3, sim_scenes.LANDING_HALF_EXTENTS, 1.0, 0.5)
        for batch in batches:
            if progress:
                progress(f"speed mujoco landing {integrator} batch={batch}")
            _, initial = sim_scenes.landing_scene()
            start_state = initial(batch_shape=(batch,), rng=np.random.default_rng(0))
            inits = np.stack(
                [
                    _state_at(model, p[0], q[0], 0.0, w[0])
                    for p, q, w in zip(
                        start_state.position,
                        start_state.orientation,
                        start_state.angular_velocity,
                        strict=True,
                    )
                ]
            )
            preroll = int(round(LANDING_PREROLL_S / dt))
            rolled = np.empty((batch, preroll, inits.shape[1]))
            _rollout.rollout(model, mujoco.MjData(model), inits, nstep=preroll, state=rolled)
            landed = np.ascontiguousarray(rolled[:, -1])
            _, probe = _timed_rollout(model, landed, 4)
            nstep = max(4, int(block_s / max(probe / 4, 1e-8)))
            best = min(_timed_rollout(model, landed, nstep)[1] for _ in range(3)) / nstep
            records.append(
                {
                    "scene": "landing",
                    "engine": "mujoco",
                    "integrator": integrator,
                    "dt": dt,
                    "batch": batch,
                    "bodies": batch,
                    "s_per_step": best,
                    "body_steps_per_s": batch / best,
                }
            )
    return records


def _timed_rollout(model: MjModel, inits: np.ndarray, nstep: int) -> tuple[np.ndarray, float]:
    out = np.empty((inits.shape[0], nstep, inits.shape[1]))
    start = time.perf_counter()
    _rollout.rollout(model, mujoco.MjData(model), inits, nstep=nstep, state=out)
    return out, time.perf_counter() - start


# --- many boxes (``rigid_env.bench.many_bodies``) -----------------------------------------------


def boxes_model(
    count: int,
    half_extents: Sequence[float],
    mass: float,
    friction: float,
    dt: float,
    gravity: float = 9.81,
    integrator: str = "Euler",
) -> MjModel:
    """``count`` free boxes on a plane, every contact with sliding friction μ (condim 3) and
    MuJoCo's default soft contact (solref 0.02 s, damping ratio 1: no bounce; default solimp),
    MuJoCo's default Euler integrator and its default solver. Each body's qpos is
    (x, y, z, w, qx, qy, qz) at ``7 i`` (:func:`place_boxes`)."""
    hx = " ".join(f"{h:.17g}" for h in half_extents)
    contact = f'condim="3" friction="{friction:.17g} 0.005 0.0001"'
    boxes = "\n".join(
        f'<body name="box{i}"><freejoint/><geom type="box" size="{hx}" mass="{mass:.17g}" '
        f"{contact}/></body>"
        for i in range(count)
    )
    xml = f"""<mujoco><option gravity="0 0 {-gravity:.17g}" timestep="{dt:.17g}"
        integrator="{integrator}"/>
      <worldbody><geom type="plane" size="50 50 0.1" {contact}/>
        {boxes}
      </worldbody></mujoco>"""
    return mujoco.MjModel.from_xml_string(xml)


def place_boxes(model: MjModel, positions: ArrayLike, orientations: ArrayLike) -> Any:
    """A fresh ``MjData`` of :func:`boxes_model` at rest with rigid_env's ``positions`` (n, 3)
    and orientations (n, 4) as (x, y, z, w)."""
    data = mujoco.MjData(model)
    q = np.asarray(orientations, float)
    qpos = data.qpos.reshape(-1, 7)
    qpos[:, :3] = positions
    qpos[:, 3:] = q[:, [3, 0, 1, 2]]
    mujoco.mj_forward(model, data)
    return data


def box_positions(data: Any) -> np.ndarray:
    """The boxes' centres (n, 3) in ``data`` of :func:`boxes_model`."""
    return np.array(data.qpos.reshape(-1, 7)[:, :3])


def step_boxes(model: MjModel, data: Any, nstep: int) -> float:
    """Seconds to take ``nstep`` steps of ``data`` in one ``mj_step`` call (MuJoCo's loop, one
    thread)."""
    start = time.perf_counter()
    mujoco.mj_step(model, data, nstep=nstep)
    return time.perf_counter() - start

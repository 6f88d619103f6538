"""MuJoCo 3 on the same free-body scene, when the optional ``peers`` extra is installed.

The box of :mod:`rigid_env.bench.scenes` as one free joint (same mass, principal moments and
initial state, no gravity), stepped by ``mujoco.rollout.rollout`` with a single ``MjData``,
i.e. single-threaded, into a preallocated output array. MuJoCo's free-joint quaternion is
(w, x, y, z) and its angular velocity is in body axes (MuJoCo docs, "Floating objects").
"""

from __future__ import annotations

import time

import numpy as np

from rigid_env.sim.rotation import quat_angle, quat_rotate

from . import scenes

INTEGRATORS = ("Euler", "RK4", "implicit", "implicitfast")
THEORETICAL_ORDER = {"Euler": 1, "RK4": 4, "implicit": 1, "implicitfast": 1}

try:
    import mujoco
    from mujoco import rollout as _rollout
except ImportError:  # optional extra "peers"
    mujoco = None


def available() -> bool:
    return mujoco is not None and mujoco.__version__.split(".")[0] == "3"


def status() -> str:
    if mujoco is None:
        return "skipped (mujoco not installed; `pip install -e .[peers]`)"
    if not available():
        return f"skipped (mujoco {mujoco.__version__} is not MuJoCo 3)"
    return f"MuJoCo {mujoco.__version__}, mujoco.rollout single-thread"


def free_body_model(integrator: str, dt: float):
    moments = np.diag(scenes.box().inertia)
    xml = f"""<mujoco><option gravity="0 0 0" timestep="{dt:.17g}" integrator="{integrator}"/>
      <worldbody><body><freejoint/>
        <inertial pos="0 0 0" mass="{scenes.BOX_MASS:.17g}" diaginertia="{" ".join(f"{m:.17g}" for m in moments)}"/>
      </body></worldbody></mujoco>"""
    return mujoco.MjModel.from_xml_string(xml)


_SPEC = None


def initial_state(model, omega_world, q=(0.0, 0.0, 0.0, 1.0)) -> np.ndarray:
    """Full physics state vector with the rigid_env orientation q (x, y, z, w) and world ω."""
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    data = mujoco.MjData(model)
    q = np.asarray(q, float)
    data.qpos[3:7] = (q[3], q[0], q[1], q[2])
    data.qvel[3:6] = quat_rotate(q * np.array([-1, -1, -1, 1.0]), np.asarray(omega_world, float))
    state = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state, spec)
    return state


def _run(model, init: np.ndarray, nstep: int, batch: int, out=None) -> tuple[np.ndarray, float]:
    data = mujoco.MjData(model)
    init = np.tile(init, (batch, 1))
    out = np.empty((batch, nstep, init.shape[1])) if out is None else out
    start = time.perf_counter()
    _rollout.rollout(model, data, init, nstep=nstep, state=out)
    return out, time.perf_counter() - start


def speed(batches, block_s: float, dt: float, progress=None) -> list[dict]:
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
    problem, dts_by_order: dict, duration: float, checkpoints: int, batch: int
) -> list[dict]:
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

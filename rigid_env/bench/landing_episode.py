"""Landing over whole episodes, rigid_env beside MuJoCo: ``python -m rigid_env.bench.landing_episode``.

The speed bench's landing rows time boxes that are already down (after its pre-roll): bouncing,
sliding and resting, the contact solve running on most steps. A training run steps something
else: every episode starts with the box in the air. This bench times that mix. A batch of the
landing scene's boxes (1 kg, half extents 0.1, 0.15, 0.2 m, restitution 0.3, friction 0.5) is
dropped from 1 m with ``landing_scene``'s random tilts and spins (seeded). It is stepped at
BoxLanding's Δt = 1/240 s for one whole episode: ``MAX_EPISODE_STEPS`` actions of
``frame_skip`` physics steps, 4 s. There is no torque. The calls are ``Scene.step(state,
steps=frame_skip)``, as the env makes them. MuJoCo steps the same boxes from the same starts
(``peers.landing_model``: soft contact, the speed target's integrator) through the whole
episode in one ``mujoco.rollout`` call, one thread. Each figure is the best of ``repeats``
runs, the two engines alternating.

The phases come from a separate, untimed pass of one step per call. Each element-step is
counted as one of:

- ``flight``: no contact carried an impulse (``ContactReport.touched`` false);
- ``impact or sliding``: a contact carried one and the box still moves;
- ``rest``: a contact carried one and the box's speed is below ``REST_SPEED`` (m/s) and its
  spin below ``REST_SPIN`` (rad/s).

The shares say what the timed figure averages over.
"""

from __future__ import annotations

import sys
import time
import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np

from rigid_env import cli, resources, sim
from rigid_env.envs.box_landing import MAX_EPISODE_STEPS, BoxLandingConfig
from rigid_env.sim.scenes import LANDING_HALF_EXTENTS, landing_scene

from . import peers

PROG = "python -m rigid_env.bench.landing_episode"
DT = BoxLandingConfig.dt
FRAME_SKIP = BoxLandingConfig.frame_skip
STEPS = MAX_EPISODE_STEPS * FRAME_SKIP  # physics steps of one episode
SCENE = "landing_episode"
MUJOCO_INTEGRATOR = "Euler"  # the speed bench's landing target compares with MuJoCo's Euler
REST_SPEED = 0.01  # m/s
REST_SPIN = 0.1  # rad/s
PHASES = ("flight", "impact or sliding", "rest")


def starts(batch: int) -> tuple[sim.Scene, sim.State]:
    """The landing scene at BoxLanding's Δt (compiled when it can be) and its seeded drops."""
    scene, initial = landing_scene(dt=DT)
    return scene, initial(batch_shape=(batch,), rng=np.random.default_rng(0))


def rollout(scene: sim.Scene, state: sim.State, actions: int) -> sim.State:
    """``actions`` calls of ``frame_skip`` steps each, as the env makes them."""
    for _ in range(actions):
        state = scene.step(state, steps=FRAME_SKIP)
    return state


def phases(scene: sim.Scene, state: sim.State, steps: int) -> dict[str, float]:
    """Each phase's share of the element-steps of ``steps`` single steps from ``state``."""
    counts = np.zeros(len(PHASES))
    for _ in range(steps):
        state = scene.step(state)
        touched = scene.report["contacts"].touched
        speed = np.linalg.norm(state.linear_velocity[:, 0], axis=-1)
        spin = np.linalg.norm(state.angular_velocity[:, 0], axis=-1)
        still = (speed < REST_SPEED) & (spin < REST_SPIN)
        counts += (np.sum(~touched), np.sum(touched & ~still), np.sum(touched & still))
    return dict(zip(PHASES, (counts / counts.sum()).tolist(), strict=True))


def measure(batch: int, actions: int = MAX_EPISODE_STEPS, repeats: int = 3) -> dict[str, Any]:
    """The phases and, per engine, a record like the speed bench's (``s_per_step`` of the whole
    batch, ``body_steps_per_s``), each the best of ``repeats`` whole-episode runs."""
    steps = actions * FRAME_SKIP
    with warnings.catch_warnings():  # a capped solve is part of the workload, not its subject
        warnings.simplefilter("ignore", sim.ContactSolverWarning)
        scene, state = starts(batch)
        rollout(scene, state[:1], 1)  # compile or load the step outside the timing
        mix = phases(scene, state, steps)
        mj = _mujoco_starts(state) if peers.available() else None
        best = {"rigid_env": np.inf, "mujoco": np.inf}
        for _ in range(repeats):
            start = time.perf_counter()
            rollout(scene, state, actions)
            best["rigid_env"] = min(best["rigid_env"], time.perf_counter() - start)
            if mj is not None:
                best["mujoco"] = min(best["mujoco"], peers._timed_rollout(*mj, steps)[1])
    records = [
        _record("rigid_env", scene.backend, scene.integrator, batch, best["rigid_env"] / steps)
    ]
    if mj is not None:
        records.append(_record("mujoco", None, MUJOCO_INTEGRATOR, batch, best["mujoco"] / steps))
    return {"batch": batch, "steps": steps, "phases": mix, "records": records}


def _record(engine: str, backend: str | None, integrator: str, batch: int, s: float) -> dict:
    record = {
        "scene": SCENE,
        "engine": engine,
        "integrator": integrator,
        "dt": DT,
        "batch": batch,
        "bodies": batch,
        "s_per_step": s,
        "body_steps_per_s": batch / s,
    }
    if backend is not None:
        record["backend"] = backend
    return record


def _mujoco_starts(state: sim.State) -> tuple[Any, np.ndarray]:
    """MuJoCo's landing model and the same starts as full physics states."""
    model = peers.landing_model(MUJOCO_INTEGRATOR, DT, 0.3, LANDING_HALF_EXTENTS, 1.0, 0.5)
    inits = np.stack(
        [
            peers._state_at(model, p[0], q[0], v[0, 2], w[0])
            for p, q, v, w in zip(
                state.position,
                state.orientation,
                state.linear_velocity,
                state.angular_velocity,
                strict=True,
            )
        ]
    )
    return model, inits


def table(result: dict[str, Any]) -> str:
    """The phases and each engine's µs per body-step, with the ratio."""
    lines = [
        f"Landing over whole episodes: batch {result['batch']}, {result['steps']} steps of "
        f"{DT:.6g} s from 1 m, phases "
        + ", ".join(f"{k} {100 * v:.1f} %" for k, v in result["phases"].items()),
        "",
        "| engine | integrator | µs per body-step |",
        "|---|---|---|",
    ]
    per_body = {}
    for r in result["records"]:
        name = r["engine"] + (f" {r['backend']}" if "backend" in r else "")
        per_body[r["engine"]] = 1e6 / r["body_steps_per_s"]
        lines.append(f"| {name} | {r['integrator']} | {per_body[r['engine']]:.3f} |")
    if "mujoco" in per_body:
        lines += [
            "",
            f"MuJoCo's time / rigid_env's: {per_body['mujoco'] / per_body['rigid_env']:.2f}",
        ]
    else:
        lines += ["", f"MuJoCo: {peers.status()}"]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = cli.Parser(prog=PROG, description=__doc__.split("\n")[0], epilog=cli.EXIT_STATUSES)
    parser.add_argument("--batch", type=cli.positive_int, default=1024, help="batch size")
    parser.add_argument(
        "--actions",
        type=cli.positive_int,
        default=MAX_EPISODE_STEPS,
        help=f"env steps of {FRAME_SKIP} physics steps each (default: one whole episode)",
    )
    parser.add_argument(
        "--repeats", type=cli.positive_int, default=3, help="runs per figure (best kept)"
    )
    args = parser.parse_args(argv)
    # The batch's state and MuJoCo's rollout of it (full physics state per step).
    steps = args.actions * FRAME_SKIP
    needed = args.batch * (resources.SCENE_BYTES + 8 * 32 * steps)
    resources.check_fits(needed, f"--batch {args.batch} --actions {args.actions}")
    print(table(measure(args.batch, args.actions, args.repeats)))
    return 0


if __name__ == "__main__":
    sys.exit(cli.run(main, PROG))

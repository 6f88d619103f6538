"""Convergence of the contact solve on the scenes the issue names, for both starts.

For each scene and each ``SolverSettings.start`` it prints the Gauss–Seidel sweeps per step
(mean and max over the steps with a contact), the steps that stopped at the cap, and the
scene's figure of merit (creep speed on the incline, drift of a resting body, yaw picked up by
a box sliding diagonally). Run: ``python -m rigid_env.bench.contact_solve`` (``--help``: the
step, the number of steps, the landing batch, the starts and a scene filter; e.g. the landing
scene at the speed bench's Δt = 0.01 s: ``--dt 0.01 --steps 100 --landing-batch 64 --only
landing``).

``--rollout boxlanding --episodes N`` instead steps ``RigidEnv/BoxLanding-v0`` (one env) under
seeded random actions (or a saved stable-baselines3 policy's, ``--policy model.zip``: a trained
lander keeps its box in contact more, where the hard solves are) and, beside it, the env's own scene one physics step at a time from the
env's state, so every contact step's solve is seen alone: it prints the contact steps, the share
capped, the mean / median / max sweeps, the share of all sweeps spent in capped steps and the
Newton steps (``python -m rigid_env.bench.contact_solve --rollout boxlanding --episodes 20``).
"""

from __future__ import annotations

import argparse
import pickle
import sys
import time
import warnings
import zipfile
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from rigid_env import cli, resources, sim
from rigid_env.sim.rotation import quat_angle, quat_exp
from rigid_env.sim.scenes import landing_scene

G = 9.81
DT = 1 / 240


def l_prism() -> sim.Body:
    """An L-shaped prism, 0.2 m tall (the resting-polyhedron case of the tests)."""
    outline = [(0, 0), (0.3, 0), (0.3, 0.1), (0.1, 0.1), (0.1, 0.3), (0, 0.3)]
    verts = [(x, y, 0.0) for x, y in outline] + [(x, y, 0.2) for x, y in outline]
    faces: list[tuple[int, ...]] = [(5, 4, 3, 2, 1, 0), (6, 7, 8, 9, 10, 11)]
    faces += [(i, (i + 1) % 6, 6 + (i + 1) % 6, 6 + i) for i in range(6)]
    return sim.Body.polyhedron(verts, faces, 1000.0)


def tetrahedron() -> sim.Body:
    verts = [(0, 0, 0), (0.2, 0, 0), (0, 0.2, 0), (0, 0, 0.2)]
    return sim.Body.polyhedron(verts, [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)], 1000.0)


def cases(
    settings: sim.SolverSettings, dt: float = DT, landing_batch: int = 8
) -> dict[str, tuple[sim.Scene, sim.State]]:
    box = sim.Body.box((0.1, 0.15, 0.2), 1.0)
    down = (0.0, 0.0, -G)

    def resting(body: sim.Body) -> tuple[sim.Scene, sim.State]:
        scene = sim.Scene(
            body, dt, gravity=down, ground=sim.Ground(0.3, 0.5), contact_solver=settings
        )
        low = -np.min(body.shape.vertices[:, 2])
        return scene, scene.initial_state(position=(0, 0, low))

    tilt = 0.3  # tan 0.3 = 0.31 < μ = 0.5: static friction must hold
    incline = sim.Scene(
        box,
        dt,
        gravity=(G * np.sin(tilt), 0.0, -G * np.cos(tilt)),
        ground=sim.Ground(0.0, 0.5),
        contact_solver=settings,
    )
    slide = sim.Scene(box, dt, gravity=down, ground=sim.Ground(0.0, 0.5), contact_solver=settings)
    yaw = quat_exp(np.array([0.0, 0.0, 0.4]))
    land, init = landing_scene()
    land = sim.Scene(
        land.model.bodies,
        dt,
        gravity=down,
        ground=land.model.ground,
        contact_solver=settings,
    )
    return {
        "resting box": resting(box),
        "resting L-prism": resting(l_prism()),
        "resting tetrahedron": resting(tetrahedron()),
        "box on incline (0.3 rad, mu 0.5)": (incline, incline.initial_state(position=(0, 0, 0.2))),
        "yawed box sliding diagonally": (
            slide,
            slide.initial_state(
                position=(0, 0, 0.2), orientation=yaw, linear_velocity=(1.5, 1.5, 0.0)
            ),
        ),
        f"landing scene, {landing_batch} tumbling boxes": (
            land,
            init((landing_batch,), np.random.default_rng(0)),
        ),
    }


def measure(
    start: str, steps: int = 480, dt: float = DT, landing_batch: int = 8, only: str = ""
) -> list[dict]:
    settings = sim.SolverSettings(start=start)
    out = []
    for name, (scene, state) in cases(settings, dt, landing_batch).items():
        if only not in name:
            continue
        first = state
        sweeps, capped, elements, engaged = [], 0, 0, 0
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sim.ContactSolverWarning)
            for _ in range(steps):
                state = scene.step(state)
                report = scene.report["contacts"]
                if report.engaged:
                    sweeps.append(report.iterations)
                capped += report.capped > 0
                elements += report.capped
                engaged += report.engaged
        drift = float(np.max(np.abs(state.position - first.position)))
        turn = float(np.max(quat_angle(state.orientation, first.orientation)))
        speed = float(np.max(np.linalg.norm(state.linear_velocity, axis=-1)))
        out.append(
            {
                "scene": name,
                "mean_sweeps": float(np.mean(sweeps)) if sweeps else 0.0,
                "median_sweeps": float(np.median(sweeps)) if sweeps else 0.0,
                "max_sweeps": int(np.max(sweeps)) if sweeps else 0,
                "capped_steps": capped,
                # Of the element-steps with a contact, the share whose solve stopped at a cap.
                "capped_fraction": elements / engaged if engaged else 0.0,
                "final_speed": speed,
                "drift_m": drift,
                "turn_rad": turn,
            }
        )
    return out


def rollout_boxlanding(
    episodes: int,
    seed: int = 0,
    settings: sim.SolverSettings | None = None,
    policy: Callable[[np.ndarray], np.ndarray] | None = None,
) -> dict:
    """Per-physics-step contact statistics of ``episodes`` BoxLanding episodes under random
    actions (``seed`` seeds the env and its action space), or under ``policy`` (observation →
    action) when given. The env steps as usual; before each
    action a copy of its scene steps the same state with the same body torque one
    physics step at a time, ``frame_skip`` times, and its reports are collected (and the wall
    time of those steps, ``settings`` the scene's solver settings)."""
    import gymnasium as gym

    import rigid_env.envs  # noqa: F401  (registers the envs)
    from rigid_env.envs.box_landing import BoxLandingTask

    env = gym.make("RigidEnv/BoxLanding-v0")
    task = env.unwrapped.task  # type: ignore[attr-defined]
    assert isinstance(task, BoxLandingTask)
    model = task.scene.model
    scene = sim.Scene(
        task.body,
        task.scene.dt,
        integrator=task.config.integrator,
        gravity=model.gravity,
        ground=model.ground,
        contact_solver=settings,
    )
    env.action_space.seed(seed)
    scene.step(task.state)  # compiles (or loads) the kernels outside the timed steps
    sweeps, capped, newton = [], [], []
    seconds, steps = 0.0, 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sim.ContactSolverWarning)
        for episode in range(episodes):
            obs, _ = env.reset(seed=seed + episode)
            done = False
            while not done:
                action = env.action_space.sample() if policy is None else policy(obs)
                torque = (action * task.max_torque)[None, None, :]
                state = task.state
                for _ in range(task.frame_skip):
                    began = time.perf_counter()
                    state = scene.step(state, body_torque=torque)
                    seconds += time.perf_counter() - began
                    steps += 1
                    report = scene.report["contacts"]
                    if report.engaged:
                        sweeps.append(report.iterations)
                        capped.append(report.capped > 0)
                        newton.append(report.newton)
                obs, _, terminated, truncated, _ = env.step(action)
                done = terminated or truncated
    env.close()
    sweeps_a = np.array(sweeps, dtype=float)
    capped_a = np.array(capped, dtype=bool)
    total = float(np.sum(sweeps_a))
    return {
        "episodes": episodes,
        "contact_steps": len(sweeps_a),
        "capped_share": float(np.mean(capped_a)) if len(capped_a) else 0.0,
        "mean_sweeps": float(np.mean(sweeps_a)) if len(sweeps_a) else 0.0,
        "median_sweeps": float(np.median(sweeps_a)) if len(sweeps_a) else 0.0,
        "max_sweeps": int(np.max(sweeps_a)) if len(sweeps_a) else 0,
        "capped_sweep_share": float(np.sum(sweeps_a[capped_a]) / total) if total else 0.0,
        "newton_steps": int(np.sum(newton)),
        "newton_solves": int(np.count_nonzero(newton)),
        "step_us": 1e6 * seconds / max(steps, 1),
    }


def saved_policy(path: str, algo: str = "ppo") -> Callable[[np.ndarray], np.ndarray]:
    """observation → action of a saved stable-baselines3 model (``algo`` "ppo" or "sac"),
    deterministic, as an evaluation acts."""
    if algo not in ("ppo", "sac"):
        raise ValueError(f"algo must be 'ppo' or 'sac', got {algo!r}")
    try:
        from stable_baselines3 import PPO, SAC
    except ImportError:
        raise cli.UsageError(
            "--policy needs stable-baselines3: pip install torch==2.13.0 -e '.[rl]'"
        ) from None
    if not Path(path).is_file():
        raise cli.UsageError(f"--policy: no such file: {path}")
    try:
        model = (PPO if algo == "ppo" else SAC).load(path, device="cpu")
    except (zipfile.BadZipFile, KeyError, ValueError, OSError, EOFError, RuntimeError,
            pickle.UnpicklingError) as error:  # fmt: skip
        raise cli.UsageError(
            f"--policy: cannot load {path} as a stable-baselines3 {algo.upper()} model "
            f"({type(error).__name__}: {error})"
        ) from None
    return lambda obs: model.predict(obs, deterministic=True)[0]


PROG = "python -m rigid_env.bench.contact_solve"
STEP_RECORD_BYTES = 64  # what a measured step keeps at least (its sweep count in a list)


def main(argv: Sequence[str] | None = None) -> int:
    parser = cli.Parser(prog=PROG, description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--dt", type=cli.positive_float, default=DT, help="time step (s), default 1/240"
    )
    parser.add_argument(
        "--steps", type=cli.positive_int, default=480, help="steps per scene, default 480"
    )
    parser.add_argument(
        "--landing-batch",
        type=cli.positive_int,
        default=8,
        help="boxes of the landing scene, default 8",
    )
    parser.add_argument(
        "--starts",
        nargs="+",
        default=["particle", "active_set"],
        choices=["particle", "active_set"],
        help="SolverSettings.start values to measure, default both",
    )
    parser.add_argument("--only", default="", help="measure the scenes whose name contains this")
    parser.add_argument(
        "--rollout",
        choices=["boxlanding"],
        help="instead of the scenes: per-step statistics of RigidEnv/BoxLanding-v0 rollouts",
    )
    parser.add_argument(
        "--episodes", type=cli.positive_int, default=20, help="rollout episodes, default 20"
    )
    parser.add_argument(
        "--seed", type=cli.nonnegative_int, default=0, help="rollout seed, default 0"
    )
    parser.add_argument(
        "--newton-after",
        type=cli.positive_int,
        default=None,
        help="SolverSettings.newton_after (rollout)",
    )
    parser.add_argument(
        "--newton-steps",
        type=cli.nonnegative_int,
        default=None,
        help="SolverSettings.newton_steps (rollout)",
    )
    parser.add_argument(
        "--policy",
        default=None,
        help="rollout actions from this saved stable-baselines3 model (.zip; deterministic) "
        "instead of random ones; needs the rl extra",
    )
    parser.add_argument(
        "--algo", default="ppo", choices=["ppo", "sac"], help="the --policy model's algorithm"
    )
    args = parser.parse_args(argv)
    if args.rollout is None:  # every scene at once, and what each of its steps records
        resources.check_fits(
            args.landing_batch * resources.SCENE_BYTES + args.steps * STEP_RECORD_BYTES,
            f"--landing-batch {args.landing_batch} with --steps {args.steps}",
        )
    else:  # per physics step of every episode (BoxLanding: at most 120 actions of 8 steps)
        resources.check_fits(
            args.episodes * 120 * 8 * STEP_RECORD_BYTES, f"--episodes {args.episodes}"
        )
    try:
        _run(args)
    except sim.DivergenceError as error:
        raise cli.UsageError(f"--dt {args.dt:g}: {error}") from None
    return 0


def _run(args: argparse.Namespace) -> None:
    if args.rollout:
        chosen = {"newton_after": args.newton_after, "newton_steps": args.newton_steps}
        settings = sim.SolverSettings(**{k: v for k, v in chosen.items() if v is not None})
        policy = None if args.policy is None else saved_policy(args.policy, args.algo)
        r = rollout_boxlanding(args.episodes, args.seed, settings, policy)
        actions = "random actions" if args.policy is None else f"policy {args.policy}"
        print(
            f"BoxLanding-v0, {r['episodes']} episodes, seed {args.seed}, {actions}: "
            f"{r['contact_steps']} contact steps, capped {100 * r['capped_share']:.2f} %, "
            f"sweeps mean {r['mean_sweeps']:.1f} median {r['median_sweeps']:.0f} "
            f"max {r['max_sweeps']}, share of sweeps in capped steps "
            f"{100 * r['capped_sweep_share']:.1f} %, Newton steps {r['newton_steps']} "
            f"in {r['newton_solves']} solves; newton_after {settings.newton_after}, "
            f"newton_steps {settings.newton_steps}; {r['step_us']:.1f} µs per physics step"
        )
        return
    # Sweeps: the most any element of the batch needed in a step (``ContactReport.iterations``),
    # over the steps with a contact; capped: steps with a capped element, and the share of
    # element-steps with a contact whose solve was capped.
    print(
        f"{'start':10s} {'scene':34s} {'sweeps':>7s} {'median':>6s} {'max':>5s} {'capped':>6s} "
        f"{'cap frac':>8s} {'|v| end':>9s} {'drift m':>9s} {'turn rad':>9s}"
    )
    for start in args.starts:
        for r in measure(start, args.steps, args.dt, args.landing_batch, args.only):
            print(
                f"{start:10s} {r['scene']:34s} {r['mean_sweeps']:7.1f} {r['median_sweeps']:6.0f} "
                f"{r['max_sweeps']:5d} {r['capped_steps']:6d} {r['capped_fraction']:8.4f} "
                f"{r['final_speed']:9.2e} {r['drift_m']:9.2e} {r['turn_rad']:9.2e}"
            )


if __name__ == "__main__":
    sys.exit(cli.run(main, PROG))

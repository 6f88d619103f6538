"""Speed: body-steps per second of each scene and integrator, per-stage costs, memory, envs.

Timing hygiene: ``time.perf_counter``; two warm-up steps; then ``REPEATS`` blocks of enough
steps to last ~``block_s`` each, reporting the best block (the least disturbed by the OS).

The per-stage breakdown is measured inside the scene's own ``Scene.step`` over a block of real
steps (the state evolving as in the speed run) by the scene's public per-stage timer
(``scene.timer = sim.StageTimer()``): every stage of ``scene.pipeline``, ``Scene.step``'s input
validation and its finiteness check are timed by their own clock reads, and the step total by
separate reads around the whole call, so the parts are disjoint intervals inside the total
(their sum falls short of it only by the bookkeeping between them). A stage a scene does not
list in ``scene.stages`` is never called, which the free body's breakdown shows.

A step is one kernel call, so its breakdown has three parts: input validation, the kernel,
output. ``compile_times`` measures, in fresh processes with empty
numba caches, the first import of a scene's compiled step (compiles) and the next (loads it from
the disk cache).

(An earlier breakdown timed each stage in isolation at the initial state and called the
difference "rest of Scene.step": for the landing scene, whose box starts 1 m up, the isolated
contact stage took its no-contact early exit while the timed steps hit the ground, and the
splitting integrator's force handling (kicks, body-frame torques) was counted in neither part.)
"""

from __future__ import annotations

import contextlib
import json
import os
import subprocess
import sys
import tempfile
import time
import tracemalloc
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any, TypedDict

import numpy as np

from rigid_env import sim
from rigid_env.sim.scenes import landing_scene

from . import contact_cases, landing_episode, peers, report, scenes


class Preset(TypedDict):
    """Batch sizes and block length of the scene timings; vector-env sizes and steps of the
    env timings; whether to run the compile-time probe."""

    batches: tuple[int, ...]
    block_s: float
    repeats: int
    env_batches: tuple[int, ...]
    env_steps: int
    compile_probe: bool
    episode_batch: int  # the whole-episode landing workload (``landing_episode``)
    episode_actions: int


PRESETS: dict[str, Preset] = {
    "full": dict(
        batches=(1, 64, 1024, 16384),
        block_s=0.25,
        repeats=5,
        env_batches=(1, 64, 1024, 4096),
        env_steps=200,
        compile_probe=True,
        episode_batch=1024,
        episode_actions=landing_episode.MAX_EPISODE_STEPS,
    ),
    "quick": dict(
        batches=(1, 64, 1024),  # 16384 in the full run (the landing pre-roll alone takes ~1 min)
        block_s=0.04,
        repeats=3,
        env_batches=(1, 64, 1024, 4096),
        env_steps=30,
        compile_probe=True,
        episode_batch=1024,
        episode_actions=landing_episode.MAX_EPISODE_STEPS,
    ),
    # tiny (the tests) skips the compile-time probe: it compiles from empty caches in fresh
    # processes, seconds per scene.
    "tiny": dict(
        batches=(1, 64),
        block_s=0.005,
        repeats=2,
        env_batches=(1, 64),
        env_steps=5,
        compile_probe=False,
        episode_batch=4,
        episode_actions=2,
    ),
}
DT = 0.01
BREAKDOWN_BATCH = 1024
BACKENDS = ("compiled",)  # how a scene steps: the kernels, serially (the table's column)

SceneFactory = Callable[[str, float], sim.Scene]  # (integrator, dt) -> Scene
InitialFn = Callable[[sim.Scene, int], sim.State]  # (scene, batch) -> State
# (name, factory, initial state: Scene.initial_state keywords or a function, integrators)
SceneCase = tuple[str, SceneFactory, dict[str, Any] | InitialFn, tuple[str, ...]]


@contextlib.contextmanager
def backend(name: str) -> Iterator[None]:
    """Scenes built inside use this backend (the factories take none of their own)."""
    saved = os.environ.get("RIGID_ENV_BACKEND")
    os.environ["RIGID_ENV_BACKEND"] = name
    try:
        yield
    finally:
        if saved is None:
            del os.environ["RIGID_ENV_BACKEND"]
        else:
            os.environ["RIGID_ENV_BACKEND"] = saved


def build(factory: SceneFactory, integrator: str, name: str) -> sim.Scene:
    """The scene on backend ``name``."""
    with backend(name):
        return factory(integrator, DT)


def _best_time(
    fn: Callable[[sim.State], sim.State], state: sim.State, block_s: float, repeats: int
) -> float:
    """Best seconds per call of ``state = fn(state)`` over ``repeats`` blocks."""
    s = fn(fn(state))
    start = time.perf_counter()
    s = fn(s)
    n = max(2, int(block_s / max(time.perf_counter() - start, 1e-7)))
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(n):
            s = fn(s)
        best = min(best, (time.perf_counter() - start) / n)
    return best


def scene_cases() -> list[SceneCase]:
    """(name, factory(integrator, dt), initial state (kwargs or (scene, batch) -> State),
    integrators)."""
    contact = contact_cases.compatible()
    cases: list[SceneCase] = [
        ("free_body", scenes.free_body, {"angular_velocity": scenes.TUMBLE_OMEGA}, sim.INTEGRATORS),
        (
            "stiff_spring",
            lambda i, dt: scenes.stiff_spring(i, dt, 1.0),
            {"position": (0.1, 0.0, 0.0)},
            tuple(i for i in ("splitting", "implicit_gyro", "implicit") if i in sim.INTEGRATORS),
        ),
    ]

    # landing_scene returns (scene, initial_state(batch_shape, rng)); tilts and spins vary
    # per batch element. Pre-rolled so the timed steps have the boxes bouncing and resting
    # on the ground (the contact solver running), the state a training episode spends in.
    # One pre-roll per (Δt, batch), on the default integrator: every timed case starts from
    # the same state.
    prerolled: dict[tuple[float, int], sim.State] = {}

    def landing_initial(scene: sim.Scene, batch: int) -> sim.State:
        key = (scene.dt, batch)
        if key not in prerolled:
            with backend("compiled"):
                roll, initial = landing_scene(dt=scene.dt)
            state = initial(batch_shape=(batch,), rng=np.random.default_rng(0))
            for _ in range(int(round(scenes.LANDING_PREROLL_S / scene.dt))):
                state = roll.step(state)
            prerolled[key] = state
        return prerolled[key]

    cases.append(
        (
            "landing",
            lambda i, dt: landing_scene(integrator=i, dt=dt)[0],
            landing_initial,
            tuple(i for i in ("implicit_gyro", "euler", "implicit") if i in contact),
        )
    )
    cases.append(
        (
            "two_body_impact",
            lambda i, dt: contact_cases.sphere_and_box(i, dt, 1.0)[0],
            lambda scene, batch: _impact_initial(scene, batch),
            tuple(i for i in ("implicit_gyro", "euler") if i in contact),
        )
    )
    return cases


def _impact_initial(scene: sim.Scene, batch: int) -> sim.State:
    """The sphere–box impact of the stability matrix, its box 1.4 m away at 1 m/s per batch
    element with a random extra gap, so impacts spread over the timed steps."""
    _, state, _ = contact_cases.sphere_and_box(scene.integrator, scene.dt, 1.0)
    gap = np.random.default_rng(0).uniform(0.0, 1.0, batch)
    x = np.broadcast_to(state.position, (batch, 2, 3)).copy()
    x[:, 1, 0] -= gap
    return scene.initial_state(
        position=x,
        linear_velocity=np.broadcast_to(state.linear_velocity, (batch, 2, 3)),
    )


def _initial(scene: sim.Scene, initial: dict[str, Any] | InitialFn, batch: int) -> sim.State:
    """``initial`` is Scene.initial_state keywords, or a function of the batch size."""
    if callable(initial):
        return initial(scene, batch)
    return scene.initial_state(**initial, batch_shape=(batch,))


def breakdown(
    scene: sim.Scene, state: sim.State, block_s: float, repeats: int
) -> list[dict[str, Any]]:
    """Seconds per step in each stage, timed inside ``scene.step`` over real steps by the
    scene's public :class:`sim.StageTimer`."""
    clock = time.perf_counter
    saved = scene.timer
    timer = scene.timer = sim.StageTimer()
    try:
        state = scene.step(scene.step(state))  # warm-up
        start = clock()
        state = scene.step(state)
        steps = max(2, int(block_s / max(clock() - start, 1e-7)))
        best: dict[str, float] = {}  # the parts of the fastest block (repeats >= 1)
        total = np.inf
        for _ in range(repeats):  # the least disturbed block, all of its parts
            timer.reset()
            for _ in range(steps):
                state = scene.step(state)
            elapsed = timer.step_seconds / steps
            if elapsed < total:
                total, best = elapsed, timer.per_step()
    finally:
        scene.timer = saved
    rows = [{"stage": "Scene.step's input validation", "s": best["validate"]}]
    rows.append({"stage": f"compiled kernel ({' → '.join(scene.stages)})", "s": best["compiled"]})
    rows.append({"stage": "Scene.step's finiteness check", "s": best["check"]})
    rows.append({"stage": "step total (instrumented)", "s": total})
    return rows


def memory_per_body(scene: sim.Scene, state: sim.State) -> dict[str, float]:
    """State bytes per body, and the peak transient allocation of one step per body."""
    bodies = int(np.prod(state.batch_shape)) * scene.n_bodies
    state_bytes = sum(a.nbytes for a in state.arrays())
    scene.step(state)
    tracemalloc.start()
    scene.step(state)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return {"state_bytes_per_body": state_bytes / bodies, "step_peak_bytes_per_body": peak / bodies}


def measure(preset: str = "full", progress: report.Progress | None = None) -> dict[str, Any]:
    cfg = PRESETS[preset]
    records: list[dict[str, Any]] = []
    stages: dict[str, dict[str, Any]] = {}
    memory: dict[str, dict[str, float]] = {}
    for name, factory, initial, integrators in scene_cases():
        for integrator in integrators:
            for engine_backend in BACKENDS:
                for batch in cfg["batches"]:
                    if progress:
                        progress(f"speed {name} {integrator} {engine_backend} batch={batch}")
                    scene = build(factory, integrator, engine_backend)
                    state = _initial(scene, initial, batch)
                    t = _best_time(scene.step, state, cfg["block_s"], cfg["repeats"])
                    records.append(
                        {
                            "scene": name,
                            "engine": "rigid_env",
                            "backend": scene.backend,
                            "integrator": integrator,
                            "dt": DT,
                            "batch": batch,
                            "bodies": batch * scene.n_bodies,
                            "stages": scene.stages,
                            "s_per_step": t,
                            "body_steps_per_s": batch * scene.n_bodies / t,
                        }
                    )
        default = (
            sim.DEFAULT_INTEGRATOR if sim.DEFAULT_INTEGRATOR in integrators else integrators[0]
        )
        batch = min(BREAKDOWN_BATCH, max(cfg["batches"]))
        for engine_backend in BACKENDS:
            scene = build(factory, default, engine_backend)
            state = _initial(scene, initial, batch)
            key = name
            stages[key] = {
                "integrator": default,
                "backend": scene.backend,
                "batch": batch,
                "stages": scene.stages,
                "rows": breakdown(scene, state, cfg["block_s"], cfg["repeats"]),
            }
            memory[key] = memory_per_body(scene, _initial(scene, initial, max(cfg["batches"])))
    if peers.available():
        records += peers.speed(cfg["batches"], cfg["block_s"], DT, progress)
        records += peers.landing_speed(cfg["batches"], cfg["block_s"], DT, progress)
    return {
        "records": records,
        "stage_breakdown": stages,
        "memory": memory,
        "compile": compile_times(progress) if cfg["compile_probe"] else [],
        "environments": env_speed(cfg, progress),
        "landing_episode": _landing_episode(cfg, progress),
        "peers": peers.status(),
    }


def _landing_episode(cfg: Preset, progress: report.Progress | None) -> dict[str, Any]:
    if progress:
        progress(f"speed landing_episode batch={cfg['episode_batch']}")
    return landing_episode.measure(
        cfg["episode_batch"], cfg["episode_actions"], repeats=min(cfg["repeats"], 3)
    )


# --- compile cost ------------------------------------------------------------------------------

_COMPILE_PROBE = """
import json, sys, time
start = time.perf_counter()
from rigid_env import sim
from rigid_env.sim import scenes
imported = time.perf_counter()
kind = sys.argv[1]
if kind == "landing":
    scene, initial = scenes.landing_scene(dt=0.01)
    state = initial(batch_shape=(1,))
elif kind == "landing_spring":  # the landing scene's kind with other forces: a new composition
    scene = sim.Scene(sim.Body.box(scenes.LANDING_HALF_EXTENTS, 1.0), 0.01,
                      gravity=(0.0, 0.0, -9.81), ground=sim.Ground(restitution=0.3, friction=0.5),
                      springs=[sim.Spring(0, (0.0, 0.0, 1.5), 20.0, 0.5)], angular_damping=0.1)
    state = scene.initial_state(position=(0.0, 0.0, 1.0), batch_shape=(1,))
else:
    scene = sim.Scene(sim.Body.box((0.1, 0.2, 0.3), 1.0), 0.01, integrator=kind)
    state = scene.initial_state(angular_velocity=(0.3, 3.0, 0.6), batch_shape=(1,))
built = time.perf_counter()
scene.step(state)
done = time.perf_counter()
print(json.dumps({"backend": scene.backend, "import_s": imported - start,
                  "scene_s": built - imported, "first_step_s": done - built}))
"""
# (scene, caches): empty (cold), then those the cold run wrote (cached); last the landing
# scene with a spring and damping added, with the landing's caches (a new composition).
COMPILE_RUNS = (
    ("splitting", "cold"),
    ("splitting", "cached"),
    ("landing", "cold"),
    ("landing", "cached"),
    ("landing_spring", "cached"),
)


TOGETHER = 4  # processes that start together on empty caches (vector envs, Ray trials)


def _probe_env(tmp: str) -> dict[str, str]:
    return {
        **os.environ,
        "NUMBA_CACHE_DIR": os.path.join(tmp, "numba"),
        "RIGID_ENV_CACHE_DIR": os.path.join(tmp, "drivers"),
        "RIGID_ENV_BACKEND": "compiled",
    }


def _probes(case: str, env: dict[str, str], count: int) -> list[dict[str, Any]]:
    """``count`` probe processes of ``case`` started together; each one's figures."""
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", _COMPILE_PROBE, case],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for _ in range(count)
    ]
    rows = []
    for proc in procs:
        out, err = proc.communicate()
        if proc.returncode != 0:
            raise subprocess.CalledProcessError(proc.returncode, proc.args, out, err)
        rows.append(json.loads(out.strip().splitlines()[-1]))
    return rows


def compile_times(progress: report.Progress | None = None) -> list[dict[str, Any]]:
    """Seconds to import rigid_env.sim, build a scene and take its first step in a fresh
    process, with empty numba and driver caches (``cold``: everything compiles) and again with
    the caches the first run wrote (``cached``); then the landing scene with a spring and
    damping added, with the landing's caches (``COMPILE_RUNS``); last, ``TOGETHER`` landing
    processes started together on empty caches (``together``: the slowest one's first step,
    and the wall time until all have stepped)."""
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        env = _probe_env(tmp)
        for case, run in COMPILE_RUNS:
            if progress:
                progress(f"compile {case} {run}")
            start = time.perf_counter()
            (row,) = _probes(case, env, 1)
            row.update(case=case, run=run, process_s=time.perf_counter() - start)
            rows.append(row)
    with tempfile.TemporaryDirectory() as tmp:
        if progress:
            progress(f"compile landing, {TOGETHER} processes together")
        start = time.perf_counter()
        together = _probes("landing", _probe_env(tmp), TOGETHER)
        slowest = max(together, key=lambda r: r["first_step_s"])
        slowest.update(case="landing", run="together", process_s=time.perf_counter() - start)
        rows.append(slowest)
    return rows


# --- environments ------------------------------------------------------------------------------


def env_ids() -> list[str]:
    """The registered ``RigidEnv/*`` environments."""
    import gymnasium

    import rigid_env  # noqa: F401  (registers the ids)

    return sorted(k for k in gymnasium.registry if k.startswith("RigidEnv/"))


def env_speed(cfg: Preset, progress: report.Progress | None = None) -> list[dict[str, Any]]:
    """Env steps per second: one env (``gymnasium.make``), and native vector envs of N, each
    run by :func:`rigid_env.bench.env_speed.run`; then Gymnasium's Hopper-v5 as a single env
    beside them when MuJoCo is installed (``peers.available()``; no physics share)."""
    import gymnasium

    from . import env_speed as loop

    rows: list[dict[str, Any]] = []
    for env_id in env_ids():
        if progress:
            progress(f"speed env {env_id}")
        env = gymnasium.make(env_id)
        single = loop.run(env, steps=cfg["env_steps"] * 5)
        env.close()
        rows.append(
            {
                "env": env_id,
                "mode": "single",
                "num_envs": 1,
                "env_steps_per_s": single.steps_per_s,
                "physics_share": single.physics_share,
            }
        )
        for n in cfg["env_batches"]:
            venv = gymnasium.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point")
            vec = loop.run(venv, steps=cfg["env_steps"])
            venv.close()
            rows.append(
                {
                    "env": env_id,
                    "mode": "vector",
                    "num_envs": n,
                    "env_steps_per_s": vec.steps_per_s,
                    "physics_share": vec.physics_share,
                }
            )
    peer = loop.peer_env(loop.PEER) if peers.available() else None
    if peer is not None:
        if progress:
            progress(f"speed env {loop.PEER}")
        rate = loop.run(peer, steps=cfg["env_steps"] * 5)
        peer.close()
        rows.append(
            {
                "env": loop.PEER,
                "mode": "single (peer)",
                "num_envs": 1,
                "env_steps_per_s": rate.steps_per_s,
            }
        )
    return rows


# --- output ------------------------------------------------------------------------------------


def table(result: dict[str, Any]) -> str:
    recs = result["records"]
    batches = sorted({r["batch"] for r in recs})
    keys = list(dict.fromkeys((r["scene"], _engine(r), r["integrator"]) for r in recs))
    rows = []
    for scene, engine, integrator in keys:
        row: dict[str, Any] = {"scene": scene, "engine": engine, "integrator": integrator}
        for r in recs:
            if (r["scene"], _engine(r), r["integrator"]) == (scene, engine, integrator):
                row[f"b{r['batch']}"] = r["body_steps_per_s"]
                if r["batch"] == 1:
                    row["us1"] = r["s_per_step"] * 1e6
        rows.append(row)
    out = [
        "Body-steps per second (dt = 0.01 s; best of repeated blocks, single process; landing "
        f"timed after a {scenes.LANDING_PREROLL_S:g} s pre-roll, boxes bouncing and resting on the "
        "ground; two_body_impact: a sphere–box head-on impact, its solver runs only on steps "
        "in contact):",
        "",
        report.markdown_table(
            rows,
            [
                ("scene", "scene", ""),
                ("engine", "engine", ""),
                ("integrator", "integrator", ""),
                ("µs/step @1", "us1", ".1f"),
                *[(f"batch {b}", f"b{b}", ".3g") for b in batches],
            ],
        ),
    ]
    for name, info in result["stage_breakdown"].items():
        out += [
            "",
            f"Stage breakdown, {name} ({info['integrator']}, batch {info['batch']}, "
            f"stages {info['stages']}), µs per step, timed inside Scene.step over real steps "
            "(each part by its own clock reads; their sum falls short of the total by the "
            "bookkeeping between them):",
            "",
            report.markdown_table(
                [{**r, "us": r["s"] * 1e6} for r in info["rows"]],
                [("stage", "stage", ""), ("µs", "us", ".1f")],
            ),
        ]
    out += ["", *targets(result)]
    if result.get("landing_episode"):
        out += ["", landing_episode.table(result["landing_episode"])]
    if result.get("compile"):
        out += [
            "",
            "Compile cost of the compiled backend: a fresh process imports rigid_env.sim, builds "
            "the scene and takes one step, with empty numba and driver caches (cold: compiles) "
            "and then with the caches that run wrote (cached), seconds:",
            "",
            report.markdown_table(
                result["compile"],
                [
                    ("scene", "case", ""),
                    ("caches", "run", ""),
                    ("backend", "backend", ""),
                    ("import sim", "import_s", ".2f"),
                    ("build scene", "scene_s", ".2f"),
                    ("first step", "first_step_s", ".2f"),
                    ("whole process", "process_s", ".2f"),
                ],
            ),
        ]
    mem = [{"scene": k, **v} for k, v in result["memory"].items()]
    out += [
        "",
        "Memory per body (bytes):",
        "",
        report.markdown_table(
            mem,
            [
                ("scene", "scene", ""),
                ("state", "state_bytes_per_body", ".0f"),
                ("step peak transient", "step_peak_bytes_per_body", ".0f"),
            ],
        ),
    ]
    out += ["", "Environment steps per second:", "", env_table(result)]
    out += [
        "",
        f"MuJoCo: {result['peers']}",
    ]
    return "\n".join(out)


def env_table(result: dict[str, Any]) -> str:
    """Env steps per second of every env, single and native vector, and the physics share."""
    return report.markdown_table(
        result["environments"],
        [
            ("env", "env", ""),
            ("mode", "mode", ""),
            ("N", "num_envs", "d"),
            ("env steps/s", "env_steps_per_s", ".3g"),
            ("physics share", "physics_share", ".0%"),
        ],
    )


def _engine(r: dict[str, Any]) -> str:
    """The table's engine label: MuJoCo, or rigid_env with its backend."""
    if r["engine"] != "rigid_env":
        return r["engine"]
    return f"rigid_env {r['backend']}"


def _record(
    recs: Sequence[dict[str, Any]], scene: str, engine: str, integrator: str, batch: int
) -> dict[str, Any] | None:
    for r in recs:
        if (r["scene"], _engine(r), r["integrator"], r["batch"]) == (
            scene,
            engine,
            integrator,
            batch,
        ):
            return r
    return None


TARGETS = (
    # (what, scene, integrator, MuJoCo integrator, batch, target µs/step or ratio)
    ("free body, batch 1", "free_body", sim.DEFAULT_INTEGRATOR, "RK4", 1, "≤ 5 µs/step"),
    ("landing, batch 1", "landing", sim.CONTACT_INTEGRATOR, "Euler", 1, "≤ 8 µs/step"),
    ("landing, batch 1024", "landing", sim.CONTACT_INTEGRATOR, "Euler", 1024, "≥ 1.5× MuJoCo"),
    ("free body rk4 (equal order), batch 1024", "free_body", "rk4", "RK4", 1024, "≥ 10× MuJoCo"),
    # whole episodes at BoxLanding's Δt: flight, impacts and rest in their proportions
    (
        "landing, whole episodes, batch 1024",
        landing_episode.SCENE,
        sim.CONTACT_INTEGRATOR,
        landing_episode.MUJOCO_INTEGRATOR,
        1024,
        "≥ 1.5× MuJoCo",
    ),
)


def targets(result: dict[str, Any]) -> list[str]:
    """The issue's speed targets against this run's figures and MuJoCo's."""
    recs = [*result["records"], *result.get("landing_episode", {}).get("records", [])]
    rows = []
    for what, scene, integrator, mj, batch, goal in TARGETS:
        row: dict[str, Any] = {"what": what, "goal": goal}
        for b in BACKENDS:
            r = _record(recs, scene, f"rigid_env {b}", integrator, batch)
            row[b] = None if r is None else r["s_per_step"] * 1e6
        peer = _record(recs, scene, "mujoco", mj, batch)
        if peer is not None:
            row["mujoco"] = peer["s_per_step"] * 1e6
            for b in BACKENDS:
                if row[b] is not None:
                    row[f"x_{b}"] = row["mujoco"] / row[b]
        rows.append(row)
    return [
        "Targets (µs per step of the whole batch; × = MuJoCo's time / ours per body, so > 1 is "
        "faster than MuJoCo; rk4 against MuJoCo's RK4 at the same dt is the equal-accuracy "
        "comparison: both fourth order, same body and tumble):",
        "",
        report.markdown_table(
            rows,
            [
                ("case", "what", ""),
                ("target", "goal", ""),
                ("rigid_env µs", "compiled", ".1f"),
                ("MuJoCo µs", "mujoco", ".1f"),
                ("× MuJoCo", "x_compiled", ".2f"),
            ],
        ),
    ]


def plot(result: dict[str, Any], path: Path) -> None:
    recs = result["records"]
    scenes_ = list(dict.fromkeys(r["scene"] for r in recs))
    fig, axes = report.subplots(len(scenes_) + 1)
    for ax, scene in zip(axes, scenes_, strict=False):
        for key in dict.fromkeys(
            (_engine(r), r["integrator"]) for r in recs if r["scene"] == scene
        ):
            line = sorted(
                (r for r in recs if r["scene"] == scene and (_engine(r), r["integrator"]) == key),
                key=lambda r: r["batch"],
            )
            ours = key[0].startswith("rigid_env")
            label = f"{key[1]} ({key[0].split()[1]})" if ours else f"MuJoCo {key[1]}"
            ax.loglog(
                [r["batch"] for r in line],
                [r["body_steps_per_s"] for r in line],
                "^-" if ours else "s--",
                ms=3,
                label=label,
            )
        ax.set(title=scene, xlabel="batch size", ylabel="body-steps / s")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    ax = axes[-1]
    for name, info in result["stage_breakdown"].items():
        rows = [r for r in info["rows"] if not r["stage"].startswith("step total")]
        left = 0.0
        for r in rows:
            ax.barh(name, r["s"] * 1e6, left=left, label=r["stage"])
            left += max(r["s"], 0.0) * 1e6
    ax.set(title=f"per-stage µs per step (batch {BREAKDOWN_BATCH})", xlabel="µs")
    ax.legend(fontsize=6)
    report.save(fig, path)

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

(An earlier breakdown timed each stage in isolation at the initial state and called the
difference "rest of Scene.step": for the landing scene, whose box starts 1 m up, the isolated
contact stage took its no-contact early exit while the timed steps hit the ground, and the
splitting integrator's force handling (kicks, body-frame torques) was counted in neither part.)
"""

from __future__ import annotations

import time
import tracemalloc

import numpy as np

from rigid_env import sim

from . import contact_cases, peers, report, scenes

PRESETS = {
    "full": dict(
        batches=(1, 64, 1024, 16384),
        block_s=0.25,
        repeats=5,
        env_batches=(1, 64, 1024, 4096),
        env_steps=200,
    ),
    "quick": dict(
        batches=(1, 64, 1024),  # 16384 in the full run (the landing pre-roll alone takes ~1 min)
        block_s=0.04,
        repeats=3,
        env_batches=(1, 64, 1024, 4096),
        env_steps=30,
    ),
    "tiny": dict(batches=(1, 64), block_s=0.005, repeats=2, env_batches=(1, 64), env_steps=5),
}
DT = 0.01
BREAKDOWN_BATCH = 1024


def _best_time(fn, state, block_s: float, repeats: int) -> float:
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


LANDING_PREROLL_S = 1.0  # the landing batch is timed after this long: boxes on the ground


def scene_cases() -> list[tuple[str, object, dict, tuple[str, ...]]]:
    """(name, factory(integrator, dt), initial state (kwargs or (scene, batch) -> State),
    integrators)."""
    contact = tuple(i for i in contact_cases.compatible() if i in sim.INTEGRATORS)
    cases = [
        ("free_body", scenes.free_body, {"angular_velocity": scenes.TUMBLE_OMEGA}, sim.INTEGRATORS),
        (
            "stiff_spring",
            lambda i, dt: scenes.stiff_spring(i, dt, 1.0),
            {"position": (0.1, 0.0, 0.0)},
            tuple(i for i in ("splitting", "implicit_gyro", "implicit") if i in sim.INTEGRATORS),
        ),
    ]
    landing = scenes.optional_scene("landing_scene")
    if landing is not None:
        # landing_scene returns (scene, initial_state(batch_shape, rng)); tilts and spins vary
        # per batch element. Pre-rolled so the timed steps have the boxes bouncing and resting
        # on the ground (the contact solver running), the state a training episode spends in.
        def landing_initial(scene, batch):
            state = landing()[1](batch_shape=(batch,), rng=np.random.default_rng(0))
            for _ in range(int(round(LANDING_PREROLL_S / scene.dt))):
                state = scene.step(state)
            return state

        cases.append(
            (
                "landing",
                lambda i, dt: landing(integrator=i, dt=dt)[0],
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


def _impact_initial(scene, batch):
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


def unavailable_scenes() -> list[str]:
    missing = []
    if scenes.optional_scene("landing_scene") is None:
        missing.append("landing (rigid_env.sim.scenes.landing_scene not in this checkout)")
    return missing


def _initial(scene, initial, batch: int):
    """``initial`` is Scene.initial_state keywords, or a function of the batch size."""
    if callable(initial):
        return initial(scene, batch)
    return scene.initial_state(**initial, batch_shape=(batch,))


def breakdown(scene: sim.Scene, state: sim.State, block_s: float, repeats: int) -> list[dict]:
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
        best, total = None, np.inf
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
    rows += [{"stage": name, "s": best[name]} for name in scene.stages]
    rows.append({"stage": "Scene.step's finiteness check", "s": best["check"]})
    rows.append({"stage": "step total (instrumented)", "s": total})
    return rows


def memory_per_body(scene: sim.Scene, state: sim.State) -> dict:
    """State bytes per body, and the peak transient allocation of one step per body."""
    bodies = int(np.prod(state.batch_shape)) * scene.n_bodies
    state_bytes = sum(a.nbytes for a in state.arrays())
    scene.step(state)
    tracemalloc.start()
    scene.step(state)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return {"state_bytes_per_body": state_bytes / bodies, "step_peak_bytes_per_body": peak / bodies}


def measure(preset: str = "full", progress=None) -> dict:
    cfg = PRESETS[preset]
    records, stages, memory = [], {}, {}
    for name, factory, initial, integrators in scene_cases():
        for integrator in integrators:
            for batch in cfg["batches"]:
                if progress:
                    progress(f"speed {name} {integrator} batch={batch}")
                scene = factory(integrator, DT)
                state = _initial(scene, initial, batch)
                t = _best_time(scene.step, state, cfg["block_s"], cfg["repeats"])
                records.append(
                    {
                        "scene": name,
                        "engine": "rigid_env",
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
        scene = factory(default, DT)
        batch = min(BREAKDOWN_BATCH, max(cfg["batches"]))
        state = _initial(scene, initial, batch)
        stages[name] = {
            "integrator": default,
            "batch": batch,
            "stages": scene.stages,
            "rows": breakdown(scene, state, cfg["block_s"], cfg["repeats"]),
        }
        memory[name] = memory_per_body(scene, _initial(scene, initial, max(cfg["batches"])))
    if peers.available():
        records += peers.speed(cfg["batches"], cfg["block_s"], DT, progress)
        if scenes.optional_scene("landing_scene") is not None:
            records += peers.landing_speed(cfg["batches"], cfg["block_s"], DT, progress)
    return {
        "records": records,
        "stage_breakdown": stages,
        "memory": memory,
        "environments": env_speed(cfg, progress),
        "unavailable": unavailable_scenes(),
        "peers": peers.status(),
    }


# --- environments ------------------------------------------------------------------------------


def env_ids() -> list[str]:
    """The registered ``RigidEnv/*`` environments (importing ``rigid_env.envs`` registers them)."""
    try:
        import gymnasium

        import rigid_env.envs  # noqa: F401
    except ImportError:
        return []
    return sorted(k for k in gymnasium.registry if k.startswith("RigidEnv/"))


def env_speed(cfg: dict, progress=None) -> list[dict]:
    """Env steps per second: one env (``gymnasium.make``), and native vector envs of N."""
    import gymnasium

    rows = []
    for env_id in env_ids():
        if progress:
            progress(f"speed env {env_id}")
        env = gymnasium.make(env_id)
        env.reset(seed=0)
        actions = [env.action_space.sample() for _ in range(64)]
        rate = _env_rate(env, actions, cfg["env_steps"] * 5, 1)
        env.close()
        rows.append({"env": env_id, "mode": "single", "num_envs": 1, "env_steps_per_s": rate})
        for n in cfg["env_batches"]:
            try:
                venv = gymnasium.make_vec(
                    env_id, num_envs=n, vectorization_mode="vector_entry_point"
                )
            except Exception as err:  # the env may not ship a native vector version
                rows.append(
                    {
                        "env": env_id,
                        "mode": "vector",
                        "num_envs": n,
                        "env_steps_per_s": None,
                        "note": f"no native vector env: {err}",
                    }
                )
                break
            venv.reset(seed=0)
            acts = [venv.action_space.sample() for _ in range(8)]
            rows.append(
                {
                    "env": env_id,
                    "mode": "vector",
                    "num_envs": n,
                    "env_steps_per_s": _env_rate(venv, acts, cfg["env_steps"], n),
                }
            )
            venv.close()
    return rows


def _env_rate(env, actions, steps: int, n: int) -> float:
    for a in actions[:2]:
        env.step(a)
    start = time.perf_counter()
    for i in range(steps):
        _, _, term, trunc, _ = env.step(actions[i % len(actions)])
        if n == 1 and (term or trunc):
            env.reset()
    return n * steps / (time.perf_counter() - start)


# --- output ------------------------------------------------------------------------------------


def table(result: dict) -> str:
    recs = result["records"]
    batches = sorted({r["batch"] for r in recs})
    keys = list(dict.fromkeys((r["scene"], r["engine"], r["integrator"]) for r in recs))
    rows = []
    for scene, engine, integrator in keys:
        row = {"scene": scene, "engine": engine, "integrator": integrator}
        for r in recs:
            if (r["scene"], r["engine"], r["integrator"]) == (scene, engine, integrator):
                row[f"b{r['batch']}"] = r["body_steps_per_s"]
                if r["batch"] == 1:
                    row["us1"] = r["s_per_step"] * 1e6
        rows.append(row)
    out = [
        "Body-steps per second (dt = 0.01 s; best of repeated blocks, single process; landing "
        f"timed after a {LANDING_PREROLL_S:g} s pre-roll, boxes bouncing and resting on the "
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
    envs = result["environments"]
    if envs:
        out += [
            "",
            "Environment steps per second:",
            "",
            report.markdown_table(
                envs,
                [
                    ("env", "env", ""),
                    ("mode", "mode", ""),
                    ("N", "num_envs", "d"),
                    ("env steps/s", "env_steps_per_s", ".3g"),
                    ("note", "note", ""),
                ],
            ),
        ]
    else:
        out += ["", "Environments: not available (no RigidEnv/* registered in this checkout)."]
    out += [
        "",
        *(f"Not available: {m}" for m in result["unavailable"]),
        "",
        f"MuJoCo: {result['peers']}",
    ]
    return "\n".join(out)


def plot(result: dict, path) -> None:
    recs = result["records"]
    scenes_ = list(dict.fromkeys(r["scene"] for r in recs))
    fig, axes = report.subplots(len(scenes_) + 1)
    for ax, scene in zip(axes, scenes_, strict=False):
        for key in dict.fromkeys(
            (r["engine"], r["integrator"]) for r in recs if r["scene"] == scene
        ):
            line = sorted(
                (r for r in recs if r["scene"] == scene and (r["engine"], r["integrator"]) == key),
                key=lambda r: r["batch"],
            )
            label = key[1] if key[0] == "rigid_env" else f"MuJoCo {key[1]}"
            ax.loglog(
                [r["batch"] for r in line],
                [r["body_steps_per_s"] for r in line],
                "o-" if key[0] == "rigid_env" else "s--",
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

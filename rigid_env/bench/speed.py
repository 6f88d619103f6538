"""Speed: body-steps per second of each scene and integrator, per-stage costs, memory, envs.

Timing hygiene: ``time.perf_counter``; two warm-up steps; then ``REPEATS`` blocks of enough
steps to last ~``block_s`` each, reporting the best block (the least disturbed by the OS).

The per-stage breakdown times each piece of a scene's step on its own at the same state: the
integrator core with no force terms, each force term (one call × the number of calls the
integrator makes per step, counted), each post-integration stage (contacts), and the remainder
of ``Scene.step`` (validation, the finiteness check). A stage a scene does not list in
``scene.stages`` is never called, which the free body's breakdown shows: its step is the
integrator core plus the fixed overhead.
"""

from __future__ import annotations

import time
import tracemalloc

import numpy as np

from rigid_env import sim
from rigid_env.sim import forces as sim_forces
from rigid_env.sim.integrators import REGISTRY

from . import peers, report, scenes

PRESETS = {
    "full": dict(
        batches=(1, 64, 1024, 16384),
        block_s=0.25,
        repeats=5,
        env_batches=(1, 64, 1024, 4096),
        env_steps=200,
    ),
    "quick": dict(
        batches=(1, 64, 1024, 16384),
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


def scene_cases() -> list[tuple[str, object, dict, tuple[str, ...]]]:
    """(name, factory(integrator, dt), initial state (kwargs or batch -> State), integrators)."""
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
        # per batch element so the contact branches are exercised as in training.
        cases.append(
            (
                "landing",
                lambda i, dt: landing(integrator=i, dt=dt)[0],
                lambda batch: landing()[1](batch_shape=(batch,), rng=np.random.default_rng(0)),
                tuple(i for i in ("implicit_gyro", "euler", "implicit") if i in sim.INTEGRATORS),
            )
        )
    return cases


def unavailable_scenes() -> list[str]:
    missing = []
    if scenes.optional_scene("landing_scene") is None:
        missing.append("landing (rigid_env.sim.scenes.landing_scene not in this checkout)")
    missing.append("two_body_impact (the simulator has no body-body contacts in this checkout)")
    return missing


def _initial(scene, initial, batch: int):
    """``initial`` is Scene.initial_state keywords, or a function of the batch size."""
    if callable(initial):
        return initial(batch)
    return scene.initial_state(**initial, batch_shape=(batch,))


def breakdown(scene: sim.Scene, state: sim.State, block_s: float, repeats: int) -> list[dict]:
    """Seconds per step spent in each stage of ``scene.stages`` plus the step's own overhead."""
    model, dt = scene.model, scene.dt
    integrate = REGISTRY[scene.integrator]
    terms = sim_forces.build_terms(model)
    calls = [0]

    def counted(x, q, v, w, force, torque):
        calls[0] += 1
        return force, torque

    integrate(model, state, dt, counted if terms else None, None, None)
    total = _best_time(scene.step, state, block_s, repeats)
    rows = [
        {
            "stage": "integrate (core, no forces)",
            "s": _best_time(
                lambda s: integrate(model, s, dt, None, None, None), state, block_s, repeats
            ),
        }
    ]
    x, q, v, w = state.arrays()
    for name, term in terms:
        per_call = _best_time(lambda s, t=term: (t(x, q, v, w), s)[1], state, block_s, repeats)
        rows.append({"stage": f"{name} (×{calls[0]} per step)", "s": per_call * calls[0]})
    new = scene.step(state)
    for name, stage in getattr(scene, "_post_stages", ()):
        rows.append(
            {
                "stage": name if isinstance(name, str) else " + ".join(name),
                "s": _best_time(lambda s, f=stage: (f(state, new), s)[1], state, block_s, repeats),
            }
        )
    rows.append(
        {"stage": "rest of Scene.step (checks, force sum)", "s": total - sum(r["s"] for r in rows)}
    )
    rows.append({"stage": "step total", "s": total})
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
    peer = peers.speed(cfg["batches"], cfg["block_s"], DT, progress) if peers.available() else None
    if peer:
        records += peer
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
        "Body-steps per second (dt = 0.01 s; best of repeated blocks, single process):",
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
            f"stages {info['stages']}), µs per step:",
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
        rows = [r for r in info["rows"] if r["stage"] != "step total"]
        left = 0.0
        for r in rows:
            ax.barh(name, r["s"] * 1e6, left=left, label=r["stage"])
            left += max(r["s"], 0.0) * 1e6
    ax.set(title=f"per-stage µs per step (batch {BREAKDOWN_BATCH})", xlabel="µs")
    ax.legend(fontsize=6)
    report.save(fig, path)

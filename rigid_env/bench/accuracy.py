"""Work–precision: each integrator's error against exact solutions, and what the accuracy costs.

For every problem, integrator and time step the run is scored at evenly spaced checkpoints
against the reference; every figure is the maximum over the checkpoints:

* ``orientation_error`` geodesic angle between q and q_ref (rad); ``angular_velocity_error``
  |ω − ω_ref| (rad/s); ``position_error``/``velocity_error`` likewise (m, m/s);
* ``energy_drift`` |E − E_ref| / max|E_ref| and ``momentum_drift`` |L − L_ref| / max|L_ref|,
  with E_ref, L_ref evaluated on the reference state (so a damped or driven problem is scored
  against its true energy, not against a constant);
* ``wall_s_per_sim_s`` wall time per simulated second, at batch 1 (timed over the scored run)
  and at batch 1024 (timed over a shorter run of identical copies, whole batch).

The landing scene's first bounce (:mod:`rigid_env.bench.bounce`) is scored separately, for the
contact-capable integrators only: post-bounce velocity and angular momentum against the impulse
closed form (and the bounce apex against ε²h for the flat drop).

The observed order is the least-squares slope of log(error) against log(dt) over the points
in the asymptotic range: above the rounding floor and below ``ASYMPTOTIC_MAX``.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, TypedDict

import numpy as np

from rigid_env import sim
from rigid_env.sim.rotation import quat_angle

from . import bounce, peers, problems, report

THEORETICAL_ORDER = {name: record.order for name, record in sim.INTEGRATOR_RECORDS.items()}
TARGETS = (1e-3, 1e-6, 1e-9)
ASYMPTOTIC_MAX = 1e-2  # above this the leading error term does not yet dominate
# Rounding accumulates like the step count: below ~100 ε per step an error is rounding, not
# truncation (Hairer, Lubich & Wanner, "Geometric Numerical Integration", §VIII.5).
ROUNDING_PER_STEP = 100 * np.finfo(float).eps


class Preset(TypedDict):
    """A dt sweep: run length (s), checkpoints, dts by theoretical order, steps timed at batch
    1024, dts of the first-bounce runs. High-order methods need larger dt to stay above rounding."""

    duration: float
    checkpoints: int
    dts: dict[int, tuple[float, ...]]
    batch_steps: int
    bounce_dts: tuple[float, ...]


PRESETS: dict[str, Preset] = {
    "full": dict(
        duration=20.0,
        checkpoints=20,
        dts={
            1: (0.02, 0.01, 0.005, 0.002, 0.001),
            2: (0.05, 0.02, 0.01, 0.005, 0.002, 0.001),
            4: (0.04, 0.02, 0.01, 0.005, 0.0025, 0.00125),
        },
        batch_steps=100,
        bounce_dts=(1 / 60, 1 / 120, 1 / 240, 1 / 480, 1 / 960, 1 / 1920),
    ),
    "quick": dict(
        duration=4.0,
        checkpoints=8,
        dts={1: (0.01, 0.005, 0.0025), 2: (0.02, 0.01, 0.005), 4: (0.04, 0.02, 0.01)},
        batch_steps=20,
        bounce_dts=(1 / 60, 1 / 240, 1 / 960),
    ),
    "tiny": dict(
        duration=1.0,
        checkpoints=4,
        dts={1: (0.004, 0.002), 2: (0.01, 0.005), 4: (0.04, 0.02)},
        batch_steps=5,
        bounce_dts=(1 / 60, 1 / 240),
    ),
}
BATCH = 1024
ORDER_SCENES = ("dzhanibekov", "symmetric_top", "damped_spring", "spin_up")


def _reference_state(
    scene: sim.Scene, initial: dict[str, Any], ref: dict[str, np.ndarray]
) -> sim.State:
    """The reference as a State (T, 1 body); fields the reference omits keep initial values."""
    names = ("position", "orientation", "linear_velocity", "angular_velocity")
    fields = {k: initial.get(k) if k not in ref else np.asarray(ref[k])[:, None, :] for k in names}
    return scene.initial_state(**fields, batch_shape=(len(next(iter(ref.values()))),))


def run(
    problem: problems.Problem, integrator: str, dt: float, duration: float, checkpoints: int
) -> dict[str, Any]:
    """One scored batch-1 run; returns the error figures and the batch-1 wall time."""
    scene = problem.build(integrator, dt)
    n_steps = int(round(duration / dt))
    marks = np.unique(np.linspace(0, n_steps, checkpoints + 1).round().astype(int))[1:]
    state = scene.initial_state(**problem.initial)
    torque = problem.torque
    saved, wall, done = [], 0.0, 0
    try:
        for mark in marks:
            start = time.perf_counter()
            for _ in range(mark - done):
                state = scene.step(state, torque=torque)
            wall += time.perf_counter() - start
            done = mark
            saved.append(state)
    except sim.DivergenceError:
        return {"diverged_at_step": done, "wall_s_per_sim_s": None}
    times = marks * dt
    got = sim.State(*(np.stack([s.arrays()[i] for s in saved]) for i in range(4)))
    ref = _reference_state(scene, problem.initial, problem.reference(times))
    out = {
        "orientation_error": float(np.max(quat_angle(got.orientation, ref.orientation))),
        "angular_velocity_error": _max_norm(got.angular_velocity - ref.angular_velocity),
        "position_error": _max_norm(got.position - ref.position),
        "velocity_error": _max_norm(got.linear_velocity - ref.linear_velocity),
        "energy_drift": _relative(scene.energy(got), scene.energy(ref)),
        "momentum_drift": _relative(scene.angular_momentum(got), scene.angular_momentum(ref)),
        "wall_s_per_sim_s": wall / (done * dt),
        "steps": done,
    }
    out["error"] = out[f"{problem.main_error}_error"]
    return out


def _max_norm(a: np.ndarray) -> float:
    return float(np.max(np.linalg.norm(a, axis=-1)))


def _relative(got: np.ndarray, ref: np.ndarray) -> float:
    diff = np.abs(got - ref) if got.ndim == 1 else np.linalg.norm(got - ref, axis=-1)
    scale = np.max(np.abs(ref) if ref.ndim == 1 else np.linalg.norm(ref, axis=-1))
    return float(np.max(diff) / scale) if scale > 0 else float(np.max(diff))


def batch_wall(
    problem: problems.Problem, integrator: str, dt: float, steps: int, batch: int = BATCH
) -> float:
    """Wall seconds per simulated second for ``batch`` copies (best of three timings)."""
    scene = problem.build(integrator, dt)
    state = scene.initial_state(**problem.initial, batch_shape=(batch,))
    state = scene.step(state, torque=problem.torque)  # warm-up
    best = np.inf
    for _ in range(3):
        s = state
        start = time.perf_counter()
        for _ in range(steps):
            s = scene.step(s, torque=problem.torque)
        best = min(best, time.perf_counter() - start)
    return best / (steps * dt)


def observed_order(
    dts: Sequence[float], errors: Sequence[float | None], duration: float | None = None
) -> float | None:
    """Slope of log error vs log dt over the asymptotic points (None if fewer than two).

    With ``duration`` a point counts only above the rounding accumulated over its steps.
    """
    pts = [
        (d, e)
        for d, e in zip(dts, errors, strict=True)
        if e is not None
        and e < ASYMPTOTIC_MAX
        and e > (ROUNDING_PER_STEP * duration / d if duration else 0.0)
    ]
    if len(pts) < 2:
        return None
    x, y = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
    return float(np.polyfit(x, y, 1)[0])


def measure(
    preset: str = "full",
    integrators: Sequence[str] | None = None,
    problem_list: Sequence[problems.Problem] | None = None,
    progress: report.Progress | None = None,
) -> dict[str, Any]:
    """Every (problem, integrator, dt) record, observed orders and the target table."""
    cfg = PRESETS[preset]
    integrators = tuple(integrators or sim.INTEGRATORS)
    problem_list = problem_list or problems.all_problems()
    records: list[dict[str, Any]] = []
    orders: dict[str, dict[str, float | None]] = {}
    for problem in problem_list:
        for integrator in integrators:
            dts = cfg["dts"][THEORETICAL_ORDER.get(integrator, 1)]
            errors: list[float | None] = []
            for dt in dts:
                if progress:
                    progress(f"accuracy {problem.name} {integrator} dt={dt}")
                res = run(problem, integrator, dt, cfg["duration"], cfg["checkpoints"])
                base = {
                    "scene": problem.name,
                    "engine": "rigid_env",
                    "integrator": integrator,
                    "dt": dt,
                    "duration_s": cfg["duration"],
                    "error_kind": problem.main_error,
                }
                records.append({**base, "batch": 1, **res})
                errors.append(res.get("error"))
                if res.get("error") is not None:
                    wall = batch_wall(problem, integrator, dt, cfg["batch_steps"])
                    records.append({**base, **res, "batch": BATCH, "wall_s_per_sim_s": wall})
            orders.setdefault(integrator, {})[problem.name] = observed_order(
                dts, errors, cfg["duration"]
            )
    summary: dict[str, dict[str, Any]] = {}
    for name, per in orders.items():
        # Prefer the Dzhanibekov problem: it exercises every term of the free rotation; on
        # others some methods are exact (Verlet on a constant torque) or leave the asymptotic
        # range only at tiny dt, so they have no order to fit.
        scene = next((s for s in ORDER_SCENES if per.get(s) is not None), None)
        summary[name] = {
            "theoretical": THEORETICAL_ORDER.get(name),
            "observed": None if scene is None else per[scene],
            "observed_on": scene,
            "by_scene": per,
        }
    bounce_records, bounce_orders = measure_bounce(
        cfg["bounce_dts"], max(10, cfg["batch_steps"]), progress
    )
    records += bounce_records
    for name, per in bounce_orders.items():
        summary.setdefault(
            name,
            {"theoretical": THEORETICAL_ORDER.get(name), "observed": None, "observed_on": None},
        ).setdefault("by_scene", {}).update(per)
    peer_orders: dict[str, dict[str, float | None]] = {}
    if peers.available():
        if progress:
            progress("accuracy MuJoCo first bounce")
        peer = peers.bounce_accuracy(
            bounce.drops(), cfg["bounce_dts"], BATCH, max(10, cfg["batch_steps"])
        )
        records += peer
        for name in peers.INTEGRATORS:
            for drop in bounce.drops():
                rows = [
                    r
                    for r in peer
                    if r["integrator"] == name
                    and r["batch"] == 1
                    and r["scene"] == f"first_bounce_{drop.name}"
                ]
                peer_orders.setdefault(name, {})[f"first_bounce_{drop.name}"] = observed_order(
                    [r["dt"] for r in rows], [r["error"] for r in rows]
                )
    if peers.available():
        dzh = next((p for p in problem_list if p.name == "dzhanibekov"), None)
        if dzh is not None:
            if progress:
                progress("accuracy MuJoCo dzhanibekov")
            peer = peers.accuracy(dzh, cfg["dts"], cfg["duration"], cfg["checkpoints"], BATCH)
            records += peer
            for name in peers.INTEGRATORS:
                rows = [r for r in peer if r["integrator"] == name and r["batch"] == 1]
                peer_orders.setdefault(name, {})["dzhanibekov"] = observed_order(
                    [r["dt"] for r in rows], [r["error"] for r in rows]
                )
    return {
        "duration_s": cfg["duration"],
        "records": records,
        "observed_order": summary,
        "peer_orders": peer_orders,
        "peers": peers.status(),
        "targets": cheapest_for_targets(records, "dzhanibekov"),
    }


def measure_bounce(
    dts: Sequence[float], batch_steps: int, progress: report.Progress | None = None
) -> tuple[list[dict[str, Any]], dict[str, dict[str, float | None]]]:
    """The landing scene's first bounce (:mod:`bounce`) for every contact-capable integrator:
    post-bounce velocity and angular-momentum errors against the impulse closed form."""
    records: list[dict[str, Any]] = []
    orders: dict[str, dict[str, float | None]] = {}
    for drop in bounce.drops():
        scene = f"first_bounce_{drop.name}"
        for integrator in bounce.integrators():
            errors: list[float | None] = []
            for dt in dts:
                if progress:
                    progress(f"accuracy {scene} {integrator} dt={dt:.3g}")
                res = bounce.run(drop, integrator, dt)
                base = {
                    "scene": scene,
                    "engine": "rigid_env",
                    "integrator": integrator,
                    "dt": dt,
                    "error_kind": "post-bounce velocity",
                    "restitution": drop.restitution,
                    "height_m": drop.height,
                    **res,
                }
                for batch in (1, BATCH):
                    wall = bounce.batch_wall(drop, integrator, dt, batch, batch_steps)
                    records.append({**base, "batch": batch, "wall_s_per_sim_s": wall})
                errors.append(res["error"])
            orders.setdefault(integrator, {})[scene] = observed_order(dts, errors)
    return records, orders


def cheapest_for_targets(
    records: list[dict[str, Any]], scene: str, targets: Sequence[float] = TARGETS
) -> list[dict[str, Any]]:
    """For each target error and batch size (1, 1024), the measured (engine, integrator, dt)
    reaching it at least wall time per simulated second per body."""
    rows = []
    for batch in (1, BATCH):
        pool = [
            r
            for r in records
            if r["scene"] == scene and r["batch"] == batch and r.get("error") is not None
        ]
        for target in targets:
            ok = [r for r in pool if r["error"] <= target]
            best = min(ok, key=lambda r: r["wall_s_per_sim_s"], default=None)
            rows.append(
                {
                    "target_rad": target,
                    "batch": batch,
                    "engine": best and best["engine"],
                    "integrator": best and best["integrator"],
                    "dt": best and best["dt"],
                    "error": best and best["error"],
                    "wall_s_per_sim_s": best and best["wall_s_per_sim_s"],
                    "wall_s_per_body_sim_s": best and best["wall_s_per_sim_s"] / batch,
                }
            )
    return rows


# --- output ------------------------------------------------------------------------------------


def targets_table(result: dict[str, Any]) -> str:
    """The cheapest measured (engine, integrator, dt) reaching each orientation error."""
    return report.markdown_table(
        result["targets"],
        [
            ("target (rad)", "target_rad", ".0e"),
            ("batch", "batch", "d"),
            ("engine", "engine", ""),
            ("integrator", "integrator", ""),
            ("dt (s)", "dt", "g"),
            ("error (rad)", "error", ".2e"),
            ("wall s / sim s (whole batch)", "wall_s_per_sim_s", ".2e"),
            ("per body", "wall_s_per_body_sim_s", ".2e"),
        ],
    )


def orders_table(result: dict[str, Any]) -> str:
    """Theoretical and observed order of every integrator, overall and per problem."""
    orders = [
        {"integrator": k, **v, **{f"order_{s}": o for s, o in v["by_scene"].items()}}
        for k, v in result["observed_order"].items()
    ]
    return report.markdown_table(
        orders,
        [
            ("integrator", "integrator", ""),
            ("theoretical", "theoretical", "d"),
            ("observed", "observed", ".2f"),
            ("fitted on", "observed_on", ""),
            *[(s, f"order_{s}", ".2f") for s in ORDER_SCENES],
        ],
    )


def table(result: dict[str, Any]) -> str:
    out = [
        "Cheapest measured integrator and dt reaching each orientation error on the "
        f"Dzhanibekov problem after {result['duration_s']:g} s, at batch 1 and batch {BATCH}:",
        "",
        targets_table(result),
        "",
        "Observed order (slope of log error vs log dt in the asymptotic range):",
        "",
        orders_table(result),
    ]
    out += ["", first_bounce_table(result)]
    out += ["", f"MuJoCo: {result['peers']}"]
    if result["peer_orders"]:
        out += [
            "",
            report.markdown_table(
                [
                    {"integrator": k, "theoretical": peers.THEORETICAL_ORDER[k], **v}
                    for k, v in result["peer_orders"].items()
                ],
                [
                    ("MuJoCo integrator", "integrator", ""),
                    ("theoretical", "theoretical", "d"),
                    ("observed (dzhanibekov)", "dzhanibekov", ".2f"),
                    ("first bounce flat", "first_bounce_flat", ".2f"),
                    ("first bounce corner", "first_bounce_corner", ".2f"),
                ],
            ),
        ]
    return "\n".join(out)


def first_bounce_table(result: dict[str, Any]) -> str:
    rows = [
        {**r, "dt_inv": 1 / r["dt"]}
        for r in result["records"]
        if r["scene"].startswith("first_bounce") and r["batch"] == 1
    ]
    if not rows:
        return "First bounce: not available (no contact-capable integrator in this checkout)."
    return "\n".join(
        [
            "First bounce of the landing box (frictionless ground, ε = 0.5, dropped from 1 m; "
            "flat = face down, corner = tilted, one corner strikes) against the impulse closed "
            "form; errors relative to the impact speed (v, apex) or to |r| m |v⁻| (L), worst "
            f"of {bounce.PHASES} impact instants spread over one step:",
            "",
            report.markdown_table(
                rows,
                [
                    ("drop", "scene", ""),
                    ("engine", "engine", ""),
                    ("integrator", "integrator", ""),
                    ("1/dt", "dt_inv", ".0f"),
                    ("v⁺ error", "velocity_error", ".2e"),
                    ("L⁺ error", "momentum_error", ".2e"),
                    ("apex error", "apex_error", ".2e"),
                    ("impact time error (s)", "impact_time_error", ".1e"),
                    ("wall s / sim s", "wall_s_per_sim_s", ".2e"),
                ],
            ),
        ]
    )


def plot(result: dict[str, Any], path: Path) -> None:
    """Error against batch-1 run time, log–log, one panel per problem, one line per method."""
    records = [r for r in result["records"] if r["batch"] == 1 and r.get("error")]
    scenes = list(dict.fromkeys(r["scene"] for r in records))
    fig, axes = report.subplots(len(scenes))
    orders = result["observed_order"]
    for ax, scene in zip(axes, scenes, strict=True):
        rows = [r for r in records if r["scene"] == scene]
        for key in dict.fromkeys((r["engine"], r["integrator"]) for r in rows):
            line = sorted(
                (r for r in rows if (r["engine"], r["integrator"]) == key),
                key=lambda r: r["wall_s_per_sim_s"],
            )
            p = (
                orders.get(key[1], {}).get("by_scene", {}).get(scene)
                if key[0] == "rigid_env"
                else result.get("peer_orders", {}).get(key[1], {}).get(scene)
            )
            label = (key[1] if key[0] == "rigid_env" else f"MuJoCo {key[1]}") + (
                f"  (p≈{p:.2f})" if p is not None else ""
            )
            ax.loglog(
                [r["wall_s_per_sim_s"] for r in line],
                [r["error"] for r in line],
                "o-" if key[0] == "rigid_env" else "s--",
                ms=3,
                label=label,
            )
        kind = rows[0]["error_kind"]
        unit = {"orientation": "rad", "position": "m"}.get(kind, "relative")
        ax.set(
            title=scene,
            xlabel="wall s per simulated s (batch 1)",
            ylabel=f"max {kind} error ({unit})",
        )
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(f"rigid_env accuracy vs cost ({result['duration_s']:g} s runs)")
    report.save(fig, path)

"""Stability: a matrix of stiff and extreme cases × integrators.

Each cell runs a case from a valid state and reports ``status``:

* ``diverged`` — the simulator raised :class:`sim.DivergenceError` (a non-finite result) or the
  energy grew past ``BLOWUP`` × its initial value; ``first_divergence_step`` says when
  (to within ``check_every`` steps). Nothing is left as a silent NaN: every figure is finite
  or ``None``.
* ``drifting`` — finite, but the relative energy (or |L|) drift exceeded ``DRIFT_LIMIT``.
* ``stable`` — otherwise.

Energy drift is max |E − E0| / E0 over the checks; momentum drift max |L − L0| / |L0| where
angular momentum is conserved (free bodies), else ``None``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rigid_env import sim

from . import report, scenes

BLOWUP = 1e3
DRIFT_LIMIT = 0.1
DT = 0.01


@dataclass(frozen=True)
class Case:
    name: str
    group: str
    build: Callable[[str], sim.Scene]  # integrator -> Scene
    initial: dict
    steps: int
    conserves_momentum: bool
    check_every: int = 1


def _free(body_fn, dt):
    return lambda integrator: scenes.free_body(integrator, dt, body_fn())


def cases(preset: str) -> list[Case]:
    short = {"full": 2000, "quick": 500, "tiny": 40}[preset]
    long = {"full": 100_000, "quick": 10_000, "tiny": 200}[preset]
    stiff = {"full": (1, 10, 1e2, 1e3, 1e4, 1e6), "quick": (1, 1e2, 1e4, 1e6), "tiny": (1, 1e4)}[
        preset
    ]
    spins = {"full": (0.01, 0.1, 1, 3, 10), "quick": (0.01, 0.1, 1, 10), "tiny": (0.1, 10)}[preset]
    needles = {"full": (1e-2, 1e-3, 1e-4), "quick": (1e-2, 1e-4), "tiny": (1e-4,)}[preset]
    out = []
    for k in stiff:
        out.append(
            Case(
                f"stiff spring kΔt²/m={k:g}",
                "stiff_spring",
                lambda i, k=k: scenes.stiff_spring(i, DT, k),
                {"position": (0.1, 0.0, 0.0)},
                short,
                False,
            )
        )
    direction = np.array([0.3, 1.0, 0.6]) / np.linalg.norm([0.3, 1.0, 0.6])
    for s in spins:
        out.append(
            Case(
                f"spin |ω|Δt={s:g}",
                "spin_rate",
                _free(scenes.box, DT),
                {"angular_velocity": direction * s / DT},
                short,
                True,
            )
        )
    for r in needles:
        # Spinning fast about the long axis, tumbling slowly about a transverse one.
        out.append(
            Case(
                f"needle I ratio={r:g}",
                "needle",
                _free(lambda r=r: scenes.needle(r), DT),
                {"angular_velocity": (1.0, 0.5, 20.0)},
                short,
                True,
            )
        )
    out.append(
        Case(
            "dt=1e-6 free body",
            "extreme_dt",
            _free(scenes.box, 1e-6),
            {"angular_velocity": scenes.DZHANIBEKOV_OMEGA},
            short,
            True,
        )
    )
    out.append(
        Case(
            "dt=0.1 free body",
            "extreme_dt",
            _free(scenes.box, 0.1),
            {"angular_velocity": scenes.DZHANIBEKOV_OMEGA},
            short,
            True,
        )
    )
    out.append(
        Case(
            f"long run {long:.0e} steps",
            "long_run",
            _free(scenes.box, DT),
            {"angular_velocity": scenes.DZHANIBEKOV_OMEGA},
            long,
            True,
            check_every=max(1, long // 100),
        )
    )
    return out


def run_case(case: Case, integrator: str) -> dict:
    # Overflow on the way to a divergence is expected here; the result is checked instead.
    with np.errstate(all="ignore"):
        return _run_case(case, integrator)


def _run_case(case: Case, integrator: str) -> dict:
    scene = case.build(integrator)
    state = scene.initial_state(**case.initial)
    e0 = float(scene.energy(state))
    l0 = scene.angular_momentum(state)
    energy_drift = momentum_drift = 0.0
    history = []  # (step, energy drift, momentum drift) at the checks, for growth laws
    status, first = "stable", None
    for step in range(1, case.steps + 1):
        try:
            state = scene.step(state)
        except sim.DivergenceError:
            status, first = "diverged", step
            break
        if step % case.check_every and step != case.steps:
            continue
        de = abs(float(scene.energy(state)) - e0) / abs(e0)
        dl = (
            float(np.linalg.norm(scene.angular_momentum(state) - l0) / np.linalg.norm(l0))
            if case.conserves_momentum
            else 0.0
        )
        if not np.isfinite(de) or de > BLOWUP:
            status, first = "diverged", step
            break
        energy_drift, momentum_drift = max(energy_drift, de), max(momentum_drift, dl)
        history.append((step, de, dl))
    if status == "stable" and max(energy_drift, momentum_drift) > DRIFT_LIMIT:
        status = "drifting"
    out = {
        "scene": case.name,
        "group": case.group,
        "integrator": integrator,
        "dt": scene.dt,
        "batch": 1,
        "steps": case.steps,
        "status": status,
        "stable": status == "stable",
        "first_divergence_step": first,
        "energy_drift": energy_drift,
        "momentum_drift": momentum_drift if case.conserves_momentum else None,
        "max_penetration": None,  # no contact case in this matrix (see "unavailable")
    }
    if case.group == "long_run" and len(history) > 2:
        out["drift_history"] = history
        out["energy_drift_growth"] = _growth(history, 1)
        out["momentum_drift_growth"] = _growth(history, 2)
    return out


def _growth(history, column) -> float | None:
    """Exponent p of drift ∝ stepsᵖ fitted over the checks (None if the drift is at rounding)."""
    pts = [(h[0], h[column]) for h in history if h[column] > 1e-13]
    if len(pts) < 3:
        return None
    x, y = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
    return float(np.polyfit(x, y, 1)[0])


def measure(preset: str = "full", progress=None, integrators=None) -> dict:
    integrators = tuple(integrators or sim.INTEGRATORS)
    records = []
    for case in cases(preset):
        for integrator in integrators:
            if progress:
                progress(f"stability {case.name} {integrator}")
            records.append(run_case(case, integrator))
    unavailable = []
    if scenes.optional_scene("landing_scene") is None:
        unavailable.append(
            "impacts up to 100 m/s / tunnelling and max penetration "
            "(rigid_env.sim.scenes.landing_scene not in this checkout)"
        )
    unavailable.append(
        "mass ratios up to 1e6 in body-body impacts and stacks of two or three "
        "boxes (the simulator has no body-body contacts in this checkout)"
    )
    return {
        "records": records,
        "integrators": integrators,
        "unavailable": unavailable,
        "thresholds": {"blowup_energy_ratio": BLOWUP, "drift_limit": DRIFT_LIMIT},
    }


# --- output ------------------------------------------------------------------------------------


def _cell(r: dict) -> str:
    if r["status"] == "diverged":
        return f"✗ step {r['first_divergence_step']}"
    mark = "✓" if r["status"] == "stable" else "~"
    return f"{mark} {r['energy_drift']:.1e}"


def table(result: dict) -> str:
    integrators = result["integrators"]
    rows = {}
    for r in result["records"]:
        rows.setdefault(r["scene"], {"case": r["scene"]})[r["integrator"]] = _cell(r)
    out = [
        f"✓ stable / ~ drifting (> {DRIFT_LIMIT:g}) / ✗ diverged (non-finite or energy × "
        f"{BLOWUP:g}), with the max relative energy drift or the first step of divergence:",
        "",
        report.markdown_table(
            list(rows.values()), [("case", "case", "")] + [(i, i, "") for i in integrators]
        ),
    ]
    longs = [r for r in result["records"] if r["group"] == "long_run"]
    if longs:
        out += [
            "",
            "Long run of the free body (energy and |L| drift, growth exponent p in "
            "drift ∝ stepsᵖ):",
            "",
            report.markdown_table(
                longs,
                [
                    ("integrator", "integrator", ""),
                    ("steps", "steps", "d"),
                    ("status", "status", ""),
                    ("energy drift", "energy_drift", ".2e"),
                    ("p (energy)", "energy_drift_growth", ".2f"),
                    ("|L| drift", "momentum_drift", ".2e"),
                    ("p (|L|)", "momentum_drift_growth", ".2f"),
                ],
            ),
        ]
    out += ["", *(f"Not available: {m}" for m in result["unavailable"])]
    return "\n".join(out)


def plot(result: dict, path) -> None:
    import matplotlib.pyplot as plt

    integrators = list(result["integrators"])
    names = list(dict.fromkeys(r["scene"] for r in result["records"]))
    grid = np.full((len(names), len(integrators)), np.nan)
    fig, ax = plt.subplots(figsize=(1.4 * len(integrators) + 3, 0.42 * len(names) + 1.5))
    for r in result["records"]:
        i, j = names.index(r["scene"]), integrators.index(r["integrator"])
        if r["status"] != "diverged":
            grid[i, j] = np.log10(max(r["energy_drift"], 1e-16))
        ax.text(
            j,
            i,
            _cell(r),
            ha="center",
            va="center",
            fontsize=6,
            color="white" if r["status"] == "diverged" else "black",
        )
    cmap = plt.get_cmap("viridis").with_extremes(bad="firebrick")  # masked = diverged
    im = ax.imshow(np.ma.masked_invalid(grid), cmap=cmap, vmin=-16, vmax=1, aspect="auto")
    ax.set_xticks(range(len(integrators)), integrators, rotation=30)
    ax.set_yticks(range(len(names)), names)
    fig.colorbar(im, ax=ax, label="log10 max relative energy drift (red: diverged)")
    ax.set_title("stability: cases × integrators")
    report.save(fig, path)

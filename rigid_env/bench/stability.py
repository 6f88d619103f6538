"""Stability: a matrix of stiff and extreme cases × integrators.

Each cell runs a case from a valid state and reports ``status``:

* ``diverged`` — the simulator raised :class:`sim.DivergenceError` (a non-finite result) or the
  energy grew past ``BLOWUP`` × its initial value; ``first_divergence_step`` says when
  (to within ``check_every`` steps). Nothing is left as a silent NaN: every figure is finite
  or ``None``.
* ``drifting`` — finite, but the relative energy (or |L|) drift exceeded ``DRIFT_LIMIT``.
* ``tunnelled`` — a contact case whose body ended below the ground (passed through it).
* ``stable`` — otherwise.
* ``n/a`` — the integrator cannot run the case (contacts need a semi-implicit integrator).

Energy drift is max |E − E0| / E0 over the checks (max over the batch when a case runs several
initial conditions at once); for contact cases, which dissipate, only a gain counts:
max(E − E0, 0) / E0 (a contact must never add energy). Momentum drift is max |L − L0| / |L0|
where angular momentum is conserved (free bodies), |P − P0| / |P0| for linear momentum (body–body
impacts in space), else ``None``. Max penetration (m) is the deepest overlap seen at any step of
a contact case.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from rigid_env import sim

from . import contact_cases, report, scenes

BLOWUP = 1e3
DRIFT_LIMIT = 0.1
DT = 0.01


# Free-body long runs: these integrators run LONG_STEPS (10⁶ in the full preset), the others a
# tenth; each runs a batch of initial spins at once (little more than one costs).
LONG_INTEGRATORS = ("splitting", "exact", "implicit_gyro")
LONG_SPINS = np.array(
    [scenes.DZHANIBEKOV_OMEGA, scenes.TUMBLE_OMEGA, (4.0, 0.1, 0.1), (0.1, 0.2, 5.0)]
)[:, None, :]


@dataclass(frozen=True)
class Case:
    name: str
    group: str
    build: Callable[[str], sim.Scene | contact_cases.Case]  # integrator -> Scene, or a contact
    # case's (Scene, State, depth)
    initial: dict[str, Any] | None  # Scene.initial_state keywords; None: the build gives a state
    steps: int
    conserves_momentum: bool | str  # True/"angular", "linear", or False
    check_every: int = 1
    contact: bool = False  # build returns (scene, state, depth); only compatible integrators
    ground: bool = False  # a body ending below z = 0 tunnelled
    steps_for: Callable[[str], int] | None = None  # per-integrator step count


def _free(body_fn: Callable[[], sim.Body], dt: float) -> Callable[[str], sim.Scene]:
    return lambda integrator: scenes.free_body(integrator, dt, body_fn())


def cases(preset: str) -> list[Case]:
    short = {"full": 2000, "quick": 500, "tiny": 40}[preset]
    long = {"full": 1_000_000, "quick": 20_000, "tiny": 200}[preset]
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
                partial(scenes.stiff_spring, dt=DT, k_dt2_over_m=k),
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
                _free(partial(scenes.needle, r), DT),
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
            "long run free body",
            "long_run",
            _free(scenes.box, DT),
            {"angular_velocity": LONG_SPINS},
            long,
            True,
            check_every=max(1, long // 1000),
            steps_for=lambda i: long if i in LONG_INTEGRATORS else long // 10,
        )
    )
    out += contact_case_list(preset)
    return out


CONTACT_DT = 1 / 60


def contact_case_list(preset: str) -> list[Case]:
    speeds = {"full": (1, 10, 100), "quick": (1, 10, 100), "tiny": (100,)}[preset]
    ratios = {"full": (1, 1e2, 1e4, 1e6), "quick": (1, 1e3, 1e6), "tiny": (1e6,)}[preset]
    steps = {"full": 240, "quick": 120, "tiny": 40}[preset]
    # A stack starts at rest: the tiny preset (the tests) checks a few of its steps; the
    # numpy solve of a 10⁶ mass ratio costs ~0.1 s per step.
    stack_steps = {"full": 240, "quick": 120, "tiny": 8}[preset]
    out = []
    for v in speeds:
        out.append(
            Case(
                f"ground impact {v:g} m/s, dt=1/60",
                "impact_speed",
                partial(contact_cases.ground_impact, dt=CONTACT_DT, speed=v),
                None,
                steps,
                False,
                contact=True,
                ground=True,
            )
        )
    for r in ratios:
        out.append(
            Case(
                f"sphere→sphere mass ratio {r:.0e}",
                "mass_ratio",
                partial(contact_cases.two_spheres, dt=CONTACT_DT, ratio=r),
                None,
                steps // 2,
                "linear",
                contact=True,
            )
        )
        out.append(
            Case(
                f"box→sphere mass ratio {r:.0e}",
                "mass_ratio",
                partial(contact_cases.sphere_and_box, dt=CONTACT_DT, ratio=r),
                None,
                steps // 2,
                "linear",
                contact=True,
            )
        )
    for count in (2, 3):
        for r in ratios:
            out.append(
                Case(
                    f"stack of {count}, top/bottom mass {r:.0e}",
                    "stack",
                    partial(contact_cases.stack, dt=CONTACT_DT, ratio=r, count=count),
                    None,
                    stack_steps,
                    False,
                    contact=True,
                    ground=True,
                )
            )
    return out


def run_case(case: Case, integrator: str) -> dict[str, Any]:
    # Overflow on the way to a divergence is expected here; the result is checked instead.
    with np.errstate(all="ignore"):
        return _run_case(case, integrator)


def _run_case(case: Case, integrator: str) -> dict[str, Any]:
    steps = case.steps_for(integrator) if case.steps_for else case.steps
    base = {
        "scene": case.name,
        "group": case.group,
        "integrator": integrator,
        "steps": steps,
        "first_divergence_step": None,
        "energy_drift": None,
        "momentum_drift": None,
        "max_penetration": None,
        "tunnelled": None,
    }
    if case.contact and integrator not in contact_cases.compatible():
        return {**base, "dt": None, "batch": 1, "status": "n/a", "stable": None}
    depth = None
    built = case.build(integrator)
    if isinstance(built, tuple):  # a contact case
        scene, state, depth = built
    else:
        scene = built
        state = scene.initial_state(**(case.initial or {}))
    e0 = scene.energy(state)
    conserved = case.conserves_momentum
    kind = "angular" if conserved is True else (conserved or None)
    momentum = scene.angular_momentum if kind == "angular" else scene.linear_momentum
    m0 = momentum(state) if kind else None
    energy_drift = momentum_drift = penetration = 0.0
    history: list[
        tuple[int, float, float]
    ] = []  # (step, energy drift, momentum drift) at the checks, for growth laws
    status, first = "stable", None
    for step in range(1, steps + 1):
        try:
            state = scene.step(state)
        except sim.DivergenceError:
            status, first = "diverged", step
            break
        if depth is not None:
            penetration = max(penetration, float(np.max(depth(state))))
        if step % case.check_every and step != steps:
            continue
        change = scene.energy(state) - e0
        if case.contact:
            change = np.maximum(change, 0.0)  # dissipation is physics; only a gain is drift
        de = float(np.max(np.abs(change) / np.abs(e0)))
        dl = (
            float(
                np.max(np.linalg.norm(momentum(state) - m0, axis=-1) / np.linalg.norm(m0, axis=-1))
            )
            if m0 is not None  # kind is set
            else 0.0
        )
        if not np.isfinite(de) or de > BLOWUP:
            status, first = "diverged", step
            break
        energy_drift, momentum_drift = max(energy_drift, de), max(momentum_drift, dl)
        history.append((step, de, dl))
    tunnelled = None
    if case.ground and status != "diverged":
        tunnelled = bool(np.any(state.position[..., 2] < 0))
        if tunnelled:
            status = "tunnelled"
    if status == "stable" and max(energy_drift, momentum_drift) > DRIFT_LIMIT:
        status = "drifting"
    out = {
        **base,
        "dt": scene.dt,
        "batch": int(np.prod(state.batch_shape)) if state.batch_shape else 1,
        "status": status,
        "stable": status == "stable",
        "first_divergence_step": first,
        "energy_drift": energy_drift,
        "momentum_drift": momentum_drift if kind else None,
        "momentum_kind": kind,
        "max_penetration": penetration if case.contact else None,
        "tunnelled": tunnelled,
    }
    if case.group == "long_run" and len(history) > 2:
        out["drift_history"] = history
        out["energy_drift_growth"] = _growth(history, 1)
        out["momentum_drift_growth"] = _growth(history, 2)
    return out


def _growth(history: list[tuple[int, float, float]], column: int) -> float | None:
    """Exponent p of drift ∝ stepsᵖ fitted over the checks (None if the drift is at rounding)."""
    pts = [(h[0], h[column]) for h in history if h[column] > 1e-13]
    if len(pts) < 3:
        return None
    x, y = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
    return float(np.polyfit(x, y, 1)[0])


def measure(
    preset: str = "full",
    progress: report.Progress | None = None,
    integrators: Sequence[str] | None = None,
) -> dict[str, Any]:
    integrators = tuple(integrators or sim.INTEGRATORS)
    records = []
    for case in cases(preset):
        for integrator in integrators:
            if progress:
                progress(f"stability {case.name} {integrator}")
            records.append(run_case(case, integrator))
    return {
        "records": records,
        "integrators": integrators,
        "thresholds": {"blowup_energy_ratio": BLOWUP, "drift_limit": DRIFT_LIMIT},
    }


# --- output ------------------------------------------------------------------------------------


def _cell(r: dict[str, Any]) -> str:
    if r["status"] == "n/a":
        return "n/a"
    if r["status"] == "diverged":
        return f"✗ step {r['first_divergence_step']}"
    if r["status"] == "tunnelled":
        return "✗ tunnelled"
    mark = "✓" if r["status"] == "stable" else "~"
    text = f"{mark} {r['energy_drift']:.1e}"
    if r.get("max_penetration") is not None:
        text += f" pen {r['max_penetration']:.0e}"
    return text


def table(result: dict[str, Any]) -> str:
    integrators = result["integrators"]
    rows: dict[str, dict[str, str]] = {}
    for r in result["records"]:
        rows.setdefault(r["scene"], {"case": r["scene"]})[r["integrator"]] = _cell(r)
    out = [
        f"✓ stable / ~ drifting (> {DRIFT_LIMIT:g}) / ✗ diverged (non-finite or energy × "
        f"{BLOWUP:g}) or tunnelled (ended below the ground), with the max relative energy "
        "drift (contact cases: energy gain only) and max penetration (m), or the first step "
        "of divergence; n/a: contacts need a semi-implicit integrator. Contact cases at "
        f"dt = 1/60 s, the others at dt = {DT:g} s unless named:",
        "",
        report.markdown_table(
            list(rows.values()), [("case", "case", "")] + [(i, i, "") for i in integrators]
        ),
    ]
    longs = [r for r in result["records"] if r["group"] == "long_run"]
    if longs:
        out += [
            "",
            "Long run of the free body, a batch of "
            f"{len(LONG_SPINS)} initial spins (worst of the batch), dt = {DT:g} s: energy "
            "and |L| drift, growth exponent p in drift ∝ stepsᵖ. "
            f"{', '.join(LONG_INTEGRATORS)} run the longest; the others a tenth of it:",
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
    contacts = [r for r in result["records"] if r.get("max_penetration") is not None]
    if contacts:
        out += [
            "",
            "Contact cases (dt = 1/60 s): energy gain, momentum drift (linear, body–body), "
            "max penetration, tunnelling:",
            "",
            report.markdown_table(
                contacts,
                [
                    ("case", "scene", ""),
                    ("integrator", "integrator", ""),
                    ("status", "status", ""),
                    ("energy gain", "energy_drift", ".1e"),
                    ("|P| drift", "momentum_drift", ".1e"),
                    ("max penetration (m)", "max_penetration", ".1e"),
                    ("tunnelled", "tunnelled", ""),
                ],
            ),
        ]
    return "\n".join(out)


def plot(result: dict[str, Any], path: Path) -> None:
    import matplotlib.pyplot as plt

    integrators = list(result["integrators"])
    names = list(dict.fromkeys(r["scene"] for r in result["records"]))
    grid = np.full((len(names), len(integrators)), np.nan)
    fig, ax = plt.subplots(figsize=(1.4 * len(integrators) + 3, 0.42 * len(names) + 1.5))
    for r in result["records"]:
        i, j = names.index(r["scene"]), integrators.index(r["integrator"])
        if r["status"] not in ("diverged", "tunnelled", "n/a"):
            grid[i, j] = np.log10(max(r["energy_drift"], 1e-16))
        ax.text(
            j,
            i,
            _cell(r),
            ha="center",
            va="center",
            fontsize=6,
            color="white" if r["status"] in ("diverged", "tunnelled") else "black",
        )
    for r in result["records"]:  # under the (transparent where masked) image: red or grey
        if r["status"] in ("diverged", "tunnelled", "n/a"):
            i, j = names.index(r["scene"]), integrators.index(r["integrator"])
            color = "lightgrey" if r["status"] == "n/a" else "firebrick"
            ax.add_patch(plt.Rectangle((j - 0.5, i - 0.5), 1, 1, color=color, zorder=-1))
    cmap = plt.get_cmap("viridis").with_extremes(bad=(0, 0, 0, 0))
    im = ax.imshow(np.ma.masked_invalid(grid), cmap=cmap, vmin=-16, vmax=1, aspect="auto")
    ax.set_xticks(range(len(integrators)), integrators, rotation=30)
    ax.set_yticks(range(len(names)), names)
    fig.colorbar(
        im, ax=ax, label="log10 max relative energy drift (red: diverged/tunnelled, grey: n/a)"
    )
    ax.set_title("stability: cases × integrators")
    report.save(fig, path)

"""Many boxes at once, rigid_env beside MuJoCo: ``python -m rigid_env.bench.many_bodies``.

Scenes of 1 kg cubes (half extent 0.1 m, friction 0.5, restitution 0, gravity −9.81 m/s²,
Δt = 1/240 s), the same starts for both engines:

- ``tower_N``: N boxes stacked exactly at rest on the ground (centres at z = 0.1, 0.3, …);
- ``pyramid_N``: rows of N, N − 1, …, 1 boxes in the x–z plane, each row offset by half a box
  on the one below, 1 mm between the boxes of a row, exactly at rest;
- ``heap_N``: N boxes (N/16 layers of a 4 × 4 grid) with random small tilts and offsets (seeded,
  a different draw per batch element), their lowest corners 0.1 m or more above the ground and
  ≥ 2 mm apart, dropped into a heap.

What is measured, per scene, engine and batch size (1 and 256 in the full run):

- the wall time per step and per body-step (µs). rigid_env batches over a leading axis (one
  ``Scene.step`` call for the whole batch; these scenes step compiled);
  its runs stop after a fixed number of steps or a time budget, whichever comes first, and say
  how many steps they timed (the first step of a run is left out when there are others). MuJoCo has no batch axis: a batch is that
  many ``MjData``, each stepped by one ``mj_step(..., nstep)`` call after the other, one
  thread. For the resting scenes the cost is the same every step, so runs of different
  lengths compare; the heap's is not: rigid_env steps it over MuJoCo's steps (within the
  drift runs' time budget), and the ratio is given only when both timed the same window.
- the rest drift of the resting scenes: the largest displacement of any box's centre from its
  start over 2 s of simulated time (480 steps, fewer in the quick and tiny presets; the JSON
  says how many), at batch 1. MuJoCo's soft contacts let the boxes sink into each other and
  the ground until the contact springs carry the weight; rigid_env's contacts are hard.

rigid_env's contact solve assembles dense matrices over every contact slot of the scene (3 rows
per slot, 4 slots per box pair and 4 per box on the ground; no broad phase yet): the compiled
step solves one batch element at a time and holds about ``COMPILED_COPIES`` (3c)² float64
matrices while it does, over the contacts within reach (at most ``NEIGHBOURS`` box pairs per
box), beside its contact rows (``layout.CONTACT_WIDTH`` floats per slot and element). A run that would
need more than half the available memory, or a dense solve of more than ``MAX_DENSE_ROWS``
rows, is not made; for the heap (up to 10752 rows at 64 boxes) that leaves the steps before
the lowest box can reach the ground (``free_steps``), which are timed and marked "in flight
only".

numpy's OpenBLAS is set to one thread (``limit_blas_threads``) so both engines use one core
(MuJoCo's set-up and the bench's own arithmetic call it).
"""

from __future__ import annotations

import ctypes
import sys
import time
import warnings
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rigid_env import cli, resources, sim
from rigid_env.sim.compiled.layout import CONTACT_WIDTH
from rigid_env.sim.rotation import quat_exp, quat_to_matrix

from . import peers, report

PROG = "python -m rigid_env.bench.many_bodies"
COMMAND = "many_bodies"
DT = 1 / 240
ENGINE = "rigid_env"
GRAVITY = 9.81
HALF = 0.1  # m, half extent of every box
MASS = 1.0  # kg
FRICTION = 0.5
RESTITUTION = 0.0
ROW_GAP = 1e-3  # m, between the boxes of a pyramid's row
HEAP_DROP = 0.1  # m, the heap's lowest corner above the ground at the start
HEAP_SEED = 0
# The compiled solve's scratch: the Delassus matrix and the active-set start's system and its
# factorisation (``compiled.contact_solve``, ``contact_starts``), one element at a time.
COMPILED_COPIES = 5
NEIGHBOURS = 26  # boxes of equal size that one box can touch at once (a 3 × 3 × 3 block's)
GROUND_SLOTS = PAIR_SLOTS = 4  # a box's on the ground (its K lowest corners), a box pair's
MEMORY_SHARE = 0.5  # of the available memory, at most, for one rigid_env run
# Rows of a dense solve that one step still does in seconds: its factorisations cost the cube
# (the heap of 64 boxes, measured: a first contact step ran for over a minute at batch 1).
MAX_DENSE_ROWS = 2000


@dataclass(frozen=True)
class Preset:
    scenes: tuple[str, ...]
    batches: tuple[int, ...]
    steps: int  # rigid_env: most steps timed per run (beyond the first) at batch > 1
    budget_s: float  # rigid_env: a run stops once its steps took this long
    drift_steps: int  # steps of the rest-drift runs (both engines, batch 1)
    drift_budget_s: float  # rigid_env's drift run stops after this long
    mujoco_steps: int  # MuJoCo: steps timed per element


PRESETS = {
    "full": Preset(("tower_4", "tower_8", "pyramid_4", "heap_64"), (1, 256), 10, 30.0, 480, 600.0, 480),
    "quick": Preset(("tower_4", "tower_8", "pyramid_4", "heap_64"), (1, 256), 2, 5.0, 60, 60.0, 120),
    "tiny": Preset(("tower_4", "pyramid_2"), (1, 2), 2, 2.0, 4, 10.0, 20),
}  # fmt: skip


# --- scenes -------------------------------------------------------------------------------------


def parse(name: str) -> tuple[str, int]:
    """``"tower_8"`` → ``("tower", 8)``; a heap's count is a multiple of 16 (4 × 4 layers)."""
    kind, _, count = name.partition("_")
    if kind not in ("tower", "pyramid", "heap") or not count.isdigit() or int(count) < 1:
        raise cli.UsageError(f"unknown scene {name!r}; expected tower_N, pyramid_N or heap_N")
    if kind == "heap" and int(count) % 16:
        raise cli.UsageError(f"{name}: a heap has a multiple of 16 boxes (4 × 4 per layer)")
    return kind, int(count)


def body_count(name: str) -> int:
    """Boxes in the scene: N, or N (N + 1)/2 for ``pyramid_N``."""
    kind, count = parse(name)
    return count * (count + 1) // 2 if kind == "pyramid" else count


def resting(name: str) -> bool:
    return parse(name)[0] != "heap"


def start(name: str, batch: int) -> tuple[np.ndarray, np.ndarray]:
    """Positions (batch, n, 3) and orientations (batch, n, 4) (x, y, z, w) of the scene's start."""
    kind, count = parse(name)
    if kind == "tower":
        pos = np.zeros((count, 3))
        pos[:, 2] = HALF + 2 * HALF * np.arange(count)
    elif kind == "pyramid":
        rows = [
            ((j - (size - 1) / 2) * (2 * HALF + ROW_GAP), 0.0, HALF + 2 * HALF * r)
            for r, size in enumerate(range(count, 0, -1))
            for j in range(size)
        ]
        pos = np.array(rows)
    else:
        return _heap(count, batch)
    q = np.zeros((len(pos), 4))
    q[:, 3] = 1.0
    return np.broadcast_to(pos, (batch, *pos.shape)).copy(), np.broadcast_to(
        q, (batch, *q.shape)
    ).copy()


def _heap(count: int, batch: int) -> tuple[np.ndarray, np.ndarray]:
    """Tilts up to 0.1 rad per axis keep a box's half height ≤ 0.123 m: layers 0.25 m and columns
    0.3 m apart (offsets ±2 cm) leave every pair apart; each centre is put so that its lowest
    corner is ``HEAP_DROP`` + its layer's height."""
    rng = np.random.default_rng(HEAP_SEED)
    grid = np.array([(i, j, k) for k in range(count // 16) for i in range(4) for j in range(4)])
    q = quat_exp(rng.uniform(-0.1, 0.1, (batch, count, 3)))
    pos = np.empty((batch, count, 3))
    pos[..., :2] = (grid[:, :2] - 1.5) * 0.3 + rng.uniform(-0.02, 0.02, (batch, count, 2))
    half_height = HALF * np.abs(quat_to_matrix(q)[..., 2, :]).sum(-1)
    pos[..., 2] = HEAP_DROP + 0.25 * grid[:, 2] + half_height
    return pos, q


def free_steps(name: str) -> int:
    """Steps from the start during which no contact can engage: none for the resting scenes; for
    the heap, the steps k with g Δt² (k + 1)(k + 2)/2 below half the drop (a semi-implicit step
    engages the ground when the gap is less than Δt times the new speed)."""
    if resting(name):
        return 0
    k = 0
    while GRAVITY * DT**2 * (k + 1) * (k + 2) / 2 < HEAP_DROP / 2:
        k += 1
    return k


def rigid_scene(count: int) -> sim.Scene:
    boxes = [sim.Body.box((HALF, HALF, HALF), MASS) for _ in range(count)]
    return sim.Scene(
        boxes,
        DT,
        gravity=(0.0, 0.0, -GRAVITY),
        ground=sim.Ground(RESTITUTION, FRICTION),
        contacts=sim.Material(RESTITUTION, FRICTION),
    )


def contact_rows(scene: sim.Scene) -> int:
    """Rows of ``scene``'s contact matrices: 3 per contact slot."""
    return 3 * max((s.layout.c for s in scene.pipeline if hasattr(s, "layout")), default=0)


def solve_rows(scene: sim.Scene) -> int:
    """Rows of the dense contact solve: the ground slots' and those of the pairs within reach,
    at most NEIGHBOURS per box (``compiled.contact_solve``)."""
    rows = contact_rows(scene)
    n = scene.model.n_bodies
    return 3 * min(rows // 3, n * GROUND_SLOTS + n * NEIGHBOURS // 2 * PAIR_SLOTS)


def contact_bytes(scene: sim.Scene, batch: int) -> float:
    """Memory of a contact step of ``scene`` at ``batch`` (module docstring)."""
    rows, live = contact_rows(scene), solve_rows(scene)
    return COMPILED_COPIES * live**2 * 8.0 + batch * rows / 3 * CONTACT_WIDTH * 8.0


def limit_blas_threads(threads: int = 1) -> str:
    """Set the OpenBLAS that numpy loaded to ``threads`` threads (Linux; no threadpoolctl here).
    Returns what was done, for the report."""
    try:
        with open("/proc/self/maps") as maps:
            libs = sorted({line.split()[-1] for line in maps if "openblas" in line.lower()})
    except OSError:
        libs = []
    for path in libs:
        lib = ctypes.CDLL(path)
        for prefix in ("scipy_openblas", "openblas"):
            for suffix in ("64_", "_64_", ""):
                setter = getattr(lib, f"{prefix}_set_num_threads{suffix}", None)
                getter = getattr(lib, f"{prefix}_get_num_threads{suffix}", None)
                if setter is not None and getter is not None:
                    setter(threads)
                    return f"OpenBLAS {Path(path).name}: {getter()} thread(s)"
    return "BLAS threads not set (no OpenBLAS found); set OMP_NUM_THREADS=1"


# --- measuring ----------------------------------------------------------------------------------


def _mean_after_first(times: list[float]) -> tuple[float, int]:
    """Mean step time leaving out the first step (first-call costs), unless it is the only one."""
    timed = times[1:] or times
    return float(np.mean(timed)), len(timed)


def rigid_run(name: str, batch: int, steps: int, budget_s: float, drift: bool) -> dict[str, Any]:
    """rigid_env on ``name`` at ``batch``: ``steps`` steps, or fewer once they took ``budget_s``,
    and the rest drift over them if ``drift``; or why it was not run."""
    scene = rigid_scene(body_count(name))
    rec: dict[str, Any] = {"engine": ENGINE, "backend": scene.backend, "batch": batch}
    rec["window"] = "rest" if resting(name) else "drop"
    need = contact_bytes(scene, batch)
    allowed = MEMORY_SHARE * resources.available_memory()
    reason = ""
    if need > allowed:
        reason = (
            f"a contact step needs ~{resources.size_text(need)} ({solve_rows(scene)}-row "
            f"dense matrices), over half the {resources.size_text(allowed / MEMORY_SHARE)} "
            "available"
        )
    elif solve_rows(scene) > MAX_DENSE_ROWS:
        reason = (
            f"a contact step's dense solve may take up to {solve_rows(scene)} rows, over "
            f"{MAX_DENSE_ROWS} (no islands or sparse solve yet)"
        )
    if reason:
        steps = min(steps, free_steps(name))
        if steps == 0:
            return {**rec, "steps_timed": 0, "note": f"not measured: {reason}"}
        rec.update(window="in flight", note=f"in flight only (before any contact): {reason}")
    pos, q = start(name, batch)
    if batch == 1:  # unbatched, as a single scene is stepped
        state = scene.initial_state(position=pos[0], orientation=q[0])
    else:
        state = scene.initial_state(position=pos, orientation=q, batch_shape=(batch,))
    x0, moved, capped = state.position, 0.0, 0
    times: list[float] = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sim.ContactSolverWarning)
        while len(times) < steps and sum(times) < budget_s:
            begin = time.perf_counter()
            state = scene.step(state)
            times.append(time.perf_counter() - begin)
            contacts = scene.report.get("contacts")
            capped += bool(contacts is not None and contacts.capped)
            if rec["window"] == "in flight" and contacts is not None and contacts.engaged:
                raise RuntimeError(f"{name}: a contact engaged in a step counted as in flight")
            if drift:
                moved = max(moved, float(np.max(np.linalg.norm(state.position - x0, axis=-1))))
    s_per_step, timed = _mean_after_first(times)
    rec.update(steps_timed=timed, s_per_step=s_per_step, capped_steps=capped)
    if drift:
        rec.update(drift_mm=1e3 * moved, drift_steps=len(times), drift_s=len(times) * DT)
    return rec


def mujoco_run(name: str, batch: int, steps: int, drift_steps: int) -> dict[str, Any]:
    """MuJoCo on ``name``: ``batch`` MjData stepped ``steps`` steps each, one after the other
    (batch 1: best of 3 after a warm-up), and at batch 1 the drift over ``drift_steps``."""
    model = peers.boxes_model(body_count(name), (HALF,) * 3, MASS, FRICTION, DT, GRAVITY)
    pos, q = start(name, batch)
    rec: dict[str, Any] = {
        "engine": "mujoco",
        "batch": batch,
        "window": "rest" if resting(name) else "drop",
        "steps_timed": steps,
        "note": f"{batch} MjData, one mj_step(nstep={steps}) each, in turn" if batch > 1 else None,
    }
    if batch == 1:
        peers.step_boxes(model, peers.place_boxes(model, pos[0], q[0]), min(steps, 10))
        wall = min(
            peers.step_boxes(model, peers.place_boxes(model, pos[0], q[0]), steps) for _ in range(3)
        )
    else:
        datas = [peers.place_boxes(model, p, o) for p, o in zip(pos, q, strict=True)]
        wall = sum(peers.step_boxes(model, data, steps) for data in datas)
    rec["s_per_step"] = wall / steps
    if batch == 1 and resting(name):
        data = peers.place_boxes(model, pos[0], q[0])
        x0, moved = peers.box_positions(data), 0.0
        for _ in range(drift_steps):
            peers.mujoco.mj_step(model, data)
            moved = max(
                moved, float(np.max(np.linalg.norm(peers.box_positions(data) - x0, axis=-1)))
            )
        rec.update(drift_mm=1e3 * moved, drift_steps=drift_steps, drift_s=drift_steps * DT)
    return rec


def mujoco_status() -> str:
    if not peers.available():
        return "MuJoCo " + peers.status()
    return f"MuJoCo {peers.mujoco.__version__}, mj_step, one thread"


def measure(preset: str = "full", progress: report.Progress | None = None) -> dict[str, Any]:
    """Every (scene, engine, batch) record of ``preset`` (MuJoCo's when it is installed)."""
    cfg = PRESETS[preset]
    threads = limit_blas_threads(1)
    records = []
    for name in cfg.scenes:
        count = body_count(name)
        for batch in cfg.batches:
            runs = []
            if progress:
                progress(f"{name} batch={batch} rigid_env")
            drift = batch == 1 and resting(name)
            steps, budget = (
                (cfg.drift_steps, cfg.drift_budget_s) if drift else (cfg.steps + 1, cfg.budget_s)
            )
            if not resting(name):  # its cost changes as it falls and piles: MuJoCo's window
                steps, budget = cfg.mujoco_steps + 1, cfg.drift_budget_s
            runs.append(rigid_run(name, batch, steps, budget, drift))
            if peers.available():
                if progress:
                    progress(f"{name} batch={batch} mujoco")
                runs.append(mujoco_run(name, batch, cfg.mujoco_steps, cfg.drift_steps))
            for rec in runs:
                rec.update(scene=name, bodies=count)
                if "s_per_step" in rec:
                    rec["us_per_step"] = 1e6 * rec["s_per_step"]
                    rec["us_per_body_step"] = rec["us_per_step"] / (count * batch)
            ours, peer = runs[0], runs[-1]
            same = resting(name) or ours.get("steps_timed") == peer.get("steps_timed")
            if len(runs) == 2 and "s_per_step" in ours and ours["window"] != "in flight" and same:
                ours["ratio_per_body_step"] = ours["us_per_body_step"] / peer["us_per_body_step"]
            records.extend(runs)
    return {
        "records": records,
        "settings": {
            **asdict(cfg),
            "dt": DT,
            "gravity": -GRAVITY,
            "half_extent": HALF,
            "mass": MASS,
            "friction": FRICTION,
            "restitution": RESTITUTION,
            "row_gap": ROW_GAP,
            "heap_drop": HEAP_DROP,
            "heap_seed": HEAP_SEED,
            "blas_threads": threads,
            "mujoco": mujoco_status(),
            "mujoco_model": "default soft contacts (solref 0.02 1), condim 3, Euler, one thread",
            "drift": "max |x(t) - x(0)| of any box centre over the drift steps, batch 1",
        },
    }


COLUMNS = [
    ("scene", "scene", ""),
    ("bodies", "bodies", "d"),
    ("engine", "engine", ""),
    ("backend", "backend", ""),
    ("batch", "batch", "d"),
    ("steps timed", "steps_timed", "d"),
    ("µs/step", "us_per_step", ".4g"),
    ("µs/body-step", "us_per_body_step", ".4g"),
    ("rigid_env/MuJoCo per body-step", "ratio_per_body_step", ".3g"),
    ("drift (mm)", "drift_mm", ".3g"),
    ("note", "note", ""),
]


def table(result: dict[str, Any]) -> str:
    s = result["settings"]
    drifts = sorted({r["drift_steps"] for r in result["records"] if "drift_steps" in r})
    head = (
        f"Δt {s['dt']:.6g} s, boxes of half extent {s['half_extent']} m, {s['mass']} kg, "
        f"μ {s['friction']}, ε {s['restitution']}; {s['blas_threads']}; {s['mujoco']}.\n"
        f"Drift over {', '.join(map(str, drifts)) or '—'} steps at batch 1 (max displacement "
        "of any box); steps timed leave out each rigid_env run's first step.\n\n"
    )
    return head + report.markdown_table(result["records"], COLUMNS)


def main(argv: Sequence[str] | None = None) -> int:
    parser = cli.Parser(prog=PROG, description=__doc__.split("\n")[0], epilog=cli.EXIT_STATUSES)
    parser.add_argument("--quick", action="store_true", help="fewer steps and shorter budgets")
    parser.add_argument("--preset", choices=tuple(PRESETS), help="overrides --quick")
    parser.add_argument("--out", type=Path, default=Path("reports"), help="output directory")
    parser.add_argument("--verbose", "-v", action="store_true", help="progress on stderr")
    args = parser.parse_args(argv)
    path = cli.writable_file(args.out / f"{COMMAND}.json", "--out")
    preset = args.preset or ("quick" if args.quick else "full")
    progress = (lambda msg: print(msg, file=sys.stderr, flush=True)) if args.verbose else None
    begin = time.perf_counter()
    result = measure(preset, progress)
    result["bench_wall_s"] = time.perf_counter() - begin
    report.write_json(path, COMMAND, preset, result)
    print(f"## {COMMAND} ({preset}, {result['bench_wall_s']:.0f} s)\n\n{table(result)}\n")
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(cli.run(main, PROG))

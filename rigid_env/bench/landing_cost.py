"""Where a batched landing step's time goes, by what each element's contacts do:
``python -m rigid_env.bench.landing_cost``.

The speed bench's landing batch (its scene, Δt, pre-rolled start and compiled backend) is split
by what one step does for each element, found by stepping each element alone (a batched step
equals each element stepped alone, bit for bit):

- ``in flight``: no contact within reach (``ContactReport.engaged`` 0);
- ``first sweep``: the start (particle or active set) already solves the contacts, which one
  Gauss–Seidel sweep confirms;
- ``2-20 sweeps``, ``over 20 sweeps``: converged after that many sweeps (with Newton polishes);
- ``capped``: stopped at a cap of ``SolverSettings``.

For each class it prints its share of the batch, the µs per element of a batch of the same
size made of that class's elements only (resampled), and the class's share of the batch's
time (share × cost over the sum), beside the batch as it is. The ``first sweep`` row is what a
landing step costs when the contact solve has nothing left to do: a floor for this pipeline
(detection, assembly, the starts, restitution's check, the energy guard) whatever the solver.
With MuJoCo installed (the ``peers`` extra) it also prints MuJoCo's µs per body on the same
scene and batch (``peers.landing_speed``).
"""

from __future__ import annotations

import sys
import time
import warnings
from collections.abc import Sequence

import numpy as np

from rigid_env import cli, resources, sim

from . import peers, speed

# MuJoCo's integrator in the speed bench's landing target row (``speed.TARGETS``)
MUJOCO_INTEGRATOR = next(t[3] for t in speed.TARGETS if t[1] == "landing")
CLASSES = ("in flight", "first sweep", "2-20 sweeps", "over 20 sweeps", "capped")


def landing_batch(batch: int) -> tuple[sim.Scene, sim.State]:
    """The speed bench's compiled landing scene and its pre-rolled start at ``batch``."""
    integrator = next(t[2] for t in speed.TARGETS if t[1] == "landing")
    factory, initial = next((c[1], c[2]) for c in speed.scene_cases() if c[0] == "landing")
    scene = speed.build(factory, integrator, "compiled")
    return scene, speed._initial(scene, initial, batch)


def classify(scene: sim.Scene, state: sim.State) -> np.ndarray:
    """Each element's class (index into ``CLASSES``), from its step taken alone."""
    out = np.empty(len(state.position), int)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sim.ContactSolverWarning)
        for e in range(len(out)):
            scene.step(state[np.array([e])])
            report = scene.report["contacts"]
            if report.capped:
                out[e] = 4
            elif not report.engaged:
                out[e] = 0
            else:
                out[e] = 1 if report.iterations <= 1 else 2 if report.iterations <= 20 else 3
    return out


def us_per_element(scene: sim.Scene, state: sim.State, block_s: float, repeats: int) -> float:
    """Best µs per element of ``scene.step(state)`` (the same start each call)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sim.ContactSolverWarning)
        scene.step(state)
        start = time.perf_counter()
        scene.step(state)
        n = max(2, int(block_s / max(time.perf_counter() - start, 1e-7)))
        best = np.inf
        for _ in range(repeats):
            start = time.perf_counter()
            for _ in range(n):
                scene.step(state)
            best = min(best, (time.perf_counter() - start) / n)
    return best * 1e6 / len(state.position)


def measure(batch: int, block_s: float, repeats: int) -> dict[str, tuple[float, float, float]]:
    """Per class (and ``batch`` for the batch as is): (share of elements, µs per element,
    share of the batch's time). A class with no element gets (0, NaN, 0)."""
    with warnings.catch_warnings():  # the pre-roll's capped solves are this bench's subject
        warnings.simplefilter("ignore", sim.ContactSolverWarning)
        scene, state = landing_batch(batch)
    kinds = classify(scene, state)
    rows = {}
    for k, name in enumerate(CLASSES):
        members = np.flatnonzero(kinds == k)
        if len(members) == 0:
            rows[name] = (0.0, float("nan"), 0.0)
            continue
        cost = us_per_element(scene, state[np.resize(members, batch)], block_s, repeats)
        rows[name] = (len(members) / batch, cost, 0.0)
    total = sum(share * cost for share, cost, _ in rows.values() if share)
    for name, (share, cost, _) in rows.items():
        rows[name] = (share, cost, share * cost / total if share else 0.0)
    rows["batch"] = (1.0, us_per_element(scene, state, block_s, repeats), 1.0)
    return rows


PROG = "python -m rigid_env.bench.landing_cost"


def main(argv: Sequence[str] | None = None) -> int:
    parser = cli.Parser(prog=PROG)
    parser.add_argument(
        "--batch", type=cli.positive_int, default=speed.BREAKDOWN_BATCH, help="batch size"
    )
    parser.add_argument(
        "--block", type=cli.positive_float, default=0.2, help="seconds per timed block"
    )
    parser.add_argument(
        "--repeats", type=cli.positive_int, default=5, help="blocks per figure (best kept)"
    )
    args = parser.parse_args(argv)
    # The batch and a copy of it per class of element (and MuJoCo's batch beside).
    resources.check_fits(3 * args.batch * resources.SCENE_BYTES, f"--batch {args.batch}")
    rows = measure(args.batch, args.block, args.repeats)
    print(
        f"landing, batch {args.batch}, dt {speed.DT} s, compiled, after the speed bench's "
        f"pre-roll; best of {args.repeats} blocks of {args.block} s"
    )
    print(f"{'class':16s}{'elements':>10s}{'µs/element':>12s}{'time share':>12s}")
    for name, (share, cost, part) in rows.items():
        print(f"{name:16s}{100 * share:9.1f}%{cost:12.3f}{100 * part:11.1f}%")
    if peers.available():
        for record in peers.landing_speed([args.batch], args.block, speed.DT):
            if record["integrator"] == MUJOCO_INTEGRATOR:
                name = f"mujoco {MUJOCO_INTEGRATOR}"
                print(f"{name:16s}{'':10s}{1e6 / record['body_steps_per_s']:12.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(cli.run(main, PROG))

"""Where a batch-1 compiled step's time goes: ``python -m rigid_env.bench.step_cost``.

For the two batch-1 speed targets (the speed bench's free body and landing scenes, same
integrators, dt and start states), it prints the best µs per call of

- ``bench row``: ``state = scene.step(state)``, the state evolving, as the speed bench times it;
- ``Scene.step``: the same call repeated from one fixed state (the box resting after the
  speed bench's pre-roll);
- ``driver call``: the scene's compiled driver on that state's arrays, without ``Scene.step``'s
  checks, report and ``State``;
- ``kernel``: the compiled step's entry point on pre-built arguments (no Python around it);
- ``empty kernel``: a compiled function that takes the same arguments and does nothing: the
  cost of the call and of unboxing its arrays;

and the differences: Python in ``Scene.step``, Python in the driver, physics in the kernel.
Reading the driver's internals is this script's purpose (it times the call's parts); the
speed bench times only the public ``Scene.step``.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Sequence

import numpy as np

from rigid_env import cli

from . import speed

CASES = ("free_body", "landing")  # the batch-1 rows of ``speed.TARGETS``


def best_us(fn: Callable[[], object], block_s: float, repeats: int) -> float:
    """Best µs per call of ``fn`` over ``repeats`` blocks of ~``block_s`` seconds each."""
    fn()
    start = time.perf_counter()
    fn()
    n = max(2, int(block_s / max(time.perf_counter() - start, 1e-7)))
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(n):
            fn()
        best = min(best, (time.perf_counter() - start) / n)
    return best * 1e6


def _empty_like_kernel(args: tuple, contacts: bool) -> Callable[..., object]:
    """A compiled function of the step's signature that does nothing, compiled for ``args``."""
    from numba import njit

    from rigid_env.sim.compiled.driver import _entry_point

    # fmt: off
    @njit
    def free(  # type: ignore[no-untyped-def]
        x0, q0, v0, w0, x, q, v, w, force, torque, body, report, counts, data, per_element,
        steps, integrator,
    ):
        return 0, 0, 0

    @njit
    def contact(  # type: ignore[no-untyped-def]
        x0, q0, v0, w0, x, q, v, w, force, torque, body, report, counts, data, per_element,
        steps, integrator, slots, width, addresses, warm_in, warm_out,
    ):
        return 0, 0, 0
    # fmt: on

    empty = contact if contacts else free
    empty(*args)
    return _entry_point(empty, tuple(empty.typeof_pyval(a) for a in args))


def breakdown(name: str, block_s: float, repeats: int) -> dict[str, float]:
    """The µs figures of the module docstring for speed case ``name`` at batch 1."""
    integrator = next(t[2] for t in speed.TARGETS if t[1] == name and t[4] == 1)
    factory, initial = next((c[1], c[2]) for c in speed.scene_cases() if c[0] == name)
    scene = speed.build(factory, integrator, "compiled")
    start = speed._initial(scene, initial, 1)
    evolving = [start]

    def bench_row() -> None:
        evolving[0] = scene.step(evolving[0])

    out = {"bench row": best_us(bench_row, block_s, repeats)}
    out["Scene.step"] = best_us(lambda: scene.step(start), block_s, repeats)
    drv = scene._driver
    assert drv is not None
    x0, q0, v0, w0 = start.arrays()
    out["driver call"] = best_us(lambda: drv(x0, q0, v0, w0, None, None), block_s, repeats)
    _, flat, qflat, rflat, zero, _ = drv._last
    outputs = (np.empty(flat), np.empty(qflat), np.empty(flat), np.empty(flat))
    report, counts = np.zeros(rflat), np.zeros((1, 3))
    args = (x0, q0, v0, w0, *outputs, zero, zero, zero, report, counts, *drv.tail(1))
    entry = drv._entries[False]
    out["kernel"] = best_us(lambda: entry(*args), block_s, repeats)
    empty = _empty_like_kernel(args, contacts=drv.contacts)
    out["empty kernel"] = best_us(lambda: empty(*args), block_s, repeats)
    out["Python in Scene.step"] = out["Scene.step"] - out["driver call"]
    out["Python in the driver"] = out["driver call"] - out["kernel"]
    out["physics in the kernel"] = out["kernel"] - out["empty kernel"]
    return out


PROG = "python -m rigid_env.bench.step_cost"


def main(argv: Sequence[str] | None = None) -> int:
    parser = cli.Parser(prog=PROG)
    parser.add_argument(
        "--block", type=cli.positive_float, default=0.05, help="seconds per timed block"
    )
    parser.add_argument(
        "--repeats", type=cli.positive_int, default=20, help="blocks per figure (best kept)"
    )
    args = parser.parse_args(argv)
    rows = {name: breakdown(name, args.block, args.repeats) for name in CASES}
    print(f"batch-1 compiled step, best µs per call ({args.repeats} blocks of {args.block} s)")
    print(f"{'':24s}" + "".join(f"{name:>12s}" for name in CASES))
    for key in rows[CASES[0]]:
        print(f"{key:24s}" + "".join(f"{rows[name][key]:12.2f}" for name in CASES))
    return 0


if __name__ == "__main__":
    sys.exit(cli.run(main, PROG))

"""Time the contact step of the landing scene (one box + ground) at several batch sizes.

Usage: python scripts/time_contacts.py [batch ...]

Two figures per batch: ``in contact`` is the mean step time once every box has landed (steps
241–480 of a drop from 1 m, random tilt and spin); ``drop`` is the mean over the whole 2 s drop
(flight steps skip the solver). Best of several repeats after a warm-up.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from rigid_env.sim.scenes import landing_scene


def _best(fn, repeats):
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def main(batches):
    scene, init = landing_scene()
    print(f"{'batch':>6} {'in contact µs/step':>19} {'drop µs/step':>13} {'body-steps/s':>13}")
    for batch in batches:
        shape = () if batch == 1 else (batch,)
        start = init(shape, np.random.default_rng(0))
        steps = 240 if batch <= 1024 else 40
        state = start
        for _ in range(240):
            state = scene.step(state)
        landed = state

        def run_contact(steps=steps, landed=landed):
            s = landed
            for _ in range(steps):
                s = scene.step(s)

        def run_drop(start=start):
            s = start
            for _ in range(480):
                s = scene.step(s)

        repeats = 5 if batch <= 1024 else 2
        run_contact()
        t_contact = _best(run_contact, repeats) / steps
        t_drop = _best(run_drop, 2 if batch <= 1024 else 1) / 480
        print(
            f"{batch:>6} {t_contact * 1e6:>19.1f} {t_drop * 1e6:>13.1f} {batch / t_contact:>13.0f}"
        )


if __name__ == "__main__":
    main([int(b) for b in sys.argv[1:]] or [1, 64, 1024, 16384])

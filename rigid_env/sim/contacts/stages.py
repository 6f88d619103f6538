"""The contact stages of the step pipeline (``rigid_env.sim.pipeline``).

Between a semi-implicit integrator's ``integrate_velocity`` and ``integrate_position``:

* ``collide_ground`` / ``collide_pairs`` detect at the start-of-step positions and put their
  hits in ``ctx.contacts`` (positions flattened to one batch axis, ``(N, n, ·)``);
* ``solve_contacts`` solves the impulses on the post-force velocities, sets ``ctx.v, ctx.w`` to
  the main pass's velocities (the positions drift with those) and ``ctx.displacement`` to the
  penetration correction (which the position update adds);

and after ``integrate_position``:

* ``restitute`` applies the restitution pass computed by the solve (velocities only, as
  Box2D v3's ``applyRestitution`` after its position update).

Transitional adapter: the current solver (``solver.ContactStage``) computes the restitution
velocities together with the main pass, so ``solve_contacts`` keeps them in ``ctx.contacts``
for ``restitute`` to apply.
"""

from __future__ import annotations

import numpy as np

from .solver import ContactStage


def _flat(ctx):
    n = ctx.model.n_bodies
    return ctx.x.reshape(-1, n, 3), ctx.q.reshape(-1, n, 4)


def _hits(ctx) -> dict:
    if ctx.contacts is None:
        ctx.contacts = {}
    return ctx.contacts


class CollideGround:
    name = "collide_ground"

    def __init__(self, ground):
        self.ground = ground

    def __call__(self, ctx) -> None:
        _hits(ctx)["ground"] = self.ground.detect(*_flat(ctx))


class CollidePairs:
    name = "collide_pairs"

    def __init__(self, pairs):
        self.pairs = pairs

    def __call__(self, ctx) -> None:
        _hits(ctx)["pairs"] = self.pairs.detect(*_flat(ctx))


class SolveContacts:
    name = "solve_contacts"

    def __init__(self, solver: ContactStage):
        self.solver = solver

    def __call__(self, ctx) -> None:
        hits = _hits(ctx)
        out = self.solver.respond(ctx.start, ctx.v, ctx.w, hits.get("ground"), hits.get("pairs"))
        hits["bounce"] = None
        if out is None:
            return
        v, w, shift, v_out, w_out = out
        ctx.v, ctx.w = np.array(v), np.array(w)
        if np.any(shift):
            ctx.displacement = shift if ctx.displacement is None else ctx.displacement + shift
        # The restitution pass changes the velocities by (v_out − v, w_out − w).
        hits["bounce"] = (v_out - v, w_out - w)


class Restitute:
    name = "restitute"

    def __call__(self, ctx) -> None:
        bounce = None if ctx.contacts is None else ctx.contacts.get("bounce")
        if bounce is not None:
            ctx.v = ctx.v + bounce[0]
            ctx.w = ctx.w + bounce[1]

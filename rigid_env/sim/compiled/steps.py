"""What every compiled step does around its stages: set up an element, check its result, and
carry one step's result into the next when a call runs several.

``BODY_TORQUE`` is the step tuple's slot after ``layout``'s: the body-frame torque (N, n, 3)
that the generated ``wrench`` turns into the world at each evaluation's orientation.
"""

from __future__ import annotations

import math

from .cache import njit
from .layout import (
    CONTACT,
    DISPLACEMENT,
    ENERGY_REMOVED,
    Q0,
    REPORT,
    STEP_TUPLE_SIZE,
    V0,
    W0,
    WARM,
    WARM_END,
    X0,
    Q,
    V,
    W,
    X,
)

BODY_TORQUE = STEP_TUPLE_SIZE  # appended by the driver after the layout's slots


# Written for numba's reference-count pruning. Where an inlined function binds the step
# tuple's arrays they are increfed, and decrefed where its body ends: an atomic add each, about
# half of Reorient's compiled step (a free body, 2 splitting steps per call: 0.30 -> 0.14 µs per
# element without them, measured on this machine). numba's pruner removes such a pair only
# across a short stretch of code with no early exit and no call that can raise. So ``begin``
# has no early return from its loop, ``finite`` no branch, and ``finite`` indexes ``st`` in
# place instead of binding names (with names, measured, the pairs stayed).


@njit(cache=True, error_model="numpy", inline="always")
def begin(e, st, tolerance):
    """Working state = the state passed in with |q| renormalised, (the
    scene's ``_norm2`` order: x² + y² + z² + w²), displacement zeroed (the driver hands the
    contact stages zeroed ``contact`` and ``report`` arrays). False when a quaternion is off
    unit length by more than ``tolerance`` (the scene's ``ORIENTATION_TOLERANCE``, written into
    the generated driver; its ``_arrays`` check): that element's step is then not run and its
    working state, written all the same, is discarded with the step (the scene raises)."""
    x0, q0, v0, w0 = st[X0], st[Q0], st[V0], st[W0]
    x, q, v, w = st[X], st[Q], st[V], st[W]
    disp = st[DISPLACEMENT]
    ok = True
    for b in range(x0.shape[1]):
        norm2 = q0[e, b, 0] ** 2 + q0[e, b, 1] ** 2 + q0[e, b, 2] ** 2 + q0[e, b, 3] ** 2
        ok = ok and abs(norm2 - 1.0) <= 2 * tolerance
        norm = math.sqrt(norm2)
        for i in range(4):
            q[e, b, i] = q0[e, b, i] / norm
        for i in range(3):
            x[e, b, i] = x0[e, b, i]
            v[e, b, i] = v0[e, b, i]
            w[e, b, i] = w0[e, b, i]
            disp[e, b, i] = 0.0
    return ok


@njit(cache=True, error_model="numpy", inline="always")
def finite(e, st):
    """Every entry of the element's result is finite: a - a is 0 for a finite a and NaN for
    ±inf or NaN, and a sum of zeros and NaNs is 0 exactly when there is no NaN (entry by entry:
    a sum of the entries themselves could overflow)."""
    acc = 0.0
    for b in range(st[X].shape[1]):
        for i in range(3):
            acc += st[X][e, b, i] - st[X][e, b, i]
            acc += st[V][e, b, i] - st[V][e, b, i]
            acc += st[W][e, b, i] - st[W][e, b, i]
        for i in range(4):
            acc += st[Q][e, b, i] - st[Q][e, b, i]
    return acc == 0.0


@njit(cache=True, error_model="numpy", inline="always")
def carry(e, st, total):
    """Between two steps of one call: the result becomes the state passed in (the start slots
    are the driver's own copies then), the contact slots are zeroed and the report row is
    folded into ``total`` (elementwise maximum; the energy removed adds up) and zeroed: the next step sees what a call of
    its own would (``begin`` does the rest), but for the warm-start columns, which the contact
    solve reads only with ``SolverSettings.warm_start``."""
    x0, q0, v0, w0 = st[X0], st[Q0], st[V0], st[W0]
    x, q, v, w = st[X], st[Q], st[V], st[W]
    for b in range(x.shape[1]):
        for i in range(3):
            x0[e, b, i] = x[e, b, i]
            v0[e, b, i] = v[e, b, i]
            w0[e, b, i] = w[e, b, i]
        for i in range(4):
            q0[e, b, i] = q[e, b, i]
    contact = st[CONTACT]
    for c in range(contact.shape[1]):
        for i in range(WARM):  # the warm-start columns carry over (``layout``)
            contact[e, c, i] = 0.0
        for i in range(WARM_END, contact.shape[2]):
            contact[e, c, i] = 0.0
    report = st[REPORT]
    for i in range(report.shape[1]):
        if i == ENERGY_REMOVED:  # an energy: the call's is the sum over its steps
            total[e, i] = total[e, i] + report[e, i]
        else:
            total[e, i] = max(total[e, i], report[e, i])
        report[e, i] = 0.0


@njit(cache=True, error_model="numpy", inline="always")
def fold(e, st, total):
    """After the last of several steps: the report row becomes the maximum over the steps (the
    sum, for the energy removed)."""
    report = st[REPORT]
    for i in range(report.shape[1]):
        if i == ENERGY_REMOVED:
            report[e, i] = total[e, i] + report[e, i]
        else:
            report[e, i] = max(total[e, i], report[e, i])

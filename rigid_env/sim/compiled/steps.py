"""What every compiled step does around its stages: set up an element, check its result."""

from __future__ import annotations

import math

from numba import njit

from .layout import DISPLACEMENT, Q0, V0, W0, X0, Q, V, W, X


@njit(cache=True, error_model="numpy")
def begin(e, st, tolerance):
    """Working state = the state passed in with |q| renormalised, as ``StepContext`` (the
    scene's ``_norm2`` order: x² + y² + z² + w²), displacement zeroed (the driver hands the
    contact stages zeroed ``contact`` and ``report`` arrays). False when
    a quaternion is off unit length by more than ``tolerance`` (the scene's
    ``ORIENTATION_TOLERANCE``, written into the generated driver; its ``_arrays`` check)."""
    x0, q0, v0, w0 = st[X0], st[Q0], st[V0], st[W0]
    x, q, v, w = st[X], st[Q], st[V], st[W]
    disp = st[DISPLACEMENT]
    for b in range(x0.shape[1]):
        norm2 = q0[e, b, 0] ** 2 + q0[e, b, 1] ** 2 + q0[e, b, 2] ** 2 + q0[e, b, 3] ** 2
        if not abs(norm2 - 1.0) <= 2 * tolerance:
            return False
        norm = math.sqrt(norm2)
        for i in range(4):
            q[e, b, i] = q0[e, b, i] / norm
        for i in range(3):
            x[e, b, i] = x0[e, b, i]
            v[e, b, i] = v0[e, b, i]
            w[e, b, i] = w0[e, b, i]
            disp[e, b, i] = 0.0
    return True


@njit(cache=True, error_model="numpy")
def finite(e, st):
    """Every entry of the element's result is finite (elementwise: a sum could overflow).
    Written out flat: a helper taking the arrays costs ~100 ns per element in calls."""
    x, q, v, w = st[X], st[Q], st[V], st[W]
    for b in range(x.shape[1]):
        for i in range(3):
            if not (math.isfinite(x[e, b, i]) and math.isfinite(v[e, b, i])):
                return False
            if not math.isfinite(w[e, b, i]):
                return False
        for i in range(4):
            if not math.isfinite(q[e, b, i]):
                return False
    return True

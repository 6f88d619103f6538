"""What every compiled step does around its stages: set up an element, check its result."""

from __future__ import annotations

import math

from numba import njit

from .layout import CONTACT, DISPLACEMENT, Q0, REPORT, V0, W0, X0, Q, V, W, X


@njit(cache=True)
def begin(e, st, tolerance):
    """Working state = the state passed in with |q| renormalised, as ``StepContext`` (the
    scene's ``_norm2`` order: x² + y² + z² + w²); displacement and report zeroed. False when
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
    st[REPORT][e, :] = 0.0
    st[CONTACT][e, :, :] = 0.0
    return True


@njit(cache=True)
def _finite_rows(a, e):
    for b in range(a.shape[1]):
        for i in range(a.shape[2]):
            if not math.isfinite(a[e, b, i]):
                return False
    return True


@njit(cache=True)
def finite(e, st):
    """Every entry of the element's result is finite (elementwise: a sum could overflow)."""
    return (
        _finite_rows(st[X], e)
        and _finite_rows(st[Q], e)
        and _finite_rows(st[V], e)
        and _finite_rows(st[W], e)
    )

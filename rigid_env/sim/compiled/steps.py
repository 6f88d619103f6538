"""The compiled steps: ``free_step`` (bodies without contacts) and ``contact_step``, each one
call over the batch, and what both do around their stages: set up an element, check its
result, and carry one step's result into the next when a call runs several.

Each step is the sequence of its stages, written out: the driver picks one of the two from the
scene's composition, once. numba specialises a step for its arguments' types: the integrator's
tag picks its kernels (``registry.integrate``), the force data's None slots drop their terms
(``forces.wrench``), a scene without a ground passes None for its detection data, and a step
without a warm start None for its impulses; each specialisation is compiled once and cached on
disk. The contact kernels are called through their addresses (``calls``): compiled once each,
shared by every composition.

``BODY_TORQUE`` is the step tuple's slot after ``layout``'s: the body-frame torque (N, n, 3)
that ``forces.wrench`` turns into the world at each evaluation's orientation.
"""

from __future__ import annotations

import math

import numpy as np
from numba import types
from numba.extending import overload

from ..state import ORIENTATION_TOLERANCE
from .cache import njit
from .calls import as_ref, call_at
from .layout import (
    CAPPED,
    CONTACT,
    DISPLACEMENT,
    ENERGY_REMOVED,
    ENGAGED,
    Q0,
    REPORT,
    STEP_TUPLE_SIZE,
    V0,
    W0,
    WARM,
    WARM_END,
    WARMED,
    X0,
    Q,
    V,
    W,
    X,
)
from .registry import integrate, integrate_position, integrate_velocity

BODY_TORQUE = STEP_TUPLE_SIZE  # appended by the driver after the layout's slots


# Written for numba's reference-count pruning. Where an inlined function binds the step
# tuple's arrays they are increfed, and decrefed where its body ends: an atomic add each, about
# half of Reorient's compiled step (``docs/performance.md``). numba's pruner removes such a pair
# only across a short stretch of code with no early exit and no call that can raise. So
# ``begin`` has no early return from its loop, ``finite`` no branch, and ``finite`` indexes
# ``st`` in place instead of binding names (with names the pairs stayed).


@njit(cache=True, error_model="numpy", inline="always")
def begin(e, st, tolerance):
    """Working state = the state passed in with |q| renormalised, (the
    scene's ``_norm2`` order: x² + y² + z² + w²), displacement zeroed (the driver hands the
    contact stages zeroed ``contact`` and ``report`` arrays). False when a quaternion is off
    unit length by more than ``tolerance`` (the scene's ``ORIENTATION_TOLERANCE``; its
    ``_arrays`` check): that element's step is then not run and its
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


# --- the kernels' data of one element ---------------------------------------------------------


def take(data, p):
    """Row p of every array of the nested tuple ``data`` (``driver.stack``: the kernels' data
    of element p's model); None stays None."""
    if data is None:
        return None
    if isinstance(data, tuple):
        return tuple(take(d, p) for d in data)
    return data[p]


@overload(take)
def _take(data, p):
    if isinstance(data, types.NoneType):
        return lambda data, p: None
    if isinstance(data, types.Array):
        return lambda data, p: data[p]
    if isinstance(data, types.BaseTuple):
        if len(data) == 0:
            return lambda data, p: ()
        return lambda data, p: (take(data[0], p),) + take(data[1:], p)
    return None


def collide_ground(address, e, ref, d):
    """The ground's detection, for a scene that has a ground (None data: nothing)."""
    if d is not None:
        call_at(address, e, ref, d)


@overload(collide_ground, inline="always")
def _collide_ground(address, e, ref, d):
    if isinstance(d, types.NoneType):
        return lambda address, e, ref, d: None
    return lambda address, e, ref, d: call_at(address, e, ref, d)


# Where ``contact_step`` finds each contact kernel's address (``driver.CONTACT_KERNELS``).
GROUND, PAIRS, ASSEMBLE, RESTITUTE, SOLVE, LIMIT, SEPARATE = range(7)


# --- the steps ----------------------------------------------------------------------------------
# The scratch (displacement, contact slots, the start copies that ``carry`` overwrites) is
# allocated here, per call: an allocation in compiled code costs a fraction of one from Python
# and of the unboxing of each array passed in; per call, so concurrent steps of one
# scene (threads) cannot mix. An element's steps are written into the loop, not an inlined
# function: binding ``st``, ``data`` and ``total`` as its arguments costs each element an
# atomic incref and decref per array (see the top of this module).


@njit(cache=True, error_model="numpy", inline="always")
def scratch(x0, q0, v0, w0, report, steps):
    """A call's start slots, displacement and report total: with several steps the start
    slots carry each step's result into the next (``carry``), so they are copies, and the
    report's running total is an array of its own."""
    disp = np.empty((x0.shape[0], x0.shape[1], 3))  # zeroed per element by begin
    if steps > 1:
        return x0.copy(), q0.copy(), v0.copy(), w0.copy(), disp, np.zeros_like(report)
    return x0, q0, v0, w0, disp, report


@njit(cache=True, nogil=True, error_model="numpy")
def free_step(
    x0, q0, v0, w0, x, q, v, w, force, torque, body, report, counts, data, rows, steps,
    integrator,
):  # fmt: skip
    """``steps`` steps of bodies without contacts: per element, the integrator (its force
    terms inside). ``data`` = (integrator data,) for every element, or, where ``rows`` is not
    None, row e of ``rows`` (stacked data of that type, ``driver.stack``) for element e.
    Returns the counts of elements with a quaternion off unit length, with a non-finite
    result, and with a capped solve (none here)."""
    x0, q0, v0, w0, disp, total = scratch(x0, q0, v0, w0, report, steps)
    contact = np.zeros((x0.shape[0], 0, 1))
    st = (x0, q0, v0, w0, x, q, v, w, force, torque, disp, contact, report, body)
    ref = as_ref(st)
    counts[:] = 0.0
    bad_orientation = diverged = 0
    (d,) = data
    for e in range(x0.shape[0]):
        if rows is not None:
            (d,) = take(rows, e)
        verdict = 0
        for k in range(steps):
            if k > 0:
                carry(e, st, total)
            if not begin(e, st, ORIENTATION_TOLERANCE):
                verdict = 1
                break
            integrate(integrator, e, ref, d)
            if not finite(e, st):
                verdict = 2
                break
        if verdict == 0 and steps > 1:
            fold(e, st, total)
        bad_orientation += verdict == 1
        diverged += verdict == 2
    return bad_orientation, diverged, 0


@njit(cache=True, nogil=True, error_model="numpy")
def contact_step(
    x0, q0, v0, w0, x, q, v, w, force, torque, body, report, counts, data, rows, steps,
    integrator, slots, width, addresses, warm_in, warm_out,
):  # fmt: skip
    """``steps`` steps of bodies with contacts: per element, the velocity update, detection
    (ground, then body–body pairs where the scene has them), assembly, impacts, the solve,
    the energy guard, the position update and the separation. ``data`` = (integrator data,
    ground detection data or None, contact data), ``rows`` as in ``free_step``; ``slots`` and
    ``width`` the contact slots per element and their columns; ``addresses`` the contact
    kernels' (at ``GROUND`` … ``SEPARATE``; 0 at ``PAIRS`` for a scene without body–body
    contacts); ``warm_in``/``warm_out`` the impulses the state carries (``Driver.__call__``),
    or None. Also counts per step the engaged, capped and warm-started elements."""
    x0, q0, v0, w0, disp, total = scratch(x0, q0, v0, w0, report, steps)
    contact = np.zeros((x0.shape[0], slots, width))
    if warm_in is not None:  # the impulses the state carries: the first step starts from them
        contact[:, :, WARM:WARM_END] = warm_in
    st = (x0, q0, v0, w0, x, q, v, w, force, torque, disp, contact, report, body)
    ref = as_ref(st)  # the kernels take st by reference (``calls``)
    counts[:] = 0.0  # (steps, 3): per step, the engaged, capped and warm-started elements
    bad_orientation = diverged = capped = 0
    idata, ground, cd = data
    for e in range(x0.shape[0]):
        if rows is not None:
            idata, ground, cd = take(rows, e)
        verdict = 0
        for k in range(steps):
            if k > 0:
                carry(e, st, total)
            if not begin(e, st, ORIENTATION_TOLERANCE):
                verdict = 1
                break
            integrate_velocity(integrator, e, ref, idata)
            collide_ground(addresses[GROUND], e, ref, ground)
            if addresses[PAIRS] != 0:
                call_at(addresses[PAIRS], e, ref, cd)
            call_at(addresses[ASSEMBLE], e, ref, cd)
            call_at(addresses[RESTITUTE], e, ref, cd)
            call_at(addresses[SOLVE], e, ref, cd)
            call_at(addresses[LIMIT], e, ref, cd)
            integrate_position(integrator, e, ref, idata)
            call_at(addresses[SEPARATE], e, ref, cd)
            if not finite(e, st):
                verdict = 2
                break
            if report[e, ENGAGED] > 0.0:
                counts[k, 0] += 1.0
            if report[e, CAPPED] > 0.0:
                counts[k, 1] += 1.0
            if report[e, WARMED] > 0.0:
                counts[k, 2] += 1.0
        if verdict == 0 and steps > 1:
            fold(e, st, total)
        bad_orientation += verdict == 1
        diverged += verdict == 2
        if report[e, CAPPED] > 0.0:
            capped += 1
    if warm_out is not None:  # and the last step's, for the state the step returns
        warm_out[:] = contact[:, :, WARM:WARM_END]
    return bad_orientation, diverged, capped

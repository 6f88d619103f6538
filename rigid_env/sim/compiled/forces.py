"""Force terms on one body (``rigid_env.sim.forces``): ``term(b, x, q, v, w, fd)``, and their sum.

Each term returns its world (force, torque) on body b as 3-tuples (zeros for a component a term
does not produce: adding a zero changes no bit of a finite sum). A scene's force data is one
tuple with a slot per term of ``TERMS``, in that order (``force_data``), None where the scene
has no such term: ``wrench`` and ``damping_matrices`` are typed for it, and numba compiles no
code for a None slot (``_optional``), so a body in space evaluates no force at all.
"""

from __future__ import annotations

import numpy as np
from numba import types
from numba.extending import overload

from ..model import Model
from . import bodies
from .cache import njit
from .registry import ForceKernel, register_force
from .rotation import cross, matmul, quat_rotate, quat_to_matrix, transpose

# The force slots of a scene's data, in the order the wrench sums them (``sim.forces.build``).
TERMS = ("gravity", "damping", "springs")

_ZERO = (0.0, 0.0, 0.0)


@njit(cache=True, error_model="numpy", inline="always")
def gravity(b, x, q, v, w, fd):
    weight = fd[0]  # (n, 3): m g per body
    return (weight[b, 0], weight[b, 1], weight[b, 2]), (0.0, 0.0, 0.0)


@njit(cache=True, error_model="numpy")
def damping_matrix(b, x, q, fd, out):
    """``forces.Damping.damping_matrix``: diag(γ_v m I, γ_ω R M0 Rᵀ), added into ``out``."""
    bd, rates = fd
    gv, gw = rates[0], rates[1]
    a = gv * bd[b, bodies.MASS]
    rot = quat_to_matrix(q)
    inertia = matmul(matmul(rot, bodies.matrix(bd, b, bodies.INERTIA)), transpose(rot))
    for i in range(3):
        out[i, i] += a
        for j in range(3):
            out[3 + i, 3 + j] += gw * inertia[3 * i + j]


@njit(cache=True, error_model="numpy", inline="always")
def damping(b, x, q, v, w, fd):
    """ṗ = −γ_v p, L̇ = −γ_ω L; ``fd = (body data, [γ_v, γ_ω])``."""
    bd, rates = fd
    gv, gw = rates[0], rates[1]
    f = (0.0, 0.0, 0.0)
    t = (0.0, 0.0, 0.0)
    if gv != 0.0:
        a = -gv * bd[b, bodies.MASS]
        f = (a * v[0], a * v[1], a * v[2])
    if gw != 0.0:
        lw = bodies.apply_inertia(bd, b, quat_to_matrix(q), w)
        t = (-gw * lw[0], -gw * lw[1], -gw * lw[2])
    return f, t


# Columns of the spring table (S, SPRING_WIDTH).
S_BODY, S_ANCHOR, S_ATTACH, S_K, S_C, S_REST = 0, 1, 4, 7, 8, 9
SPRING_WIDTH = 10


def spring_table(model: Model) -> np.ndarray:
    table = np.zeros((len(model.springs), SPRING_WIDTH))
    for i, sp in enumerate(model.springs):
        table[i, S_BODY] = sp.body
        table[i, S_ANCHOR : S_ANCHOR + 3] = sp.anchor
        table[i, S_ATTACH : S_ATTACH + 3] = sp.attach
        table[i, S_K], table[i, S_C], table[i, S_REST] = sp.stiffness, sp.damping, sp.rest_length
    return table


@njit(cache=True, error_model="numpy")
def spring_force(sd, s, x, q, v, w):
    """Force and torque of spring s on its body, and its arm R r (``forces.springs``)."""
    anchor = (sd[s, S_ANCHOR], sd[s, S_ANCHOR + 1], sd[s, S_ANCHOR + 2])
    attach = (sd[s, S_ATTACH], sd[s, S_ATTACH + 1], sd[s, S_ATTACH + 2])
    k, c, rest = sd[s, S_K], sd[s, S_C], sd[s, S_REST]
    arm = quat_rotate(q, attach)
    d = (x[0] + arm[0] - anchor[0], x[1] + arm[1] - anchor[1], x[2] + arm[2] - anchor[2])
    wa = cross(w, arm)
    pdot = (v[0] + wa[0], v[1] + wa[1], v[2] + wa[2])
    length = np.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2)
    safe = length if length > 0 else 1.0
    unit = (d[0] / safe, d[1] / safe, d[2] / safe)
    if rest > 0:
        a = k * (length - rest)
        stretched = (a * unit[0], a * unit[1], a * unit[2])
        g = c * (pdot[0] * unit[0] + pdot[1] * unit[1] + pdot[2] * unit[2])
        damped = (g * unit[0], g * unit[1], g * unit[2])
    else:
        stretched = (k * d[0], k * d[1], k * d[2])
        damped = (c * pdot[0], c * pdot[1], c * pdot[2])
    f = (-(stretched[0] + damped[0]), -(stretched[1] + damped[1]), -(stretched[2] + damped[2]))
    return f, cross(arm, f)


@njit(cache=True, error_model="numpy")
def spring_damping_matrix(b, x, q, fd, out):
    """``forces.Springs.damping_matrix``: Σ Jᵀ C J over body b's springs, added into ``out``."""
    sd = fd[0]
    for s in range(sd.shape[0]):
        if int(sd[s, S_BODY]) != b or sd[s, S_C] == 0.0:
            continue
        attach = (sd[s, S_ATTACH], sd[s, S_ATTACH + 1], sd[s, S_ATTACH + 2])
        c, rest = sd[s, S_C], sd[s, S_REST]
        arm = quat_rotate(q, attach)
        d = (
            x[0] + arm[0] - sd[s, S_ANCHOR],
            x[1] + arm[1] - sd[s, S_ANCHOR + 1],
            x[2] + arm[2] - sd[s, S_ANCHOR + 2],
        )
        length = np.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2)
        safe = length if length > 0 else 1.0
        unit = (d[0] / safe, d[1] / safe, d[2] / safe)
        jac = np.zeros((3, 6))  # J = [I, −(R r)*]
        for i in range(3):
            jac[i, i] = 1.0
        jac[0, 4], jac[0, 5] = arm[2], -arm[1]
        jac[1, 3], jac[1, 5] = -arm[2], arm[0]
        jac[2, 3], jac[2, 4] = arm[1], -arm[0]
        for i in range(6):
            for j in range(6):
                acc = 0.0
                for a in range(3):
                    for bb in range(3):
                        cab = c * (unit[a] * unit[bb]) if rest > 0 else (c if a == bb else 0.0)
                        acc += jac[a, i] * cab * jac[bb, j]
                out[i, j] += acc


@njit(cache=True, error_model="numpy", inline="always")
def springs(b, x, q, v, w, fd):
    """Sum over the springs on body b, in spring order."""
    sd = fd[0]
    fx = fy = fz = tx = ty = tz = 0.0
    for s in range(sd.shape[0]):
        if int(sd[s, S_BODY]) != b:
            continue
        f, t = spring_force(sd, s, x, q, v, w)
        fx, fy, fz = fx + f[0], fy + f[1], fz + f[2]
        tx, ty, tz = tx + t[0], ty + t[1], tz + t[2]
    return (fx, fy, fz), (tx, ty, tz)


def _optional(term, matrix=False):
    """``term`` where its slot holds data; nothing where it holds None (a scene without it).

    Force terms give ``(f, t) + term(...)``; damping matrices (``matrix``) add into ``out``.
    The overloads pick by the slot's type when the step compiles; the plain functions are what
    runs without numba's JIT."""
    if matrix:

        def add(fd, b, x, q, out):
            if fd is not None:
                term(b, x, q, fd, out)

        @overload(add)
        def _add(fd, b, x, q, out):
            if isinstance(fd, types.NoneType):
                return lambda fd, b, x, q, out: None
            return lambda fd, b, x, q, out: term(b, x, q, fd, out)

        return add

    def plus(fd, b, x, q, v, w, f, t):
        if fd is None:
            return f, t
        fi, ti = term(b, x, q, v, w, fd)
        return (f[0] + fi[0], f[1] + fi[1], f[2] + fi[2]), (
            t[0] + ti[0],
            t[1] + ti[1],
            t[2] + ti[2],
        )

    @overload(plus)
    def _plus(fd, b, x, q, v, w, f, t):
        if isinstance(fd, types.NoneType):
            return lambda fd, b, x, q, v, w, f, t: (f, t)

        def impl(fd, b, x, q, v, w, f, t):
            fi, ti = term(b, x, q, v, w, fd)
            f = (f[0] + fi[0], f[1] + fi[1], f[2] + fi[2])
            return f, (t[0] + ti[0], t[1] + ti[1], t[2] + ti[2])

        return impl

    return plus


plus_gravity = _optional(gravity)
plus_damping = _optional(damping)
plus_springs = _optional(springs)
add_damping = _optional(damping_matrix, matrix=True)
add_spring_damping = _optional(spring_damping_matrix, matrix=True)


@njit(cache=True, error_model="numpy")
def wrench(b, x, q, v, w, fa, ta, tb, fds):
    """The world (force, torque) on body b at state (x, q, v, w): the applied world loads
    ``fa``, ``ta``, the body-frame torque ``tb`` turned into the world at q (skipped when zero),
    then each term of the scene's force data ``fds`` (``TERMS`` order)."""
    f, t = fa, ta
    if tb[0] != 0.0 or tb[1] != 0.0 or tb[2] != 0.0:
        r = quat_rotate(q, tb)
        t = (t[0] + r[0], t[1] + r[1], t[2] + r[2])
    f, t = plus_gravity(fds[0], b, x, q, v, w, f, t)
    f, t = plus_damping(fds[1], b, x, q, v, w, f, t)
    return plus_springs(fds[2], b, x, q, v, w, f, t)


@njit(cache=True, error_model="numpy")
def damping_matrices(b, x, q, fds, out):
    """Add the damping matrices C of the velocity-dependent terms on body b into ``out``
    (``(F, T) = (F, T)|ᵤ₌₀ − C u``, u = (v, ω)); an undamped spring adds nothing."""
    add_damping(fds[1], b, x, q, out)
    add_spring_damping(fds[2], b, x, q, out)


def force_data(forces) -> tuple:
    """The scene's force data: one slot per term of ``TERMS`` (its ``ForceKernel`` data, or
    None)."""
    given = {f.name: f.data for f in forces}
    return tuple(given.get(name) for name in TERMS)


@register_force("gravity")
def _gravity(scene):
    weight = np.ascontiguousarray(scene.model.mass[:, None] * scene.model.gravity)
    return ForceKernel("gravity", (weight,))


@register_force("damping")
def _damping(scene):
    m = scene.model
    rates = np.array([m.linear_damping, m.angular_damping])
    return ForceKernel("damping", (bodies.body_data(m), rates))


@register_force("springs")
def _springs(scene):
    return ForceKernel("springs", (spring_table(scene.model),))

"""The integrators' kernels, one body at a time (``rigid_env.sim.integrators`` holds their
records and derivations).

Each integrator registers its element kernels (``registry.register_integrator``): ``<name>``
for a one-part integrator (stage ``integrate``), ``<name>_velocity`` and ``<name>_position``
for a semi-implicit one (stages ``integrate_velocity`` / ``integrate_position``), with
``d = ((body data, [dt, velocity_dependent], spring table), force data)``; each updates the
working state in place. Loads are evaluated only through ``forces.wrench(b, x, q, v, w, fa,
ta, tb, fds)``, which turns the body-frame torque ``tb`` into the world at the orientation it
is given; numba compiles a kernel once per type of the force data ``fds``, so a scene's
kernels evaluate exactly its force terms.
"""

from __future__ import annotations

import math

import numpy as np

from ..integrators import W0 as YOSHIDA_W0
from ..integrators import W1 as YOSHIDA_W1
from . import bodies
from .bodies import (
    INV_MASS,
    INV_MOMENTS,
    MOMENTS,
    PRINCIPAL,
    PRINCIPAL_CONJ,
    PRINCIPAL_QUAT,
    apply_inertia,
    apply_inverse_inertia,
    vec3,
    vec4,
)
from .cache import njit
from .forces import S_ANCHOR, S_ATTACH, S_BODY, S_C, S_K, S_REST, spring_table, wrench
from .forces import damping_matrices as damping
from .layout import DISPLACEMENT, FORCE, TORQUE, Q, V, W, X
from .registry import INTEGRATORS, Kernel, register, register_integrator
from .rotation import (
    align_sign,
    cross,
    gram_schmidt,
    matmul,
    matrix_to_quat,
    quat_conjugate,
    quat_exp,
    quat_multiply,
    quat_normalize,
    quat_rotate,
    quat_to_matrix,
    rotate,
    rotate_inverse,
    skew,
    transpose,
)
from .steps import BODY_TORQUE

# --- shared pieces ----------------------------------------------------------------------------
# The helpers that take the step tuple are inlined (numba IR): called, each would cost more
# per element in argument passing than the arithmetic of a whole free-body step.


@njit(cache=True, error_model="numpy", inline="always")
def load(st, e, b):
    """Working state and applied loads of body b of element e, as tuples."""
    x = (st[X][e, b, 0], st[X][e, b, 1], st[X][e, b, 2])
    q = (st[Q][e, b, 0], st[Q][e, b, 1], st[Q][e, b, 2], st[Q][e, b, 3])
    v = (st[V][e, b, 0], st[V][e, b, 1], st[V][e, b, 2])
    w = (st[W][e, b, 0], st[W][e, b, 1], st[W][e, b, 2])
    fa = (st[FORCE][e, b, 0], st[FORCE][e, b, 1], st[FORCE][e, b, 2])
    ta = (st[TORQUE][e, b, 0], st[TORQUE][e, b, 1], st[TORQUE][e, b, 2])
    return x, q, v, w, fa, ta


@njit(cache=True, error_model="numpy", inline="always")
def load_body_torque(st, e, b):
    """The body-frame torque on body b of element e (``wrench`` turns it at each evaluation)."""
    tb = st[BODY_TORQUE]
    return (tb[e, b, 0], tb[e, b, 1], tb[e, b, 2])


@njit(cache=True, error_model="numpy", inline="always")
def store(st, e, b, x, q, v, w):
    for i in range(3):
        st[X][e, b, i] = x[i]
        st[V][e, b, i] = v[i]
        st[W][e, b, i] = w[i]
    for i in range(4):
        st[Q][e, b, i] = q[i]


@njit(cache=True, error_model="numpy", inline="always")
def store_velocity(st, e, b, v, w):
    for i in range(3):
        st[V][e, b, i] = v[i]
        st[W][e, b, i] = w[i]


@njit(cache=True, error_model="numpy", inline="always")
def translate(st, e, b, x, v, dt):
    """``common.translate``: x + Δt v, plus the contact displacement (zero when none)."""
    disp = st[DISPLACEMENT]
    return (
        x[0] + dt * v[0] + disp[e, b, 0],
        x[1] + dt * v[1] + disp[e, b, 1],
        x[2] + dt * v[2] + disp[e, b, 2],
    )


@njit(cache=True, error_model="numpy")
def kick(v, h, inverse, f):
    """``v + h · inverse · f`` ."""
    a = h * inverse
    return (v[0] + a * f[0], v[1] + a * f[1], v[2] + a * f[2])


@njit(cache=True, error_model="numpy")
def axpy(y, a, x):
    """``y + a x``."""
    return (y[0] + a * x[0], y[1] + a * x[1], y[2] + a * x[2])


@njit(cache=True, error_model="numpy")
def axpy4(y, a, x):
    return (y[0] + a * x[0], y[1] + a * x[1], y[2] + a * x[2], y[3] + a * x[3])


@njit(cache=True, error_model="numpy")
def is_zero(t):
    """An absent load is zeros here."""
    return t[0] == 0.0 and t[1] == 0.0 and t[2] == 0.0


# --- euler, euler_quat ------------------------------------------------------------------------


def euler_velocity(tag, e, st, d):
    """v += Δt F/m; ω = M⁻¹ (M ω + Δt T) at the start pose."""
    (bd, prm, sd), fds = d
    dt = prm[0]
    for b in range(st[X].shape[1]):
        x, q, v, w, fa, ta = load(st, e, b)
        tb = load_body_torque(st, e, b)
        f, t = wrench(b, x, q, v, w, fa, ta, tb, fds)
        if not is_zero(f):
            v = kick(v, dt, bd[b, INV_MASS], f)
        if not is_zero(t):
            rot = quat_to_matrix(q)
            w = apply_inverse_inertia(bd, b, rot, axpy(apply_inertia(bd, b, rot, w), dt, t))
        store_velocity(st, e, b, v, w)


def euler_position(tag, e, st, d):
    """R += Δt ω* R, Gram–Schmidt; ω = M⁻¹ L after."""
    (bd, prm, sd), fds = d
    dt = prm[0]
    for b in range(st[X].shape[1]):
        x, q, v, w, fa, ta = load(st, e, b)
        rot = quat_to_matrix(q)
        lw = apply_inertia(bd, b, rot, w)
        c0 = cross(w, (rot[0], rot[3], rot[6]))
        c1 = cross(w, (rot[1], rot[4], rot[7]))
        c2 = cross(w, (rot[2], rot[5], rot[8]))
        wr = (c0[0], c1[0], c2[0], c0[1], c1[1], c2[1], c0[2], c1[2], c2[2])
        moved = (
            rot[0] + dt * wr[0],
            rot[1] + dt * wr[1],
            rot[2] + dt * wr[2],
            rot[3] + dt * wr[3],
            rot[4] + dt * wr[4],
            rot[5] + dt * wr[5],
            rot[6] + dt * wr[6],
            rot[7] + dt * wr[7],
            rot[8] + dt * wr[8],
        )
        rot = gram_schmidt(moved)
        x = translate(st, e, b, x, v, dt)
        q = align_sign(matrix_to_quat(rot), q)
        store(st, e, b, x, q, v, apply_inverse_inertia(bd, b, rot, lw))


def euler_quat_position(tag, e, st, d):
    """q̇ = ½ (ω, 0) ∘ q, renormalise; ω = M⁻¹ L after."""
    (bd, prm, sd), fds = d
    dt = prm[0]
    for b in range(st[X].shape[1]):
        x, q, v, w, fa, ta = load(st, e, b)
        lw = apply_inertia(bd, b, quat_to_matrix(q), w)
        dq = quat_multiply((w[0], w[1], w[2], 0.0), q)
        q = quat_normalize(axpy4(q, 0.5 * dt, dq))
        x = translate(st, e, b, x, v, dt)
        store(st, e, b, x, q, v, apply_inverse_inertia(bd, b, quat_to_matrix(q), lw))


# --- rk4 --------------------------------------------------------------------------------------


@njit(cache=True, error_model="numpy")
def rk4_derivative(bd, b, fds, x, q, v, lw, fa, ta, tb, start, x0, q0, v0, w0):
    """The RK4 derivative; at the first stage (``start``) the wrench is the force
    stages' one, evaluated at the working state itself."""
    qn = quat_normalize(q)
    w = apply_inverse_inertia(bd, b, quat_to_matrix(qn), lw)
    if start:
        f, t = wrench(b, x0, q0, v0, w0, fa, ta, tb, fds)
    else:
        f, t = wrench(b, x, qn, v, w, fa, ta, tb, fds)
    qd = quat_multiply((w[0], w[1], w[2], 0.0), qn)
    qdot = (0.5 * qd[0], 0.5 * qd[1], 0.5 * qd[2], 0.5 * qd[3])
    im = bd[b, INV_MASS]
    vdot = (f[0] * im, f[1] * im, f[2] * im)
    ldot = (t[0] + 0.0, t[1] + 0.0, t[2] + 0.0)
    return v, qdot, vdot, ldot


@njit(cache=True, error_model="numpy")
def rk4_stage(bd, b, fds, y0, h, k, loads, begin):
    """The RK4 derivative at y0 + h k, y = (x, q, v, L); ``loads`` = (fa, ta, tb) and ``begin``
    the step's start state (x0, q0, v0, w0), as ``rk4_derivative`` takes them."""
    (x0, q0, v0, l0), (fa, ta, tb), (xs, qs, vs, ws) = y0, loads, begin
    x, q, v = axpy(x0, h, k[0]), axpy4(q0, h, k[1]), axpy(v0, h, k[2])
    lw = axpy(l0, h, k[3])
    return rk4_derivative(bd, b, fds, x, q, v, lw, fa, ta, tb, False, xs, qs, vs, ws)


def rk4(tag, e, st, d):
    """classical RK4 on (x, q, v, L)."""
    (bd, prm, sd), fds = d
    dt = prm[0]
    for b in range(st[X].shape[1]):
        x0, q0, v0, w0, fa, ta = load(st, e, b)
        tb = load_body_torque(st, e, b)
        l0 = apply_inertia(bd, b, quat_to_matrix(q0), w0)
        k1 = rk4_derivative(bd, b, fds, x0, q0, v0, l0, fa, ta, tb, True, x0, q0, v0, w0)
        y0, loads, begin = (x0, q0, v0, l0), (fa, ta, tb), (x0, q0, v0, w0)
        h = 0.5 * dt
        k2 = rk4_stage(bd, b, fds, y0, h, k1, loads, begin)
        k3 = rk4_stage(bd, b, fds, y0, h, k2, loads, begin)
        k4 = rk4_stage(bd, b, fds, y0, dt, k3, loads, begin)
        s = dt / 6
        x = rk4_combine3(x0, s, k1[0], k2[0], k3[0], k4[0])
        q = rk4_combine4(q0, s, k1[1], k2[1], k3[1], k4[1])
        v = rk4_combine3(v0, s, k1[2], k2[2], k3[2], k4[2])
        lw = rk4_combine3(l0, s, k1[3], k2[3], k3[3], k4[3])
        q = quat_normalize(q)
        store(st, e, b, x, q, v, apply_inverse_inertia(bd, b, quat_to_matrix(q), lw))


@njit(cache=True, error_model="numpy")
def rk4_combine3(y, s, a, b, c, d):
    """``y + s (a + 2 b + 2 c + d)``, left to right."""
    return (
        y[0] + s * (a[0] + 2 * b[0] + 2 * c[0] + d[0]),
        y[1] + s * (a[1] + 2 * b[1] + 2 * c[1] + d[1]),
        y[2] + s * (a[2] + 2 * b[2] + 2 * c[2] + d[2]),
    )


@njit(cache=True, error_model="numpy")
def rk4_combine4(y, s, a, b, c, d):
    return (
        y[0] + s * (a[0] + 2 * b[0] + 2 * c[0] + d[0]),
        y[1] + s * (a[1] + 2 * b[1] + 2 * c[1] + d[1]),
        y[2] + s * (a[2] + 2 * b[2] + 2 * c[2] + d[2]),
        y[3] + s * (a[3] + 2 * b[3] + 2 * c[3] + d[3]),
    )


# --- splitting, splitting4 --------------------------------------------------------------------


@njit(cache=True, error_model="numpy")
def _axis_flow(pa, pj, pk, ra, rj, rk, r3, phi):
    """One exact sub-flow about principal axis a ."""
    c, s = math.cos(phi), math.sin(phi)
    pj, pk = c * pj + s * pk, c * pk - s * pj
    half = 0.5 * phi
    ch, sh = math.cos(half), math.sin(half)
    ra, r3, rj, rk = ch * ra + sh * r3, ch * r3 - sh * ra, ch * rj + sh * rk, ch * rk - sh * rj
    return pj, pk, ra, rj, rk, r3


@njit(cache=True, error_model="numpy", inline="always")
def free_rotation(inv, qp, pi, h):
    """axes (0, ½)(1, ½)(2, 1)(1, ½)(0, ½), then renormalise.
    Inlined: a call can raise (numba's status), which keeps the step tuple's reference counts
    in the element loop (see ``steps.py``)."""
    p0, p1, p2 = pi
    r0, r1, r2, r3 = qp
    phi = (0.5 * h) * (inv[0] * p0)
    p1, p2, r0, r1, r2, r3 = _axis_flow(p0, p1, p2, r0, r1, r2, r3, phi)
    phi = (0.5 * h) * (inv[1] * p1)
    p2, p0, r1, r2, r0, r3 = _axis_flow(p1, p2, p0, r1, r2, r0, r3, phi)
    phi = (1.0 * h) * (inv[2] * p2)
    p0, p1, r2, r0, r1, r3 = _axis_flow(p2, p0, p1, r2, r0, r1, r3, phi)
    phi = (0.5 * h) * (inv[1] * p1)
    p2, p0, r1, r2, r0, r3 = _axis_flow(p1, p2, p0, r1, r2, r0, r3, phi)
    phi = (0.5 * h) * (inv[0] * p0)
    p1, p2, r0, r1, r2, r3 = _axis_flow(p0, p1, p2, r0, r1, r2, r3, phi)
    n = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2 + r3 * r3)
    return (r0 / n, r1 / n, r2 / n, r3 / n), (p0, p1, p2)


@njit(cache=True, error_model="numpy", inline="always")
def strang_drift(bd, b, fds, x, q, v, w, fa, ta, tb, dt):
    """The Strang step up to its closing half kick: half kick, then the drift with the
    exact free rotation."""
    f, t = wrench(b, x, q, v, w, fa, ta, tb, fds)
    v = kick(v, 0.5 * dt, bd[b, INV_MASS], f)
    x = axpy(x, dt, v)
    principal = bd[b, PRINCIPAL] != 0.0
    qp = quat_multiply(q, vec4(bd, b, PRINCIPAL_QUAT)) if principal else q
    conj = quat_conjugate(qp)
    moments = vec3(bd, b, MOMENTS)
    r = quat_rotate(conj, w)
    pi = (moments[0] * r[0], moments[1] * r[1], moments[2] * r[2])
    pi = axpy(pi, 0.5 * dt, quat_rotate(conj, t))
    inv = vec3(bd, b, INV_MOMENTS)
    qp, pi = free_rotation(inv, qp, pi, dt)
    w = quat_rotate(qp, (pi[0] * inv[0], pi[1] * inv[1], pi[2] * inv[2]))
    q = quat_multiply(qp, vec4(bd, b, PRINCIPAL_CONJ)) if principal else qp
    return x, q, v, w


@njit(cache=True, error_model="numpy", inline="always")
def strang(bd, b, fds, x, q, v, w, fa, ta, tb, dt):
    """The Strang step's end without velocity-dependent forces: drift, explicit half kick."""
    x, q, v, w = strang_drift(bd, b, fds, x, q, v, w, fa, ta, tb, dt)
    f, t = wrench(b, x, q, v, w, fa, ta, tb, fds)
    v = kick(v, 0.5 * dt, bd[b, INV_MASS], f)
    w = axpy(w, 0.5 * dt, apply_inverse_inertia(bd, b, quat_to_matrix(q), t))
    return x, q, v, w


@njit(cache=True, error_model="numpy")
def strang_damped(bd, b, fds, x, q, v, w, fa, ta, tb, dt):
    """The Strang step's end with velocity-dependent forces: drift, implicit half kick."""
    x, q, v, w = strang_drift(bd, b, fds, x, q, v, w, fa, ta, tb, dt)
    v, w = implicit_half_kick(bd, b, fds, x, q, v, w, fa, ta, tb, dt)
    return x, q, v, w


@njit(cache=True, error_model="numpy")
def implicit_half_kick(bd, b, fds, x, q, v, w, fa, ta, tb, dt):
    """(M + ½ Δt C) u⁺ = M u + ½ Δt F(x, q, 0), one 6×6
    solve, C the sum of the velocity-dependent terms' damping matrices (``damping``, defined
    with ``wrench`` in the driver)."""
    zero = (0.0, 0.0, 0.0)
    f0, t0 = wrench(b, x, q, zero, zero, fa, ta, tb, fds)
    system = np.zeros((6, 6))
    damping(b, x, q, fds, system)
    h = 0.5 * dt
    rot = quat_to_matrix(q)
    inertia = matmul(matmul(rot, bodies.matrix(bd, b, bodies.INERTIA)), transpose(rot))
    m = bd[b, bodies.MASS]
    for i in range(6):
        for j in range(6):
            system[i, j] = h * system[i, j]
    for i in range(3):
        system[i, i] += m
        for j in range(3):
            system[3 + i, 3 + j] += inertia[3 * i + j]
    iw = rotate(inertia, w)
    rhs = np.empty(6)
    for i in range(3):
        rhs[i] = m * v[i] + h * f0[i]
        rhs[3 + i] = iw[i] + h * t0[i]
    u = solve6(system, rhs)
    return (u[0], u[1], u[2]), (u[3], u[4], u[5])


def splitting(tag, e, st, d):
    """Strang splitting, second order. Without
    velocity-dependent forces; ``splitting_damped`` is the scene's stage with them
    (``_integrator_stage``), so this one calls nothing that can raise (see ``free_rotation``)."""
    (bd, prm, sd), fds = d
    dt = prm[0]
    for b in range(st[X].shape[1]):
        x, q, v, w, fa, ta = load(st, e, b)
        tb = load_body_torque(st, e, b)
        x, q, v, w = strang(bd, b, fds, x, q, v, w, fa, ta, tb, dt)
        store(st, e, b, x, q, v, w)


def splitting4(tag, e, st, d):
    """Yoshida's triple jump of ``splitting``."""
    (bd, prm, sd), fds = d
    dt = prm[0]
    for b in range(st[X].shape[1]):
        x, q, v, w, fa, ta = load(st, e, b)
        tb = load_body_torque(st, e, b)
        x, q, v, w = strang(bd, b, fds, x, q, v, w, fa, ta, tb, YOSHIDA_W1 * dt)
        x, q, v, w = strang(bd, b, fds, x, q, v, w, fa, ta, tb, YOSHIDA_W0 * dt)
        x, q, v, w = strang(bd, b, fds, x, q, v, w, fa, ta, tb, YOSHIDA_W1 * dt)
        store(st, e, b, x, q, v, w)


def splitting_damped(tag, e, st, d):
    """``splitting`` with velocity-dependent forces (the implicit closing half kick)."""
    (bd, prm, sd), fds = d
    dt = prm[0]
    for b in range(st[X].shape[1]):
        x, q, v, w, fa, ta = load(st, e, b)
        tb = load_body_torque(st, e, b)
        x, q, v, w = strang_damped(bd, b, fds, x, q, v, w, fa, ta, tb, dt)
        store(st, e, b, x, q, v, w)


def splitting4_damped(tag, e, st, d):
    """``splitting4`` with velocity-dependent forces."""
    (bd, prm, sd), fds = d
    dt = prm[0]
    for b in range(st[X].shape[1]):
        x, q, v, w, fa, ta = load(st, e, b)
        tb = load_body_torque(st, e, b)
        x, q, v, w = strang_damped(bd, b, fds, x, q, v, w, fa, ta, tb, YOSHIDA_W1 * dt)
        x, q, v, w = strang_damped(bd, b, fds, x, q, v, w, fa, ta, tb, YOSHIDA_W0 * dt)
        x, q, v, w = strang_damped(bd, b, fds, x, q, v, w, fa, ta, tb, YOSHIDA_W1 * dt)
        store(st, e, b, x, q, v, w)


# --- implicit_gyro ----------------------------------------------------------------------------


@njit(cache=True, error_model="numpy")
def gyroscopic_newton_step(moments, omega, h):
    """one Newton step, Cramer's rule."""
    i1, i2, i3 = moments
    o1, o2, o3 = omega
    f1 = h * (i3 - i2) * o2 * o3
    f2 = h * (i1 - i3) * o3 * o1
    f3 = h * (i2 - i1) * o1 * o2
    b, c = h * (i3 - i2) * o3, h * (i3 - i2) * o2
    d, g = h * (i1 - i3) * o3, h * (i1 - i3) * o1
    p, r = h * (i2 - i1) * o2, h * (i2 - i1) * o1
    c11, c12, c13 = i2 * i3 - g * r, g * p - d * i3, d * r - i2 * p
    det = i1 * c11 + b * c12 + c * c13
    x1 = (c11 * f1 + (c * r - b * i3) * f2 + (b * g - c * i2) * f3) / det
    x2 = (c12 * f1 + (i1 * i3 - c * p) * f2 + (c * d - i1 * g) * f3) / det
    x3 = (c13 * f1 + (b * p - i1 * r) * f2 + (i1 * i2 - b * d) * f3) / det
    return (o1 - x1, o2 - x2, o3 - x3)


@njit(cache=True, error_model="numpy", inline="always")
def gyro_velocity(bd, b, q, w, t, dt):
    """The angular half of ``implicit_gyro``: body-axes kick, then the implicit gyro step."""
    rot = quat_to_matrix(q)
    if bd[b, PRINCIPAL] != 0.0:
        rot = matmul(rot, bodies.matrix(bd, b, bodies.AXES))
    omega = rotate_inverse(rot, w)
    inv = vec3(bd, b, INV_MOMENTS)
    rt = rotate_inverse(rot, t)
    omega = (
        omega[0] + dt * inv[0] * rt[0],
        omega[1] + dt * inv[1] * rt[1],
        omega[2] + dt * inv[2] * rt[2],
    )
    omega = gyroscopic_newton_step(vec3(bd, b, MOMENTS), omega, dt)
    return rotate(rot, omega)


def implicit_gyro_velocity(tag, e, st, d):
    """kick v; implicit gyroscopic step for ω."""
    (bd, prm, sd), fds = d
    dt = prm[0]
    for b in range(st[X].shape[1]):
        x, q, v, w, fa, ta = load(st, e, b)
        tb = load_body_torque(st, e, b)
        f, t = wrench(b, x, q, v, w, fa, ta, tb, fds)
        v = kick(v, dt, bd[b, INV_MASS], f)
        store_velocity(st, e, b, v, gyro_velocity(bd, b, q, w, t, dt))


def implicit_gyro_position(tag, e, st, d):
    """translate; q ← normalise(exp(Δt ω) ∘ q)."""
    (bd, prm, sd), fds = d
    dt = prm[0]
    for b in range(st[X].shape[1]):
        x, q, v, w, fa, ta = load(st, e, b)
        x = translate(st, e, b, x, v, dt)
        q = quat_normalize(quat_multiply(quat_exp((dt * w[0], dt * w[1], dt * w[2])), q))
        store(st, e, b, x, q, v, w)


# --- implicit ---------------------------------------------------------------------------------


@njit(cache=True, error_model="numpy")
def spring_matrices(sd, b, x, q, jkj, jcj):
    """Add Σ Jᵀ K J and Σ Jᵀ C J of the springs on body b into (6, 6) ``jkj``, ``jcj``."""
    jac = np.zeros((3, 6))
    stiff = np.zeros((3, 3))
    damp = np.zeros((3, 3))
    for s in range(sd.shape[0]):
        if int(sd[s, S_BODY]) != b:
            continue
        attach = (sd[s, S_ATTACH], sd[s, S_ATTACH + 1], sd[s, S_ATTACH + 2])
        k, c, rest = sd[s, S_K], sd[s, S_C], sd[s, S_REST]
        arm = quat_rotate(q, attach)
        dd = (
            x[0] + arm[0] - sd[s, S_ANCHOR],
            x[1] + arm[1] - sd[s, S_ANCHOR + 1],
            x[2] + arm[2] - sd[s, S_ANCHOR + 2],
        )
        length = math.sqrt(dd[0] ** 2 + dd[1] ** 2 + dd[2] ** 2)
        safe = length if length > 0 else 1.0
        unit = (dd[0] / safe, dd[1] / safe, dd[2] / safe)
        ratio = rest / safe if length > 0 else 0.0
        transverse = max(1.0 - ratio, 0.0)
        for i in range(3):
            for j in range(3):
                along = unit[i] * unit[j]
                eye = 1.0 if i == j else 0.0
                if rest > 0:
                    stiff[i, j] = k * (along + transverse * (eye - along))
                    damp[i, j] = c * along
                else:
                    stiff[i, j] = k * eye
                    damp[i, j] = c * eye
        # J = [I, −(R r)*]
        jac[:] = 0.0
        for i in range(3):
            jac[i, i] = 1.0
        jac[0, 4], jac[0, 5] = arm[2], -arm[1]
        jac[1, 3], jac[1, 5] = -arm[2], arm[0]
        jac[2, 3], jac[2, 4] = arm[1], -arm[0]
        for i in range(6):
            for j in range(6):
                sk = 0.0
                sc = 0.0
                for a in range(3):
                    for bb in range(3):
                        sk += jac[a, i] * stiff[a, bb] * jac[bb, j]
                        sc += jac[a, i] * damp[a, bb] * jac[bb, j]
                jkj[i, j] += sk
                jcj[i, j] += sc


@njit(cache=True, error_model="numpy")
def solve6(a, r):
    """Solve a x = r in place (Gaussian elimination with partial pivoting); returns x = r."""
    n = 6
    for col in range(n):
        piv = col
        big = abs(a[col, col])
        for i in range(col + 1, n):
            if abs(a[i, col]) > big:
                big, piv = abs(a[i, col]), i
        if piv != col:
            for j in range(n):
                a[col, j], a[piv, j] = a[piv, j], a[col, j]
            r[col], r[piv] = r[piv], r[col]
        for i in range(col + 1, n):
            factor = a[i, col] / a[col, col]
            for j in range(col, n):
                a[i, j] -= factor * a[col, j]
            r[i] -= factor * r[col]
    for i in range(n - 1, -1, -1):
        acc = r[i]
        for j in range(i + 1, n):
            acc -= a[i, j] * r[j]
        r[i] = acc / a[i, i]
    return r


def implicit_velocity(tag, e, st, d):
    """linearised backward Euler, one 6×6 solve per body."""
    (bd, prm, sd), fds = d
    dt = prm[0]
    system = np.empty((6, 6))
    jkj = np.empty((6, 6))
    jcj = np.empty((6, 6))
    u = np.empty(6)
    rhs = np.empty(6)
    for b in range(st[X].shape[1]):
        x, q, v, w, fa, ta = load(st, e, b)
        tb = load_body_torque(st, e, b)
        f, t = wrench(b, x, q, v, w, fa, ta, tb, fds)
        rot = quat_to_matrix(q)
        inertia = matmul(matmul(rot, bodies.matrix(bd, b, bodies.INERTIA)), transpose(rot))
        momentum = rotate(inertia, w)
        cw = cross(w, momentum)
        ang = (-cw[0] + t[0], -cw[1] + t[1], -cw[2] + t[2])
        system[:] = 0.0
        mass = bd[b, bodies.MASS]
        for i in range(3):
            system[i, i] = mass
            u[i], u[3 + i] = v[i], w[i]
            rhs[i], rhs[3 + i] = dt * f[i], dt * ang[i]
        sw = skew(w)
        sm = skew(momentum)
        swi = matmul(sw, inertia)
        for i in range(3):
            for j in range(3):
                system[3 + i, 3 + j] = inertia[3 * i + j] + dt * (swi[3 * i + j] - sm[3 * i + j])
        if sd.shape[0] > 0:
            jkj[:] = 0.0
            jcj[:] = 0.0
            spring_matrices(sd, b, x, q, jkj, jcj)
            for i in range(6):
                acc = 0.0
                for j in range(6):
                    system[i, j] = system[i, j] + dt * jcj[i, j] + dt * dt * jkj[i, j]
                    acc += jkj[i, j] * u[j]
                rhs[i] = rhs[i] - dt * dt * acc
        du = solve6(system, rhs)
        v = (v[0] + du[0], v[1] + du[1], v[2] + du[2])
        w = (w[0] + du[3], w[1] + du[4], w[2] + du[5])
        store_velocity(st, e, b, v, w)


def implicit_position(tag, e, st, d):
    """translate; q ← exp(Δt ω) ∘ q (not renormalised)."""
    (bd, prm, sd), fds = d
    dt = prm[0]
    for b in range(st[X].shape[1]):
        x, q, v, w, fa, ta = load(st, e, b)
        x = translate(st, e, b, x, v, dt)
        q = quat_multiply(quat_exp((dt * w[0], dt * w[1], dt * w[2])), q)
        store(st, e, b, x, q, v, w)


def integrator_data(scene) -> tuple:
    """The data every integrator kernel gets: (body data, [dt, velocity_dependent], springs)."""
    model = scene.model
    velocity_dependent = any(term.velocity_dependent for term in scene.forces)
    params = np.array([scene.dt, float(velocity_dependent)])
    return (bodies.body_data(model), params, spring_table(model))


register_integrator("euler", globals(), velocity=euler_velocity, position=euler_position)
# The two Euler variants share the velocity update (``integrators.euler``).
register_integrator("euler_quat", globals(), velocity=euler_velocity, position=euler_quat_position)
register_integrator("rk4", globals(), one=rk4)
register_integrator("splitting", globals(), one=splitting)
register_integrator("splitting_damped", globals(), one=splitting_damped)
register_integrator("splitting4", globals(), one=splitting4)
register_integrator("splitting4_damped", globals(), one=splitting4_damped)
register_integrator(
    "implicit_gyro", globals(), velocity=implicit_gyro_velocity, position=implicit_gyro_position
)
register_integrator("implicit", globals(), velocity=implicit_velocity, position=implicit_position)


def _integrator_stage(part: str):
    def factory(scene):
        # A splitting integrator comes in a ``_damped`` variant for velocity-dependent forces,
        # so the plain one calls nothing that can raise (``free_rotation``).
        variant = scene.integrator
        if variant + "_damped" in INTEGRATORS and any(t.velocity_dependent for t in scene.forces):
            variant += "_damped"
        record = INTEGRATORS.get(variant)
        kernel = None if record is None else getattr(record, part)
        if kernel is None:
            return None
        fn = getattr(kernel, "py_func", kernel)
        return Kernel(fn.__module__, fn.__name__, integrator_data(scene), tag=record.tag)

    return factory


register("integrate")(_integrator_stage("one"))
register("integrate_velocity")(_integrator_stage("velocity"))
register("integrate_position")(_integrator_stage("position"))

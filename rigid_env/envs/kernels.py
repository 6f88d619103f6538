"""Compiled per-step work of the hold tasks: one numba call where numpy needs dozens.

With one env the per-step arrays hold a single element, so numpy's cost is its dispatch per
operation, not arithmetic, and measuring, rewarding and observing take dozens of operations per
step. Each kernel here loops over the batch and does an element's work in scalar code, so a
call costs about the same for one env as a single numpy operation does, and an element's result
does not depend on the batch size or its position in it: a vector env stays bit-identical to
single envs.

Quaternions are (x, y, z, w), scalar last, mapping body to world as in the simulator. R(q) is
the standard rotation matrix of a unit quaternion (Shoemake, "Animating rotation with
quaternion curves", SIGGRAPH 1985).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

Arr = np.ndarray


@njit(cache=True)
def finite_clip(a: Arr) -> bool:
    """Clip the 1-D float64 ``a`` to [-1, 1] in place; False (``a`` partly clipped) if an
    entry is NaN or infinite. Same values as ``np.clip``: min(max(x, -1), 1)."""
    for i in range(a.shape[0]):
        if not math.isfinite(a[i]):
            return False
        a[i] = min(max(a[i], -1.0), 1.0)
    return True


@njit(cache=True, inline="always")
def rotation(q: Arr, r: Arr) -> None:
    """R(q) of the unit quaternion ``q`` (4,) into ``r`` (3, 3)."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    r[0, 0] = 1.0 - 2.0 * (y * y + z * z)
    r[0, 1] = 2.0 * (x * y - z * w)
    r[0, 2] = 2.0 * (x * z + y * w)
    r[1, 0] = 2.0 * (x * y + z * w)
    r[1, 1] = 1.0 - 2.0 * (x * x + z * z)
    r[1, 2] = 2.0 * (y * z - x * w)
    r[2, 0] = 2.0 * (x * z - y * w)
    r[2, 1] = 2.0 * (y * z + x * w)
    r[2, 2] = 1.0 - 2.0 * (x * x + y * y)


@njit(cache=True)
def _rotations(q: Arr, out: Arr) -> None:
    for e in range(q.shape[0]):
        rotation(q[e], out[e])


def rotation_matrices(q: Arr) -> Arr:
    """R(q) (body → world) for unit quaternions ``(N, 4)`` → ``(N, 3, 3)`` (e.g. for drawing)."""
    q = np.ascontiguousarray(q, dtype=np.float64)
    out = np.empty((q.shape[0], 3, 3))
    _rotations(q, out)
    return out


@njit(cache=True)
def world_torque(q: Arr, torque: Arr, out: Arr) -> None:
    """``out[e, 0] = R(q[e, 0]) torque[e]``: the body-fixed torque in world axes for a one-body
    scene; ``q`` (N, 1, 4), ``torque`` (N, 3), ``out`` (N, 1, 3)."""
    r = np.empty((3, 3))
    for e in range(q.shape[0]):
        rotation(q[e, 0], r)
        for i in range(3):
            out[e, 0, i] = r[i, 0] * torque[e, 0] + r[i, 1] * torque[e, 1] + r[i, 2] * torque[e, 2]


@njit(cache=True)
def count_touchdowns(
    clearance: Arr, tolerance: float, touched: Arr, touching: Arr, touchdowns: Arr,
    bounce_coef: float, terms: Arr,
) -> None:  # fmt: skip
    """Touchdowns of one action period, per env. The box touched the ground during the period
    if a contact carried an impulse in it (``touched``, the contact report's) or its lowest
    corner ends it within ``tolerance`` (``clearance``, as ``landing_measure`` wrote it). A
    touchdown is touching now after not touching in the previous period (``touching``, updated
    in place); ``touchdowns`` counts them in place, and one that is not the first (a bounce)
    writes ``-bounce_coef`` into ``terms[:, 1]`` (else ``-bounce_coef · 0``)."""
    for e in range(clearance.shape[0]):
        now = touched[e] or clearance[e] < tolerance
        touchdown = now and not touching[e]
        terms[e, 1] = -bounce_coef * (1.0 if touchdown and touchdowns[e] > 0 else 0.0)
        touchdowns[e] += touchdown
        touching[e] = now


@njit(cache=True)
def hold_step(
    within: Arr, hold: Arr, spin: Arr, action: Arr, params: Arr, task_terms: Arr, terms: Arr,
    reward: Arr, success: Arr,
) -> None:  # fmt: skip
    """The shared end of a step, per env, with ``params`` = [hold_steps, spin_coef, ctrl_coef,
    bonus]: the hold timer (``hold`` updated in place), success, the reward terms into
    ``terms`` (N, T + 3): the task's own ``task_terms`` (N, T), then spin
    (``-spin_coef |Ω|``), control (``-ctrl_coef |a|²``), success bonus; and their sum, in
    column order, into ``reward``."""
    hold_steps, spin_coef, ctrl_coef, bonus = params[0], params[1], params[2], params[3]
    t = task_terms.shape[1]
    for e in range(within.shape[0]):
        for k in range(t):
            terms[e, k] = task_terms[e, k]
        hold[e] = hold[e] + 1 if within[e] else 0
        done = hold[e] >= hold_steps
        success[e] = done
        a = action[e]
        terms[e, t] = -spin_coef * spin[e]
        terms[e, t + 1] = -ctrl_coef * (a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
        terms[e, t + 2] = bonus if done else 0.0
        total = 0.0
        for k in range(terms.shape[1]):
            total = total + terms[e, k]
        reward[e] = total


@njit(cache=True)
def reorient_measure(
    index: Arr, q: Arr, w: Arr, target: Arr, inertia: Arr, params: Arr, prev_action: Arr,
    obs: Arr, rot: Arr, meas: Arr, within: Arr, terms: Arr,
) -> None:  # fmt: skip
    """Everything Reorient reads off a state, for the envs ``index`` (rows of the outputs
    not in it are left as they are). In: ``q`` (N, 1, 4), ``w`` (N, 1, 3)
    world angular velocity, ``target`` (N, 4), ``inertia`` (N, 3, 3) body axes, ``params`` =
    [spin_scale, observation limit, angle_threshold, spin_threshold, angle_coef],
    ``prev_action`` (N, 3). Out: ``obs`` (N, 10) float32 [q_err (w >= 0), clip(Ω / spin_scale,
    ±limit), prev_action]; ``rot`` R(q); ``meas`` (N, 9) [Ω = Rᵀ ω (3), θ = 2 atan2(|q_err,v|,
    q_err,w), |Ω|, energy ½ Ωᵀ I Ω, world angular momentum R I Ω (3)]; ``within`` the goal;
    ``terms[:, 0]`` ``-angle_coef θ``.

    q_err = q_target⁻¹ ∘ q (Hamilton product), with q⁻¹ = (−v, w) for a unit quaternion."""
    spin_scale, limit, angle_threshold, spin_threshold, angle_coef = (
        params[0], params[1], params[2], params[3], params[4]
    )  # fmt: skip
    for e in index:
        r = rot[e]
        qe = q[e, 0]
        rotation(qe, r)
        # a ∘ b = (a_w b_v + b_w a_v + a_v × b_v, a_w b_w − a_v · b_v), a = conj(target).
        ax, ay, az, aw = -target[e, 0], -target[e, 1], -target[e, 2], target[e, 3]
        bx, by, bz, bw = qe[0], qe[1], qe[2], qe[3]
        ex = aw * bx + bw * ax + (ay * bz - az * by)
        ey = aw * by + bw * ay + (az * bx - ax * bz)
        ez = aw * bz + bw * az + (ax * by - ay * bx)
        ew = aw * bw - (ax * bx + ay * by + az * bz)
        sign = math.copysign(1.0, ew)  # w >= 0: continuous near the goal
        ex, ey, ez, ew = ex * sign, ey * sign, ez * sign, ew * sign
        obs[e, 0], obs[e, 1], obs[e, 2], obs[e, 3] = ex, ey, ez, ew
        we = w[e, 0]
        m = meas[e]
        for i in range(3):
            m[i] = r[0, i] * we[0] + r[1, i] * we[1] + r[2, i] * we[2]
        ox, oy, oz = m[0], m[1], m[2]
        angle = 2.0 * math.atan2(math.sqrt(ex * ex + ey * ey + ez * ez), ew)
        spin = math.sqrt(ox * ox + oy * oy + oz * oz)
        m[3], m[4] = angle, spin
        for i in range(3):
            obs[e, 4 + i] = min(max(m[i] / spin_scale, -limit), limit)
            obs[e, 7 + i] = prev_action[e, i]
        within[e] = angle < angle_threshold and spin < spin_threshold
        terms[e, 0] = -angle_coef * angle
        ie = inertia[e]
        mx = ie[0, 0] * ox + ie[0, 1] * oy + ie[0, 2] * oz  # I Ω, body axes
        my = ie[1, 0] * ox + ie[1, 1] * oy + ie[1, 2] * oz
        mz = ie[2, 0] * ox + ie[2, 1] * oy + ie[2, 2] * oz
        m[5] = 0.5 * (ox * mx + oy * my + oz * mz)
        for i in range(3):
            m[6 + i] = r[i, 0] * mx + r[i, 1] * my + r[i, 2] * mz


@njit(cache=True)
def landing_measure(
    index: Arr, x: Arr, q: Arr, v: Arr, w: Arr, face_normal: Arr, corners: Arr, mass: Arr,
    inertia: Arr, params: Arr, prev_action: Arr, obs: Arr, rot: Arr, meas: Arr, ints: Arr,
    within: Arr, terms: Arr,
) -> None:  # fmt: skip
    """Everything BoxLanding reads off a state, for the envs ``index`` (rows of the outputs
    not in it are left as they are). In: the state's (N, 1, ·) arrays,
    ``face_normal`` (N, 3) the target face's outward normal (body axes), ``corners`` (8, 3),
    ``mass`` (N,), ``inertia`` (N, 3, 3), ``params`` = [gravity, spin_scale, velocity_scale,
    height_limit, observation limit, contact_tolerance, face_threshold, speed_threshold,
    spin_threshold, face_coef], ``prev_action`` (N, 3). Out: ``obs`` (N, 25) float32 in the order of the task's
    observation parts; ``rot`` R(q); ``meas`` (N, 9) [Ω = Rᵀ ω (3), θ between the face normal
    and world −z (by atan2: arccos loses digits near 0), |Ω|, speed, height, clearance (the
    lowest corner's height), energy]; ``ints`` (N, 2) [corners in contact, the face nearest
    down (index into FACES)]; ``within`` the goal; ``terms[:, 0]`` the face term (the bounce
    term, ``terms[:, 1]``, is ``count_touchdowns``'s, from the clearance written here).

    A corner's gap is z + (R c)_z, with world +z in body axes (Rᵀ e_z) being R's last row."""
    gravity, spin_scale, velocity_scale, height_limit, limit = (
        params[0], params[1], params[2], params[3], params[4]
    )  # fmt: skip
    tolerance, face_threshold, speed_threshold, spin_threshold, face_coef = (
        params[5], params[6], params[7], params[8], params[9]
    )  # fmt: skip
    for e in index:
        r = rot[e]
        m = meas[e]
        rotation(q[e, 0], r)
        ux, uy, uz = r[2, 0], r[2, 1], r[2, 2]  # world up in body axes
        dx, dy, dz = -ux, -uy, -uz
        nx, ny, nz = face_normal[e, 0], face_normal[e, 1], face_normal[e, 2]
        cx, cy, cz = ny * dz - nz * dy, nz * dx - nx * dz, nx * dy - ny * dx
        angle = math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), nx * dx + ny * dy + nz * dz)
        we = w[e, 0]
        for i in range(3):
            m[i] = r[0, i] * we[0] + r[1, i] * we[1] + r[2, i] * we[2]
        ox, oy, oz = m[0], m[1], m[2]
        spin = math.sqrt(ox * ox + oy * oy + oz * oz)
        ve = v[e, 0]
        speed = math.sqrt(ve[0] * ve[0] + ve[1] * ve[1] + ve[2] * ve[2])
        z = x[e, 0, 2]
        clearance = math.inf
        count = 0
        for c in range(corners.shape[0]):
            gap = z + ux * corners[c, 0] + uy * corners[c, 1] + uz * corners[c, 2]
            clearance = min(clearance, gap)
            touch = gap < tolerance
            count += touch
            obs[e, 14 + c] = 1.0 if touch else 0.0
        # The face nearest down: the largest |down| component (first on ties, as argmax).
        axis, best = 0, abs(dx)
        if abs(dy) > best:
            axis, best = 1, abs(dy)
        if abs(dz) > best:
            axis = 2
        d = dx if axis == 0 else (dy if axis == 1 else dz)
        ints[e, 0] = count
        ints[e, 1] = 2 * axis + (0 if d > 0 else 1)
        obs[e, 0] = min(max(z, 0.0), height_limit)
        obs[e, 1] = min(max(clearance, 0.0), height_limit)
        for i in range(3):
            obs[e, 2 + i] = min(max(ve[i] / velocity_scale, -limit), limit)
            obs[e, 8 + i] = min(max(m[i] / spin_scale, -limit), limit)
            obs[e, 11 + i] = face_normal[e, i]
            obs[e, 22 + i] = prev_action[e, i]
        obs[e, 5], obs[e, 6], obs[e, 7] = ux, uy, uz
        within[e] = (
            count > 0
            and angle < face_threshold
            and speed < speed_threshold
            and spin < spin_threshold
        )
        terms[e, 0] = -face_coef * angle
        ie, me = inertia[e], mass[e]
        mx = ie[0, 0] * ox + ie[0, 1] * oy + ie[0, 2] * oz  # I Ω, body axes
        my = ie[1, 0] * ox + ie[1, 1] * oy + ie[1, 2] * oz
        mz = ie[2, 0] * ox + ie[2, 1] * oy + ie[2, 2] * oz
        kinetic = me * (ve[0] * ve[0] + ve[1] * ve[1] + ve[2] * ve[2]) + (
            ox * mx + oy * my + oz * mz
        )
        m[3], m[4], m[5], m[6], m[7] = angle, spin, speed, z, clearance
        m[8] = 0.5 * kinetic + me * gravity * z

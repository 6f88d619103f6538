"""Body–body detection kernels: sphere–sphere, sphere–box, box–box, one pair at a time.

The one implementation of body–body detection. ``contacts.pairs`` and ``contacts.box_box`` hand
the batch to these loops (each pair of each batch element alone), so the numpy step and any
compiled one detect alike. The algorithms, their sources and their tie-breaking are described in
``contacts.box_box`` and ``contacts.pairs``; the comments here say only what the loop form
changes. Ties go to the lower index everywhere (as ``np.argmax``), and the clipped polygon keeps
its entries in Sutherland–Hodgman order, then the unused ones in order, so the padding of a
polygon that clipped away entirely is defined too (its slots carry the gap ``FAR``).

Rows: ``xa, xb`` (M, 3) and ``qa, qb`` (M, 4) hold pair m of a flattened batch; its shape
parameters are row ``m % P`` of the (P, ·) tables. Outputs are written in place.
"""

from __future__ import annotations

import math

import numpy as np

from ..contacts.box_box import EDGE_FUDGE, FAR, MAX_POLYGON, NEAR_PARALLEL, SLOTS
from .cache import njit
from .rotation import quat_to_matrix

TINY = 1e-12  # below this distance a direction is taken as undefined (``contacts.pairs``)
SIGNS = ((1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0))  # a quad's corners, cyclic


def pair_rows(xa, qa, xb, qb):
    """The pairs' poses (…, P, 3|4) as C-ordered float64 rows (M, 3|4), M = every batch
    element's P pairs in turn (so pair m's shape parameters are row m % P), and (…, P)."""
    shape = np.broadcast_shapes(xa.shape[:-1], qa.shape[:-1], xb.shape[:-1], qb.shape[:-1])
    rows = tuple(
        np.ascontiguousarray(
            np.broadcast_to(a, (*shape, a.shape[-1])).reshape(-1, a.shape[-1]), dtype=np.float64
        )
        for a in (xa, qa, xb, qb)
    )
    return rows, shape


@njit(cache=True, error_model="numpy", inline="always")
def _sign(v):
    """``np.sign``: −1, 0 or 1."""
    return 1.0 if v > 0 else (-1.0 if v < 0 else 0.0)


@njit(cache=True, error_model="numpy")
def sphere_sphere(xa, xb, ra, rb, arm_a, arm_b, normal, gap):
    """Normal along the centres (+z when they coincide), from b to a; gap = distance − radii."""
    pairs = ra.shape[0]
    for m in range(xa.shape[0]):
        p = m % pairs
        d0, d1, d2 = xa[m, 0] - xb[m, 0], xa[m, 1] - xb[m, 1], xa[m, 2] - xb[m, 2]
        dist = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        n = (d0 / dist, d1 / dist, d2 / dist) if dist > TINY else (0.0, 0.0, 1.0)
        for i in range(3):
            arm_a[m, i] = -ra[p] * n[i]
            arm_b[m, i] = rb[p] * n[i]
            normal[m, i] = n[i]
        gap[m] = dist - ra[p] - rb[p]


@njit(cache=True, error_model="numpy")
def sphere_box(xa, xb, qb, radius, half, arm_a, arm_b, normal, gap):
    """Sphere a against box b: the box's closest point to the centre (Ericson 5.1.3); a centre
    inside the box leaves through the face of least penetration."""
    pairs = radius.shape[0]
    for m in range(xa.shape[0]):
        p = m % pairs
        rot = quat_to_matrix((qb[m, 0], qb[m, 1], qb[m, 2], qb[m, 3]))
        d = (xa[m, 0] - xb[m, 0], xa[m, 1] - xb[m, 1], xa[m, 2] - xb[m, 2])
        c = np.empty(3)  # the centre in box axes
        closest = np.empty(3)
        for i in range(3):
            c[i] = rot[i] * d[0] + rot[3 + i] * d[1] + rot[6 + i] * d[2]
            closest[i] = min(max(c[i], -half[p, i]), half[p, i])
        e = (c[0] - closest[0], c[1] - closest[1], c[2] - closest[2])
        dist = math.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2])
        local = np.empty(3)
        if dist > TINY:
            for i in range(3):
                local[i] = e[i] / dist
            g = dist
        else:  # inside: push out through the face of least penetration
            axis, depth = 0, half[p, 0] - abs(c[0])
            for i in range(1, 3):
                if half[p, i] - abs(c[i]) < depth:
                    axis, depth = i, half[p, i] - abs(c[i])
            for i in range(3):
                local[i] = 0.0
            local[axis] = 1.0 if c[axis] >= 0 else -1.0
            closest[axis] = local[axis] * half[p, axis]
            for i in range(3):
                if i != axis:
                    closest[i] = c[i]
            g = -depth
        for i in range(3):
            n_i = rot[3 * i] * local[0] + rot[3 * i + 1] * local[1] + rot[3 * i + 2] * local[2]
            normal[m, i] = n_i
            arm_a[m, i] = -radius[p] * n_i
            arm_b[m, i] = (
                rot[3 * i] * closest[0] + rot[3 * i + 1] * closest[1] + rot[3 * i + 2] * closest[2]
            )
        gap[m] = g - radius[p]


@njit(cache=True, error_model="numpy", inline="always")
def _dot_rows(a, i, b, j):
    return a[i, 0] * b[j, 0] + a[i, 1] * b[j, 1] + a[i, 2] * b[j, 2]


@njit(cache=True, error_model="numpy")
def _clip(poly, count, coord, sign, bound, out, valid):
    """Clip the polygon's first ``count`` vertices to ``sign * p[coord] <= bound``
    (Sutherland–Hodgman, one plane; strict crossings, so a vertex on the plane is kept once).
    Returns the new count; ``poly`` holds the result, then the unused candidates in order."""
    size = poly.shape[0]
    for k in range(size):
        nxt = k + 1 if k + 1 < count else 0
        d = sign * poly[k, coord] - bound
        d_next = sign * poly[nxt, coord] - bound
        edge = k < count
        crossing = edge and ((d < 0 and d_next > 0) or (d > 0 and d_next < 0))
        t = d / (d - d_next) if crossing else 0.0
        for i in range(3):
            out[2 * k, i] = poly[k, i] + t * (poly[nxt, i] - poly[k, i])
            out[2 * k + 1, i] = poly[nxt, i]
        valid[2 * k] = crossing
        valid[2 * k + 1] = edge and d_next <= 0
    at = 0
    for first in (True, False):  # the valid entries, then the others, each in order
        for k in range(2 * size):
            if valid[k] == first and at < size:
                for i in range(3):
                    poly[at, i] = out[k, i]
                at += 1
    kept = 0
    for k in range(2 * size):
        if valid[k]:
            kept += 1
    return min(kept, size)


@njit(cache=True, error_model="numpy", inline="always")
def _axes_last(axes, half, last):
    """A box's axes (rows) and half extents in the order (k+1, k+2, k), k = ``last``: a
    right-handed permutation with that axis last."""
    rows = np.empty((3, 3))
    h = np.empty(3)
    for k in range(3):
        a = (last + 1 + k) % 3
        h[k] = half[a]
        for i in range(3):
            rows[k, i] = axes[a, i]
    return rows, h


@njit(cache=True, error_model="numpy")
def _face(m, ref_b, face, n, xa, xb, axes_a, axes_b, ha, hb, arm_a, arm_b, gap):
    """The clipped face manifold (``contacts.box_box``): reference face of box b when
    ``ref_b``, else of box a, ``face`` its axis; the incident face the other box's most
    anti-parallel one. Writes the four slots of row m."""
    x_r, x_i = (xb, xa) if ref_b else (xa, xb)
    axes_r, axes_i = (axes_b, axes_a) if ref_b else (axes_a, axes_b)
    h_r, h_i = (hb, ha) if ref_b else (ha, hb)
    s = 1.0 if ref_b else -1.0
    out = (s * n[0], s * n[1], s * n[2])  # the reference face's outward normal
    # Reference frame with the face axis last: (k+1, k+2, k), a right-handed permutation.
    ref, h_ref = _axes_last(axes_r, h_r, face)
    j, best = 0, -1.0
    dots = np.empty(3)
    for k in range(3):
        dots[k] = axes_i[k, 0] * out[0] + axes_i[k, 1] * out[1] + axes_i[k, 2] * out[2]
        if abs(dots[k]) > best:
            j, best = k, abs(dots[k])
    u, h_u = _axes_last(axes_i, h_i, j)
    s_j = -_sign(dots[j])
    poly = np.empty((MAX_POLYGON, 3))
    for c in range(4):
        corner = np.empty(3)
        for i in range(3):
            centre = x_i[m, i] + s_j * h_u[2] * u[2, i]
            corner[i] = (
                centre
                + (SIGNS[c][0] * h_u[0] * u[0, i] + SIGNS[c][1] * h_u[1] * u[1, i])
                - x_r[m, i]
            )
        for k in range(3):
            poly[c, k] = corner[0] * ref[k, 0] + corner[1] * ref[k, 1] + corner[2] * ref[k, 2]
    for c in range(4, MAX_POLYGON):
        for k in range(3):
            poly[c, k] = poly[0, k]
    scratch = np.empty((2 * MAX_POLYGON, 3))
    valid = np.empty(2 * MAX_POLYGON, dtype=np.bool_)
    count = 4
    for coord in range(2):
        for sign in (1.0, -1.0):
            count = _clip(poly, count, coord, sign, h_ref[coord], scratch, valid)
    # Height above the reference face, on its outward side.
    s_r = _sign(out[0] * ref[2, 0] + out[1] * ref[2, 1] + out[2] * ref[2, 2])
    heights = np.empty(MAX_POLYGON)
    for k in range(MAX_POLYGON):
        heights[k] = s_r * poly[k, 2] - h_ref[2]
    # Reduce to 4 (Gregorius): the deepest, the farthest from it, the two largest triangles.
    i0, top = 0, -math.inf
    for k in range(count):
        if -heights[k] > top:
            i0, top = k, -heights[k]
    i1, top = 0, -math.inf
    for k in range(count):
        r0, r1 = poly[k, 0] - poly[i0, 0], poly[k, 1] - poly[i0, 1]
        if r0 * r0 + r1 * r1 > top:
            i1, top = k, r0 * r0 + r1 * r1
    e0, e1 = poly[i1, 0] - poly[i0, 0], poly[i1, 1] - poly[i0, 1]
    i2, top, i3, low = 0, -math.inf, 0, math.inf
    for k in range(count):
        area = e0 * (poly[k, 1] - poly[i0, 1]) - e1 * (poly[k, 0] - poly[i0, 0])
        if area > top:
            i2, top = k, area
        if area < low:
            i3, low = k, area
    for slot, k in enumerate((i0, i1, i2, i3)):
        g = heights[k]
        for i in range(3):
            p_inc = x_r[m, i] + (
                poly[k, 0] * ref[0, i] + poly[k, 1] * ref[1, i] + poly[k, 2] * ref[2, i]
            )
            p_ref = p_inc - g * out[i]
            p_a, p_b = (p_inc, p_ref) if ref_b else (p_ref, p_inc)
            arm_a[m, slot, i] = p_a - xa[m, i]
            arm_b[m, slot, i] = p_b - xb[m, i]
        gap[m, slot] = g if count > 0 else FAR


@njit(cache=True, error_model="numpy")
def _edge(m, edge, n, xa, xb, axes_a, axes_b, ha, hb, arm_a, arm_b, gap):
    """Closest points of a's edge along axis ``edge // 3`` and b's along ``edge % 3``, each the
    edge of its box furthest towards the other (Ericson 5.1.8, clamped), in all four slots."""
    i, j = edge // 3, edge % 3
    c_a = np.zeros(3)  # first the sums over the box's axes, then the centre added
    c_b = np.zeros(3)
    for a in range(3):
        s_a = -_sign(axes_a[a, 0] * n[0] + axes_a[a, 1] * n[1] + axes_a[a, 2] * n[2])
        s_b = _sign(axes_b[a, 0] * n[0] + axes_b[a, 1] * n[1] + axes_b[a, 2] * n[2])
        s_a = (1.0 if s_a == 0 else s_a) * (a != i)
        s_b = (1.0 if s_b == 0 else s_b) * (a != j)
        for k in range(3):
            c_a[k] += s_a * ha[a] * axes_a[a, k]
            c_b[k] += s_b * hb[a] * axes_b[a, k]
    for k in range(3):
        c_a[k] = xa[m, k] + c_a[k]
        c_b[k] = xb[m, k] + c_b[k]
    r = (c_a[0] - c_b[0], c_a[1] - c_b[1], c_a[2] - c_b[2])
    b = _dot_rows(axes_a, i, axes_b, j)
    c = axes_a[i, 0] * r[0] + axes_a[i, 1] * r[1] + axes_a[i, 2] * r[2]
    f = axes_b[j, 0] * r[0] + axes_b[j, 1] * r[1] + axes_b[j, 2] * r[2]
    denom = max(1.0 - b * b, NEAR_PARALLEL**2)  # ≥ |u_a × u_b|² of a valid edge axis
    s = min(max((b * f - c) / denom, -ha[i]), ha[i])
    t = min(max(b * s + f, -hb[j]), hb[j])
    g = 0.0
    p_a = np.empty(3)
    p_b = np.empty(3)
    for k in range(3):
        p_a[k] = c_a[k] + s * axes_a[i, k]
        p_b[k] = c_b[k] + t * axes_b[j, k]
        g += (p_a[k] - p_b[k]) * n[k]
    for slot in range(SLOTS):
        for k in range(3):
            arm_a[m, slot, k] = p_a[k] - xa[m, k]
            arm_b[m, slot, k] = p_b[k] - xb[m, k]
        gap[m, slot] = g


@njit(cache=True, error_model="numpy")
def box_box(xa, qa, xb, qb, half_a, half_b, margin, arm_a, arm_b, normal, gap):
    """Separating axes over the 3 + 3 face normals and the 9 edge cross products (near-parallel
    pairs skipped), faces preferred by ``EDGE_FUDGE`` and ``margin``; then the face manifold or
    the edge point (``contacts.box_box``)."""
    pairs = half_a.shape[0]
    axes = np.empty((15, 3))
    sep = np.empty(15)
    along = np.empty(15)
    for m in range(xa.shape[0]):
        p = m % pairs
        ha, hb = half_a[p], half_b[p]
        ra = quat_to_matrix((qa[m, 0], qa[m, 1], qa[m, 2], qa[m, 3]))
        rb = quat_to_matrix((qb[m, 0], qb[m, 1], qb[m, 2], qb[m, 3]))
        for k in range(3):  # rows: body axes in the world (columns of R)
            for i in range(3):
                axes[k, i] = ra[3 * i + k]
                axes[3 + k, i] = rb[3 * i + k]
        axes_a, axes_b = axes[:3], axes[3:6]
        usable = np.empty(9, dtype=np.bool_)
        for k in range(3):
            for l in range(3):
                e = 6 + 3 * k + l
                a, b = axes[k], axes[3 + l]
                c = (
                    a[1] * b[2] - a[2] * b[1],
                    a[2] * b[0] - a[0] * b[2],
                    a[0] * b[1] - a[1] * b[0],
                )
                length = math.sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2])
                usable[3 * k + l] = length > NEAR_PARALLEL
                div = length if length > NEAR_PARALLEL else 1.0
                for i in range(3):
                    axes[e, i] = c[i] / div
        d = (xa[m, 0] - xb[m, 0], xa[m, 1] - xb[m, 1], xa[m, 2] - xb[m, 2])
        for k in range(15):
            along[k] = axes[k, 0] * d[0] + axes[k, 1] * d[1] + axes[k, 2] * d[2]
            reach = 0.0
            for a in range(3):
                reach += abs(_dot_rows(axes, k, axes, a)) * ha[a]
            reach_b = 0.0
            for a in range(3):
                reach_b += abs(_dot_rows(axes, k, axes, 3 + a)) * hb[a]
            sep[k] = abs(along[k]) - reach - reach_b
            if k >= 6 and not usable[k - 6]:
                sep[k] = -math.inf
        fa, fb, ea = 0, 3, 6
        for k in range(1, 3):
            if sep[k] > sep[fa]:
                fa = k
            if sep[3 + k] > sep[fb]:
                fb = 3 + k
        for k in range(7, 15):
            if sep[k] > sep[ea]:
                ea = k
        ref_b = sep[fb] > sep[fa] + margin[p]
        s_face = sep[fb] if ref_b else sep[fa]
        use_edge = sep[ea] > s_face + (EDGE_FUDGE - 1.0) * abs(s_face) + margin[p]
        best = ea if use_edge else (fb if ref_b else fa)
        side = _sign(along[best])
        side = 1.0 if side == 0 else side
        n = (side * axes[best, 0], side * axes[best, 1], side * axes[best, 2])  # from b to a
        for slot in range(SLOTS):
            for i in range(3):
                normal[m, slot, i] = n[i]
        if use_edge:
            _edge(m, ea - 6, n, xa, xb, axes_a, axes_b, ha, hb, arm_a, arm_b, gap)
        else:
            face = fb - 3 if ref_b else fa
            _face(m, ref_b, face, n, xa, xb, axes_a, axes_b, ha, hb, arm_a, arm_b, gap)

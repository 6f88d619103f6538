"""Body–body detection kernels: sphere–sphere, sphere–box, box–box, one pair at a time.

The one implementation of body–body detection: the step's kernels call them per element, and
``contacts.pairs`` and ``contacts.box_box`` hand a batch to these loops (each pair of each batch
element alone) for inspection and tests. The algorithms, their sources and their tie-breaking are described in
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
from .rotation import add, cross, dot, norm3, quat_to_matrix, rotate, rotate_inverse, scale, sub

TINY = 1e-12  # below this distance a direction is taken as undefined (``contacts.pairs``)
SIGNS = ((1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0))  # a quad's corners, cyclic


def run(kernel, poses, params, slots=None):
    """``kernel`` on the pairs' poses ``(xa, qa, xb, qb)`` (…, P, 3|4) with its (P, ·) shape
    tables ``params``: arms on a and on b, normal (…, P[, slots], 3) and gap (…, P[, slots]).
    The poses go in as C-ordered float64 rows (M, 3|4), every batch element's P pairs in turn,
    so pair m's shape parameters are row m % P."""
    shape = np.broadcast_shapes(*(a.shape[:-1] for a in poses))
    rows = tuple(
        np.ascontiguousarray(
            np.broadcast_to(a, (*shape, a.shape[-1])).reshape(-1, a.shape[-1]), dtype=np.float64
        )
        for a in poses
    )
    per_pair = () if slots is None else (slots,)
    arm_a, arm_b, normal = (np.empty((*shape, *per_pair, 3)) for _ in range(3))
    gap = np.empty((*shape, *per_pair))
    flat = tuple(a.reshape(-1, *per_pair, 3) for a in (arm_a, arm_b, normal))
    kernel(*rows, *params, *flat, gap.reshape(-1, *per_pair))
    return arm_a, arm_b, normal, gap


@njit(cache=True, error_model="numpy", inline="always")
def _sign(v):
    """``np.sign``: −1, 0 or 1."""
    return 1.0 if v > 0 else (-1.0 if v < 0 else 0.0)


@njit(cache=True, error_model="numpy")
def sphere_sphere(xa, qa, xb, qb, ra, rb, arm_a, arm_b, normal, gap):
    """Normal along the centres (+z when they coincide), from b to a; gap = distance − radii.
    (The orientations are not read: the kernels share one signature, ``run``.)"""
    pairs = ra.shape[0]
    for m in range(xa.shape[0]):
        p = m % pairs
        d = (xa[m, 0] - xb[m, 0], xa[m, 1] - xb[m, 1], xa[m, 2] - xb[m, 2])
        dist = norm3(d)
        n = (d[0] / dist, d[1] / dist, d[2] / dist) if dist > TINY else (0.0, 0.0, 1.0)
        for i in range(3):
            arm_a[m, i] = -ra[p] * n[i]
            arm_b[m, i] = rb[p] * n[i]
            normal[m, i] = n[i]
        gap[m] = dist - ra[p] - rb[p]


@njit(cache=True, error_model="numpy")
def sphere_box(xa, qa, xb, qb, radius, half, arm_a, arm_b, normal, gap):
    """Sphere a against box b: the box's closest point to the centre (Ericson 5.1.3); a centre
    inside the box leaves through the face of least penetration."""
    pairs = radius.shape[0]
    for m in range(xa.shape[0]):
        p = m % pairs
        h = (half[p, 0], half[p, 1], half[p, 2])
        rot = quat_to_matrix((qb[m, 0], qb[m, 1], qb[m, 2], qb[m, 3]))
        c = rotate_inverse(rot, (xa[m, 0] - xb[m, 0], xa[m, 1] - xb[m, 1], xa[m, 2] - xb[m, 2]))
        closest = (
            min(max(c[0], -h[0]), h[0]),
            min(max(c[1], -h[1]), h[1]),
            min(max(c[2], -h[2]), h[2]),
        )
        e = (c[0] - closest[0], c[1] - closest[1], c[2] - closest[2])
        dist = norm3(e)
        if dist > TINY:
            local = (e[0] / dist, e[1] / dist, e[2] / dist)
            g = dist
        else:  # inside: push out through the face of least penetration
            axis = 0
            for i in range(1, 3):
                if h[i] - abs(c[i]) < h[axis] - abs(c[axis]):
                    axis = i
            side = 1.0 if c[axis] >= 0 else -1.0
            local = (side * (axis == 0), side * (axis == 1), side * (axis == 2))
            closest = (
                side * h[0] if axis == 0 else c[0],
                side * h[1] if axis == 1 else c[1],
                side * h[2] if axis == 2 else c[2],
            )
            g = -(h[axis] - abs(c[axis]))
        n = rotate(rot, local)
        point = rotate(rot, closest)
        for i in range(3):
            normal[m, i] = n[i]
            arm_a[m, i] = -radius[p] * n[i]
            arm_b[m, i] = point[i]
        gap[m] = g - radius[p]


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
def _axes_last(axes, half, last, rows, h):
    """Into ``rows``, ``h``: a box's axes (rows) and half extents in the order (k+1, k+2, k),
    k = ``last``, a right-handed permutation with that axis last."""
    for k in range(3):
        a = (last + 1 + k) % 3
        h[k] = half[a]
        for i in range(3):
            rows[k, i] = axes[a, i]


@njit(cache=True, error_model="numpy")
def _face(m, ref_b, face, n, xa, xb, axes_a, axes_b, ha, hb, arm_a, arm_b, gap, work):
    """The clipped face manifold (``contacts.box_box``): reference face of box b when
    ``ref_b``, else of box a, ``face`` its axis; the incident face the other box's most
    anti-parallel one. Writes the four slots of row m; ``work``: ``box_box``'s scratch."""
    ref, h_ref, u, h_u, poly, scratch, valid, heights = work
    x_r, x_i = (xb, xa) if ref_b else (xa, xb)
    axes_r, axes_i = (axes_b, axes_a) if ref_b else (axes_a, axes_b)
    h_r, h_i = (hb, ha) if ref_b else (ha, hb)
    s = 1.0 if ref_b else -1.0
    out = (s * n[0], s * n[1], s * n[2])  # the reference face's outward normal
    # Reference frame with the face axis last: (k+1, k+2, k), a right-handed permutation.
    _axes_last(axes_r, h_r, face, ref, h_ref)
    j, best, d_j = 0, -1.0, 0.0
    for k in range(3):
        d_k = dot(axes_i[k], out)
        if abs(d_k) > best:
            j, best, d_j = k, abs(d_k), d_k
    _axes_last(axes_i, h_i, j, u, h_u)
    s_j = -_sign(d_j)
    x_ref = (x_r[m, 0], x_r[m, 1], x_r[m, 2])
    centre = add((x_i[m, 0], x_i[m, 1], x_i[m, 2]), scale(s_j * h_u[2], u[2]))
    for c in range(4):
        side = add(scale(SIGNS[c][0] * h_u[0], u[0]), scale(SIGNS[c][1] * h_u[1], u[1]))
        corner = sub(add(centre, side), x_ref)
        for k in range(3):
            poly[c, k] = dot(corner, ref[k])
    for c in range(4, MAX_POLYGON):
        for k in range(3):
            poly[c, k] = poly[0, k]
    count = 4
    for coord in range(2):
        for sign in (1.0, -1.0):
            count = _clip(poly, count, coord, sign, h_ref[coord], scratch, valid)
    # Height above the reference face, on its outward side.
    s_r = _sign(dot(out, ref[2]))
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
    # each box's edge centre: the sum over its axes first, then its centre added
    sum_a, sum_b = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    for a in range(3):
        s_a = -_sign(dot(axes_a[a], n))
        s_b = _sign(dot(axes_b[a], n))
        s_a = (1.0 if s_a == 0 else s_a) * (a != i)
        s_b = (1.0 if s_b == 0 else s_b) * (a != j)
        sum_a = add(sum_a, scale(s_a * ha[a], axes_a[a]))
        sum_b = add(sum_b, scale(s_b * hb[a], axes_b[a]))
    c_a = add((xa[m, 0], xa[m, 1], xa[m, 2]), sum_a)
    c_b = add((xb[m, 0], xb[m, 1], xb[m, 2]), sum_b)
    r = sub(c_a, c_b)
    b = dot(axes_a[i], axes_b[j])
    c = dot(axes_a[i], r)
    f = dot(axes_b[j], r)
    denom = max(1.0 - b * b, NEAR_PARALLEL**2)  # ≥ |u_a × u_b|² of a valid edge axis
    s = min(max((b * f - c) / denom, -ha[i]), ha[i])
    t = min(max(b * s + f, -hb[j]), hb[j])
    p_a = add(c_a, scale(s, axes_a[i]))
    p_b = add(c_b, scale(t, axes_b[j]))
    g = dot(sub(p_a, p_b), n)
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
    usable = np.empty(9, dtype=np.bool_)
    work = (  # ``_face``'s scratch, once per call
        np.empty((3, 3)),
        np.empty(3),
        np.empty((3, 3)),
        np.empty(3),
        np.empty((MAX_POLYGON, 3)),
        np.empty((2 * MAX_POLYGON, 3)),
        np.empty(2 * MAX_POLYGON, dtype=np.bool_),
        np.empty(MAX_POLYGON),
    )
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
        for k in range(3):
            for l in range(3):
                e = 6 + 3 * k + l
                c = cross(axes[k], axes[3 + l])
                length = norm3(c)
                usable[3 * k + l] = length > NEAR_PARALLEL
                div = length if length > NEAR_PARALLEL else 1.0
                for i in range(3):
                    axes[e, i] = c[i] / div
        d = (xa[m, 0] - xb[m, 0], xa[m, 1] - xb[m, 1], xa[m, 2] - xb[m, 2])
        for k in range(15):
            along[k] = dot(axes[k], d)
            reach = 0.0
            for a in range(3):
                reach += abs(dot(axes[k], axes[a])) * ha[a]
            reach_b = 0.0
            for a in range(3):
                reach_b += abs(dot(axes[k], axes[3 + a])) * hb[a]
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
            _face(m, ref_b, face, n, xa, xb, axes_a, axes_b, ha, hb, arm_a, arm_b, gap, work)

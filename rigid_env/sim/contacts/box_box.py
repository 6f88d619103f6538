"""Box against box: separating axes, then a clipped face manifold or one edge–edge point.

Separating-axis test (Gottschalk, Lin & Manocha, "OBBTree", 1996; Ericson, *Real-Time Collision
Detection* 4.4.1) over the 15 candidate axes: the 3 + 3 face normals and the 9 cross products
of an edge of a with an edge of b (near-parallel pairs skipped: their cross product has no
direction). The axis of largest separation (least penetration) is the contact normal. Face axes
are preferred (Bullet's ``btBoxBoxDetector``, from ODE's ``dBoxBox``: an edge axis must beat the
best face by its relative fudge factor 1.05) plus an absolute margin (Box2D's
``0.1 * linear_slop`` between the two reference-face candidates): near ties otherwise flip
between a 4-point face manifold and a 1-point edge contact from one step to the next, and a
resting stack rocks on that single point.

Face contact: the reference face is the face of the chosen axis, the incident face the face of
the other box most anti-parallel to it; the incident quad is clipped against the reference
face's four side planes (Sutherland–Hodgman on fixed-size padded polygons, ≤ 8 vertices, so the
whole batch clips in one pass of array operations) and reduced to 4 points: the deepest, the one
farthest from it, and the two spanning the largest triangles on either side of that diagonal
(Gregorius, "Robust contact creation for physics simulations", GDC 2015). Points above the
reference face are kept with gap > 0: the solver treats them as speculative contacts.
Edge contact: the closest points of the two supporting edges (Ericson 5.1.8), one point
repeated in all four slots (a repeated point splits its impulse, it does not change it).

Convention as in ``pairs.py``: ``normal`` points from b to a, ``gap`` < 0 is penetration.
"""

from __future__ import annotations

import numpy as np

from ..rotation import cross, quat_to_matrix

SLOTS = 4
MAX_POLYGON = 8  # a quad clipped by 4 half-planes gains at most one vertex per plane
NEAR_PARALLEL = 1e-6  # |e_a × e_b| below this: the edge pair defines no axis
EDGE_FUDGE = 1.05  # relative preference for face axes (ODE / Bullet)
FACE_MARGIN = 1e-3  # absolute preference, as a fraction of the smallest half-extent
# Gap of a slot with no contact point (separated boxes whose faces do not overlap): far out of
# reach of any step, yet finite so the solver's arithmetic on it stays finite. Its target is
# no velocity of the problem: the solve's scales leave it out (``solve.contact_scales``).
FAR = 1e9


def _take(arr, idx):
    """``arr[..., idx, :]`` with a per-element index (…,) → (…, ·)."""
    return np.take_along_axis(arr, idx[..., None, None], axis=-2)[..., 0, :]


def _clip(poly, count, coord, sign, bound):
    """Clip padded polygons (…, M, 3) with ``count`` valid vertices to ``sign * p[coord] <=
    bound`` (Sutherland–Hodgman, one plane). Crossings are strict, so a vertex on the plane is
    kept once and never duplicated: the count grows by at most one."""
    size = poly.shape[-2]
    idx = np.arange(size)
    nxt = np.where(idx + 1 < count[..., None], idx + 1, 0)
    p_next = np.take_along_axis(poly, nxt[..., None], axis=-2)
    d = sign * poly[..., coord] - bound[..., None]
    d_next = np.take_along_axis(d, nxt, axis=-1)
    edge = idx < count[..., None]
    crossing = edge & (((d < 0) & (d_next > 0)) | ((d > 0) & (d_next < 0)))
    t = np.where(crossing, d / np.where(crossing, d - d_next, 1.0), 0.0)
    inter = poly + t[..., None] * (p_next - poly)
    out = np.stack((inter, p_next), axis=-2).reshape(*poly.shape[:-2], 2 * size, 3)
    valid = np.stack((crossing, edge & (d_next <= 0)), axis=-1).reshape(*d.shape[:-1], -1)
    order = np.argsort(~valid, axis=-1, kind="stable")[..., :MAX_POLYGON]
    out = np.take_along_axis(out, order[..., None], axis=-2)
    return out, np.minimum(np.sum(valid, axis=-1), MAX_POLYGON)


def _reduce(points, gap, count):
    """Indices (…, 4) of the deepest valid point, the farthest from it, and the two spanning
    the largest triangles on either side of that diagonal (face-plane coordinates 0, 1)."""
    valid = np.arange(points.shape[-2]) < count[..., None]
    uv = points[..., :2]
    i0 = np.argmax(np.where(valid, -gap, -np.inf), axis=-1)
    rel = uv - _take(uv, i0)[..., None, :]
    i1 = np.argmax(np.where(valid, np.sum(rel**2, axis=-1), -np.inf), axis=-1)
    e = _take(rel, i1)
    area = e[..., None, 0] * rel[..., 1] - e[..., None, 1] * rel[..., 0]
    i2 = np.argmax(np.where(valid, area, -np.inf), axis=-1)
    i3 = np.argmin(np.where(valid, area, np.inf), axis=-1)
    return np.stack((i0, i1, i2, i3), axis=-1)


def _face_contacts(ref_b, face, n, xa, xb, axes_a, axes_b, half_a, half_b):
    """Manifold (points on a, points on b, gap) (…, 4, ·) with the reference face of box b
    where ``ref_b``, else of box a; ``face`` (…,) is its axis index in that box."""
    rb = ref_b[..., None]
    x_r, x_i = np.where(rb, xb, xa), np.where(rb, xa, xb)
    axes_r = np.where(rb[..., None], axes_b, axes_a)
    axes_i = np.where(rb[..., None], axes_a, axes_b)
    h_r, h_i = np.where(rb, half_b, half_a), np.where(rb, half_a, half_b)
    out = np.where(rb, n, -n)  # reference face's outward normal, towards the incident box
    # Reference frame with the face axis last: (k+1, k+2, k), a right-handed permutation.
    perm = (face[..., None] + np.array([1, 2, 0])) % 3
    axes_r = np.take_along_axis(axes_r, perm[..., None], axis=-2)
    h_r = np.take_along_axis(h_r, perm, axis=-1)
    # Incident face: the face of the other box whose outward normal is most against ``out``.
    dots = np.sum(axes_i * out[..., None, :], axis=-1)
    j = np.argmax(np.abs(dots), axis=-1)
    j_perm = (j[..., None] + np.array([1, 2, 0])) % 3
    u_i = np.take_along_axis(axes_i, j_perm[..., None], axis=-2)
    h_u = np.take_along_axis(h_i, j_perm, axis=-1)
    s_j = -np.sign(np.take_along_axis(dots, j[..., None], axis=-1))
    centre = x_i + s_j * h_u[..., 2:] * u_i[..., 2, :]
    signs = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])  # cyclic quad
    corners = centre[..., None, :] + (signs * h_u[..., None, :2]) @ u_i[..., :2, :]
    local = (corners - x_r[..., None, :]) @ np.swapaxes(axes_r, -1, -2)  # reference frame
    poly = np.concatenate((local, np.repeat(local[..., :1, :], MAX_POLYGON - 4, -2)), -2)
    count = np.full(poly.shape[:-2], 4)
    for coord in (0, 1):
        for sign in (1.0, -1.0):
            poly, count = _clip(poly, count, coord, sign, h_r[..., coord])
    # Height above the reference face (its outward side: sign of ``out`` along the face axis).
    s_r = np.sign(np.sum(out * axes_r[..., 2, :], axis=-1))
    gap = s_r[..., None] * poly[..., 2] - h_r[..., 2:]
    pick = _reduce(poly, gap, count)
    poly = np.take_along_axis(poly, pick[..., None], axis=-2)
    gap = np.take_along_axis(gap, pick, axis=-1)
    p_inc = x_r[..., None, :] + poly @ axes_r
    p_ref = p_inc - gap[..., None] * out[..., None, :]
    gap = np.where(count[..., None] > 0, gap, FAR)
    p_a = np.where(rb[..., None], p_inc, p_ref)
    p_b = np.where(rb[..., None], p_ref, p_inc)
    return p_a, p_b, gap


def _edge_contact(edge, n, xa, xb, axes_a, axes_b, half_a, half_b):
    """Closest points of a's edge along axis ``edge // 3`` and b's along ``edge % 3``, each the
    edge of its box furthest towards the other (Ericson 5.1.8 on the two lines, clamped)."""
    i, j = edge // 3, edge % 3
    s_a = -np.sign(np.sum(axes_a * n[..., None, :], axis=-1))  # a's support towards b: −n
    s_b = np.sign(np.sum(axes_b * n[..., None, :], axis=-1))
    s_a = np.where(s_a == 0, 1.0, s_a) * (np.arange(3) != i[..., None])
    s_b = np.where(s_b == 0, 1.0, s_b) * (np.arange(3) != j[..., None])
    c_a = xa + np.sum((s_a * half_a)[..., None] * axes_a, axis=-2)
    c_b = xb + np.sum((s_b * half_b)[..., None] * axes_b, axis=-2)
    u_a, u_b = _take(axes_a, i), _take(axes_b, j)
    r = c_a - c_b
    b = np.sum(u_a * u_b, axis=-1)
    c, f = np.sum(u_a * r, axis=-1), np.sum(u_b * r, axis=-1)
    denom = np.maximum(1.0 - b * b, NEAR_PARALLEL**2)  # ≥ |u_a × u_b|² of a valid edge axis
    ha = np.take_along_axis(np.broadcast_to(half_a, c_a.shape), i[..., None], -1)[..., 0]
    hb = np.take_along_axis(np.broadcast_to(half_b, c_b.shape), j[..., None], -1)[..., 0]
    s = np.clip((b * f - c) / denom, -ha, ha)
    t = np.clip(b * s + f, -hb, hb)
    p_a, p_b = c_a + s[..., None] * u_a, c_b + t[..., None] * u_b
    return p_a, p_b, np.sum((p_a - p_b) * n, axis=-1)


def box_box(half_a, half_b):
    """Detection for pairs of boxes with half extents ``half_a``, ``half_b`` (P, 3)."""
    half_a, half_b = np.asarray(half_a, float), np.asarray(half_b, float)
    margin = FACE_MARGIN * np.minimum(half_a.min(-1), half_b.min(-1))

    def detect(xa, qa, xb, qb):
        axes_a = np.swapaxes(quat_to_matrix(qa), -1, -2)  # rows: body axes in world
        axes_b = np.swapaxes(quat_to_matrix(qb), -1, -2)
        edges = cross(axes_a[..., :, None, :], axes_b[..., None, :, :])
        edges = edges.reshape(*edges.shape[:-3], 9, 3)
        length = np.linalg.norm(edges, axis=-1)
        usable = length > NEAR_PARALLEL
        edges = edges / np.where(usable, length, 1.0)[..., None]
        axes = np.concatenate((axes_a, axes_b, edges), axis=-2)  # (…, 15, 3)
        d = xa - xb
        along = np.sum(axes * d[..., None, :], axis=-1)
        reach_a = np.abs(axes @ np.swapaxes(axes_a, -1, -2)) @ half_a[..., None]
        reach_b = np.abs(axes @ np.swapaxes(axes_b, -1, -2)) @ half_b[..., None]
        sep = np.abs(along) - reach_a[..., 0] - reach_b[..., 0]
        sep[..., 6:] = np.where(usable, sep[..., 6:], -np.inf)
        fa, fb = np.argmax(sep[..., :3], -1), np.argmax(sep[..., 3:6], -1)
        ea = np.argmax(sep[..., 6:], -1)
        sa = np.take_along_axis(sep, fa[..., None], -1)[..., 0]
        sb = np.take_along_axis(sep, 3 + fb[..., None], -1)[..., 0]
        se = np.take_along_axis(sep, 6 + ea[..., None], -1)[..., 0]
        ref_b = sb > sa + margin
        s_face = np.where(ref_b, sb, sa)
        use_edge = se > s_face + (EDGE_FUDGE - 1.0) * np.abs(s_face) + margin
        best = np.where(use_edge, 6 + ea, np.where(ref_b, 3 + fb, fa))
        side = np.sign(np.take_along_axis(along, best[..., None], -1))
        n = np.where(side == 0, 1.0, side) * _take(axes, best)  # from b to a
        face = np.where(ref_b, fb, fa)
        pa, pb, gap = _face_contacts(ref_b, face, n, xa, xb, axes_a, axes_b, half_a, half_b)
        if np.any(use_edge):
            ea_pa, ea_pb, ea_gap = _edge_contact(ea, n, xa, xb, axes_a, axes_b, half_a, half_b)
            e = use_edge[..., None]
            pa = np.where(e[..., None], ea_pa[..., None, :], pa)
            pb = np.where(e[..., None], ea_pb[..., None, :], pb)
            gap = np.where(e, ea_gap[..., None], gap)
        normal = np.broadcast_to(n[..., None, :], pa.shape)
        return pa - xa[..., None, :], pb - xb[..., None, :], normal, gap

    return detect


__all__ = ["SLOTS", "box_box"]

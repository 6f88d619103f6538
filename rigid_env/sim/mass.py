"""Mass properties of rigid bodies: boxes, spheres and closed polyhedra.

Polyhedra use Brian Mirtich, "Fast and Accurate Computation of Polyhedral Mass Properties",
Journal of Graphics Tools 1(2):31-50, 1996. The volume integrals of 1, x, x², xy, ... are
reduced by the divergence theorem to integrals over the faces, and each face integral to an
integral over the face's projection onto a coordinate plane, which Green's theorem turns into
a sum over the polygon's edges. The result is exact for polyhedra, up to floating point.

Because every step is a boundary integral, a face may be any simple planar polygon, convex or
not, with its vertices counter-clockwise seen from outside (the right-hand rule gives the
outward normal). Its normal is computed with Newell's method, which is exact for planar
polygons whatever their convexity (Mirtich's reference code takes it from the first three
vertices, which fails at a reflex corner).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

# A polyhedron's faces: vertex-index sequences (or an integer array, one row per face).
Faces = Sequence[Sequence[int]] | np.ndarray


@dataclass(frozen=True, eq=False)
class MassProperties:
    mass: float
    center_of_mass: np.ndarray  # (3,), in the input coordinates
    inertia: np.ndarray  # (3, 3), about the centre of mass, input axes (symmetric)


def _props(mass: float, com: np.ndarray, inertia: np.ndarray) -> MassProperties:
    com = np.array(com, dtype=float)
    inertia = np.array(0.5 * (inertia + inertia.T), dtype=float)
    com.flags.writeable = False  # the dataclass is frozen; so are its arrays
    inertia.flags.writeable = False
    return MassProperties(float(mass), com, inertia)


def _positive_scalar(name: str, value: float) -> float:
    try:
        x = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}") from None
    if x.shape != () or not np.isfinite(x) or x <= 0:
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    return float(x)


def box(half_extents: ArrayLike, mass: float) -> MassProperties:
    """A uniform box centred at the origin, edges along the axes.

    I = m/3 diag(b² + c², a² + c², a² + b²) for half extents (a, b, c) (the textbook
    m/12 (w² + h²) with full widths w = 2a, h = 2b).
    """
    try:
        h = np.array(half_extents, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"half_extents must be 3 positive numbers, got {half_extents!r}") from None
    if h.shape != (3,) or not np.all(np.isfinite(h)) or np.any(h <= 0):
        raise ValueError(f"half_extents must be 3 positive finite numbers, got {half_extents!r}")
    m = _positive_scalar("mass", mass)
    a2, b2, c2 = h**2
    return _props(m, np.zeros(3), m / 3.0 * np.diag([b2 + c2, a2 + c2, a2 + b2]))


def sphere(radius: float, mass: float) -> MassProperties:
    """A uniform solid sphere centred at the origin: I = 2/5 m r² Id."""
    r = _positive_scalar("radius", radius)
    m = _positive_scalar("mass", mass)
    return _props(m, np.zeros(3), 0.4 * m * r * r * np.eye(3))


def _check_polyhedron(vertices: ArrayLike, faces: Faces) -> tuple[np.ndarray, list[np.ndarray]]:
    try:
        v = np.array(vertices, dtype=float)  # a copy: the input is never modified
    except (TypeError, ValueError):
        raise ValueError("vertices must be a (V, 3) array of finite numbers") from None
    if v.ndim != 2 or v.shape[1] != 3 or v.shape[0] < 4:
        raise ValueError(f"vertices must have shape (V, 3) with V >= 4, got {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError("vertices must be finite (found NaN or inf)")

    if isinstance(faces, (str, bytes)) or not isinstance(faces, (Sequence, np.ndarray)):
        raise ValueError("faces must be a sequence of vertex-index sequences")
    if len(faces) < 4:
        raise ValueError(f"faces: a closed polyhedron needs at least 4 faces, got {len(faces)}")
    checked = []
    for i, face in enumerate(faces):
        f = np.array(face)
        if f.ndim != 1 or f.size < 3 or not np.issubdtype(f.dtype, np.integer):
            raise ValueError(f"faces[{i}] must be a list of >= 3 vertex indices, got {face!r}")
        if f.min() < 0 or f.max() >= len(v):
            raise ValueError(f"faces[{i}] has a vertex index out of range [0, {len(v)})")
        if len(np.unique(f)) != f.size:
            raise ValueError(f"faces[{i}] repeats a vertex: {face!r}")
        checked.append(f.astype(np.intp))

    # Closed and consistently oriented: every directed edge a→b occurs once, and its
    # reverse b→a once in another face. A reversed face repeats its neighbours' directions.
    edges: Counter[tuple[int, int]] = Counter()
    for f in checked:
        edges.update(zip(f.tolist(), np.roll(f, -1).tolist(), strict=True))
    for (a, b), count in edges.items():
        if count > 1:
            raise ValueError(
                f"faces: edge {a}->{b} is traversed {count} times in the same direction: "
                "inconsistent orientation (or a non-manifold edge)"
            )
        if (b, a) not in edges:
            raise ValueError(f"faces: polyhedron is not closed: edge {a}->{b} has no {b}->{a}")
    return v, checked


def _volume_integrals(
    v: np.ndarray, faces: list[np.ndarray]
) -> tuple[float, np.ndarray, np.ndarray, np.ndarray, float]:
    """Mirtich's T0 = ∫1, T1 = ∫(x, y, z), T2 = ∫(x², y², z²), TP = ∫(xy, yz, zx) over the solid.

    Mirtich's compVolumeIntegrals / compFaceIntegrals / compProjectionIntegrals, vectorised
    over all edges of all faces at once.
    """
    n_faces = len(faces)
    sizes = np.array([len(f) for f in faces])
    face_of_edge = np.repeat(np.arange(n_faces), sizes)
    i0 = np.concatenate(faces)
    i1 = np.concatenate([np.roll(f, -1) for f in faces])
    p0, p1 = v[i0], v[i1]

    def per_face(x: np.ndarray) -> np.ndarray:
        return np.bincount(face_of_edge, weights=x, minlength=n_faces)

    # Newell's area vector ½ Σ p_i × p_{i+1}: |.| is the face area for any planar polygon.
    area_vec = 0.5 * np.stack([per_face(c) for c in np.cross(p0, p1).T], axis=-1)
    area = np.linalg.norm(area_vec, axis=-1)
    scale = np.max(np.ptp(v, axis=0))
    keep = area > 1e-14 * scale**2  # a zero-area face contributes nothing and has no normal
    norm = np.zeros_like(area_vec)
    norm[keep] = area_vec[keep] / area[keep, None]
    centroid = np.stack([per_face(c) for c in p0.T], axis=-1) / sizes[:, None]
    w = -np.einsum("fi,fi->f", norm, centroid)  # plane n·x + w = 0
    off_plane = np.abs(np.einsum("ei,ei->e", norm[face_of_edge], p0) + w[face_of_edge])
    if np.any(off_plane > 1e-8 * scale):
        bad = int(face_of_edge[np.argmax(off_plane)])
        raise ValueError(f"faces[{bad}] is not planar")

    # Project each face onto the coordinate plane (A, B) that maximises the projected area;
    # gamma = C is the dropped axis, with Mirtich's tie-breaking.
    absn = np.abs(norm)
    C = np.where(
        (absn[:, 0] > absn[:, 1]) & (absn[:, 0] > absn[:, 2]),
        0,
        np.where(absn[:, 1] > absn[:, 2], 1, 2),
    )
    A = (C + 1) % 3
    B = (A + 1) % 3
    Ae, Be = A[face_of_edge], B[face_of_edge]
    edge = np.arange(len(i0))
    a0, b0 = p0[edge, Ae], p0[edge, Be]
    a1, b1 = p1[edge, Ae], p1[edge, Be]

    # compProjectionIntegrals: P_{a^p b^q} = ∫ a^p b^q over the projected polygon (Green).
    da, db = a1 - a0, b1 - b0
    a0_2, b0_2, a1_2, b1_2 = a0 * a0, b0 * b0, a1 * a1, b1 * b1
    a0_3, b0_3, a1_3, b1_3 = a0_2 * a0, b0_2 * b0, a1_2 * a1, b1_2 * b1
    C1 = a1 + a0
    Ca = a1 * C1 + a0_2
    Caa = a1 * Ca + a0_3
    Caaa = a1 * Caa + a0_3 * a0
    Cb = b1 * (b1 + b0) + b0_2
    Cbb = b1 * Cb + b0_3
    Cbbb = b1 * Cbb + b0_3 * b0
    Cab = 3 * a1_2 + 2 * a1 * a0 + a0_2
    Kab = a1_2 + 2 * a1 * a0 + 3 * a0_2
    Caab = a0 * Cab + 4 * a1_3
    Kaab = a1 * Kab + 4 * a0_3
    Cabb = 4 * b1_3 + 3 * b1_2 * b0 + 2 * b1 * b0_2 + b0_3
    Kabb = b1_3 + 2 * b1_2 * b0 + 3 * b1 * b0_2 + 4 * b0_3
    P1 = per_face(db * C1) / 2
    Pa = per_face(db * Ca) / 6
    Paa = per_face(db * Caa) / 12
    Paaa = per_face(db * Caaa) / 20
    Pb = per_face(da * Cb) / -6
    Pbb = per_face(da * Cbb) / -12
    Pbbb = per_face(da * Cbbb) / -20
    Pab = per_face(db * (b1 * Cab + b0 * Kab)) / 24
    Paab = per_face(db * (b1 * Caab + b0 * Kaab)) / 60
    Pabb = per_face(da * (a1 * Cabb + a0 * Kabb)) / -60

    # compFaceIntegrals: lift to the face plane, c = -(nA a + nB b + w) / nC.
    rows = np.flatnonzero(keep)
    nA, nB, nC = (norm[rows, A[rows]], norm[rows, B[rows]], norm[rows, C[rows]])
    w = w[rows]
    P1, Pa, Pb, Paa, Pab, Pbb, Paaa, Paab, Pabb, Pbbb = (
        P[rows] for P in (P1, Pa, Pb, Paa, Pab, Pbb, Paaa, Paab, Pabb, Pbbb)
    )
    k1 = 1 / nC  # |nC| >= 1/√3 by the choice of C
    k2, k3, k4 = k1 * k1, k1**3, k1**4
    Fa = k1 * Pa
    Fb = k1 * Pb
    Fc = -k2 * (nA * Pa + nB * Pb + w * P1)
    Faa = k1 * Paa
    Fbb = k1 * Pbb
    Fcc = k3 * (
        nA**2 * Paa + 2 * nA * nB * Pab + nB**2 * Pbb + w * (2 * (nA * Pa + nB * Pb) + w * P1)
    )
    Faaa = k1 * Paaa
    Fbbb = k1 * Pbbb
    Fccc = -k4 * (
        nA**3 * Paaa
        + 3 * nA**2 * nB * Paab
        + 3 * nA * nB**2 * Pabb
        + nB**3 * Pbbb
        + 3 * w * (nA**2 * Paa + 2 * nA * nB * Pab + nB**2 * Pbb)
        + w * w * (3 * (nA * Pa + nB * Pb) + w * P1)
    )
    Faab = k1 * Paab
    Fbbc = -k2 * (nA * Pabb + nB * Pbbb + w * Pbb)
    Fcca = k3 * (
        nA**2 * Paaa + 2 * nA * nB * Paab + nB**2 * Pabb + w * (2 * (nA * Paa + nB * Pab) + w * Pa)
    )

    # compVolumeIntegrals: scatter (A, B, C) back to (x, y, z); per face they're a permutation.
    def xyz(fa: np.ndarray, fb: np.ndarray, fc: np.ndarray) -> np.ndarray:
        out = np.empty((len(rows), 3))
        out[np.arange(len(rows)), A[rows]] = fa
        out[np.arange(len(rows)), B[rows]] = fb
        out[np.arange(len(rows)), C[rows]] = fc
        return out

    n = norm[rows]
    T0 = float(np.sum(n[:, 0] * xyz(Fa, Fb, Fc)[:, 0]))
    T1 = np.sum(n * xyz(Faa, Fbb, Fcc), axis=0) / 2
    T2 = np.sum(n * xyz(Faaa, Fbbb, Fccc), axis=0) / 3
    TP = np.sum(n * xyz(Faab, Fbbc, Fcca), axis=0) / 2  # (∫xy, ∫yz, ∫zx)
    return T0, T1, T2, TP, float(scale)


def polyhedron(vertices: ArrayLike, faces: Faces, density: float) -> MassProperties:
    """A uniform closed polyhedron (Mirtich 1996).

    ``vertices`` (V, 3); ``faces`` a sequence of vertex-index lists, each a simple planar
    polygon (convex or not) with at least 3 vertices, counter-clockwise seen from outside.
    Returns mass = density × volume, the centre of mass in the input coordinates, and the
    inertia about the centre of mass along the input axes.
    """
    rho = _positive_scalar("density", density)
    v, checked = _check_polyhedron(vertices, faces)

    # The integrals are cubic in the coordinates. Far from the origin, ∫x² ≈ m d² and the
    # parallel-axis shift to the centre of mass cancels catastrophically (relative error
    # ~ eps (d/size)²). Integrating about the vertices' mean keeps d ~ size.
    used = np.unique(np.concatenate(checked))
    shift = v[used].mean(axis=0)
    T0, T1, T2, TP, scale = _volume_integrals(v - shift, checked)

    if abs(T0) <= 1e-12 * scale**3:
        raise ValueError("vertices/faces: degenerate polyhedron (zero volume)")
    if T0 < 0:
        raise ValueError(
            "faces: polyhedron is inside out (negative volume): faces must be counter-clockwise "
            "seen from outside, not clockwise"
        )

    mass = rho * T0
    r = T1 / T0  # centre of mass relative to shift
    xx, yy, zz = rho * T2
    xy, yz, zx = rho * TP
    # Inertia about the shifted origin: I = ∫(|x|² Id - x xᵀ) dm (Mirtich's J).
    origin = np.array([[yy + zz, -xy, -zx], [-xy, zz + xx, -yz], [-zx, -yz, xx + yy]])
    # Parallel-axis theorem: I_com = I_origin - m (|r|² Id - r rᵀ).
    inertia = origin - mass * (np.dot(r, r) * np.eye(3) - np.outer(r, r))
    return _props(mass, r + shift, inertia)

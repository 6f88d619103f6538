"""Mass properties, checked against independent closed forms (not Mirtich's algorithm).

Tolerances: every reference is an exact formula evaluated in float64 on O(1) inputs, so both
sides agree to a few ulps times a small operation count: 1e-12 relative leaves ample margin.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rigid_env.sim import mass

RTOL = 1e-12

# Unit cube corners, index 4x + 2y + z; quads counter-clockwise seen from outside.
CUBE_VERTICES = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
CUBE_FACES = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]


def rotation(q) -> np.ndarray:
    """Rotation matrix of a (not necessarily unit) quaternion (x, y, z, w)."""
    x, y, z, w = np.asarray(q, float) / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def assert_props(p, m, com, inertia, rtol=RTOL):
    scale = np.abs(inertia).max()
    assert p.mass == pytest.approx(m, rel=rtol)
    np.testing.assert_allclose(p.center_of_mass, com, rtol=0, atol=rtol * (1 + np.abs(com).max()))
    np.testing.assert_allclose(p.inertia, inertia, rtol=0, atol=rtol * scale)
    np.testing.assert_array_equal(p.inertia, p.inertia.T)


def tetra_reference(w, density):
    """Blow & Binstock (2004): covariance C = ∫ x xᵀ dV of the tetrahedron 0, A e1, A e2, A e3
    is det(A) A C_canon Aᵀ, with C_canon = (Id + 1 1ᵀ)/120 for the canonical tetrahedron
    (∫x² = 1/60, ∫xy = 1/120). Shift to the centre of mass, then I = tr(C) Id - C."""
    w = np.asarray(w, float)
    A = (w[1:] - w[0]).T
    det = np.linalg.det(A)
    m = density * det / 6
    c = density * det * A @ ((np.eye(3) + np.ones((3, 3))) / 120) @ A.T  # about w0
    d = A.sum(axis=1) / 4  # centre of mass relative to w0
    c = c - m * np.outer(d, d)
    return m, w[0] + d, np.trace(c) * np.eye(3) - c


TETRA_FACES = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]  # for det(w1-w0, w2-w0, w3-w0) > 0


def test_box_and_sphere_closed_forms():
    assert_props(mass.box([0.5, 1.0, 1.5], 12.0), 12.0, np.zeros(3), np.diag([13.0, 10.0, 5.0]))
    assert_props(mass.sphere(2.0, 5.0), 5.0, np.zeros(3), 8.0 * np.eye(3))


def test_cube_offset_and_rotated():
    s, density = 2.0, 3.0
    R = rotation([0.3, -0.5, 0.2, 0.8])
    t = np.array([4.0, -7.0, 2.5])
    v = (CUBE_VERTICES - 0.5) * s @ R.T + t
    p = mass.polyhedron(v, CUBE_FACES, density)
    m = density * s**3
    assert_props(p, m, t, m / 6 * s**2 * np.eye(3))  # solid cube: m s²/6 about any axis
    assert_props(p, m, t, R @ mass.box([s / 2] * 3, m).inertia @ R.T)


def test_rectangular_box_rotated_matches_box():
    half = np.array([0.5, 1.25, 2.0])
    R = rotation([-0.1, 0.7, 0.4, 0.5])
    t = np.array([-3.0, 1.0, 10.0])
    v = (2 * CUBE_VERTICES - 1) * half @ R.T + t
    p = mass.polyhedron(v, CUBE_FACES, 0.5)
    m = 0.5 * np.prod(2 * half)
    assert_props(p, m, t, R @ mass.box(half, m).inertia @ R.T)


def test_far_from_origin():
    # Corners at 1e6 ± 0.5 are exact in float64; without the internal shift, ∫x² ≈ m·1e12
    # would leave the O(1) inertia about the centre of mass with nothing but rounding noise.
    t = np.array([1e6, -2e6, 3e6])
    p = mass.polyhedron(CUBE_VERTICES - 0.5 + t, CUBE_FACES, 1.0)
    assert_props(p, 1.0, t, np.eye(3) / 6)


def test_right_corner_tetrahedron():
    a, b, c = 1.0, 2.0, 3.0
    v = [[0, 0, 0], [a, 0, 0], [0, b, 0], [0, 0, c]]
    p = mass.polyhedron(v, TETRA_FACES, 1.0)
    assert p.mass == pytest.approx(a * b * c / 6, rel=RTOL)
    np.testing.assert_allclose(p.center_of_mass, np.array([a, b, c]) / 4, rtol=RTOL)
    assert_props(p, *tetra_reference(v, 1.0))


def test_general_tetrahedron():
    v = np.array([[0.3, -1.2, 0.5], [2.1, 0.4, -0.3], [-0.7, 1.9, 0.8], [0.5, 0.2, 2.6]])
    assert np.linalg.det((v[1:] - v[0]).T) > 0
    assert_props(mass.polyhedron(v, TETRA_FACES, 2.5), *tetra_reference(v, 2.5))


def l_prism(h=1.5):
    """L-shaped prism: [0,2]x[0,1] ∪ [0,1]x[1,3] in xy, extruded over z in [0, h].

    The caps are single non-convex hexagons (reflex corner at (1, 1))."""
    outline = np.array([[0, 0], [2, 0], [2, 1], [1, 1], [1, 3], [0, 3]], float)  # CCW from +z
    n = len(outline)
    v = np.vstack([np.c_[outline, np.zeros(n)], np.c_[outline, np.full(n, h)]])
    bottom = list(range(n))[::-1]
    top = list(range(n, 2 * n))
    sides = [[i, (i + 1) % n, (i + 1) % n + n, i + n] for i in range(n)]
    return v, [bottom, top, *sides]


def test_nonconvex_prism_is_two_boxes():
    h, density = 1.5, 2.0
    v, faces = l_prism(h)
    pieces = [  # (centre, half extents) of [0,2]x[0,1]x[0,h] and [0,1]x[1,3]x[0,h]
        (np.array([1.0, 0.5, h / 2]), np.array([1.0, 0.5, h / 2])),
        (np.array([0.5, 2.0, h / 2]), np.array([0.5, 1.0, h / 2])),
    ]
    boxes = [(c, mass.box(e, density * np.prod(2 * e))) for c, e in pieces]
    m = sum(b.mass for _, b in boxes)
    com = sum(b.mass * c for c, b in boxes) / m
    # Parallel-axis theorem: I = Σ I_i + m_i (|d_i|² Id - d_i d_iᵀ), d_i = c_i - com.
    inertia = sum(
        b.inertia + b.mass * ((c - com) @ (c - com) * np.eye(3) - np.outer(c - com, c - com))
        for c, b in boxes
    )
    assert_props(mass.polyhedron(v, faces, density), m, com, inertia)


def _midpoint(v, mid, a, b):
    key = (min(a, b), max(a, b))
    if key not in mid:
        p = v[a] + v[b]
        v.append(p / np.linalg.norm(p))
        mid[key] = len(v) - 1
    return mid[key]


def icosphere(level):
    t = (1 + 5**0.5) / 2
    v = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t]]
    v += [[0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4]]
    f += [[11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8]]
    f += [[3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    v = [np.array(p, float) / np.linalg.norm(p) for p in v]
    for _ in range(level):
        mid: dict[tuple[int, int], int] = {}  # edge -> index of its midpoint on the sphere
        new = []
        for a, b, c in f:
            ab, bc, ca = (_midpoint(v, mid, i, j) for i, j in ((a, b), (b, c), (c, a)))
            new += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        f = new
    return np.array(v), f


def test_icosphere_converges_from_below():
    r, density = 2.0, 1.0
    exact = 0.4 * density * 4 / 3 * np.pi * r**5  # 2/5 m r² of the solid sphere
    errors = []
    for level in (1, 2, 3):
        v, f = icosphere(level)
        p = mass.polyhedron(r * v, f, density)
        np.testing.assert_allclose(p.center_of_mass, 0, atol=1e-12)
        moments = np.linalg.eigvalsh(p.inertia)
        assert np.all(moments < exact)  # the inscribed polyhedron has less inertia
        errors.append(exact - moments.max())
    assert errors[2] < errors[1] < errors[0]
    assert errors[2] / exact < 0.02


@settings(max_examples=50, deadline=None)
@given(
    q=st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(lambda q: np.linalg.norm(q) > 0.1),
    t=st.lists(st.floats(-1e3, 1e3), min_size=3, max_size=3),
)
def test_rigid_motion_property(q, t):
    # Moving the vertices rounds them by ~eps·|t| ≤ 2e-13 absolute; relative to the body's
    # size (~3) that perturbs the mass and inertia by ≲1e-13 relative: within 1e-12.
    R, t = rotation(q), np.array(t)
    v, faces = l_prism()
    p0 = mass.polyhedron(v, faces, 1.3)
    p = mass.polyhedron(v @ R.T + t, faces, 1.3)
    assert p.mass == pytest.approx(p0.mass, rel=RTOL)
    np.testing.assert_allclose(
        p.center_of_mass, R @ p0.center_of_mass + t, rtol=0, atol=RTOL * (1 + np.abs(t).max())
    )
    np.testing.assert_allclose(
        p.inertia, R @ p0.inertia @ R.T, rtol=0, atol=RTOL * np.abs(p0.inertia).max()
    )


def test_inputs_not_modified():
    v = CUBE_VERTICES.copy()
    faces = np.array(CUBE_FACES)
    half = np.array([1.0, 2.0, 3.0])
    mass.polyhedron(v, faces, 1.0)
    mass.box(half, 1.0)
    np.testing.assert_array_equal(v, CUBE_VERTICES)
    np.testing.assert_array_equal(faces, CUBE_FACES)
    np.testing.assert_array_equal(half, [1.0, 2.0, 3.0])


def test_returned_arrays_are_read_only():
    p = mass.polyhedron(CUBE_VERTICES, CUBE_FACES, 1.0)
    with pytest.raises(ValueError):
        p.inertia[0, 0] = 1.0


BAD_SCALARS = [0.0, -1.0, np.nan, np.inf, "heavy", [1.0]]


@pytest.mark.parametrize("bad", BAD_SCALARS)
def test_bad_scalars(bad):
    with pytest.raises(ValueError, match="mass"):
        mass.box([1, 1, 1], bad)
    with pytest.raises(ValueError, match="mass"):
        mass.sphere(1.0, bad)
    with pytest.raises(ValueError, match="radius"):
        mass.sphere(bad, 1.0)
    with pytest.raises(ValueError, match="density"):
        mass.polyhedron(CUBE_VERTICES, CUBE_FACES, bad)


@pytest.mark.parametrize("bad", [[1, 1], [1, 1, 0], [1, -1, 1], [1, np.nan, 1], [[1, 1, 1]], "x"])
def test_bad_half_extents(bad):
    with pytest.raises(ValueError, match="half_extents"):
        mass.box(bad, 1.0)


def _with(i, value):
    v = CUBE_VERTICES.copy()
    v[i] = value
    return v


@pytest.mark.parametrize(
    "vertices",
    [CUBE_VERTICES[:, :2], CUBE_VERTICES[:3], CUBE_VERTICES.ravel(), _with(3, np.nan)]
    + [_with(5, np.inf), [["a", "b", "c"]] * 8],
)
def test_bad_vertices(vertices):
    with pytest.raises(ValueError, match="vertices"):
        mass.polyhedron(vertices, CUBE_FACES, 1.0)


def test_degenerate_polyhedron():
    flat = CUBE_VERTICES * [1, 1, 0]  # the cube squashed into the plane z = 0
    with pytest.raises(ValueError, match="degenerate"):
        mass.polyhedron(flat, CUBE_FACES, 1.0)


@pytest.mark.parametrize(
    "faces, message",
    [
        (CUBE_FACES[:-1], "not closed"),  # one face missing
        ([f[::-1] for f in CUBE_FACES], "inside out"),  # all reversed
        (CUBE_FACES[:-1] + [CUBE_FACES[-1][::-1]], "inconsistent orientation"),  # one reversed
        (CUBE_FACES[:-1] + [[1, 5, 7]], "faces"),  # a triangle where a quad belongs
        (CUBE_FACES[:-1] + [[1, 5, 8, 3]], "out of range"),
        (CUBE_FACES[:-1] + [[1, 5, -1, 3]], "out of range"),
        (CUBE_FACES[:-1] + [[1, 5]], "faces"),
        (CUBE_FACES[:-1] + [[1, 5, 5, 7, 3]], "repeats"),
        (CUBE_FACES[:-1] + [[1.0, 5.0, 7.0, 3.0]], "faces"),
        (CUBE_FACES + CUBE_FACES[:1], "inconsistent orientation"),  # a duplicated face
        ([], "faces"),
        ("faces", "faces"),
        (42, "faces"),
    ],
)
def test_bad_faces(faces, message):
    with pytest.raises(ValueError, match=message) as info:
        mass.polyhedron(CUBE_VERTICES, faces, 1.0)
    assert "faces" in str(info.value)


def test_non_planar_face():
    v = _with(7, [1.0, 1.0, 1.2])  # corner (1,1,1) lifted: three quads become non-planar
    with pytest.raises(ValueError, match="faces.*not planar"):
        mass.polyhedron(v, CUBE_FACES, 1.0)

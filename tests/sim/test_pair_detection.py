"""Body–body detection (``compiled.pairs``, the one implementation, behind ``contacts.pairs``
and ``contacts.box_box``): the kernels take the batch as rows, pair m of the flattened batch
with the shape parameters of row m % P. A wrong row or parameter index would mix elements or
pairs; these tests compare a batched call with each element and pair detected alone, bit for
bit (the same operations on the same numbers), and a broadcast input with its explicit copy.
Each law of the detection itself (gaps, normals, manifolds) is pinned by closed forms in
``test_contacts.py`` and ``test_box_box.py``.
"""

import numpy as np
import pytest

from rigid_env.sim.contacts.box_box import box_box
from rigid_env.sim.contacts.pairs import sphere_box, sphere_sphere
from rigid_env.sim.rotation import random_quaternions

P = 3


def poses(shape, seed=0):
    rng = np.random.default_rng(seed)
    return (
        rng.normal(0, 0.2, (*shape, P, 3)),
        random_quaternions(rng, (*shape, P)),
        rng.normal(0, 0.2, (*shape, P, 3)),
        random_quaternions(rng, (*shape, P)),
    )


def detectors():
    rng = np.random.default_rng(1)
    half_a, half_b = rng.uniform(0.05, 0.3, (P, 3)), rng.uniform(0.05, 0.3, (P, 3))
    radius = rng.uniform(0.05, 0.3, P)
    return {
        "box_box": (box_box(half_a, half_b), (half_a, half_b)),
        "sphere_box": (sphere_box(radius, half_b), (radius, half_b)),
        "sphere_sphere": (sphere_sphere(radius, radius[::-1]), (radius, radius[::-1])),
    }


@pytest.mark.parametrize("kind", ["box_box", "sphere_box", "sphere_sphere"])
def test_a_batch_is_each_element_and_pair_alone(kind):
    detect, params = detectors()[kind]
    make = {"box_box": box_box, "sphere_box": sphere_box, "sphere_sphere": sphere_sphere}[kind]
    xa, qa, xb, qb = poses((2, 3))
    batched = detect(xa, qa, xb, qb)
    assert batched[3].shape[:3] == (2, 3, P)
    for i in range(2):
        for j in range(3):
            for p in range(P):
                alone = make(*(np.asarray(a)[p : p + 1] for a in params))(
                    xa[i, j, p : p + 1],
                    qa[i, j, p : p + 1],
                    xb[i, j, p : p + 1],
                    qb[i, j, p : p + 1],
                )
                for ours, theirs in zip(batched, alone, strict=True):
                    np.testing.assert_array_equal(ours[i, j, p], theirs[0])


@pytest.mark.parametrize("kind", ["box_box", "sphere_box", "sphere_sphere"])
def test_broadcast_and_strided_inputs_are_their_copies(kind):
    detect, _ = detectors()[kind]
    xa, qa, xb, qb = poses((4,))
    # b's pose shared by the batch (broadcast), a's read through a transposed view
    xa_view = np.ascontiguousarray(np.swapaxes(xa, 0, 1)).swapaxes(0, 1)
    ours = detect(xa_view, qa, xb[0], qb[0])
    theirs = detect(
        xa.copy(),
        qa,
        np.broadcast_to(xb[0], xa.shape).copy(),
        np.broadcast_to(qb[0], qa.shape).copy(),
    )
    for a, b in zip(ours, theirs, strict=True):
        np.testing.assert_array_equal(a, b)

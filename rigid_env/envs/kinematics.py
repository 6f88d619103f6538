"""Quaternion maps as small stacked matrix products: the cheap form for an env's hot path.

``rigid_env.sim.rotation`` builds each result from many elementwise operations, which for one
body costs tens of microseconds of numpy call overhead. Here the matrices that are linear in q
come from one product with a constant 0/±1 selection tensor (each entry picks a single ±q_k, so
the result is exact whatever order BLAS sums in), and the rest are stacked 3×3 / 4×4 products:
a handful of numpy calls whatever the batch size, and per-element results that do not depend on
the batch size (every slice goes through the same small product), which keeps a vector env
bit-identical to single envs.

Quaternions are (x, y, z, w), scalar last, as in the simulator (course notes).
"""

from __future__ import annotations

import numpy as np


def _selection(rows: list[list[str]]) -> np.ndarray:
    """(4, r·c) matrix mapping q to the flattened r×c matrix whose entries are ±x, ±y, ±z, ±w, 0."""
    index = {"x": 0, "y": 1, "z": 2, "w": 3}
    flat = [e for row in rows for e in row]
    sel = np.zeros((4, len(flat)))
    for j, e in enumerate(flat):
        if e != "0":
            sel[index[e[-1]], j] = -1.0 if e[0] == "-" else 1.0
    return sel


# Ξ(q) = [[w I + [u]×], [−uᵀ]] and Ψ(q) = [[w I − [u]×], [−uᵀ]] (4×3): R(q) = Ψᵀ Ξ.
_XI = _selection([["w", "-z", "y"], ["z", "w", "-x"], ["-y", "x", "w"], ["-x", "-y", "-z"]])
_PSI = _selection([["w", "z", "-y"], ["-z", "w", "x"], ["y", "-x", "w"], ["-x", "-y", "-z"]])
# L(a): a ∘ b = L(a) b (Hamilton product), 4×4.
_LEFT = _selection(
    [["w", "-z", "y", "x"], ["z", "w", "-x", "y"], ["-y", "x", "w", "z"], ["-x", "-y", "-z", "w"]]
)


def rotation_matrices(q: np.ndarray) -> np.ndarray:
    """R(q) (body → world) for unit quaternions ``(N, 4)`` → ``(N, 3, 3)``."""
    n = q.shape[0]
    xi = (q @ _XI).reshape(n, 4, 3)
    psi = (q @ _PSI).reshape(n, 4, 3)
    return np.matmul(psi.transpose(0, 2, 1), xi)


def left_matrices(q: np.ndarray) -> np.ndarray:
    """L(q) with ``q ∘ p = L(q) p``, ``(N, 4)`` → ``(N, 4, 4)``."""
    return (q @ _LEFT).reshape(q.shape[0], 4, 4)


def apply(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``m @ v`` for stacks ``(N, r, c)`` and ``(N, c)``."""
    return np.matmul(m, v[:, :, None])[:, :, 0]


def apply_transpose(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``mᵀ @ v`` for stacks ``(N, r, c)`` and ``(N, r)``."""
    return np.matmul(v[:, None, :], m)[:, 0, :]

"""Per-element model parameters: each batch element's masses, inertias and ground material.

A vector env that randomises its physics per sub-env (domain randomisation) steps every
sub-env in one call when the model's parameters differ per batch element:

    params = scene.parameters(mass=m, inertia=i, friction=mu, restitution=eps)
    state = scene.step(state, body_torque=tau, parameters=params)

Row p of the arrays is the model of the elements that take row p: with R rows, a batch of R
elements takes one row each (element e row e, over the flattened batch), and a single row
serves any batch. Element e then steps exactly as the same state would on a scene built with
row e's bodies and ground, bit for bit (``tests/sim/test_parameters.py``): the compiled step's
kernels read element e's row of their data (``compiled.driver``), which is built by the same
kernel factories from the scene with row e's bodies and ground, so nothing is computed twice.

What may differ per element is what does not change a scene's composition or its contact
slots: the bodies' masses and inertias (the shapes stay the scene's) and the ground's friction
and restitution.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .body import Body
from .compiled.backend import kernels_for

# Row arrays by name: the trailing shape of one row, with n the scene's body count.
FIELDS = ("mass", "inertia", "friction", "restitution")


class Parameters:
    """R rows of per-element model parameters of one scene (``Scene.parameters``).

    ``mass`` (R, n) kg, ``inertia`` (R, n, 3, 3) body-axes tensors about the centres of mass,
    ``friction`` and ``restitution`` (R,) the ground's coefficients (present when the scene
    has a ground); read-only arrays, changed only by :meth:`update`. ``data`` is what the
    compiled step takes (the kernels' data tuples of every row, stacked).
    """

    def __init__(self, scene, values: dict[str, np.ndarray]) -> None:
        self.scene = scene
        self._values = values
        from .compiled.driver import stack

        rows = [row_data(scene, *self._row(values, p)) for p in range(self.rows)]
        self.data = stack(rows)
        for arr in values.values():
            arr.setflags(write=False)

    @property
    def rows(self) -> int:
        return len(self._values["mass"])

    @property
    def mass(self) -> np.ndarray:
        return self._values["mass"]

    @property
    def inertia(self) -> np.ndarray:
        return self._values["inertia"]

    @property
    def friction(self) -> np.ndarray | None:
        return self._values.get("friction")

    @property
    def restitution(self) -> np.ndarray | None:
        return self._values.get("restitution")

    def values(self) -> dict[str, np.ndarray]:
        """Copies of the arrays by ``Scene.parameters``' names: ``scene.parameters(**p.values())``
        builds the same rows (on a rebuilt scene, say)."""
        return {name: np.array(arr) for name, arr in self._values.items()}

    def update(self, index: ArrayLike, **values: ArrayLike) -> None:
        """Set rows ``index`` (ints) of the named arrays (``mass=``, ``inertia=``, ``friction=``,
        ``restitution=``), each given for those rows (leading axis ``len(index)``). Every row
        is checked and built before any is written: on a ``ValueError`` nothing changed."""
        rows = np.asarray(index)
        if rows.ndim != 1 or (rows.size and rows.dtype.kind not in "iu"):
            raise ValueError(f"index must be a 1-D array of row numbers, got {index!r}")
        if rows.size and (rows.min() < -self.rows or rows.max() >= self.rows):
            raise ValueError(f"index out of range for {self.rows} rows: {rows.tolist()}")
        new = {name: np.array(arr) for name, arr in self._values.items()}
        given = _checked(self.scene, values, len(rows), new)
        for name, arr in given.items():
            new[name][rows] = arr
        built = [row_data(self.scene, *self._row(new, int(p))) for p in rows]
        for arr in new.values():
            arr.setflags(write=False)
        self._values = new
        for k, p in enumerate(rows):
            _write_row(self.data, built[k], int(p))

    def _row(self, values: dict[str, np.ndarray], p: int) -> tuple[list[Body], Any]:
        """Row p as the scene's bodies and ground with that row's values (``Body`` and
        ``Ground`` check them: a ``ValueError`` names the field and the row)."""
        model = self.scene.model
        try:
            bodies = [
                Body(values["mass"][p, b], values["inertia"][p, b], body.shape, body.center_of_mass)
                for b, body in enumerate(model.bodies)
            ]
            ground = model.ground
            if ground is not None:
                ground = dataclasses.replace(
                    ground, friction=values["friction"][p], restitution=values["restitution"][p]
                )
        except ValueError as err:
            raise ValueError(f"parameters row {p}: {err}") from None
        return bodies, ground


def build(scene, values: dict[str, ArrayLike]) -> Parameters:
    """``Scene.parameters``: the given arrays (each with a leading axis of R rows), the
    scene's own values for the others."""
    given = {k: v for k, v in values.items() if v is not None}
    for name, value in given.items():
        if not np.ndim(value):
            raise ValueError(f"{name} must have a leading axis of rows, got a scalar")
    sizes = {k: int(np.shape(v)[0]) for k, v in given.items()}
    counts = set(sizes.values())
    if len(counts) > 1:
        raise ValueError(f"the parameters' row counts differ: {sizes}")
    if scene._driver is None:
        raise ValueError("parameters: this scene lends a parameter row its data and does not step")
    rows = counts.pop() if counts else 1
    if rows < 1:
        raise ValueError("parameters need at least one row")
    model = scene.model
    full = {
        "mass": np.repeat(model.mass[None], rows, axis=0),
        "inertia": np.repeat(model.inertia[None], rows, axis=0),
    }
    if model.ground is not None:
        full["friction"] = np.full(rows, model.ground.friction)
        full["restitution"] = np.full(rows, model.ground.restitution)
    full.update(_checked(scene, given, rows, full))
    return Parameters(scene, full)


def _checked(scene, values: dict, rows: int, full: dict) -> dict[str, np.ndarray]:
    """The given arrays as float64 of shape (rows, *row shape); a ``ValueError`` names the
    first one that does not fit (values themselves are checked by ``Parameters._row``)."""
    n = scene.model.n_bodies
    shapes = {"mass": (n,), "inertia": (n, 3, 3), "friction": (), "restitution": ()}
    out = {}
    for name, value in values.items():
        if name not in shapes:
            raise ValueError(f"unknown parameter {name!r}; expected one of {FIELDS}")
        if name not in full:
            raise ValueError(f"{name}: the scene has no ground whose {name} it could set")
        try:
            arr = np.array(value, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"{name} must be a numeric array, got {value!r}") from None
        if n == 1 and name in ("mass", "inertia") and arr.shape == (rows, *shapes[name][1:]):
            arr = arr[:, None]  # a one-body scene's (R,) masses, (R, 3, 3) inertias
        if arr.shape != (rows, *shapes[name]):
            raise ValueError(
                f"{name} must have shape {(rows, *shapes[name])} (rows, ...), got {arr.shape}"
            )
        out[name] = arr
    return out


def row_data(scene, bodies: list[Body], ground) -> tuple:
    """The compiled step's data of ``scene`` with these bodies and ground, in the layout of
    the scene's driver (``driver.step_data``)."""
    from .compiled.driver import step_data

    drv = scene._driver
    twin = scene.rebuilt(bodies, ground)
    found = kernels_for(twin)
    if found is None:  # (the composition is the scene's: it has a kernel for every stage)
        raise RuntimeError("a parameter row's scene has a stage without a kernel")
    kernels, forces = found
    names = [(k.module, k.name) for k in kernels]
    if names != [(k.module, k.name) for k in drv.kernels]:
        raise RuntimeError("a parameter row's scene composed other kernels than its scene")
    return step_data(tuple(kernels), tuple(forces))


def _write_row(data, row, p: int) -> None:
    if data is None:
        return
    if isinstance(data, tuple):
        for d, r in zip(data, row, strict=True):
            _write_row(d, r, p)
        return
    data[p] = row

"""The driver: one compiled call runs a whole step of a scene over its batch, or several.

Composition. A scene's stage tuple names its kernels (``registry``); the driver picks one of
the two compiled steps of ``steps.py`` from it, once: ``free_step`` for bodies without
contacts, ``contact_step`` for bodies with them. Each is a plain function whose stages are
written out in order. The integrator is chosen by the type of the scene's integrator tag
(``registry.integrate``) and the force terms by the slots of its force data
(``forces.wrench``), so numba compiles each composition's specialisation once and caches it
on disk (``cache=True``); a later process loads it. The contact kernels are called through
their addresses (``calls.call_at``): each is compiled once, for its own cache entry, and shared
by every composition (a direct call would link its IR into every step, see ``calls``).

Several steps (``Scene.step(..., steps=k)``) loop inside each element: between two,
``steps.carry`` makes the result the next step's start (in the step's own copies of the start
slots), zeroes the contact slots and folds the report row into its running maximum, so each
step computes what a call of its own would, bit for bit.

Data. Every array of the kernels' data has a leading axis of parameter rows (``stack``): one
row, the scene's, for every element, or one per element (``sim.Parameters``); element e's
kernels take row e (``steps.take``), so each element steps as a scene of its own model would.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from . import compile_helper, layout
from .first_call import first_call
from .forces import force_data
from .registry import ForceKernel, Kernel
from .steps import (
    ASSEMBLE,
    GROUND,
    LIMIT,
    PAIRS,
    RESTITUTE,
    SEPARATE,
    SOLVE,
    contact_step,
    free_step,
)
from .steps import take as _row

_PACKAGE = Path(__file__).resolve().parent
_F64 = np.dtype(np.float64)
# Where ``contact_step`` takes each contact kernel's address, by the kernel's name.
CONTACT_KERNELS = {
    "detect": GROUND,
    "collide": PAIRS,
    "assemble": ASSEMBLE,
    "restitute": RESTITUTE,
    "solve": SOLVE,
    "limit_energy": LIMIT,
    "separate_contacts": SEPARATE,
}
# The order ``contact_step`` runs them in, the integrator's halves around the first six.
_CONTACT_ORDER = ("velocity", "detect", "collide", "assemble", "restitute", "solve",
                  "limit_energy", "position", "separate_contacts")  # fmt: skip


def cache_dir() -> Path:
    """Where the first calls' locks and the compile times live (``first_call``):
    ``RIGID_ENV_CACHE_DIR``, else ``compiled/__pycache__/rigid_env`` in the package when
    writable, else ``~/.cache/rigid_env``. numba's own cache is in ``__pycache__`` (or
    ``NUMBA_CACHE_DIR``)."""
    env = os.environ.get("RIGID_ENV_CACHE_DIR")
    candidates = [Path(env)] if env else []
    candidates += [
        _PACKAGE / "__pycache__" / "rigid_env",
        Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "rigid_env",
    ]
    for path in candidates:
        try:
            path.mkdir(parents=True, exist_ok=True)
        except OSError:
            continue
        if os.access(path, os.W_OK):
            return path
    raise OSError("no writable cache directory for the compile locks (set RIGID_ENV_CACHE_DIR)")


def step_data(kernels: tuple[Kernel, ...], forces: tuple[ForceKernel, ...]) -> tuple:
    """The data the step takes: (integrator data,) without contacts; with them (integrator
    data, the ground detection's data or None, the contact data every other contact kernel
    shares). The integrator's data is its kernels' with the force data (``force_data``)."""
    integrator = next(k for k in kernels if k.tag is not None)
    idata = (integrator.data, force_data(forces))
    contact = [k for k in kernels if k.tag is None]
    if not contact:
        return (idata,)
    ground = next((k.data for k in contact if k.name == "detect"), None)
    return (idata, ground, next(k.data for k in contact if k.name != "detect"))


def _check_composition(kernels: tuple[Kernel, ...]) -> None:
    """The kernels are one of the two steps' sequences (a bug otherwise, never a fallback)."""
    parts = [k for k in kernels if k.tag is not None]
    if len({k.tag for k in parts}) != 1:
        raise ValueError(f"a step runs one integrator, got the kernels {kernels}")
    if len(parts) == len(kernels):
        return
    if len(parts) != 2:
        raise ValueError("contacts need the two halves of a semi-implicit integrator")
    names = [k.name for k in kernels]
    names[kernels.index(parts[0])], names[kernels.index(parts[1])] = "velocity", "position"
    required = {"velocity", "assemble", "restitute", "solve", "limit_energy", "position"}
    if names != [n for n in _CONTACT_ORDER if n in names] or not required <= set(names):
        raise ValueError(f"the contact step runs {_CONTACT_ORDER}, not {names}")


def stack(rows: list) -> tuple:
    """The data tuples of several models' kernels as one: each array the rows' arrays stacked
    on a new leading axis (row p = model p's; None stays None), so that ``steps.take(data,
    p)`` gives each kernel the data it was built with."""
    first = rows[0]
    if first is None:
        return None  # type: ignore[return-value]
    if isinstance(first, tuple):
        return tuple(stack([r[i] for r in rows]) for i in range(len(first)))
    return np.ascontiguousarray(np.stack(rows))


class Driver:
    """The compiled step of one scene: ``driver(x, q, v, w, force, torque, body_torque,
    steps)`` → new arrays after ``steps`` steps.

    Arrays are (N, n, ·) float64; the loads (N, n, 3). Returns the new state arrays, the
    report columns and the counts of ``__call__``.
    """

    def __init__(self, kernels, forces, threads: bool = False, warm: bool = False):
        self.kernels = tuple(kernels)
        self.forces = tuple(forces)
        _check_composition(self.kernels)
        self.integrator = next(k.tag for k in self.kernels if k.tag is not None)(0)
        self.data = step_data(self.kernels, self.forces)
        self.slots = sum(k.slots for k in self.kernels)
        self.width = max(k.width for k in self.kernels)
        self.contacts = len(self.data) > 1
        self.step = contact_step if self.contacts else free_step
        # The data as the step takes it: row 0 of its ``stack``, whose arrays are C-contiguous
        # as the rows of per-element parameters are (``Parameters.data``, one row per element).
        self.data = _row(stack([self.data]), 0)
        # The kernels called through their addresses (``calls``), with the data the step passes
        # them (a kernel compiled for other types would read the wrong memory), and where
        # ``contact_step`` finds each; ``addresses`` is filled on the first call, under its lock.
        _, ground, shared = self.data if self.contacts else (None, None, None)
        self._callees = tuple(
            (k, ground if k.name == "detect" else shared) for k in self.kernels if k.tag is None
        )
        self.addresses = np.zeros(len(CONTACT_KERNELS), np.int64) if self.contacts else None
        self._one_row: tuple = (None, None)  # the last one-row parameters and their row 0
        # ``warm``: the contact solve warm-starts (``SolverSettings.warm_start``), so a call
        # takes the impulses the state carries and returns the last step's (``__call__``).
        self.warm = warm
        self.threads = threads
        self.workers = os.cpu_count() or 1
        self._pool = None
        self._last = None
        # Per kind of call (with or without per-element rows): the step's argument types and
        # its compiled entry point, after the first such call (``first_call``).
        self.signatures: dict[bool, tuple] = {}
        self._entries: dict[bool, object] = {}
        self._reporters = tuple(k.report for k in self.kernels if k.report is not None)
        self._one_step_counts = np.empty((1, 3))

    def report(self, columns, counts=None) -> dict:
        """``scene.report`` from the step's report columns, by the kernels that wrote them;
        ``counts`` the per-step counts of a call of several steps (``__call__``), else None."""
        reporters = self._reporters
        if len(reporters) == 1:  # (the common case: no dict to merge)
            return reporters[0](columns, counts)
        out = {}
        for fn in reporters:
            out.update(fn(columns, counts))
        return out

    def _shapes(self, shape):
        """Per state shape: the state shape, the kernels' (N, n, 3), (N, n, 4) and report
        shapes, and a zero load and report (shared, never written: without contact slots no
        kernel writes the report, and its running maximum over several steps stays zero)."""
        size = int(np.prod(shape[:-2], dtype=np.int64))
        flat = (size, shape[-2], 3)
        report = (size, layout.REPORT_WIDTH)
        self._last = (shape, flat, (size, shape[-2], 4), report, np.zeros(flat), np.zeros(report))
        return self._last

    def __call__(
        self, x0, q0, v0, w0, force, torque, body_torque=None, steps=1, data=None, warm=None
    ):
        """``steps`` steps from the state arrays (float64, any batch shape and memory layout)
        and the validated loads (None or broadcastable). Returns the new arrays as (N, n, ·),
        the report array (over several steps, its elementwise maximum over them), the
        counts of elements with a quaternion off unit length, with a non-finite result and
        with a contact solve stopped at its cap (``layout.CAPPED``) in some step, and per
        step the counts of engaged, capped and warm-started elements ((steps, 3)). ``data``:
        the kernels' data with one row per element (``Parameters.data``), else the scene's
        (one row for all). ``warm`` (with ``self.warm`` only): (in, out), two (N, C, 4) arrays
        per contact slot of the impulse (n, t₁, t₂) and in slot 0 the flag of a converged
        solve (``layout.WARM``, ``WARM_OK``): the first step starts from ``in``, the last
        step's are written to ``out``."""
        shape = x0.shape
        last = self._last
        if last is None or last[0] != shape:
            last = self._shapes(shape)
        _, flat, qflat, rflat, zero, zero_report = last
        if len(shape) != 3:
            x0, q0, v0, w0 = x0.reshape(flat), q0.reshape(qflat), v0.reshape(flat), w0.reshape(flat)
        # ``carray``: C-contiguous, aligned and writeable, the one array type the compiled step
        # takes (one flag read; float64 is the caller's: ``Scene`` passes nothing else).
        if not (x0.flags.carray and q0.flags.carray and v0.flags.carray and w0.flags.carray):
            x0, q0, v0, w0 = _plain(x0), _plain(q0), _plain(v0), _plain(w0)
        force = zero if force is None else _load(force, shape, flat)
        torque = zero if torque is None else _load(torque, shape, flat)
        body = zero if body_torque is None else _load(body_torque, shape, flat)
        # Fresh outputs (np.empty of a shape: cheaper than empty_like) and report.
        x, q, v, w = np.empty(flat), np.empty(qflat), np.empty(flat), np.empty(flat)
        report = np.zeros(rflat) if self.slots else zero_report
        # A single step's counts are the report's own (the scene does not read these): one
        # scratch array for all such calls, shared even by concurrent ones.
        counts = self._one_step_counts if steps == 1 else np.empty((steps, 3))
        # Every element takes ``one``, or with per-element rows element e takes row e.
        one, rows = self.data, None
        if data is not None:
            if data is self._one_row[0]:  # (its row 0 is views: updates write through them)
                one = self._one_row[1]
            elif _rows(data) == 1:
                one = _row(data, 0)
                self._one_row = (data, one)
            else:
                rows = data
        entry = self._entries.get(rows is not None)
        if entry is None:
            args = (x0, q0, v0, w0, x, q, v, w, force, torque, body, report, counts)
            return (x, q, v, w, report, self._dispatch(args, steps, one, rows, warm), counts)
        if not self.contacts:
            bad = entry(
                x0, q0, v0, w0, x, q, v, w, force, torque, body, report, counts, one, rows,
                steps, self.integrator,
            )  # fmt: skip
        else:
            warm_in, warm_out = (None, None) if warm is None else warm
            bad = entry(
                x0, q0, v0, w0, x, q, v, w, force, torque, body, report, counts, one, rows,
                steps, self.integrator, self.slots, self.width, self.addresses, warm_in, warm_out,
            )  # fmt: skip
        return x, q, v, w, report, bad, counts

    @property
    def signature(self) -> tuple | None:
        """The step's argument types without per-element rows (after such a call)."""
        return self.signatures.get(False)

    def tail(self, steps: int, data=None, rows=None, warm=None) -> tuple:
        """The compiled step's arguments after the arrays (``__call__`` writes them out):
        ``data`` every element's (the scene's by default), ``rows`` None or the per-element
        rows, ``warm`` as in ``__call__``."""
        head = (self.data if data is None else data, rows, steps, self.integrator)
        if not self.contacts:
            return head
        warm = (None, None) if warm is None else warm
        return (*head, self.slots, self.width, self.addresses, *warm)

    def _dispatch(self, args, steps, data, rows, warm) -> tuple[int, int, int]:
        """The step through numba's dispatcher (which compiles or loads it on the first call of
        its kind, under the composition's lock: ``first_call``), or over threads; a serial
        driver then calls its compiled entry point directly."""
        tail = self.tail(steps, data, rows, warm)
        kind = rows is not None
        if kind not in self.signatures:
            typeof = getattr(self.step, "typeof_pyval", None)  # (None: numba's JIT disabled)
            self.signatures[kind] = tuple(map(typeof, (*args, *tail))) if typeof else ()
            what = "stages " + ", ".join(dict.fromkeys(k.name for k in self.kernels))
            bad = first_call(
                self.step,
                (*args, *tail),
                lambda: self._resolve() or self._serial(args, tail),
                cache_dir(),
                "contacts" if self.contacts else "free",
                what,
            )
        elif self.threads and args[0].shape[0] > 1:
            return self._threaded(args, steps, data, rows, warm)
        else:
            bad = self._serial(args, tail)
        if not self.threads:
            self._entries[kind] = _entry_point(self.step, self.signatures[kind])
        return bad

    def _resolve(self) -> None:
        """Compile or load each called kernel for its data (on two cores when several are
        cold: ``compile_helper``) and note its address where ``contact_step`` reads it (once)."""
        if not self._callees or self.addresses[ASSEMBLE] != 0:
            return
        callees = [(k.module, k.name, data) for k, data in self._callees]
        found = compile_helper.addresses(callees, cache_dir())
        for (k, _), address in zip(self._callees, found, strict=True):
            self.addresses[CONTACT_KERNELS[k.name]] = address

    def _serial(self, args, tail) -> tuple[int, int, int]:
        return self.step(*args, *tail)

    def _threaded(self, args, steps, data, rows, warm) -> tuple[int, int, int]:
        """The batch in one contiguous chunk per worker thread; ``step`` releases the GIL.
        Elements are independent, so the bits are those of the serial loop. Each chunk
        counts its elements per step into its own array; the sums go into ``counts``."""
        # One chunk per thread: four per thread, taken as threads free up, were no faster on
        # BoxLanding's unevenly costly states (``docs/performance.md``).
        size = args[0].shape[0]
        workers = min(self.workers, size)
        bounds = np.linspace(0, size, workers + 1).astype(int)
        *arrays, counts = args
        pieces = list(zip(bounds[:-1], bounds[1:], strict=True))
        chunks = [(*(a[lo:hi] for a in arrays), np.empty_like(counts)) for lo, hi in pieces]
        # Per-element parameters are chunked with the elements; one row serves every chunk.
        tails = [
            self.tail(
                steps,
                data,
                None if rows is None else _take(rows, lo, hi),
                None if warm is None else (warm[0][lo:hi], warm[1][lo:hi]),
            )
            for lo, hi in pieces
        ]
        step = self.step
        verdicts = list(
            self.pool().map(lambda job: step(*job[0], *job[1]), zip(chunks, tails, strict=True))
        )
        counts[:] = sum(chunk[-1] for chunk in chunks)
        return tuple(sum(v[i] for v in verdicts) for i in range(3))

    def pool(self):
        if self._pool is None:
            self._pool = ThreadPoolExecutor(self.workers, thread_name_prefix="rigid_env")
        return self._pool


def _rows(data) -> int:
    """The parameter rows of stacked data (``stack``): the leading axis of its arrays."""
    if data is None:
        return 0
    if isinstance(data, tuple):
        return next((r for r in map(_rows, data) if r), 0)
    return data.shape[0]


def _take(data, lo: int, hi: int):
    """Rows lo..hi of stacked data."""
    if data is None:
        return None
    if isinstance(data, tuple):
        return tuple(_take(d, lo, hi) for d in data)
    return data[lo:hi]


def _entry_point(dispatcher, signature):
    """The compiled function behind a dispatcher for these argument types, callable without
    the dispatcher's type resolution (a share of a batch-1 step). Safe here because ``_plain``
    and the driver's own buffers give every call of one driver the same argument types; None
    (use the dispatcher) if numba's internals differ from what this expects."""
    try:
        return dispatcher.overloads[signature].entry_point
    except (AttributeError, KeyError, ValueError, TypeError):
        return None


def _plain(arr: np.ndarray) -> np.ndarray:
    """``arr`` as the kernels take it: float64, C-contiguous, aligned and writable (one compiled
    type)."""
    if arr.flags.carray and arr.dtype is _F64:
        return arr
    return np.array(arr, dtype=np.float64, order="C")


def _load(arr: np.ndarray, shape, flat) -> np.ndarray:
    """An applied load (broadcastable to the state's shape) as a fresh or plain (N, n, 3)."""
    if arr.shape == shape:
        arr = _plain(arr)
        return arr if shape == flat else arr.reshape(flat)
    full = np.empty(flat)
    (full if shape == flat else full.reshape(shape))[...] = arr
    return full

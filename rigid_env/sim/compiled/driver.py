"""The driver: one compiled call runs a whole step of a scene over its batch, or several.

Several steps (``Scene.step(..., steps=k)``) loop inside each element: between two,
``steps.carry`` makes the result the next step's start (in the driver's own copies of the
start slots), zeroes the contact slots and folds the report row into its running maximum,
so each step computes what a call of its own would, bit for bit.

Data. Every array of the kernels' data has a leading axis of parameter rows (``stack``): one
row, the scene's, for every element, or one per element (``sim.Parameters``); element e's
kernels take row e (``row``), so each element steps as a scene of its own model would.

Composition. A scene's stage tuple names its kernels (``registry``); the driver generates the
source of a module that runs them in that order, and numba caches that module's compiled code
to disk (``cache=True``). The integrator's templates and the force terms are compiled into the
module (a free body's step is a few hundred nanoseconds, less than a call would cost); every
other kernel is called through its address (``calls.call_at``), compiled once for its own
cache entry and shared by every composition. Generated source is how the integrator and the
force terms compose with numba's cache across processes: it keys its cache on a function's file
and bytecode, and a kernel received as a dispatcher argument or a closure variable makes every
new process a cache miss (measured with numba 0.68). So each distinct stage tuple compiles its
integrator and forces once, ever, and later processes import it from the cache.

The generated module lives in the cache directory (``RIGID_ENV_CACHE_DIR``, else
``compiled/__pycache__/drivers`` in the package when writable, else
``~/.cache/rigid_env/drivers``), named by a hash of its source and of every simulator source
(``cache.sources_hash``), so editing a kernel gives a new driver; ``cache.py`` makes numba's
own cache of every kernel notice such an edit too.
"""

from __future__ import annotations

import hashlib
import importlib.util
import inspect
import os
import sys
import textwrap
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from ..state import ORIENTATION_TOLERANCE
from . import compile_helper, layout
from .cache import sources_hash
from .first_call import first_call
from .registry import ForceKernel, Kernel
from .steps import BODY_TORQUE

# The generated ``step`` builds the step tuple as the layout's slots then the body torque.
if (layout.STEP_TUPLE_SIZE, BODY_TORQUE) != (13, 13):
    raise ImportError("compiled.layout changed its step tuple: update generate()'s `st`")

_PACKAGE = Path(__file__).resolve().parent
_F64 = np.dtype(np.float64)
# Every kernel: cached, numpy's floating-point semantics (x/0 gives inf or nan, which the
# finiteness check reports; Python's would raise ZeroDivisionError).
_JIT = '@njit(cache=True, error_model="numpy")'
_JIT_NOGIL = '@njit(cache=True, nogil=True, error_model="numpy")'
# A function that takes the step tuple is inlined into its caller (numba IR): a call passes
# every array of the tuple field by field (14 arrays of 11 words each), ~30-100 ns per call
# per element, more than a free body's arithmetic (as ``integrators``' ``load``/``store``).
# The contact kernels are called through their addresses (``calls``): each compiles once, for
# its own cache entry, and no composition links or re-optimises it (a direct call would link
# its IR into every driver, see ``calls``), so a new composition (other forces, another
# integrator) compiles only its integrator and force terms. Their work per engaged element
# (microseconds) dwarfs a call; inlined, they measured 4.6 → 4.3 µs per element step of
# BoxLanding's physics on an earlier, quieter machine.
_JIT_INLINE = '@njit(cache=True, error_model="numpy", inline="always")'


def cache_dir() -> Path:
    env = os.environ.get("RIGID_ENV_CACHE_DIR")
    candidates = [Path(env)] if env else []
    candidates += [
        _PACKAGE / "__pycache__" / "drivers",
        Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "rigid_env" / "drivers",
    ]
    for path in candidates:
        try:
            path.mkdir(parents=True, exist_ok=True)
        except OSError:
            continue
        if os.access(path, os.W_OK):
            return path
    raise OSError("no writable cache directory for compiled drivers (set RIGID_ENV_CACHE_DIR)")


def generate(
    kernels: tuple[Kernel, ...],
    forces: tuple[ForceKernel, ...],
    index: tuple[int, ...],
    unique: tuple,
    warm: bool = False,
) -> str:
    """The driver module's source for these kernels (in order) and force terms; kernel i
    takes row p of ``data[index[i]]`` (``share``; ``unique``, the distinct data tuples, gives
    their nesting: every array of ``data`` has a leading axis of parameter rows, ``stack``).
    ``warm``: the step takes the contact solve's warm start in and out (``Driver.warm``)."""
    lines = [
        f"# Generated by {__name__}; do not edit. Kernel sources {sources_hash()}.",
        "import numpy as np",
        "from numba import njit",
        f"from {__package__}.rotation import quat_rotate as body_to_world",
        f"from {__package__}.steps import begin, carry, finite, fold",
        f"from {__package__}.calls import as_ref, call_at",
    ]
    templates = []
    for module in dict.fromkeys(k.module for k in kernels if k.template):
        lines.append(f"from {module} import *  # noqa")
        templates.append(module)
    for i, f in enumerate(forces):
        lines.append(f"from {f.module} import {f.name} as force_{i}")
        if f.damping is not None:
            lines.append(f"from {f.module} import {f.damping} as damping_{i}")
    # The applied world loads, the body torque turned into the world at q (skipped when zero,
    # zeros for none), then the force terms, in stage order.
    lines += ["", "", _JIT, "def wrench(b, x, q, v, w, fa, ta, tb, fds):"]
    lines += [
        "    f, t = fa, ta",
        "    if tb[0] != 0.0 or tb[1] != 0.0 or tb[2] != 0.0:",
        "        r = body_to_world(q, tb)",
        "        t = (t[0] + r[0], t[1] + r[1], t[2] + r[2])",
    ]
    for i in range(len(forces)):
        lines += [
            f"    fi, ti = force_{i}(b, x, q, v, w, fds[{i}])",
            "    f = (f[0] + fi[0], f[1] + fi[1], f[2] + fi[2])",
            "    t = (t[0] + ti[0], t[1] + ti[1], t[2] + ti[2])",
        ]
    lines.append("    return f, t")
    # Row p of every array of the data (``stack``): the kernels' data of element p's model.
    lines += ["", "", _JIT_INLINE, "def row(data, p):", f"    return {_row_of('data', unique)}"]
    lines += ["", "", _JIT, "def damping(b, x, q, fds, out):"]
    damped = [i for i, f in enumerate(forces) if f.damping is not None]
    lines += [f"    damping_{i}(b, x, q, fds[{i}], out)" for i in damped] or ["    return"]
    stages = {k.name for k in kernels if k.template}
    for module in templates:
        mod = importlib.import_module(module)
        inline = stages.union(getattr(mod, "INLINE", ()))  # helpers the module wants inlined
        for name in mod.TEMPLATES:
            src = textwrap.dedent(inspect.getsource(getattr(mod, name)))
            lines += ["", "", _JIT_INLINE if name in inline else _JIT, src.rstrip()]
    # The scratch (displacement, contact slots, the running report maximum, the start copies
    # that ``carry`` overwrites) is allocated here, per call: an allocation costs ~0.03 µs in
    # compiled code against ~0.2-1 µs from Python plus the unboxing of each array passed in;
    # per call, so concurrent steps of one scene (threads) cannot mix. An element's steps are
    # written into the loop, not an inlined function: binding ``st``, ``data`` and ``total`` as
    # its arguments costs each element an atomic incref and decref per array (see steps.py).
    calling = any(not k.template for k in kernels)  # some kernel is called by address
    lines += [
        "",
        "",
        _JIT_NOGIL,
        "def step(x0, q0, v0, w0, x, q, v, w, force, torque, body, report, counts, data, slots,",
        # ``addresses`` only where a kernel is called by it (unboxing an array is a visible part
        # of a free body's batch-1 step)
        "         steps"
        + (", addresses" if calling else "")
        + (", warm_in, warm_out" if warm else "")
        + "):",
        "    size = x0.shape[0]",
        "    disp = np.empty((size, x0.shape[1], 3))  # zeroed per element by begin",
        f"    contact = np.zeros((size, slots, {max(k.width for k in kernels)}))",
    ]
    if warm:  # the impulses the state carries: the first step warm-starts from them
        lines.append(f"    contact[:, :, {layout.WARM}:{layout.WARM_END}] = warm_in")
    lines += [
        "    total = report",
        "    if steps > 1:  # the start slots carry each step's result into the next: copies",
        "        x0, q0, v0, w0 = x0.copy(), q0.copy(), v0.copy(), w0.copy()",
        "        total = np.zeros_like(report)",
        "    st = (x0, q0, v0, w0, x, q, v, w, force, torque, disp, contact, report, body)",
    ]
    if calling:  # the called kernels take st by reference (``calls.as_ref``)
        lines.append("    ref = as_ref(st)")
    lines += [
        "    counts[:] = 0.0  # (steps, 3): per step, the engaged, capped and warm-started elements",
        "    bad_orientation = 0",
        "    diverged = 0",
        "    capped = 0",
        # One row of parameters serves every element (taken once); else element e takes row e.
        f"    per_element = {_first_array('data', unique) or 'np.zeros(1)'}.shape[0] > 1",
        "    d = row(data, 0)",
        "    for e in range(size):",
        "        if per_element:",
        "            d = row(data, e)",
        "        # element e: its steps; between two, carry makes the result the next start",
        "        verdict = 0",
        "        for k in range(steps):",
        "            if k > 0:",
        "                carry(e, st, total)",
        f"            if not begin(e, st, {ORIENTATION_TOLERANCE!r}):",
        "                verdict = 1",
        "                break",
    ]
    called = 0  # the kernels that are not templates, called through ``addresses`` in order
    for i, k in enumerate(kernels):
        if k.template:
            lines.append(f"            {k.name}(e, st, d[{index[i]}])")
        else:
            lines.append(f"            call_at(addresses[{called}], e, ref, d[{index[i]}])")
            called += 1
    lines += [
        "            if not finite(e, st):",
        "                verdict = 2",
        "                break",
    ]
    if any(kernel.report is not None for kernel in kernels):  # only stages that report count
        lines += [
            f"            if report[e, {layout.ENGAGED}] > 0.0:",
            "                counts[k, 0] += 1.0",
            f"            if report[e, {layout.CAPPED}] > 0.0:",
            "                counts[k, 1] += 1.0",
            f"            if report[e, {layout.WARMED}] > 0.0:",
            "                counts[k, 2] += 1.0",
        ]
    lines += [
        "        if verdict == 0 and steps > 1:",
        "            fold(e, st, total)",
        "        if verdict == 1:",
        "            bad_orientation += 1",
        "        elif verdict == 2:",
        "            diverged += 1",
        f"        if report[e, {layout.CAPPED}] > 0.0:",
        "            capped += 1",
    ]
    if warm:  # and the last step's, for the state the step returns
        lines.append(f"    warm_out[:] = contact[:, :, {layout.WARM}:{layout.WARM_END}]")
    lines += [
        "    return bad_orientation, diverged, capped",
    ]
    return "\n".join(lines) + "\n"


def share(datas: tuple) -> tuple[tuple, tuple[int, ...]]:
    """The distinct entries of ``datas`` (kernel data tuples) and, per entry, the index of its
    equal in them: numba unboxes every array of an argument on every call (~0.04 µs each), and
    the contact kernels of a landing scene get five equal copies of one data tuple, the two
    halves of a semi-implicit integrator two. Equal means the same nesting, dtypes, shapes and
    bytes (so -0.0 and 0.0 stay apart): a kernel sees exactly the values it was built with."""
    unique: list = []
    index = []
    for d in datas:
        for j, u in enumerate(unique):
            if _same(d, u):
                index.append(j)
                break
        else:
            index.append(len(unique))
            unique.append(d)
    return tuple(unique), tuple(index)


def _row_of(name: str, data) -> str:
    """Source of the tuple with ``data``'s nesting whose leaves are ``<leaf>[p]``."""
    if isinstance(data, tuple):
        parts = [_row_of(f"{name}[{i}]", d) for i, d in enumerate(data)]
        return "(" + "".join(f"{part}, " for part in parts) + ")"
    return f"{name}[p]"


def _first_array(name: str, data) -> str | None:
    """Source naming the first array of the nested tuple ``data`` (None if it holds none)."""
    if not isinstance(data, tuple):
        return name
    for i, d in enumerate(data):
        found = _first_array(f"{name}[{i}]", d)
        if found is not None:
            return found
    return None


def stack(rows: list) -> tuple:
    """The data tuples of several models' kernels as one: each array the rows' arrays stacked
    on a new leading axis (row p = model p's), so that ``row(data, p)`` gives each kernel the
    data it was built with."""
    first = rows[0]
    if isinstance(first, tuple):
        return tuple(stack([r[i] for r in rows]) for i in range(len(first)))
    return np.ascontiguousarray(np.stack(rows))


def _same(a, b) -> bool:
    if isinstance(a, tuple) or isinstance(b, tuple):
        return (
            isinstance(a, tuple)
            and isinstance(b, tuple)
            and len(a) == len(b)
            and all(_same(x, y) for x, y in zip(a, b, strict=True))
        )
    if isinstance(a, np.ndarray) and isinstance(b, np.ndarray):
        return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
    return False


def load(source: str):
    """Write the module once under its hash (an unchanged file keeps numba's cache valid)."""
    key = hashlib.sha256(source.encode()).hexdigest()[:20]
    name = f"rigid_env_driver_{key}"
    if name in sys.modules:
        return sys.modules[name]
    path = cache_dir() / f"{name}.py"
    if not path.exists() or path.read_text() != source:
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(source)
        os.replace(tmp, path)
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


class Driver:
    """The compiled step of one scene: ``driver(x, q, v, w, force, torque, body_torque,
    steps)`` → new arrays after ``steps`` steps.

    Arrays are (N, n, ·) float64; the loads (N, n, 3). Returns the new state arrays, the
    report columns and the counts of ``__call__``.
    """

    def __init__(self, kernels, forces, threads: bool = False, warm: bool = False):
        self.kernels = tuple(kernels)
        self.forces = tuple(forces)
        self.data, index = share(
            tuple(
                (k.data, tuple(f.data for f in self.forces)) if k.template else k.data
                for k in self.kernels
            )
        )
        self.slots = sum(k.slots for k in self.kernels)
        # The kernels called through their addresses (``calls``), in stage order, with their
        # data; ``addresses`` is filled on the first call, under the driver's lock.
        self._callees = tuple(
            (k, self.data[j]) for k, j in zip(self.kernels, index, strict=True) if not k.template
        )
        self.addresses = np.zeros(len(self._callees), dtype=np.int64) if self._callees else None
        # The data as one row of parameters (``stack``): what a step without per-element
        # parameters passes (``Parameters.data`` holds one row per element).
        self.rows = stack([self.data])
        self.index = index
        # ``warm``: the contact solve warm-starts (``SolverSettings.warm_start``), so a call
        # takes the impulses the state carries and returns the last step's (``__call__``).
        self.warm = warm
        self.source = generate(self.kernels, self.forces, index, self.data, warm)
        self.module = load(self.source)
        self.threads = threads
        self.workers = os.cpu_count() or 1
        self._pool = None
        self._last = None
        self._entry = None
        self._called = False  # the first call compiles or loads (``first_call``)
        self._reporters = tuple(k.report for k in self.kernels if k.report is not None)
        self._one_step_counts = np.empty((1, 3))

    def report(self, columns, counts=None) -> dict:
        """``scene.report`` from the step's report columns, by the kernels that wrote them;
        ``counts`` the per-step counts of a call of several steps (``__call__``), else None."""
        reporters = self._reporters
        if len(reporters) == 1:  # (the common case: a batch-1 step saves ~0.1 µs)
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
        # Fresh outputs (np.empty of a shape: ~0.1 µs cheaper than empty_like) and report.
        x, q, v, w = np.empty(flat), np.empty(qflat), np.empty(flat), np.empty(flat)
        report = np.zeros(rflat) if self.slots else zero_report
        # A single step's counts are the report's own (the scene does not read these): one
        # scratch array for all such calls, shared even by concurrent ones.
        counts = self._one_step_counts if steps == 1 else np.empty((steps, 3))
        entry = self._entry
        if data is None:
            data = self.rows
        if entry is None:
            args = (x0, q0, v0, w0, x, q, v, w, force, torque, body, report, counts)
            bad = self._dispatch(args, steps, data, warm)
        else:
            slots, addresses = self.slots, self.addresses
            if warm is not None:
                bad = entry(
                    x0, q0, v0, w0, x, q, v, w, force, torque, body, report, counts, data, slots,
                    steps, *self._addressed(), *warm,
                )  # fmt: skip
            elif addresses is None:
                bad = entry(
                    x0, q0, v0, w0, x, q, v, w, force, torque, body, report, counts, data, slots,
                    steps,
                )  # fmt: skip
            else:
                bad = entry(
                    x0, q0, v0, w0, x, q, v, w, force, torque, body, report, counts, data, slots,
                    steps, addresses,
                )  # fmt: skip
        return x, q, v, w, report, bad, counts

    def _addressed(self) -> tuple:
        return () if self.addresses is None else (self.addresses,)

    def _dispatch(self, args, steps, data, warm) -> tuple[int, int, int]:
        """The step through numba's dispatcher (which compiles or loads it on the first call,
        under the driver's lock: ``first_call``), or over threads; a serial driver then
        calls its compiled entry point directly."""
        if not self._called:
            what = "stages " + ", ".join(dict.fromkeys(k.name for k in self.kernels))
            kind = "contacts" if self.slots else "free"
            bad = first_call(
                self.module.step,
                lambda: self._resolve() or self._serial(args, steps, data, warm),
                cache_dir(),
                self.module.__name__,
                kind,
                what,
            )
            self._called = True
            if not self.threads:
                self._entry = _entry_point(self.module.step)
            return bad
        if self.threads:
            if args[0].shape[0] > 1:
                return self._threaded(args, steps, data, warm)
            return self._serial(args, steps, data, warm)
        bad = self._serial(args, steps, data, warm)
        self._entry = _entry_point(self.module.step)
        return bad

    def _resolve(self) -> None:
        """Compile or load each called kernel for its data (on two cores when several are
        cold: ``compile_helper``) and note its address."""
        if self.addresses is None:
            return
        callees = [(k.module, k.name, data) for k, data in self._callees]
        self.addresses[:] = compile_helper.addresses(callees, cache_dir())

    def tail(self, steps: int, data=None, warm=None) -> tuple:
        """The compiled ``step``'s arguments after the arrays (``__call__`` writes them out);
        ``data`` and ``warm`` as in ``__call__``."""
        if data is None:
            data = self.rows
        return (data, self.slots, steps, *self._addressed(), *(() if warm is None else warm))

    def _serial(self, args, steps, data, warm) -> tuple[int, int, int]:
        return self.module.step(*args, *self.tail(steps, data, warm))

    def _threaded(self, args, steps, data, warm) -> tuple[int, int, int]:
        """The batch in one contiguous chunk per worker thread; ``step`` releases the GIL.
        Elements are independent, so the bits are those of the serial loop. Each chunk
        counts its elements per step into its own array; the sums go into ``counts``."""
        # One chunk per thread although the two halves of BoxLanding's trained-policy states
        # differ by 5 % in cost (capped solves): four per thread, taken as threads free up,
        # measured no faster (3.00-3.14 µs per element step against 2.94-3.05).
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
                data if _rows(data) == 1 else _take(data, lo, hi),
                None if warm is None else (warm[0][lo:hi], warm[1][lo:hi]),
            )
            for lo, hi in pieces
        ]
        step = self.module.step
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
    if isinstance(data, tuple):
        return next((r for r in map(_rows, data) if r), 0)
    return data.shape[0]


def _take(data, lo: int, hi: int):
    """Rows lo..hi of stacked data."""
    if isinstance(data, tuple):
        return tuple(_take(d, lo, hi) for d in data)
    return data[lo:hi]


def _entry_point(dispatcher):
    """The compiled function behind a dispatcher with exactly one signature, callable without
    the dispatcher's type resolution (~1 µs of a batch-1 step). Safe here because ``_plain``
    and the driver's own buffers give every call the same argument types; None (use the
    dispatcher) if numba's internals differ from what this expects."""
    try:
        (signature,) = dispatcher.signatures
        return dispatcher.overloads[signature].entry_point
    except (AttributeError, KeyError, ValueError):
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

"""Calling a compiled kernel through its address, so that a step links none of its kernels.

Why. When a numba function calls another, numba links the callee's LLVM IR into the caller's
module and optimises and emits the whole module again (``numba.core.codegen``:
``CPUCodeLibrary.finalize`` links each callee's ``_get_module_for_linking`` and reruns the full
module passes). A step that called its contact kernels directly therefore compiled every
contact kernel once for the kernel's own cache entry and once more inside each composition's
driver: a landing scene with one spring added recompiled the whole contact solve.

Here the driver calls a kernel through a pointer to its compiled code, passed in as an int64
(``call_at``), with numba's own calling convention (the one its first-class functions use for a
jitted function's ``jit_addr``). The driver's machine code holds no address, so numba caches it
as usual; each kernel is compiled for its one signature (``address``), once, under its own
cache entry, and shared by every composition that runs it.

The caller must pass exactly the types the kernel was compiled for: ``address`` compiles it
for ``(int64, step_tuple_type(), typeof(data))``, the types the driver's ``step`` passes
(``step_tuple_type`` is built from ``layout``; ``tests/sim/test_compiled.py`` checks it against
the tuple a step builds). With ``NUMBA_DISABLE_JIT=1`` an address is an index into a table of
the kernels' Python functions and ``call_at`` looks it up: the same driver source runs as
Python.
"""

from __future__ import annotations

from numba import typeof, types
from numba.core import cgutils, config
from numba.extending import intrinsic

from .layout import REPORT, STEP_TUPLE_SIZE

# The step tuple's arrays: (N, n, ·) or (N, C, CW) float64, and the report (N, RW); then the
# body torque (``steps.BODY_TORQUE``), as the driver's ``step`` builds it.
_ARRAY3 = types.Array(types.float64, 3, "C")
_ARRAY2 = types.Array(types.float64, 2, "C")


def step_tuple_type() -> types.Tuple:
    """numba's type of the step tuple ``st`` (what every element kernel receives)."""
    slots = [_ARRAY2 if i == REPORT else _ARRAY3 for i in range(STEP_TUPLE_SIZE + 1)]
    return types.Tuple(slots)


def signature(data) -> tuple:
    """The argument types of an element kernel ``kernel(e, st, d)`` with data ``d``."""
    return (types.int64, step_tuple_type(), typeof(data))


if config.DISABLE_JIT:
    _PYTHON: list = []

    def address(dispatcher, data) -> int:
        """The kernel's index in the table of Python functions (numba's JIT disabled)."""
        _PYTHON.append(dispatcher)
        return len(_PYTHON) - 1

    def call_at(addr, e, st, d):
        _PYTHON[addr](e, st, d)

else:

    def address(dispatcher, data) -> int:
        """Compile (or load from the cache) the kernel for data ``d``'s signature; the address
        of its compiled function (numba's calling convention)."""
        sig = signature(data)
        dispatcher.compile(sig)
        compiled = dispatcher.overloads[sig]
        return compiled.library.get_pointer_to_function(compiled.fndesc.llvm_func_name)

    @intrinsic
    def call_at(typingctx, addr, e, st, d):
        """``kernel(e, st, d)`` for the kernel compiled at ``addr`` (``address``); an error it
        returns propagates as from a direct call."""
        args = (e, st, d)

        def codegen(context, builder, sig, llargs):
            fnty = context.call_conv.get_function_type(types.none, args)
            pointer = builder.inttoptr(llargs[0], fnty.as_pointer())
            status, _ = context.call_conv.call_function(
                builder, pointer, types.none, args, llargs[1:]
            )
            with cgutils.if_unlikely(builder, status.is_error):
                context.call_conv.return_status_propagate(builder, status)
            return context.get_dummy_value()

        return types.none(addr, e, st, d), codegen


__all__ = ["address", "call_at", "signature", "step_tuple_type"]

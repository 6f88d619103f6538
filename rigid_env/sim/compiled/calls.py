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

The step tuple goes by reference. numba passes a tuple of arrays to a called function field by
field (14 arrays of 11 words), more than the work of a resting element's contact kernels
(``docs/performance.md`` has the measurement). So the driver stores
``st`` once per call in its own frame and passes a pointer to it (``as_ref``): a kernel compiled
for a ``StepRef`` indexes it as it would the tuple (``st[X]``, constant indices only), each
index a load of that array from the stored tuple; a call then costs a few nanoseconds.

The caller must pass exactly the types the kernel was compiled for: ``address`` compiles it
for ``signature(data)`` = ``(int64, StepRef(step_tuple_type()), typeof(data))``, the types the
driver's ``step`` passes (``step_tuple_type`` is built from ``layout``;
``tests/sim/test_compiled.py`` checks it against the tuple a step builds). With
``NUMBA_DISABLE_JIT=1`` an address is an index into a table of the kernels' Python functions,
``call_at`` looks it up and ``as_ref`` is the tuple itself: the same driver source runs as
Python.
"""

from __future__ import annotations

import operator

from numba import typeof, types
from numba.core import cgutils, config
from numba.core.imputils import impl_ret_borrowed, lower_builtin
from numba.core.typing.templates import AbstractTemplate, infer, infer_global
from numba.core.typing.templates import signature as typed
from numba.extending import intrinsic, models, register_model

from .layout import REPORT, STEP_TUPLE_SIZE

# The step tuple's arrays: (N, n, ·) or (N, C, CW) float64, and the report (N, RW); then the
# body torque (``steps.BODY_TORQUE``), as the driver's ``step`` builds it.
_ARRAY3 = types.Array(types.float64, 3, "C")
_ARRAY2 = types.Array(types.float64, 2, "C")


def step_tuple_type() -> types.Tuple:
    """numba's type of the step tuple ``st`` (what every element kernel receives)."""
    slots = [_ARRAY2 if i == REPORT else _ARRAY3 for i in range(STEP_TUPLE_SIZE + 1)]
    return types.Tuple(slots)


class StepRef(types.Type):
    """A pointer to a step tuple stored by ``as_ref``; ``ref[i]`` is the tuple's array i."""

    def __init__(self, tuple_type: types.BaseTuple):
        self.tuple_type = tuple_type
        super().__init__(name=f"StepRef({tuple_type})")


@register_model(StepRef)
class _StepRefModel(models.PrimitiveModel):
    def __init__(self, dmm, fe_type):
        pointer = dmm.lookup(fe_type.tuple_type).get_value_type().as_pointer()
        super().__init__(dmm, fe_type, pointer)


@infer
class _StaticIndex(AbstractTemplate):
    key = "static_getitem"

    def generic(self, args, kws):
        ref, index = args
        if isinstance(ref, StepRef) and isinstance(index, int):
            return typed(ref.tuple_type.types[index], ref, types.literal(index))
        return None


@infer_global(operator.getitem)
class _ConstantIndex(AbstractTemplate):
    prefer_literal = True

    def generic(self, args, kws):
        ref, index = args
        if isinstance(ref, StepRef) and isinstance(index, types.IntegerLiteral):
            return typed(ref.tuple_type.types[index.literal_value], ref, index)
        return None


@lower_builtin("static_getitem", StepRef, types.IntegerLiteral)
@lower_builtin(operator.getitem, StepRef, types.IntegerLiteral)
def _load(context, builder, sig, args):
    ref, index = sig.args
    k = index.literal_value
    field = builder.gep(args[0], [cgutils.int32_t(0), cgutils.int32_t(k)])
    return impl_ret_borrowed(context, builder, ref.tuple_type.types[k], builder.load(field))


def signature(data) -> tuple:
    """The argument types of an element kernel ``kernel(e, st, d)`` with data ``d``."""
    return (types.int64, StepRef(step_tuple_type()), typeof(data))


if config.DISABLE_JIT:
    _PYTHON: list = []

    def address(dispatcher, data) -> int:
        """The kernel's index in the table of Python functions (numba's JIT disabled)."""
        _PYTHON.append(dispatcher)
        return len(_PYTHON) - 1

    def call_at(addr, e, st, d):
        _PYTHON[addr](e, st, d)

    def as_ref(st):
        return st

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

    @intrinsic
    def as_ref(typingctx, st):
        """``st`` stored in the caller's frame (for the whole call): a ``StepRef`` to it."""

        def codegen(context, builder, sig, llargs):
            slot = cgutils.alloca_once(builder, llargs[0].type)
            builder.store(llargs[0], slot)
            return slot

        return StepRef(st)(st), codegen


__all__ = ["StepRef", "address", "as_ref", "call_at", "signature", "step_tuple_type"]

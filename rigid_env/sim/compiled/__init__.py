"""``rigid_env.sim.compiled``: the compiled (numba) step, one call per step over the batch.

The element kernels here are the simulator's one implementation of every stage: integrators,
forces, detection, assembly, impacts, solve, energy guarantee and separation. Correctness is
pinned by closed forms, conservation laws, the bench's reference solutions and MuJoCo side by
side (``tests/sim``, ``rigid_env/bench``). ``NUMBA_DISABLE_JIT=1`` runs the same source as
plain Python, a debugging mode (``tests/sim/test_disable_jit.py``).

Kernel conventions (contacts and integrators written by others follow them)
---------------------------------------------------------------------------
Everything is ``@njit(cache=True, error_model="numpy")``, with ``cache.njit`` (numba's, after
the cache locator that notices an edit of any simulator file is installed), float64, no ``fastmath`` (results must not depend on the
compiler's reassociation), no allocation in the per-step path where a scalar tuple will do.
numba compiles a helper once per argument types, and a constant argument has its own literal
type: ``gauss_seidel(..., 1, ...)`` and ``gauss_seidel(..., 2, ...)`` are two compiles. Pass
``np.int64(1)`` or ``np.bool_(True)`` where one compile should serve every caller, a bare
constant only where the specialisation is wanted (the row counts 1 and 3 of ``delassus``).
A step runs the stages of ``scene.pipeline`` (``rigid_env.sim.pipeline``) per batch element,
on the arrays of the step tuple.

**The step tuple** ``st`` is what every element kernel receives (``layout.py`` names the slots):

====  ===========  ==================  ==========================================================
slot  name         shape               meaning
====  ===========  ==================  ==========================================================
0-3   x0 q0 v0 w0  (N, n, 3|4)         the state passed in; read only
4-7   x  q  v  w   (N, n, 3|4)         the working state: set to the state
                                       passed in with |q| renormalised before the first stage,
                                       updated in place by the stages, the step's result after
                                       the last (fresh arrays, never the caller's)
8-9   force torq   (N, n, 3)           applied world force / torque (zeros when none given)
10    displace     (N, n, 3)           the displacement: zero before the first stage; the
                                       contact solve adds its correction, the position update
                                       adds it to x + Δt v
11    contact      (N, C, CW)          contact slots: zero before the first
                                       stage (fresh per call); detection writes, the solve and
                                       restitution read and write
12    report       (N, RW)             per-element figures, zero before the
                                       first stage (fresh per call)
13    body torque  (N, n, 3)           applied body-frame torque (zeros
                                       when none given), slot ``steps.BODY_TORQUE``
====  ===========  ==================  ==========================================================

N is the flattened batch, n the bodies of one element, C the scene's contact slots (0 without
contacts). ``contact`` columns: ``ARM`` (3, world vector from the body's centre of mass to the
point), ``GAP`` (signed height, < 0 = penetration), ``BODY`` (body index as a float); the
columns from ``SOLVER`` on belong to the contact solve and restitution (``contact_*.py``: the
rows of J̃, the tangent, the gap after the impacts, their impulse, a body's velocities after the
velocity update and its orientation along the impacts' path; see ``layout.py``). Every contact
scene runs its contact stages compiled, body–body contacts included (``contact_pairs.py``:
detection by ``pairs.py``'s kernels, the one implementation of sphere–sphere, sphere–box and
box–box detection; then every contact of the element takes part in each impact, with the
pairs' rows moved to its instant, and in one solve). A body's record through the step (its velocities after the velocity update,
its path through the impacts) is kept in the contact row ``O_RECORD`` names: its first
ground slot, or without a ground a row of its own after the contacts. Ground slots come first: shaped body g (in body order) owns slots ``g*K .. g*K+K-1``, its K lowest
candidate points in ascending vertex order (ties: the lower vertex index), normal +z, detected
at the start-of-step pose (its order is Gauss–Seidel's visiting order). ``report`` columns: ``ITERATIONS`` (most iterations a
solve of this element used this step), ``CAPPED`` (1.0 if a solve stopped at its cap) and the
others in ``layout.py``; a kernel that writes them gives its ``Kernel`` a ``report`` function
that turns the columns into the ``state.report`` entries.

**An element kernel** is ``kernel(e, st, d) -> None``. It reads and writes only row ``e`` of
the ``st`` arrays (so a batched step equals the same element stepped alone, bit for bit, and
elements may run on threads), and ``d``, the stage's own constants: a tuple of float64/int64
arrays built once from the scene (never sized by the batch; scalars as 1-element arrays). With
per-element parameters (``sim.parameters``) the driver holds one such tuple per row, built by
the same factories from a scene with that row's bodies and ground, stacked on a leading axis,
and hands element e row e (``steps.take``): a kernel never sees the batch in its data. The
body count n is ``st[0].shape[1]``.

**A force kernel** (body level, pure) is ``term(b, x, q, v, w, fd) -> (f, t)``: body index b,
x/v/w 3-tuples, q a 4-tuple (all world frame, the state the integrator evaluates at), ``fd`` the
term's data tuple; it returns its world force and torque on body b as 3-tuples. The driver sums
the scene's force terms onto the applied load: ``forces.wrench(b, x, q, v, w, fa, ta, tb, fds)
-> (f, t)`` with ``tb`` the body-frame torque, which it turns into the world at q (so a body
torque follows the body through every evaluation), and ``fds`` the scene's force data, a slot
per term of ``forces.TERMS`` (gravity, damping, springs: their order in ``sim.forces``), None
for a term the scene lacks, which numba compiles away. Force terms are not element kernels: the
integrator evaluates them (at the start state, and at its own intermediate states).

**An integrator kernel** ``kernel(tag, e, st, d)`` is an element kernel that evaluates forces
only through ``forces.wrench``, with ``d = ((body data, [dt, velocity_dependent], spring
table), force data)`` (``integrators.integrator_data``); ``st`` comes by reference. It is a
plain function: ``registry.register_integrator(name, globals(), one=...)`` (or ``velocity=``
and ``position=`` for a semi-implicit integrator, the contact stages between them) gives the
integrator a tag class of its own, and the step's call ``registry.integrate(tag, e, st, d)``
(``integrate_velocity``, ``integrate_position``) resolves to its kernels by the tag's type when
the step compiles. A ``<name>_damped`` variant is taken for velocity-dependent forces.

**How a stage exposes its kernel**: ``registry.py`` maps a stage name (an entry of
``scene.stages``) to a factory ``factory(scene) -> Kernel | tuple[Kernel, ...] | None``;
``Kernel`` records the module path and function name of the element kernel, its data tuple,
an integrator part's tag, and the contact slots it writes (detection). A factory returns
``None`` when the scene has nothing for it to do (no contacts); a stage without a kernel is a
``ValueError`` when the scene is built. Force terms register likewise (``register_force``) and
return a ``ForceKernel``. A kernel module is listed in ``backend.KERNEL_MODULES``.

**The steps** (``steps.py``) are two explicit functions, each its stages in order:
``free_step`` (the integrator) and ``contact_step`` (the velocity update, ground detection,
pair detection, assembly, impacts, solve, energy guard, position update, separation). The
driver (``driver.py``) picks one from the scene's composition, once, and checks that the
scene's kernels are that step's sequence. Per element each runs ``steps.begin`` (working state,
zeroed scratch), its stages, then ``steps.finite``, ``steps`` times (``Scene.step(...,
steps=k)``; between two, ``steps.carry`` makes the result the next start, zeroes the contact
slots and folds the report row into ``total``, so a report column over k steps is its maximum
over them: write columns for which that is the right summary, as flags, counts per step and
largest values are). A step allocates the scratch (displacement, contact slots, the start
copies of several steps), builds ``st`` and loops over the batch (element e with row e of the
per-element ``rows`` when given), counting the elements with a bad quaternion, a non-finite
result and a capped solve (the scene builds its report dict from the columns when read, at
once when a solve was capped). ``steps.begin``, ``finite`` and ``carry`` are inlined: a call
passes each array of ``st`` field by field, per call per element. Every kernel is
called with ``st`` by reference (a ``calls.StepRef``: index it with constants, as the tuple):
the integrator's through its overload, detection and the contact kernels through their
addresses (``calls.py``), compiled once each, for ``calls.signature(d)``, and linked into no
composition (``calls.py`` gives the measured trade). A cold first step compiles them on two
cores (``compile_helper.py``). A step runs ``nogil`` (with ``backend="compiled-threads"`` the
driver runs it on one contiguous chunk of the batch per thread: numba's ``prange`` cannot take
the step tuple, as its parallel loop bodies accept no tuples of arrays). numba caches each
composition's specialisation of a step to disk (``cache=True``): one compile per composition
ever, a load afterwards. Composition, not flags, decides what a step runs: a body in space
compiles no force, contact or spring code.
"""

"""Integrators by name: one :class:`Integrator` record each, in ``RECORDS``; their element
kernels are ``compiled/integrators.py`` and ``compiled/exact_kernels.py``.

| name            | order | torque-free body keeps            | cost / step         | fails where            |
|-----------------|-------|-----------------------------------|---------------------|------------------------|
| `euler`         | 1     | world L exactly; energy drifts    | matrix + repair     | energy drift ∝ Δt      |
| `euler_quat`    | 1     | world L exactly; energy grows     | cheapest            | as `euler`             |
| `rk4`           | 4     | nothing exactly; drift O(Δt⁴)     | 4 force evaluations | long runs, stiff terms |
| `splitting`     | 2     | world L exactly; energy bounded   | 5 axis rotations    | phase error O(Δt²)     |
| `splitting4`    | 4     | as `splitting`                    | 3 × `splitting`     | large ω Δt             |
| `exact`         | 2     | the exact flow: rounding only     | sn cn dn, R_F, R_J  | torques: error O(Δt²)  |
| `exact4`        | 4     | as `exact`                        | 3 × `exact`         | torques: error O(Δt⁴)  |
| `implicit_gyro` | 1     | never blows up; loses energy      | one 3×3 solve       | damps fast spin        |
| `implicit`      | 1     | stiff springs bounded (any k Δt²) | one 6×6 solve/body  | damps resolved springs |

Semi-implicit integrators (``integrate_velocity`` then ``integrate_position``) take contacts
between their two parts: `euler`, `euler_quat`, `implicit_gyro`, `implicit`. Explicit
symplectic Euler on a spring of natural frequency ω_n diverges once ω_n Δt > 2; `implicit`
does not.

Adding an integrator: write its element kernels (``compiled.registry.register_integrator``) and
add its record to ``RECORDS`` below; every table derives from the records.

``euler``, ``euler_quat``
-------------------------
The course notes' modified explicit Euler, on rotation matrices and on quaternions.

Notes, "Integración Numérica": v ← v + Δt F/m; x ← x + Δt v; L ← L + Δt T; ω = M⁻¹ L;
R ← R + Δt ω* R; repair R (Gram–Schmidt); M⁻¹ = R M0⁻¹ Rᵀ. First order. The state keeps ω,
so L = M ω is recovered from the start-of-step inertia, which reproduces the notes' sequence
and keeps L constant in torque-free motion.

Split into the pipeline's two parts: the velocity part applies the kicks (v, and ω = M⁻¹ L
with the start-of-step inertia); the position part moves x and R with those (possibly
contact-corrected) velocities and re-expresses ω = M⁻¹ L in the new orientation.

``rk4``
-------
Classical fourth-order Runge–Kutta on the full state (x, q, v, L).

Forces are re-evaluated at each stage (the first from the step's force stages); the applied
force and torque are held over the step. The quaternion is normalised where a rotation is needed
and once at the end: RK4 preserves neither |q| nor energy exactly, but its errors are O(Δt⁴).

``splitting``, ``splitting4``
-----------------------------
Symplectic splitting with the free rotation solved exactly piece by piece.

Dullweber, Leimkuhler & McLachlan, "Symplectic splitting methods for rigid body molecular
dynamics", J. Chem. Phys. 107 (1997); McLachlan, "Explicit Lie–Poisson integration and the
Euler equations", Phys. Rev. Lett. 71 (1993). The kinetic energy splits into
H_i = Π_i² / (2 I_i) over the principal axes; each flow is an exact rotation of the body about
axis i by Π_i h / I_i, with Π turned back by the same angle, so world L = R Π is kept to
rounding, |Π| exactly, and energy stays bounded (the map is symplectic). Forces enter as half
kicks around the drift (Strang / velocity Verlet): second order. With velocity-dependent forces
(damping) the closing half kick is implicit, the adjoint of the explicit opening one, so the step
stays symmetric. ``splitting4`` composes it by Yoshida's triple jump (Phys. Lett. A 150, 1990)
for fourth order, with damping too.

``exact``, ``exact4``
---------------------
The exact flow of the torque-free rigid body, and splittings of it with kicks.

Method: Celledoni, Fassò & Säfström, "Exact computation of the free rigid body motion and its
use in splitting methods", SIAM J. Sci. Comput. 30(4) (2008), with the corrections and the
choice of reference axis of P. Leroy's notes on that article (Principia, 2020). Principal
moments I₁ ≤ I₂ ≤ I₃, body angular momentum m = I Ω, |m| = G, kinetic energy T:

* m(t) by Jacobi elliptic functions (Landau & Lifshitz, *Mechanics*, §37): in a proper,
  signed relabelling of the principal axes in which the axis m circulates about is the third
  (the "dn" axis: I₃ if G² > 2TI₂, else I₁ with the axes reversed) and m₁, m₃ >= 0 at t = 0,
  m = (B₁ cn u, B₂ sn u, B₃ dn u), u = u₀ + λ t, u₀ = F(am u₀ | k²) (Carlson's R_F).
* The attitude R(t) = C R_z(ψ(t)) S(m(t)) with S the shortest rotation taking m/G to e₃ (never
  singular: m₃ > 0 on the dn axis) and C fixed by R(0). With that S (CFS §3; Leroy):

      ψ̇ = G/I₃ + G (I₃ − I₁)/(I₁ I₃) · (1 − a dn u) / (1 + ν sn² u),
      a = B₃/G,  ν = I₃ (I₂ − I₁) / (I₁ (I₃ − I₂)),

  (Leroy's ψ̇ = G/I₃ + (2TI₃ − G²) / (G I₃ (1 + m₃/G)), multiplied through by 1 − a dn and
  using 1 − a² dn² = (B₁/G)² (1 + ν sn²), B₁² = I₁ (2TI₃ − G²)/(I₃ − I₁): the vanishing factor
  2TI₃ − G² cancels analytically instead of numerically),

  whose integral over a step is Π(−ν; am u | k²) − a ∫ dθ/(1 + ν sin² θ): an incomplete
  elliptic integral of the third kind (Carlson's R_F and R_J, DLMF 19.25.14) and an arctangent.
  Written this way nothing divides by a vanishing quantity: ν and the prefactor are constants
  of the body, and the formula is continuous into every limit (k → 0 steady spin, k → 1 the
  separatrix, two equal moments where ν = 0 or k = 0). The constant motions (Ω along a
  principal axis or an eigenplane, the sphere, Ω = 0) take the uniform rotation exp(t Ω).

Every quantity that can become small is formed without cancellation: G² − 2TI_j as sums of
same-signed terms (Leroy), k'² = (I₃ − I₁)(G² − 2TI₂) / ((I₃ − I₂)(G² − 2TI₁)) from
G² − 2TI₂ itself, the Jacobi functions with both k² and k'² (``compiled.exact_kernels``). Over a step the
amplitude is reduced by whole periods 2K so Carlson's forms see |am| <= π/2.

``exact`` is ``splitting``'s Strang step, half kick – exact free flow (with the drift) – half
kick, with this flow as its rotation: second order, exact when no torque acts. ``exact4``
composes it by Yoshida's triple jump (Phys. Lett. A 150, 1990): fourth order; its negative
middle step is exact too. The state keeps ω in world axes, so every step reads m = I Rᵀ ω and
writes ω back; the written ω is refined once so that the next read returns m (see
the splitting kernel's read-back).

What is left is rounding, and near the separatrix it is amplified: an error that moves m to a
neighbouring orbit (changes (G² − 2TI₂)/G²) shifts every later flip, ~8e4 rad per unit at
t = 15 s on the bench's flip. Measured there over 20 s at dt = 1e-3 (20 000 steps), against
one 80-bit evaluation of this flow (30-digit mpmath agrees with it to 1e-17): 5e-11 to 7e-11
rad from the bench's start, 3e-10 to 2e-9 rad from other start orientations, mostly from the
rounding of the read m = I Rᵀ ω and of the write of ω (a few ulp each). With every step done
in 80-bit arithmetic, rounding only the stored float64 q and ω still gives 1.5e-11 to 7e-11
rad: the floor of a float64 state at this step count.

``implicit_gyro``
-----------------
Semi-implicit Euler with the gyroscopic term solved implicitly (one Newton step).

Catto, "Numerical Methods", GDC 2015 (as in Bullet's ``computeGyroscopicImpulseImplicit_Body``):
in body axes, solve f(Ω₂) = I (Ω₂ − Ω₁) + h Ω₂ × I Ω₂ = 0 from Ω₁ with Jacobian
J = I + h (Ω₁* I − (I Ω₁)*). Explicit Euler on ω̇ = I⁻¹(−ω × Iω) gains energy and blows up
for elongated bodies at game time steps; the implicit term dissipates a little instead. The
rotation then follows by the exact exponential map q ← exp(h ω) ∘ q. First order.

Worked in principal axes, where I = diag(I₁, I₂, I₃) and
J = [[I₁, hΩ₃(I₃−I₂), hΩ₂(I₃−I₂)], [hΩ₃(I₁−I₃), I₂, hΩ₁(I₁−I₃)], [hΩ₂(I₂−I₁), hΩ₁(I₂−I₁), I₃]],
so the Newton step is a closed-form 3×3 solve on components.

``implicit``
------------
Linearised backward Euler in the spring and damper forces (and the gyroscopic term).

Backward Euler, M (u⁺ − u) = Δt F(x⁺, u⁺), on the generalised velocity u = (v, ω) of each body,
linearised once about the start of the step (Baraff & Witkin, "Large Steps in Cloth
Simulation", SIGGRAPH 1998, eq. 6–7): with a spring's point Jacobian J = [I, −(R r)*]
(ṗ = v + ω × R r), its stiffness K = −∂f/∂p and damping C = −∂f/∂ṗ,

    (M + Δt Jᵀ C J + Δt² Jᵀ K J) Δu = Δt (F − Δt Jᵀ K J u),

plus the gyroscopic Jacobian Δt ((ω*) M − (M ω)*) in the angular block (as ``implicit_gyro``).
One batched 6×6 solve per body; positions then drift with the new velocities (semi-implicit,
so contacts combine with it). Unconditionally stable for linear springs: ``k Δt²/m`` of 10⁶ only
damps the oscillation, where symplectic Euler diverges once ω_n Δt > 2. Gravity, applied
loads and the scene's damping rates stay explicit. First order; it dissipates energy at the
rate of the stiffest spring the step cannot resolve.
"""

from __future__ import annotations

from dataclasses import dataclass

from .pipeline import NamedStage

VELOCITY, POSITION, INTEGRATE = "integrate_velocity", "integrate_position", "integrate"
# Yoshida's triple-jump weights (Phys. Lett. A 150, 1990): w₁, w₀, w₁ with 2 w₁ + w₀ = 1.
W1 = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))
W0 = -(2.0 ** (1.0 / 3.0)) * W1


@dataclass(frozen=True)
class Integrator:
    """One integrator.

    ``parts`` are its stage names in step order: either ``"integrate"`` (the whole step), or
    ``"integrate_velocity"`` then ``"integrate_position"`` for a semi-implicit method (forces →
    v, ω; then v, ω → x, q), between which contact stages run. ``order`` is the global order
    of accuracy on smooth problems; ``symplectic`` whether the map is symplectic (bounded
    energy error, no drift).
    """

    name: str
    parts: tuple[str, ...]
    order: int
    symplectic: bool
    summary: str = ""

    def __post_init__(self):
        if self.parts not in ((INTEGRATE,), (VELOCITY, POSITION)):
            raise ValueError(
                f"integrator {self.name}: parts must be {INTEGRATE!r} or "
                f"({VELOCITY!r}, {POSITION!r}), got {self.parts}"
            )

    @property
    def semi_implicit(self) -> bool:
        """Velocities are updated first, then positions drift with the new velocities."""
        return self.parts[0] == VELOCITY

    @property
    def contact_capable(self) -> bool:
        """Contacts need the velocity/position split: they act between the two parts."""
        return self.semi_implicit

    def stages(self) -> tuple[NamedStage, ...]:
        """The stage objects of its parts, for a scene's pipeline."""
        return tuple(NamedStage(name) for name in self.parts)


_SEMI = (VELOCITY, POSITION)
_WHOLE = (INTEGRATE,)
RECORDS: dict[str, Integrator] = {
    r.name: r
    for r in (
        Integrator(
            "euler",
            _SEMI,
            order=1,
            symplectic=False,
            summary="the notes' Euler on R with Gram–Schmidt repair; world L exact, energy drifts",
        ),
        Integrator(
            "euler_quat",
            _SEMI,
            order=1,
            symplectic=False,
            summary="the same on quaternions (cheapest); world L exact, energy grows",
        ),
        Integrator(
            "rk4",
            _WHOLE,
            order=4,
            symplectic=False,
            summary="classical Runge–Kutta, 4 force evaluations; drift O(Δt⁴), nothing kept exactly",
        ),
        Integrator(
            "splitting",
            _WHOLE,
            order=2,
            symplectic=True,
            summary="Strang splitting with exact free-rotation sub-flows; world L exact, energy bounded",
        ),
        Integrator(
            "splitting4",
            _WHOLE,
            order=4,
            symplectic=True,
            summary="Yoshida's triple jump of the symmetric splitting step; 3 × splitting",
        ),
        Integrator(
            "exact",
            _WHOLE,
            order=2,
            symplectic=True,
            summary="Strang splitting of the exact torque-free flow with kicks; exact without torque",
        ),
        Integrator(
            "exact4",
            _WHOLE,
            order=4,
            symplectic=True,
            summary="Yoshida's triple jump of the exact Strang step; 3 × exact",
        ),
        Integrator(
            "implicit_gyro",
            _SEMI,
            order=1,
            symplectic=False,
            summary="semi-implicit Euler, implicit gyroscopic term; never blows up, damps fast spin",
        ),
        Integrator(
            "implicit",
            _SEMI,
            order=1,
            symplectic=False,
            summary="linearised backward Euler in springs, dampers and gyroscopic term; stiff springs",
        ),
    )
}
ORDERS: dict[str, int] = {name: r.order for name, r in RECORDS.items()}
CONTACT_CAPABLE: tuple[str, ...] = tuple(n for n, r in RECORDS.items() if r.contact_capable)

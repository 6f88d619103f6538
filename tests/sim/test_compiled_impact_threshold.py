"""The restitution's shortcut (``contact_impacts._may_strike``): an element whose contacts
cannot strike this step skips the impact loop. At the edges of that verdict the step must
still bounce exactly when the impact speed at the closing is above the threshold.

A sphere (radius r, one contact) at height r + d falling at v₀, under gravity g, Δt = 0.01 s.
After the velocity update v_n = v₀ − g Δt; the contact closes at t = d / (−v_n) into the step
and its impact speed there is −w with w = v_n + a (t − Δt/2), a = −g (``restitution``'s
targets). With d = −v_n t, −w = −v₀ + (1/2 + t/Δt) g Δt (touching, t = 0: −v₀ + g Δt/2). A
relative 1e-6 from the threshold (1e-7 m/s) is far above the roundings of these few
operations on numbers of size 0.1 m/s (~1e-17 m/s), so each case is on its side of the
threshold.

After a bounce at speed s the stored velocity is ε s + a (Δt/2 − t) (the step mean of the
outgoing motion): with ε = 0.9, s ≥ 0.1 m/s and t ≥ 0, at least 0.09 − 0.049 = 0.041 m/s
upward, before the energy guard scales it down (keeping its sign).
"""

import pytest

from rigid_env import sim

G = 9.81
DT = 0.01
R = 0.1
THRESHOLD = sim.Ground().restitution_threshold


def sphere_scene():
    ground = sim.Ground(restitution=0.9, friction=0.5)
    return sim.Scene(sim.Body.sphere(R, 1.0), DT, gravity=(0, 0, -G), ground=ground)


def closing_at(fraction, speed):
    """(d, v₀) of a sphere whose contact closes at t = ``fraction`` · Δt into the step with
    impact speed ``speed``: −w = −v_n + g (t − Δt/2) = −v₀ + (1/2 + fraction) g Δt, and
    d = −v_n t."""
    v0 = (0.5 + fraction) * G * DT - speed
    return -(v0 - G * DT) * fraction * DT, v0


CASES = {
    "touching, just above the threshold": (closing_at(0.0, THRESHOLD * (1 + 1e-6)), 1),
    "touching, just below the threshold": (closing_at(0.0, THRESHOLD * (1 - 1e-6)), 0),
    "closing late in the step, fast": (closing_at(0.95, 1.0), 1),
    "closing late, just above the threshold": (closing_at(0.95, THRESHOLD * (1 + 1e-6)), 1),
    "closing late, just below the threshold": (closing_at(0.95, THRESHOLD * (1 - 1e-6)), 0),
}


@pytest.mark.parametrize("name", list(CASES))
def test_a_sphere_bounces_exactly_when_it_strikes_above_the_threshold(name):
    (d, v0), impacts = CASES[name]
    scene = sphere_scene()
    out = scene.step(scene.initial_state(position=(0, 0, R + d), linear_velocity=(0, 0, v0)))
    report = scene.report["contacts"]
    assert report.engaged == 1
    assert report.impacts == impacts
    # A bounce leaves the sphere rising: the energy guard scales v⁺ by the f > 0 with
    # ½ (f v⁺)² + g Δt f v⁺ = ½ v₀² (the bounce's extra energy taken out), which keeps its
    # sign. Without one the contact only holds, v_n = −d/Δt ≤ 0.
    assert (out.linear_velocity[0, 2] > 0.0) == bool(impacts)

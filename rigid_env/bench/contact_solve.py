"""Convergence of the contact solve on the scenes the issue names, for both starts.

For each scene and each ``SolverSettings.start`` it prints the Gauss–Seidel sweeps per step
(mean and max over the steps with a contact), the steps that stopped at the cap, and the
scene's figure of merit (creep speed on the incline, drift of a resting body, yaw picked up by
a box sliding diagonally). Run: ``python -m rigid_env.bench.contact_solve``.
"""

from __future__ import annotations

import warnings

import numpy as np

from rigid_env import sim
from rigid_env.sim.rotation import quat_angle, quat_exp
from rigid_env.sim.scenes import landing_scene

G = 9.81
DT = 1 / 240


def l_prism() -> sim.Body:
    """An L-shaped prism, 0.2 m tall (the resting-polyhedron case of the tests)."""
    outline = [(0, 0), (0.3, 0), (0.3, 0.1), (0.1, 0.1), (0.1, 0.3), (0, 0.3)]
    verts = [(x, y, 0.0) for x, y in outline] + [(x, y, 0.2) for x, y in outline]
    faces = [(5, 4, 3, 2, 1, 0), (6, 7, 8, 9, 10, 11)]
    faces += [(i, (i + 1) % 6, 6 + (i + 1) % 6, 6 + i) for i in range(6)]
    return sim.Body.polyhedron(verts, faces, 1000.0)


def tetrahedron() -> sim.Body:
    verts = [(0, 0, 0), (0.2, 0, 0), (0, 0.2, 0), (0, 0, 0.2)]
    return sim.Body.polyhedron(verts, [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)], 1000.0)


def cases(settings: sim.SolverSettings):
    box = sim.Body.box((0.1, 0.15, 0.2), 1.0)
    down = (0.0, 0.0, -G)

    def resting(body):
        scene = sim.Scene(
            body, DT, gravity=down, ground=sim.Ground(0.3, 0.5), contact_solver=settings
        )
        low = -np.min(body.shape.vertices[:, 2])
        return scene, scene.initial_state(position=(0, 0, low))

    tilt = 0.3  # tan 0.3 = 0.31 < μ = 0.5: static friction must hold
    incline = sim.Scene(
        box,
        DT,
        gravity=(G * np.sin(tilt), 0.0, -G * np.cos(tilt)),
        ground=sim.Ground(0.0, 0.5),
        contact_solver=settings,
    )
    slide = sim.Scene(box, DT, gravity=down, ground=sim.Ground(0.0, 0.5), contact_solver=settings)
    yaw = quat_exp(np.array([0.0, 0.0, 0.4]))
    land, init = landing_scene()
    land = sim.Scene(
        land.model.bodies,
        DT,
        gravity=down,
        ground=land.model.ground,
        contact_solver=settings,
    )
    return {
        "resting box": resting(box),
        "resting L-prism": resting(l_prism()),
        "resting tetrahedron": resting(tetrahedron()),
        "box on incline (0.3 rad, mu 0.5)": (incline, incline.initial_state(position=(0, 0, 0.2))),
        "yawed box sliding diagonally": (
            slide,
            slide.initial_state(
                position=(0, 0, 0.2), orientation=yaw, linear_velocity=(1.5, 1.5, 0.0)
            ),
        ),
        "landing scene, 8 tumbling boxes": (land, init((8,), np.random.default_rng(0))),
    }


def measure(start: str, steps: int = 480) -> list[dict]:
    settings = sim.SolverSettings(start=start)
    out = []
    for name, (scene, state) in cases(settings).items():
        first = state
        sweeps, capped = [], 0
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sim.ContactSolverWarning)
            for _ in range(steps):
                state = scene.step(state)
                report = scene.report["contacts"]
                if report.engaged:
                    sweeps.append(report.iterations)
                capped += report.capped > 0
        drift = float(np.max(np.abs(state.position - first.position)))
        turn = float(np.max(quat_angle(state.orientation, first.orientation)))
        speed = float(np.max(np.linalg.norm(state.linear_velocity, axis=-1)))
        out.append(
            {
                "scene": name,
                "mean_sweeps": float(np.mean(sweeps)) if sweeps else 0.0,
                "max_sweeps": int(np.max(sweeps)) if sweeps else 0,
                "capped_steps": capped,
                "final_speed": speed,
                "drift_m": drift,
                "turn_rad": turn,
            }
        )
    return out


def main() -> None:
    print(
        f"{'start':10s} {'scene':34s} {'sweeps':>7s} {'max':>5s} {'capped':>6s} "
        f"{'|v| end':>9s} {'drift m':>9s} {'turn rad':>9s}"
    )
    for start in ("particle", "active_set"):
        for r in measure(start):
            print(
                f"{start:10s} {r['scene']:34s} {r['mean_sweeps']:7.1f} {r['max_sweeps']:5d} "
                f"{r['capped_steps']:6d} {r['final_speed']:9.2e} {r['drift_m']:9.2e} "
                f"{r['turn_rad']:9.2e}"
            )


if __name__ == "__main__":
    main()

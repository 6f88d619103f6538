"""The debugging mode: with ``NUMBA_DISABLE_JIT=1`` the same kernels and the same step run as
plain Python, and give the compiled step's results.

The landing box starts 5 mm above the ground, falling at 1 m/s, tilted and spinning: its first
steps run every contact kernel (detection, assembly, an impact within the step, the solve, the
energy guard, separation) besides the integrator's two halves. No transcendental function of
Python's ``math`` differs from LLVM's by more than an ulp, and nothing here amplifies an ulp
over 8 steps by more than a few thousand (the solve converges to 1e-12 relative): the two agree
to 1e-12.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]

SCRIPT = """
import json, sys
import numpy as np
from rigid_env.sim.scenes import landing_scene
from rigid_env.sim.rotation import quat_exp

scene, _ = landing_scene(dt=1 / 240)
tilt = quat_exp(np.array([[[0.3, 0.2, 0.0]], [[-0.1, 0.4, 0.2]]]))
state = scene.initial_state(
    position=(0.0, 0.0, 0.3),
    orientation=tilt,
    linear_velocity=(0.0, 0.0, -1.0),
    angular_velocity=(1.0, 2.0, 3.0),
    batch_shape=(2,),
)
# put each box's lowest corner 5 mm above the ground
corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
from rigid_env.sim.rotation import quat_rotate
from rigid_env.sim.scenes import LANDING_HALF_EXTENTS
low = np.array([min(quat_rotate(q[0], c * LANDING_HALF_EXTENTS)[2] for c in corners)
                for q in state.orientation])
position = state.position.copy()
position[:, 0, 2] = 0.005 - low
state = scene.initial_state(position=position, orientation=state.orientation,
                            linear_velocity=state.linear_velocity,
                            angular_velocity=state.angular_velocity)
touched = []
for _ in range(8):
    state = scene.step(state)
    touched.append(scene.report["contacts"].touched.tolist())
step = scene._driver.step
out = {
    "backend": scene.backend,
    "python": type(step).__name__ == "function",
    "touched": touched,
    "state": [a.tolist() for a in state.arrays()],
}
print(json.dumps(out))
"""


def run(disable_jit: bool) -> tuple[dict, str]:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "RIGID_ENV_BACKEND": "compiled"}
    env.pop("NUMBA_DISABLE_JIT", None)
    if disable_jit:
        env["NUMBA_DISABLE_JIT"] = "1"
    proc = subprocess.run(
        [sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, check=True
    )
    return json.loads(proc.stdout.splitlines()[-1]), proc.stderr


def test_the_kernels_run_as_python_and_match_the_compiled_step():
    python, notices = run(disable_jit=True)
    compiled, _ = run(disable_jit=False)
    assert python["backend"] == compiled["backend"] == "compiled"  # the same driver and kernels
    assert python["python"] and not compiled["python"]
    assert any(any(t) for t in python["touched"])  # the contact kernels ran on an impact
    assert python["touched"] == compiled["touched"]
    for ours, theirs in zip(python["state"], compiled["state"], strict=True):
        np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-12)
    assert "compiling" not in notices  # nothing compiles, so nothing is announced

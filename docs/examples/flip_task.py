"""MyTasks/Flip-v0: tip a box resting on the ground over onto a chosen face.

BoxLanding's task with another start: the box rests on one face, the target is another, and the
reaction wheels are strong enough (3 N m) to tip it over any edge (it takes m g d: 1.96 N m at
most). The observation, reward, success and rendering are BoxLanding's.
"""

from dataclasses import dataclass

import gymnasium as gym
import numpy as np

from rigid_env.envs.box_landing import FACE_NORMALS, FACES, BoxLandingConfig, BoxLandingTask
from rigid_env.envs.core import TaskEnv, TaskVectorEnv
from rigid_env.sim.rotation import quat_from_axis_angle, quat_multiply

MAX_EPISODE_STEPS = 150  # 5 s at the default 1/30 s action period


def resting_orientation(face: int) -> np.ndarray:
    """The quaternion that turns the box so that ``face`` points down (the shortest turn)."""
    normal, down = FACE_NORMALS[face], np.array([0.0, 0.0, -1.0])
    axis = np.cross(normal, down)
    if not axis.any():  # -z is down already, or +z: half a turn about x
        axis = np.array([1.0, 0.0, 0.0])
    angle = np.arccos(np.clip(normal @ down, -1.0, 1.0))
    return quat_from_axis_angle(axis / np.linalg.norm(axis), np.array(angle))


@dataclass(frozen=True, kw_only=True, eq=False)
class FlipConfig(BoxLandingConfig):
    max_torque: float = 3.0
    target_face: str | int = "random"


class FlipTask(BoxLandingTask):
    config_class = FlipConfig
    env_name = "MyTasks/Flip-v0"

    def draw_start(self, rng: np.random.Generator) -> np.ndarray:
        return rng.random(3)  # [target face, start face offset from it, yaw]

    def reset_start(self, index: np.ndarray, draws: np.ndarray) -> None:
        if self.random_face:
            target = np.minimum((draws[:, 0] * 6).astype(int), 5)
        else:
            target = np.full(len(index), FACES.index(self.config.target_face))
        start = (target + 1 + np.minimum((draws[:, 1] * 5).astype(int), 4)) % 6
        yaw = quat_from_axis_angle(np.array([0.0, 0.0, 1.0]), 2 * np.pi * draws[:, 2])
        orientation = quat_multiply(yaw, np.stack([resting_orientation(f) for f in start]))
        half = np.asarray(self.body.shape.half_extents)
        position = np.zeros((len(index), 3))
        position[:, 2] = half[start // 2]  # the centre above the face it rests on
        self.set_state(index, position, orientation, np.zeros(3), np.zeros(3), target_face=target)


class FlipEnv(TaskEnv):
    task_class = FlipTask


class FlipVectorEnv(TaskVectorEnv):
    task_class = FlipTask
    default_max_episode_steps = MAX_EPISODE_STEPS


gym.register(
    "MyTasks/Flip-v0",
    entry_point=FlipEnv,
    vector_entry_point=FlipVectorEnv,
    max_episode_steps=MAX_EPISODE_STEPS,
)

"""What an environment shows: the frame size, the camera, and a renderer made on first use.

The keywords are those of Gymnasium's MuJoCo v5 envs: ``width`` and ``height`` in pixels and
``default_camera_config``, a dict of ``distance``, ``azimuth``, ``elevation`` and ``lookat``
(:class:`~rigid_env.envs.rendering.CameraConfig`); keys it does not give keep the task's own
camera. They are checked when the env is made, whatever its ``render_mode``.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from .rendering import CameraConfig, Renderer, camera_config, frame_size

DEFAULT_SIZE = 480  # pixels, width and height


class Display:
    """The rendering state of one env: checked options and the (unpicklable) renderer."""

    def __init__(
        self,
        task: Any,
        render_mode: str | None,
        width: Any = None,
        height: Any = None,
        default_camera_config: Any = None,
    ):
        self.mode = render_mode
        self.width = frame_size(DEFAULT_SIZE if width is None else width, "width")
        self.height = frame_size(DEFAULT_SIZE if height is None else height, "height")
        self.camera: CameraConfig = camera_config(default_camera_config, task.default_camera())
        self._renderer: Renderer | None = None

    def draw(self, task: Any, i: int) -> np.ndarray | None:
        """Env ``i``'s frame: an (height, width, 3) uint8 array in ``rgb_array`` mode, else
        ``None`` (``human`` shows it in a window)."""
        if self.mode is None:
            raise ValueError("render_mode: this env was made without one")
        if self._renderer is None:
            view = replace(task.view(), width=self.width, height=self.height)
            self._renderer = Renderer(self.mode, view, fps=task.render_fps)
        camera = self.camera.camera(task.camera_target(i))
        return self._renderer.draw(task.frame(i), camera)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def __getstate__(self) -> dict[str, Any]:
        state = dict(self.__dict__)
        state["_renderer"] = None  # pygame surfaces and windows do not pickle
        return state

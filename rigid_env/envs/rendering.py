"""A small software renderer for rigid bodies: flat-shaded convex meshes, axes, ghosts, ground.

Pinhole camera, back-face culling and a painter's sort of the visible faces (exact for one convex
body, good enough for a few), Lambert shading from one directional light, drawn with
``pygame.draw`` on an off-screen ``Surface``: that works headless (``SDL_VIDEODRIVER=dummy``), so
``rgb_array`` needs no display. ``human`` blits the same surface to a window at ``fps``.
Shadows are the bodies' faces projected straight down onto the ground (their union is the
shadow of a convex body), drawn before the bodies.
"""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..sim.shapes import Box, Polyhedron, Sphere
from ..sim.validation import finite_array, positive_scalar

AXIS_COLORS = ((220, 60, 60), (60, 190, 80), (70, 120, 235))  # body x, y, z
GHOST_AXIS_COLORS = ((255, 170, 170), (170, 240, 180), (170, 200, 255))
MAX_FRAME_SIZE = 4096  # pixels, the bound of ``width`` and ``height``
MAX_CAMERA_DISTANCE = 1e4  # m


@dataclass(frozen=True)
class Camera:
    """A pinhole camera at ``eye`` looking at ``look_at``; ``up`` fixes the roll (world +z)."""

    eye: tuple[float, float, float]
    look_at: tuple[float, float, float] = (0.0, 0.0, 0.0)
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    fov_deg: float = 35.0


@dataclass(frozen=True)
class CameraConfig:
    """An orbit camera in the terms of MuJoCo's free camera (and its v5 envs'
    ``default_camera_config``): it looks at ``lookat`` from ``distance`` m away, along the
    direction of ``azimuth`` degrees (about world +z from +x) and ``elevation`` degrees (negative:
    from above, looking down). ``lookat=None`` follows a point the task names (its body)."""

    distance: float
    azimuth: float
    elevation: float
    lookat: tuple[float, float, float] | None = None
    fov_deg: float = 35.0

    def camera(self, target: Any = (0.0, 0.0, 0.0)) -> Camera:
        """The pinhole camera, looking at ``lookat`` (or at ``target`` when that is ``None``)."""
        a, e = math.radians(self.azimuth), math.radians(self.elevation)
        forward = np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])
        look = np.asarray(target if self.lookat is None else self.lookat, dtype=float)
        eye = look - self.distance * forward
        return Camera(tuple(eye.tolist()), tuple(look.tolist()), fov_deg=self.fov_deg)


CAMERA_KEYS = ("distance", "azimuth", "elevation", "lookat")


def camera_config(value: Any, default: CameraConfig) -> CameraConfig:
    """``default`` with the entries of ``value`` (a dict of :data:`CAMERA_KEYS`, or ``None``),
    each checked: a ``ValueError`` names ``default_camera_config`` and the key."""
    if value is None:
        return default
    if not isinstance(value, Mapping):
        raise ValueError(
            f"default_camera_config must be a dict with keys from {CAMERA_KEYS}, got {value!r}"
        )
    changes: dict[str, Any] = {}
    for key, item in value.items():
        name = f"default_camera_config[{key!r}]"
        if key not in CAMERA_KEYS:
            raise ValueError(
                f"default_camera_config: unknown key {key!r}; the keys are {CAMERA_KEYS}"
            )
        if key == "lookat":
            point = finite_array(item, name)
            if point.shape != (3,):
                raise ValueError(f"{name} must be a point (x, y, z), got {item!r}")
            changes[key] = tuple(point.tolist())
            continue
        try:
            number = float(item)
        except (TypeError, ValueError):
            raise ValueError(f"{name} must be a number, got {item!r}") from None
        if not math.isfinite(number):
            raise ValueError(f"{name} must be finite, got {item!r}")
        if key == "distance":
            number = positive_scalar(number, name)
            if number > MAX_CAMERA_DISTANCE:
                raise ValueError(f"{name} must be at most {MAX_CAMERA_DISTANCE:g} m, got {item!r}")
        if key == "elevation" and not -90.0 < number < 90.0:
            raise ValueError(f"{name} must lie strictly between -90 and 90 degrees, got {item!r}")
        changes[key] = number
    return replace(default, **changes)


def frame_size(value: Any, name: str) -> int:
    """A frame's ``width`` or ``height``: an integer number of pixels in [1, MAX_FRAME_SIZE]."""
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, np.integer))
        or not 1 <= value <= MAX_FRAME_SIZE
    ):
        raise ValueError(
            f"{name} must be an integer in [1, {MAX_FRAME_SIZE}] pixels, got {value!r}"
        )
    return int(value)


@dataclass(frozen=True)
class View:
    """Everything about the picture but the camera: its size and scenery."""

    width: int = 480
    height: int = 480
    ground: bool = False  # draw the plane z = 0 (a checkerboard) and the bodies' shadows
    ground_extent: float = 3.0  # half-width of the drawn ground square, m
    ground_cell: float = 0.5  # checker size, m
    background: tuple[tuple[int, int, int], tuple[int, int, int]] = ((12, 16, 34), (40, 48, 80))


@dataclass(frozen=True, eq=False)
class Mesh:
    """A closed convex polygon mesh in body coordinates: vertices (V, 3), faces as index loops."""

    vertices: np.ndarray
    faces: tuple[tuple[int, ...], ...]
    edges: np.ndarray = field(init=False)  # (E, 2) unique vertex pairs

    def __post_init__(self) -> None:
        pairs = {
            tuple(sorted((f[k], f[(k + 1) % len(f)]))) for f in self.faces for k in range(len(f))
        }
        object.__setattr__(self, "edges", np.array(sorted(pairs), dtype=np.intp))

    @classmethod
    def from_shape(cls, shape: Box | Sphere | Polyhedron) -> Mesh:
        if isinstance(shape, Box):
            # Box.vertices index = 4 ix + 2 iy + iz; each loop walks one face's corners in order.
            loops = (
                (0, 1, 3, 2),
                (4, 5, 7, 6),
                (0, 1, 5, 4),
                (2, 3, 7, 6),
                (0, 2, 6, 4),
                (1, 3, 7, 5),
            )
            return cls(np.asarray(shape.vertices, float), loops)
        if isinstance(shape, Polyhedron):
            return cls(np.asarray(shape.vertices, float), tuple(tuple(f) for f in shape.faces))
        if isinstance(shape, Sphere):
            return cls.uv_sphere(shape.radius)
        raise ValueError(f"cannot draw shape {shape!r}; give a Box, Sphere or Polyhedron")

    @classmethod
    def uv_sphere(cls, radius: float, rings: int = 8, segments: int = 14) -> Mesh:
        theta = np.pi * np.arange(1, rings) / rings  # polar angles of the inner rings
        phi = 2 * np.pi * np.arange(segments) / segments
        ring = np.stack(
            (
                np.sin(theta)[:, None] * np.cos(phi),
                np.sin(theta)[:, None] * np.sin(phi),
                np.cos(theta)[:, None] * np.ones_like(phi),
            ),
            axis=-1,
        ).reshape(-1, 3)
        verts = np.vstack(([0.0, 0.0, 1.0], ring, [0.0, 0.0, -1.0])) * radius
        bottom = len(verts) - 1

        def idx(r: int, s: int) -> int:
            return 1 + r * segments + s % segments

        faces: list[tuple[int, ...]] = [(0, idx(0, s), idx(0, s + 1)) for s in range(segments)]
        faces += [
            (idx(r, s), idx(r + 1, s), idx(r + 1, s + 1), idx(r, s + 1))
            for r in range(rings - 2)
            for s in range(segments)
        ]
        faces += [(idx(rings - 2, s), bottom, idx(rings - 2, s + 1)) for s in range(segments)]
        return cls(verts, tuple(faces))


@dataclass(frozen=True, eq=False)
class Item:
    """A mesh placed in the world: world point = ``position + rotation @ body point``."""

    mesh: Mesh
    rotation: np.ndarray
    position: np.ndarray
    color: tuple[int, int, int] = (200, 200, 210)
    axes_length: float = 0.0  # draw the body axes this long (m); 0 = no axes


@dataclass(frozen=True)
class Frame:
    """One picture: solid bodies, ghost wireframes (e.g. a target pose), lines of text."""

    bodies: Sequence[Item]
    ghosts: Sequence[Item] = ()
    text: Sequence[str] = ()


class Renderer:
    """Draws :class:`Frame` s of a fixed :class:`View` through a :class:`Camera` given per
    frame; ``rgb_array`` returns (H, W, 3) uint8."""

    def __init__(self, render_mode: str, view: View, fps: float = 30.0):
        # Gymnasium hides pygame's greeting as well; set here too, for any import order.
        os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
        try:
            import pygame
        except ImportError as e:  # pragma: no cover - pygame is in the render extra
            from gymnasium.error import DependencyNotInstalled

            raise DependencyNotInstalled(
                'rendering needs pygame: pip install "rigid-env[render]"'
            ) from e
        if render_mode not in ("human", "rgb_array"):
            raise ValueError(f"render_mode must be 'human' or 'rgb_array', got {render_mode!r}")
        self._pg = pygame
        self.mode, self.view, self.fps = render_mode, view, float(fps)
        self.size = (int(view.width), int(view.height))
        self.surface = pygame.Surface(self.size)
        self.window: Any = None  # pygame objects, created on first use
        self.clock: Any = None
        self._background = self._gradient(view)
        self._font: Any = None
        self._camera: Camera | None = None
        self._light = np.array([0.35, -0.45, 0.82])
        self._light /= np.linalg.norm(self._light)

    # --- camera ---------------------------------------------------------------------------------

    def set_camera(self, cam: Camera) -> None:
        """Look through ``cam`` from the next frame on (and for :meth:`project`)."""
        if cam == self._camera:
            return
        self._camera = cam
        eye, target = np.asarray(cam.eye, float), np.asarray(cam.look_at, float)
        forward = target - eye
        forward /= np.linalg.norm(forward)
        right = np.cross(forward, np.asarray(cam.up, float))
        right /= np.linalg.norm(right)
        self._eye = eye
        self._axes = np.stack((right, np.cross(right, forward), forward))  # rows: x, y, depth
        self._focal = 0.5 * self.size[1] / np.tan(np.radians(cam.fov_deg) / 2)

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Screen pixels (..., 2) and depth (...) of world points (..., 3)."""
        cam = (points - self._eye) @ self._axes.T
        depth = cam[..., 2]
        z = np.maximum(depth, 1e-6)
        px = 0.5 * self.size[0] + self._focal * cam[..., 0] / z
        py = 0.5 * self.size[1] - self._focal * cam[..., 1] / z
        return np.stack((px, py), axis=-1), depth

    # --- drawing --------------------------------------------------------------------------------

    @staticmethod
    def _gradient(view: View) -> np.ndarray:
        top, bottom = (np.array(c, float) for c in view.background)
        t = np.linspace(0.0, 1.0, view.height)[None, :, None]
        return np.broadcast_to(top + t * (bottom - top), (view.width, view.height, 3)).astype(
            np.uint8
        )

    def draw(self, frame: Frame, camera: Camera | None = None) -> np.ndarray | None:
        """Draw ``frame`` through ``camera`` (default: the last one set)."""
        if camera is not None:
            self.set_camera(camera)
        if self._camera is None:
            raise ValueError("camera: no camera set; pass one to draw() or set_camera()")
        pg = self._pg
        pg.surfarray.blit_array(self.surface, self._background)
        if self.view.ground:
            self._draw_ground()
            for item in frame.bodies:
                self._draw_shadow(item)
        self._draw_solids(frame.bodies)
        for item in frame.bodies:
            self._draw_axes(item, AXIS_COLORS, width=3)
        for item in frame.ghosts:
            self._draw_wire(item)
            self._draw_axes(item, GHOST_AXIS_COLORS, width=1)
        self._draw_text(frame.text)
        if self.mode == "rgb_array":
            return np.transpose(pg.surfarray.array3d(self.surface), (1, 0, 2))
        self._show()
        return None

    def _world(self, item: Item) -> np.ndarray:
        return item.position + item.mesh.vertices @ np.asarray(item.rotation).T

    def _draw_solids(self, items: Sequence[Item]) -> None:
        polygons = []  # (depth, points, colour)
        for item in items:
            world = self._world(item)
            screen, depth = self.project(world)
            centre = world.mean(axis=0)
            base = np.array(item.color, float)
            for face in item.mesh.faces:
                pts = world[list(face)]
                mid = pts.mean(axis=0)
                normal = np.cross(pts[1] - pts[0], pts[2] - pts[0])
                if normal @ (mid - centre) < 0:  # orient outward whatever the loop direction
                    normal = -normal
                if normal @ (self._eye - mid) <= 0 or np.any(depth[list(face)] <= 1e-3):
                    continue  # back face, or behind the camera
                normal /= np.linalg.norm(normal)
                shade = 0.35 + 0.65 * max(0.0, float(normal @ self._light))
                colour = tuple(int(c) for c in np.clip(base * shade, 0, 255))
                polygons.append((float(depth[list(face)].mean()), screen[list(face)], colour))
        for _, pts, colour in sorted(polygons, key=lambda p: -p[0]):
            self._pg.draw.polygon(self.surface, colour, pts.tolist())
            self._pg.draw.aalines(self.surface, (20, 20, 25), True, pts.tolist())

    def _draw_axes(self, item: Item, colours: Sequence[tuple[int, int, int]], width: int) -> None:
        if item.axes_length <= 0:
            return
        ends = item.position + item.axes_length * np.asarray(item.rotation).T  # rows: R e_i
        (origin, *tips), depth = self.project(np.vstack((item.position, ends)))
        if np.any(depth <= 1e-3):
            return
        for tip, colour in zip(tips, colours, strict=True):
            self._pg.draw.line(self.surface, colour, origin.tolist(), tip.tolist(), width)

    def _draw_wire(self, item: Item) -> None:
        screen, depth = self.project(self._world(item))
        for a, b in item.mesh.edges:
            if depth[a] > 1e-3 and depth[b] > 1e-3:
                self._pg.draw.aaline(
                    self.surface, (235, 235, 245), screen[a].tolist(), screen[b].tolist()
                )

    def _draw_ground(self) -> None:
        v = self.view
        look_at = np.asarray(self._camera.look_at[:2] if self._camera else (0.0, 0.0))
        cx, cy = np.round(look_at / v.ground_cell) * v.ground_cell
        n = int(np.ceil(v.ground_extent / v.ground_cell))
        cells = []
        for i in range(-n, n):
            for j in range(-n, n):
                x0, y0 = cx + i * v.ground_cell, cy + j * v.ground_cell
                x1, y1 = x0 + v.ground_cell, y0 + v.ground_cell
                quad = np.array([[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0]], float)
                screen, depth = self.project(quad)
                if np.all(depth > 1e-2):
                    colour = (150, 150, 140) if (i + j) % 2 else (125, 125, 118)
                    cells.append((depth.mean(), screen, colour))
        for _, screen, colour in sorted(cells, key=lambda c: -c[0]):
            self._pg.draw.polygon(self.surface, colour, screen.tolist())

    def _draw_shadow(self, item: Item) -> None:
        flat = self._world(item) * np.array([1.0, 1.0, 0.0])
        screen, depth = self.project(flat)
        for face in item.mesh.faces:
            if np.all(depth[list(face)] > 1e-2):
                self._pg.draw.polygon(self.surface, (60, 60, 58), screen[list(face)].tolist())

    def _draw_text(self, lines: Sequence[str]) -> None:
        if not lines:
            return
        pg = self._pg
        if self._font is None or not pg.font.get_init():
            try:
                pg.font.init()
                self._font = pg.font.Font(None, 20)
            except (pg.error, FileNotFoundError):  # pragma: no cover - fonts missing
                return
        for k, line in enumerate(lines):
            self.surface.blit(self._font.render(line, True, (235, 235, 235)), (8, 6 + 18 * k))

    def _show(self) -> None:
        pg = self._pg
        # pygame has one display: another renderer's close() may have shut it, so re-open then.
        if self.window is None or not pg.display.get_init():
            _init_display(pg)
            self.window = pg.display.set_mode(self.size)
            pg.display.set_caption("rigid_env")
            self.clock = pg.time.Clock()
        pg.event.pump()
        self.window.blit(self.surface, (0, 0))
        pg.display.flip()
        self.clock.tick(self.fps)

    def close(self) -> None:
        if self.window is not None:
            self._pg.display.quit()
            self.window = None


def _init_display(pg: Any) -> None:
    """``pygame.display.init()``; without a display to open (a headless Linux machine: no
    ``DISPLAY`` or ``WAYLAND_DISPLAY``) and no ``SDL_VIDEODRIVER`` chosen, SDL's offscreen
    driver directly. SDL would end there anyway, after printing an error about
    ``XDG_RUNTIME_DIR`` for each display driver it tried; the window then shows nothing."""
    headless = (
        sys.platform.startswith("linux")
        and not os.environ.get("DISPLAY")
        and not os.environ.get("WAYLAND_DISPLAY")
        and "SDL_VIDEODRIVER" not in os.environ
    )
    if not headless:
        pg.display.init()
        return
    os.environ["SDL_VIDEODRIVER"] = "offscreen"
    try:
        pg.display.init()
    finally:
        del os.environ["SDL_VIDEODRIVER"]

"""Pictures of a recorded run: a PNG frame or strip, or an animated GIF, drawn offscreen.

Rendering *replays* ``world.trajectory`` over the world's road network after the run, so
simulation never pays for drawing and any recorded case can be drawn later. Frames are
plain ``pygame.Surface`` objects (no display is ever opened, so no ``SDL_VIDEODRIVER``
setting matters); lane markings come from highway-env's ``LaneGraphics``, while asphalt,
stop lines, crosswalks, vehicles, the bus with its stop arm and pedestrians are drawn here.
The picture is north-up (highway-env's own viewer draws y downward, mirroring the scene).
Images are written with Pillow.
"""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np

__all__ = ["render_png", "render_gif", "frame"]

GRASS = (96, 128, 86)
ASPHALT = (72, 72, 76)
PARKING = (92, 92, 98)
WHITE = (240, 240, 240)
COLOURS = {
    "ego": (60, 200, 80),
    "car": (90, 150, 230),
    "bus": (250, 190, 20),
    "parked": (150, 150, 160),
    "pedestrian": (230, 60, 200),
}
CRASH = (255, 40, 40)


def _pygame() -> Any:
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    import pygame

    return pygame


def _surface_class() -> Any:
    from highway_env.road.graphics import WorldSurface

    class NorthUpSurface(WorldSurface):
        """highway-env's world surface with y pointing up; ``origin`` is the top-left corner."""

        def pos2pix(self, x: float, y: float) -> tuple[int, int]:
            return int((x - self.origin[0]) * self.scaling), int((self.origin[1] - y) * self.scaling)

        def is_visible(self, vec: Any, margin: int = 50) -> bool:
            x, y = self.vec2pix(vec)
            return -margin < x < self.get_width() + margin and -margin < y < self.get_height() + margin

    return NorthUpSurface


def _view(world: Any, step: int, centre: Any = None,
          width: float | None = None) -> tuple[tuple[int, int], float, np.ndarray]:
    """(size [px], scale [px/m], world point at the top-left corner [m]) for a frame.

    Default: the whole intersection; on a road network a 110 m square following the ego; a
    133 m window following the ego on other roads. ``centre`` (an (x, y) [m], a place, or an
    agent name) fixes the window's centre and ``width`` [m] its width.
    """
    tr = world.trajectory
    road = world.road
    box = world.lane_index.boxes
    if road.kind == "intersection":
        size = (640, 640)
        half = road.half + min(road.approach_length, 28.0)
        cx, cy = 0.0, 0.0
        scale = size[0] / (2 * half)
    elif road.kind == "network":
        size = (640, 640)
        scale = size[0] / 110.0
        x0, y0 = float(tr.x[0, step]), float(tr.y[0, step])
        if math.isfinite(x0) and math.isfinite(y0):
            cx, cy = x0, y0
        else:
            cx, cy = float(box[:, 0].min() + box[:, 2].max()) / 2, \
                float(box[:, 1].min() + box[:, 3].max()) / 2
    else:
        size = (800, 320)
        scale = 6.0
        x0 = float(tr.x[0, step])
        cx = x0 + size[0] / scale / 6 if math.isfinite(x0) else 0.0
        cy = float(box[:, 1].min() + box[:, 3].max()) / 2
        if road.kind == "highway":
            # Curves and ramps: follow the ego both ways, a little ahead of it.
            y0, h0 = float(tr.y[0, step]), float(tr.heading[0, step])
            if math.isfinite(x0) and math.isfinite(y0):
                ahead = size[0] / scale / 6
                cx, cy = x0 + ahead * math.cos(h0), y0 + ahead * math.sin(h0)
    if width is not None:
        scale = size[0] / float(width)
    if centre is not None:
        if isinstance(centre, str):
            i = tr.names.index(centre)
            centre = (tr.x[i, step], tr.y[i, step])
        elif hasattr(centre, "position"):
            centre = centre.position
        cx, cy = float(centre[0]), float(centre[1])
    w, h = size[0] / scale, size[1] / scale
    return size, scale, np.array([cx - w / 2, cy + h / 2])


def _poly(surface: Any, lane: Any, r0: float, r1: float, s0: float, s1: float) -> list:
    g = lane.geometry
    ss = np.linspace(s0, s1, max(2, int((s1 - s0) // 2) + 2))
    left = [surface.vec2pix(g.position(s, r1)) for s in ss]
    right = [surface.vec2pix(g.position(s, r0)) for s in ss[::-1]]
    return left + right


def frame(world: Any, step: int, centre: Any = None, width: float | None = None) -> Any:
    """The ``pygame.Surface`` of recorded ``step`` (view options as :func:`_view`)."""
    pygame = _pygame()
    from highway_env.road.graphics import LaneGraphics

    tr = world.trajectory
    if tr is None:
        from .errors import SimError

        raise SimError("nothing to render: call world.run() first", test=world.name)
    step = int(step) % tr.n_steps
    size, scale, origin = _view(world, step, centre, width)
    Surf = _surface_class()
    surface = Surf(size, 0, pygame.Surface(size))
    surface.scaling = scale
    surface.origin = origin
    surface.fill(GRASS)
    lanes = world.lane_index.order
    # Asphalt first, then markings, so lane lines stay visible over neighbouring lanes. The
    # box of an intersection is paved whole (its lanes alone leave the middle between the
    # turns and any median unpaved).
    road = world.road
    boxes = ([road] if road.kind == "intersection" else
             list(road.intersections.values()) if road.kind == "network" else [])
    for inter in boxes:
        cx, cy, h = inter.centre.x, inter.centre.y, inter.half
        pygame.draw.polygon(surface, ASPHALT, [surface.vec2pix(p) for p in (
            (cx - h, cy - h), (cx + h, cy - h), (cx + h, cy + h), (cx - h, cy + h))])
    for lane in lanes:
        w = lane.width
        colour = PARKING if lane.kind == "parking" else ASPHALT
        pygame.draw.polygon(surface, colour, _poly(surface, lane, -w / 2, w / 2, 0.0, lane.length))
    for lane in lanes:
        LaneGraphics.display(lane.geometry, surface)
    for end in getattr(road, "lane_ends", []):
        # Where a lane ends with traffic in it (a lane drop, an acceleration lane): a hatch.
        g, w = end.lane.geometry, end.lane.width
        for r in np.linspace(-w / 2, w / 2, 4):
            pygame.draw.line(surface, WHITE, surface.vec2pix(g.position(end.s - 3.0, r)),
                             surface.vec2pix(g.position(end.s, r - w / 4)), max(1, int(0.2 * scale)))
        pygame.draw.line(surface, WHITE, surface.vec2pix(g.position(end.s, -w / 2)),
                         surface.vec2pix(g.position(end.s, w / 2)), max(2, int(0.3 * scale)))
    for cw in getattr(road, "crosswalks", []):
        _draw_crosswalk(pygame, surface, cw)
    for sl in getattr(road, "stop_lines", []):
        g = sl.lane.geometry
        w = sl.lane.width
        pygame.draw.line(surface, WHITE, surface.vec2pix(g.position(sl.s, -w / 2)),
                         surface.vec2pix(g.position(sl.s, w / 2)), max(2, int(0.4 * scale)))
    arms = {name[: -len(".stop_arm")]: v for name, v in tr.signals.items()
            if name.endswith(".stop_arm")}
    order = sorted(range(tr.n_agents), key=lambda i: tr.kinds[i] == "pedestrian")
    for i in order:
        if not tr.present[i, step]:
            continue
        x, y, h = tr.x[i, step], tr.y[i, step], tr.heading[i, step]
        kind = tr.kinds[i]
        colour = COLOURS.get(kind, COLOURS["car"])
        crashed = bool(tr.crashed[i, step])
        if kind == "pedestrian":
            c = surface.vec2pix((x, y))
            rad = max(4, int(0.5 * scale))
            pygame.draw.circle(surface, colour, c, rad)
            pygame.draw.circle(surface, CRASH if crashed else (20, 20, 20), c, rad, 2 if crashed else 1)
            continue
        L, W = tr.length[i], tr.width[i]
        ch, sh = math.cos(h), math.sin(h)
        corners = [(x + ch * a - sh * b, y + sh * a + ch * b)
                   for a, b in ((L / 2, W / 2), (L / 2, -W / 2), (-L / 2, -W / 2), (-L / 2, W / 2))]
        pix = [surface.vec2pix(p) for p in corners]
        pygame.draw.polygon(surface, colour, pix)
        pygame.draw.polygon(surface, CRASH if crashed else (20, 20, 20), pix, 3 if crashed else 1)
        # A windscreen stripe shows which way the vehicle faces.
        fa, fb = (x + ch * (L / 2 - 1.2) - sh * W / 2.5, y + sh * (L / 2 - 1.2) + ch * W / 2.5), \
                 (x + ch * (L / 2 - 1.2) + sh * W / 2.5, y + sh * (L / 2 - 1.2) - ch * W / 2.5)
        pygame.draw.line(surface, (30, 30, 30), surface.vec2pix(fa), surface.vec2pix(fb),
                         max(1, int(0.3 * scale)))
        name = tr.names[i]
        if name in arms and arms[name][step] > 0.5:
            # The stop arm swings out on the driver's (left) side behind the front door.
            ax, ay = x + ch * (L / 2 - 2.0) - sh * (W / 2 + 0.8), y + sh * (L / 2 - 2.0) + ch * (W / 2 + 0.8)
            pygame.draw.circle(surface, CRASH, surface.vec2pix((ax, ay)), max(3, int(0.6 * scale)))
    _label(pygame, surface, f"t = {tr.t[step]:.1f} s")
    return surface


def _draw_crosswalk(pygame: Any, surface: Any, cw: Any) -> None:
    pts = cw.path.array
    a, b = pts[0], pts[-1]
    d = b - a
    length = float(np.hypot(*d))
    u = d / length
    n = np.array([-u[1], u[0]])
    k = 0.0
    while k < length - 0.3:
        k0, k1 = k + 0.3, min(k + 0.9, length)
        quad = [a + u * k0 + n * cw.width / 2, a + u * k1 + n * cw.width / 2,
                a + u * k1 - n * cw.width / 2, a + u * k0 - n * cw.width / 2]
        pygame.draw.polygon(surface, WHITE, [surface.vec2pix(q) for q in quad])
        k += 1.2


def _label(pygame: Any, surface: Any, text: str) -> None:
    try:
        if not pygame.font.get_init():
            pygame.font.init()
        font = pygame.font.Font(None, 22)
    except Exception:  # no font support in this pygame build: frames stay unlabelled
        return
    surface.blit(font.render(text, True, (255, 255, 255), (30, 30, 30)), (6, 6))


def _image(surface: Any) -> Any:
    pygame = _pygame()
    from PIL import Image

    arr = pygame.surfarray.array3d(surface).swapaxes(0, 1)
    return Image.fromarray(np.ascontiguousarray(arr))


def render_png(world: Any, path: str, step: int | None = None, frames: int = 6,
               centre: Any = None, width: float | None = None) -> str:
    """One frame at ``step`` or, with ``step=None``, a grid of ``frames`` evenly spaced frames.

    ``centre``/``width`` [m] fix the view (default: follow the ego; whole intersection).
    """
    from PIL import Image

    tr = world.trajectory
    if step is not None:
        _image(frame(world, step, centre, width)).save(path)
        return os.fspath(path)
    n = tr.n_steps if tr is not None else 0
    steps = sorted(set(np.linspace(0, max(n - 1, 0), frames).round().astype(int).tolist()))
    images = [_image(frame(world, s, centre, width)) for s in steps]
    w, h = images[0].size
    cols = 2 if w > h else 3
    rows = math.ceil(len(images) / cols)
    sheet = Image.new("RGB", (cols * w, rows * h), (0, 0, 0))
    for k, im in enumerate(images):
        sheet.paste(im, ((k % cols) * w, (k // cols) * h))
    sheet.save(path)
    return os.fspath(path)


def render_gif(world: Any, path: str, every: int = 1, centre: Any = None,
               width: float | None = None) -> str:
    """An animated GIF of every ``every``-th recorded step, at real-time speed (view as PNG)."""
    tr = world.trajectory
    if tr is None:
        from .errors import SimError

        raise SimError("nothing to render: call world.run() first", test=world.name)
    from PIL import Image

    every = max(1, int(every))
    images = [_image(frame(world, s, centre, width)).convert("P", palette=Image.Palette.ADAPTIVE,
                                                             colors=64)
              for s in range(0, tr.n_steps, every)]
    images[0].save(path, save_all=True, append_images=images[1:],
                   duration=max(20, int(round(1000 * tr.dt * every))), loop=0)
    return os.fspath(path)

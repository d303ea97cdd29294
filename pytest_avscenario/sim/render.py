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

__all__ = ["render_png", "render_gif", "render_moment", "frame"]

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

    The view of :func:`view_spec` at ``step``; ``centre`` (an (x, y) [m], a place, or an
    agent name) fixes the window's centre and ``width`` [m] its width.
    """
    from .replay import view_spec

    tr = world.trajectory
    box = world.lane_index.boxes
    size, scale, cx, cy, lead, along = view_spec(world)
    x0, y0 = float(tr.x[0, step]), float(tr.y[0, step])
    ego_here = math.isfinite(x0) and math.isfinite(y0)
    if along and ego_here:  # curves and ramps: the ego's heading says where "ahead" is
        h0 = float(tr.heading[0, step])
        cx, cy = x0 + lead * math.cos(h0), y0 + lead * math.sin(h0)
    elif along:
        cx, cy = 0.0, float(box[:, 1].min() + box[:, 3].max()) / 2
    if cx is None:
        cx = x0 + lead if ego_here else (
            float(box[:, 0].min() + box[:, 2].max()) / 2 if cy is None else 0.0)
    if cy is None:
        cy = y0 if ego_here else float(box[:, 1].min() + box[:, 3].max()) / 2
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


def frame(world: Any, step: int, centre: Any = None, width: float | None = None,
          clock: bool = True) -> Any:
    """The ``pygame.Surface`` of recorded ``step`` (view options as :func:`_view`); ``clock``
    writes its time in the top-left corner."""
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
    if clock:
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


# -- the annotated still -------------------------------------------------------------------------

HIGHLIGHT = (255, 150, 0)
INK = (25, 25, 28)
PAPER = (250, 250, 250)


def _font(pygame: Any, size: int) -> Any:
    try:
        if not pygame.font.get_init():
            pygame.font.init()
        return pygame.font.Font(None, size)
    except Exception:  # no font support in this pygame build: the still has no text
        return None


def _arrow(pygame: Any, surface: Any, a: tuple[int, int], b: tuple[int, int], colour: tuple, width: int) -> None:
    pygame.draw.line(surface, colour, a, b, width)
    dx, dy = b[0] - a[0], b[1] - a[1]
    n = math.hypot(dx, dy)
    if n < 4:
        return
    ux, uy = dx / n, dy / n
    head = min(10.0, n / 2)
    left = (b[0] - ux * head - uy * head * 0.6, b[1] - uy * head + ux * head * 0.6)
    right = (b[0] - ux * head + uy * head * 0.6, b[1] - uy * head - ux * head * 0.6)
    pygame.draw.polygon(surface, colour, [b, left, right])


def _nice_length(metres: float) -> float:
    """The scale bar's length [m]: the largest of 1, 2, 5, 10, 20, 50 … not above ``metres``."""
    best = 1.0
    for decade in (1, 10, 100, 1000):
        for m in (1, 2, 5):
            if m * decade <= metres:
                best = float(m * decade)
    return best


def render_moment(world: Any, path: str, data: Any, k: int | None = None,
                  title: str | None = None) -> dict[str, Any]:
    """Write the annotated still of frame ``k`` (default: the first violation) of replay
    ``data`` (:func:`~.replay.replay_data` of ``world``) as a palette PNG at ``path``.

    Above the scene the title (``title`` or the data's) with the time; in the scene every agent
    labelled with its name and speed, a velocity arrow per agent (as long as the distance it
    covers in :data:`~.replay.ARROW_S` s), the critical agent ringed, a scale bar; below it
    the metric values of the frame (:func:`~.replay.frame_lines`). Returns what was drawn:
    ``{"path", "t", "step", "labels", "critical", "lines"}``.
    """
    from PIL import Image

    from .replay import decoded, frame_lines

    pygame = _pygame()
    tr = world.trajectory
    k = int(data["first"] if k is None else k)
    data = decoded(data)
    t = float(data["t"][k])
    step = int(np.argmin(np.abs(tr.t - t)))
    surface = frame(world, step, clock=False)
    size, scale, origin = _view(world, step)
    font = _font(pygame, 19)
    small = _font(pygame, 17)
    agents = data["agents"]
    critical = data.get("critical")
    pix = surface.vec2pix
    for a in agents:
        x, y, h, v = a["x"][k], a["y"][k], a["h"][k], a["v"][k]
        if x is None:
            continue
        c = pix((x, y))
        if a["name"] == critical:
            rad = max(10, int((max(a["L"], a["W"]) / 2 + 1.2) * scale))
            pygame.draw.circle(surface, HIGHLIGHT, c, rad, 3)
        if v is not None and abs(v) > 0.05:
            hr = math.radians(h)
            length = v * data.get("arrow_s", 1.0)
            tip = pix((x + math.cos(hr) * length, y + math.sin(hr) * length))
            _arrow(pygame, surface, c, tip, (255, 255, 255), 2)
    # the scale bar, bottom left
    metres = _nice_length(size[0] / scale / 6)
    bar = int(metres * scale)
    x0, y0 = 12, size[1] - 14
    legend = small.render(f"{metres:g} m   arrows: {data.get('arrow_s', 1.0):g} s of travel", True, PAPER) \
        if small is not None else None
    box_w = max(bar, legend.get_width() if legend is not None else 0) + 12
    scale_box = pygame.Rect(x0 - 6, y0 - 26, box_w, 34)
    pygame.draw.rect(surface, (35, 35, 40), scale_box)
    pygame.draw.line(surface, PAPER, (x0, y0), (x0 + bar, y0), 3)
    for xx in (x0, x0 + bar):
        pygame.draw.line(surface, PAPER, (xx, y0 - 5), (xx, y0 + 3), 2)
    if legend is not None:
        surface.blit(legend, (x0, y0 - 22))
    labels: list[str] = []
    taken: list[Any] = [scale_box]  # labels keep off the scale bar and off each other
    order = sorted(range(len(agents)), key=lambda i: (agents[i]["name"] != critical, i))
    for i in order:
        a = agents[i]
        x, y, v = a["x"][k], a["y"][k], a["v"][k]
        if x is None:
            continue
        cx, cy = pix((x, y))
        text = f"{a['name']} {0.0 if v is None else v:.1f} m/s"
        if not surface.get_rect().collidepoint(cx, cy):
            text += " (out of view)"
        labels.append(a["name"])
        if font is None:
            continue
        hot = a["name"] == critical
        img = font.render(text, True, INK if hot else PAPER, HIGHLIGHT if hot else (35, 35, 40))
        off = int((max(a["L"], a["W"]) / 2 + 1.5) * scale) + 4
        # the ego's label below it, the others' above (inside the picture, for an agent out of
        # view too); moved on until it overlaps no other label, upward at the bottom edge
        rect = img.get_rect(midtop=(cx, cy + off)) if i == 0 else img.get_rect(midbottom=(cx, cy - off))
        rect.clamp_ip(surface.get_rect())
        down = i == 0 and rect.bottom < surface.get_height() - 2 * rect.height
        for _ in range(8):
            if rect.collidelist(taken) < 0:
                break
            rect.move_ip(0, rect.height + 2 if down else -(rect.height + 2))
        rect.clamp_ip(surface.get_rect())
        taken.append(rect)
        end = (min(max(cx, rect.left), rect.right), rect.top if rect.top > cy else rect.bottom)
        pygame.draw.line(surface, HIGHLIGHT if hot else (35, 35, 40), (cx, cy), end, 1)
        surface.blit(img, rect)
    scene = _image(surface)
    # pygame's built-in font has no infinity sign
    lines = [line.replace("∞", "inf") for line in frame_lines(data, k)]
    head = title or data.get("title") or ""
    head = f"{head} — {lines[0]}" if head else lines[0]
    band = 24
    out = Image.new("RGB", (size[0], band + size[1] + band * (len(lines) - 1) + 6), (245, 245, 245))
    out.paste(scene, (0, band))
    if font is not None:
        text = pygame.Surface((size[0], out.height), 0, 24)
        text.fill((245, 245, 245))
        text.blit(font.render(head, True, INK), (6, 4))
        for n, line in enumerate(lines[1:]):
            text.blit(font.render(line, True, INK), (6, band + size[1] + 4 + n * band))
        strip = _image(text)
        out.paste(strip.crop((0, 0, size[0], band)), (0, 0))
        out.paste(strip.crop((0, band + size[1], size[0], out.height)), (0, band + size[1]))
    _save_atomic(out.convert("P", palette=Image.Palette.ADAPTIVE, colors=32), path)  # flat colours: 32 suffice
    return {"path": os.fspath(path), "t": t, "step": step, "labels": labels, "critical": critical,
            "lines": lines}


def _save_atomic(image: Any, path: str | os.PathLike) -> None:
    """Save a Pillow image as PNG so readers never see half a file (not fsynced: one of a
    report's many per-case files)."""
    import io

    from ..report.folder import atomic_write_bytes

    buf = io.BytesIO()
    image.save(buf, format="PNG", optimize=True)
    atomic_write_bytes(path, buf.getvalue(), durable=False)

"""Pictures of a recorded run: a PNG frame or strip, or an animated GIF, drawn offscreen.

Rendering *redraws* ``world.trajectory`` over the world's road network after the run, so
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
    "truck": (200, 110, 60),
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
    from .clip import view_spec

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
    if road.kind == "map":  # the lanes in view, in their real shape (sidewalks too)
        from .map_render import draw

        draw(road, surface, pygame)
        lanes = []
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
    _draw_lights(pygame, surface, tr, step, scale)
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


#: a traffic light's state colours (green, amber, red), as the recording codes them 0, 1, 2
LIGHT_COLOURS = ((40, 200, 80), (255, 185, 0), (230, 30, 30))


def _draw_lights(pygame: Any, surface: Any, tr: Any, step: int, scale: float) -> None:
    """Each recorded traffic light in its state at ``step``: a bar across every lane it
    stops (at the stop position) and its head, a dark box with the lit lamp, where it stands."""
    for light in (tr.meta or {}).get("lights", ()):
        codes = tr.signals.get(f"light.{light['id']}")
        if codes is None:
            continue
        code = int(codes[step])
        colour = LIGHT_COLOURS[min(max(code, 0), 2)]
        for stop in light.get("stops", ()):
            h, half = stop["heading"], stop["width"] / 2
            nx, ny = -math.sin(h) * half, math.cos(h) * half
            a = surface.vec2pix((stop["x"] + nx, stop["y"] + ny))
            b = surface.vec2pix((stop["x"] - nx, stop["y"] - ny))
            pygame.draw.line(surface, colour, a, b, max(3, int(0.6 * scale)))
        cx, cy = surface.vec2pix((light["x"], light["y"]))
        r = max(5, int(1.2 * scale))
        pygame.draw.rect(surface, (25, 25, 25), pygame.Rect(cx - r - 2, cy - r - 2, 2 * r + 4, 2 * r + 4))
        pygame.draw.circle(surface, colour, (cx, cy), r)


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
    """Write the annotated still of frame ``k`` (default: the first violation) of clip
    ``data`` (:func:`~.clip.clip_data` of ``world``, as a case's recording holds it) as a palette PNG at ``path``.

    Above the scene the title (``title`` or the data's) with the time; in the scene every agent
    labelled with its name and speed, a velocity arrow per agent (as long as the distance it
    covers in :data:`~.clip.ARROW_S` s), the critical agent ringed, a scale bar; below it
    the metric values of the frame (:func:`~.clip.frame_lines`). Each label is placed by
    :func:`_place_labels` beside its own car, off the other cars and labels where there is room.
    Returns what was drawn: ``{"path", "t", "step", "labels", "critical", "lines", "placed",
    "view"}`` — ``placed``: per agent name its label's ``box`` and its car's ``car`` footprint
    box (``(left, top, width, height)`` in the PNG's pixels), the ``anchor`` its leader line
    starts from and the ``text``; ``view``: the world point at the scene's top-left corner
    ``origin`` [m], ``scale`` [px/m] and the scene's ``top`` [px] in the PNG.
    """
    from PIL import Image

    from .clip import decoded, frame_lines

    pygame = _pygame()
    tr = world.trajectory
    k = int(data["first"] if k is None else k)
    data = decoded(data)
    t = float(data["t"][k])
    step = int(np.argmin(np.abs(tr.t - t)))
    surface = frame(world, step, clock=False)
    size, scale, origin = _view(world, step)
    band = 24  # the title's height above the scene [px]
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
    # Labels: the ego's and the critical agent's first, then the others nearest the ego first,
    # each at the free spot nearest its own car (see _place_labels); the leader lines are drawn
    # before any label, so no line runs across a label.
    order = sorted((i for i, a in enumerate(agents) if a["x"][k] is not None),
                   key=lambda i: (i != 0, agents[i]["name"] != critical, _ego_distance(agents, i, k)))
    bounds = surface.get_rect()
    cars: list[tuple[int, int, int, int]] = []
    todo = []
    for i in order:
        a = agents[i]
        cx, cy = pix((a["x"][k], a["y"][k]))
        box = _footprint_box(a, k, pix, scale)
        inside = bounds.collidepoint(cx, cy)
        text = f"{a['name']} {0.0 if a['v'][k] is None else a['v'][k]:.1f} m/s" + ("" if inside else " (out of view)")
        if inside:
            cars.append(box)
        else:  # an agent out of view is labelled at the picture's edge, toward it
            cx, cy = min(max(cx, 0), size[0] - 1), min(max(cy, 0), size[1] - 1)
            box = (cx, cy, 0, 0)
        todo.append((i, text, (cx, cy), box))
    labels = [agents[i]["name"] for i, *_ in todo]
    placed: dict[str, dict[str, Any]] = {}
    if font is not None:
        # the critical agent's ring is kept clear too: a label on it would hide whom it rings
        rings = [_ring_box(a, k, pix, scale) for a in agents if a["name"] == critical and a["x"][k] is not None
                 and bounds.collidepoint(pix((a["x"][k], a["y"][k])))]
        arrows = [seg for seg in (_arrow_segment(a, k, pix, data.get("arrow_s", 1.0)) for a in agents) if seg]
        images = {i: font.render(text, True, INK if agents[i]["name"] == critical else PAPER,
                                 HIGHLIGHT if agents[i]["name"] == critical else (35, 35, 40))
                  for i, text, _, _ in todo}
        # the critical agent's label goes around its ring, not onto it
        boxes = _place_labels(
            [(images[i].get_width(), images[i].get_height(), anchor,
              rings[0] if rings and agents[i]["name"] == critical else box, i == 0) for i, _, anchor, box in todo],
            cars=cars + rings, fixed=[tuple(scale_box)], arrows=arrows,
            bounds=(size[0], size[1]))
        for (i, _, anchor, _), rect in zip(todo, boxes):  # leader lines under every label
            hot = agents[i]["name"] == critical
            pygame.draw.line(surface, HIGHLIGHT if hot else (35, 35, 40), anchor, _nearest_point(rect, anchor), 1)
        for (i, text, anchor, box), rect in zip(todo, boxes):
            surface.blit(images[i], rect[:2])
            placed[agents[i]["name"]] = {"box": (rect[0], rect[1] + band, rect[2], rect[3]),
                                         "car": (box[0], box[1] + band, box[2], box[3]),
                                         "anchor": (anchor[0], anchor[1] + band), "text": text}
    scene = _image(surface)
    # pygame's built-in font has no infinity sign
    lines = [line.replace("∞", "inf") for line in frame_lines(data, k)]
    head = title or data.get("title") or ""
    head = f"{head} — {lines[0]}" if head else lines[0]
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
            "lines": lines, "placed": placed,
            "view": {"origin": (float(origin[0]), float(origin[1])), "scale": float(scale), "top": band}}


# -- label placement ------------------------------------------------------------------------------

Box = tuple  # (left, top, width, height) [px]

#: how far [px] beyond its car's footprint a label may be moved to find a free spot: the
#: rings of candidate spots are this far apart, out to LABEL_REACH_PX
LABEL_STEP_PX = 10
LABEL_REACH_PX = 110

#: the directions tried around a car, clockwise from above; a label's first choice is above
#: its car (below for the ego, as before), so equally free spots keep that habit
_DIRECTIONS = [(math.sin(a), -math.cos(a)) for a in np.radians(np.arange(0, 360, 22.5))]


def _ego_distance(agents: list, i: int, k: int) -> float:
    e, a = agents[0], agents[i]
    if e["x"][k] is None:
        return float(i)
    return math.hypot(a["x"][k] - e["x"][k], a["y"][k] - e["y"][k])


def _corners(a: dict, k: int, grow: float = 0.0) -> list[tuple[float, float]]:
    x, y, h = a["x"][k], a["y"][k], math.radians(a["h"][k] or 0.0)
    L, W = a["L"] / 2 + grow, a["W"] / 2 + grow
    ch, sh = math.cos(h), math.sin(h)
    return [(x + ch * p - sh * q, y + sh * p + ch * q) for p, q in ((L, W), (L, -W), (-L, -W), (-L, W))]


def _bbox(points: list[tuple[int, int]]) -> Box:
    xs, ys = [p[0] for p in points], [p[1] for p in points]
    return min(xs), min(ys), max(xs) - min(xs) + 1, max(ys) - min(ys) + 1


def _footprint_box(a: dict, k: int, pix: Any, scale: float) -> Box:
    """The pixel box around an agent's drawn footprint (a pedestrian's disc)."""
    if a["kind"] == "pedestrian":
        cx, cy = pix((a["x"][k], a["y"][k]))
        r = max(4, int(0.5 * scale))
        return cx - r, cy - r, 2 * r + 1, 2 * r + 1
    return _bbox([pix(p) for p in _corners(a, k)])


def _ring_box(a: dict, k: int, pix: Any, scale: float) -> Box:
    cx, cy = pix((a["x"][k], a["y"][k]))
    r = max(10, int((max(a["L"], a["W"]) / 2 + 1.2) * scale)) + 2
    return cx - r, cy - r, 2 * r + 1, 2 * r + 1


def _arrow_segment(a: dict, k: int, pix: Any, arrow_s: float) -> tuple | None:
    x, y, h, v = a["x"][k], a["y"][k], a["h"][k], a["v"][k]
    if x is None or v is None or abs(v) <= 0.05:
        return None
    hr = math.radians(h)
    return pix((x, y)), pix((x + math.cos(hr) * v * arrow_s, y + math.sin(hr) * v * arrow_s))


def _overlap(a: Box, b: Box) -> int:
    """The area [px²] two boxes share."""
    w = min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0])
    h = min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1])
    return w * h if w > 0 and h > 0 else 0


def _within(a: Box, b: Box) -> bool:
    return b[0] <= a[0] and b[1] <= a[1] and a[0] + a[2] <= b[0] + b[2] and a[1] + a[3] <= b[1] + b[3]


def _gap(a: Box, b: Box) -> float:
    """The distance [px] between two boxes (0 when they touch or overlap)."""
    dx = max(b[0] - (a[0] + a[2]), a[0] - (b[0] + b[2]), 0)
    dy = max(b[1] - (a[1] + a[3]), a[1] - (b[1] + b[3]), 0)
    return math.hypot(dx, dy)


def _nearest_point(box: Box, p: tuple[int, int]) -> tuple[int, int]:
    return min(max(p[0], box[0]), box[0] + box[2] - 1), min(max(p[1], box[1]), box[1] + box[3] - 1)


def _crosses(seg: tuple, box: Box) -> bool:
    """Whether segment ``seg`` passes through ``box`` (Liang–Barsky clipping)."""
    (x0, y0), (x1, y1) = seg
    dx, dy = x1 - x0, y1 - y0
    t0, t1 = 0.0, 1.0
    for p, q in ((-dx, x0 - box[0]), (dx, box[0] + box[2] - x0), (-dy, y0 - box[1]), (dy, box[1] + box[3] - y0)):
        if p == 0:
            if q < 0:
                return False
            continue
        r = q / p
        if p < 0:
            t0 = max(t0, r)
        else:
            t1 = min(t1, r)
        if t0 > t1:
            return False
    return True


def _place_labels(labels: list[tuple], *, cars: list[Box], fixed: list[Box], arrows: list[tuple],
                  bounds: tuple[int, int]) -> list[Box]:
    """A box per label, greedily in the order given (most important first).

    ``labels``: ``(width, height, anchor, own box, below)`` — the label's size, the point its
    leader line starts from, its own car's footprint box (the critical agent's: its ring's)
    and whether it prefers the spot below its car. ``cars``: every car's footprint box (and the critical agent's ring), which no
    label may cover; ``fixed``: boxes already taken (the scale bar); ``arrows``: velocity
    arrows as pixel segments, which a label should rather not hide.

    Candidates lie around the car on rings every :data:`LABEL_STEP_PX` pixels beyond its
    footprint, out to :data:`LABEL_REACH_PX`, in 16 directions, inside ``bounds``. Each is
    scored: covering another car or label is forbidden in effect (a huge cost per pixel²);
    sitting as near another car as its own (it would read as that car's), drawing the leader
    line across another car or hiding an arrow cost a little; distance from the car the most
    of the rest, so a label moves only as far as it must.
    With no free candidate the least bad one wins.
    """
    W, H = bounds
    taken: list[Box] = list(fixed)
    out: list[Box] = []
    for w, h, anchor, own, below in labels:
        others = [c for c in cars if not _within(c, own)]  # its own footprint is within its own box
        best: tuple[float, Box] | None = None
        ocx, ocy = own[0] + own[2] / 2, own[1] + own[3] / 2
        for ring, d in enumerate(range(2, LABEL_REACH_PX + 1, LABEL_STEP_PX)):
            for j, (ux, uy) in enumerate(_DIRECTIONS):
                if below:
                    uy = -uy
                # the label's centre along (ux, uy) far enough that its box stays d px off the car
                reach = [(d + (own[2] + w) / 2) / abs(ux) if abs(ux) > 1e-9 else math.inf,
                         (d + (own[3] + h) / 2) / abs(uy) if abs(uy) > 1e-9 else math.inf]
                t = min(reach)
                left, top = int(round(ocx + ux * t - w / 2)), int(round(ocy + uy * t - h / 2))
                if left < 0 or top < 0 or left + w > W or top + h > H:
                    continue
                box = (left, top, w, h)
                cost = 1e6 * (sum(_overlap(box, c) for c in others) + sum(_overlap(box, b) for b in taken))
                cost += 1e3 * _overlap(box, own)
                end = _nearest_point(box, anchor)
                cost += 300 * sum(_crosses((anchor, end), c) for c in others)
                cost += 60 * sum(_crosses(seg, box) for seg in arrows)
                near = _gap(box, own)
                if others and min(_gap(box, c) for c in others) < near + 4:
                    cost += 250  # as near another car as its own: it would read as that car's
                cost += 10 * near + j % 8  # nearer first; then above (or below)
                if best is None or cost < best[0]:
                    best = (cost, box)
            if best is not None and best[0] < 10 * (d + LABEL_STEP_PX):
                break  # farther rings cost at least their distance: none can do better
        if best is None:  # no candidate inside the picture: next to the car, clamped in
            left = min(max(int(ocx - w / 2), 0), max(W - w, 0))
            top = min(max(int(own[1] - h - 2), 0), max(H - h, 0))
            best = (0.0, (left, top, w, h))
        taken.append(best[1])
        out.append(best[1])
    return out


def _save_atomic(image: Any, path: str | os.PathLike) -> None:
    """Save a Pillow image as PNG so readers never see half a file (not fsynced: one of a
    report's many per-case files)."""
    import io

    from ..files import atomic_write_bytes

    buf = io.BytesIO()
    image.save(buf, format="PNG", optimize=True)
    atomic_write_bytes(path, buf.getvalue(), durable=False)

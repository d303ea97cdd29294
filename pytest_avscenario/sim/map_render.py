"""Drawing a map's roads into a frame: the lanes near the view in their real shape.

:func:`draw` paints, for the lanes of a :class:`~.maps.MapRoad` whose box meets the view,
the sidewalks, then the asphalt of every drivable lane (junction lanes overlapping into the
junction's area), then the markings of lanes outside junctions: a solid line along a
carriageway's outer edges, a dashed one between lanes of one direction. Lane outlines are
the file's lane edges (exact widths), not a constant width around the centre line. Only
lanes in view are drawn, so a frame on Town06 costs what a frame on a built road does.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["draw", "lanes_near"]

ASPHALT = (72, 72, 76)
PARKING = (92, 92, 98)
SIDEWALK = (150, 150, 146)
WHITE = (240, 240, 240)
_DASH_M = 3.0  # [m] dash and gap of a lane line


def _boxes(road: Any) -> tuple[np.ndarray, list]:
    """Boxes (xmin, ymin, xmax, ymax) [m] of every lane of the map (all kinds), cached."""
    built = road._built
    got = getattr(built, "_draw_boxes", None)
    if got is None:
        lanes = [l for l in road.data.lanes.values() if l.kind in ("sidewalk",) or
                 l.id in built.by_id]
        boxes = []
        for l in lanes:
            pad = float(l.width.max()) / 2
            boxes.append([l.xy[:, 0].min() - pad, l.xy[:, 1].min() - pad,
                          l.xy[:, 0].max() + pad, l.xy[:, 1].max() + pad])
        got = built._draw_boxes = (np.asarray(boxes, dtype=float).reshape(-1, 4), lanes)
    return got


def lanes_near(road: Any, xy: np.ndarray, margin: float) -> list:
    """The drivable lanes (world lanes, in index order) within ``margin`` [m] of any point
    of ``xy`` (N, 2) [m] — what a replay of a run on this map needs to draw."""
    b = road.world.lane_index.boxes
    pts = np.asarray(xy, dtype=float).reshape(-1, 2)
    pts = pts[np.isfinite(pts).all(axis=1)]
    if not len(pts):
        return []
    keep = np.zeros(len(b), dtype=bool)
    for chunk in np.array_split(pts, max(1, len(pts) // 64)):
        keep |= ((b[:, 0] - margin <= chunk[:, 0:1]) & (chunk[:, 0:1] <= b[:, 2] + margin)
                 & (b[:, 1] - margin <= chunk[:, 1:2]) & (chunk[:, 1:2] <= b[:, 3] + margin)).any(axis=0)
    order = road.world.lane_index.order
    return [order[j] for j in np.flatnonzero(keep)]


def draw(road: Any, surface: Any, pygame: Any) -> None:
    """Paint the map's lanes in ``surface``'s view (a highway-env WorldSurface, north up)."""
    scale = float(surface.scaling)
    ox, oy = float(surface.origin[0]), float(surface.origin[1])
    w, h = surface.get_width() / scale, surface.get_height() / scale
    boxes, lanes = _boxes(road)
    hit = np.flatnonzero((boxes[:, 2] >= ox) & (boxes[:, 0] <= ox + w)
                         & (boxes[:, 3] >= oy - h) & (boxes[:, 1] <= oy))
    visible = [lanes[j] for j in hit]

    def pix(a: np.ndarray) -> list:
        return np.column_stack(((a[:, 0] - ox) * scale, (oy - a[:, 1]) * scale)).astype(int).tolist()

    built = road._built
    for kind in ("sidewalk", "drivable"):
        for lane in visible:
            if (lane.kind == "sidewalk") != (kind == "sidewalk"):
                continue
            left, right = lane.edges()
            colour = SIDEWALK if kind == "sidewalk" else PARKING if lane.kind == "parking" else ASPHALT
            pygame.draw.polygon(surface, colour, pix(np.vstack([left, right[::-1]])))
    thick = max(1, int(round(0.15 * scale)))
    for lane in visible:
        if lane.kind == "sidewalk" or lane.junction:
            continue
        me = built.by_id[lane.id]
        beside = {o.number for o in built.index._beside[me.index]}
        left, right = lane.edges()
        if me.number == 0:  # the carriageway's left edge (the centre line or a median)
            pygame.draw.lines(surface, WHITE, False, pix(left), thick)
        if me.number + 1 in beside:
            _dashed(pygame, surface, pix(right), lane.s, thick)
        else:
            pygame.draw.lines(surface, WHITE, False, pix(right), thick)


def _dashed(pygame: Any, surface: Any, pts: list, s: np.ndarray, thick: int) -> None:
    on = (np.floor(s / _DASH_M) % 2 == 0)
    start = None
    for k, flag in enumerate(on.tolist()):
        if flag and start is None:
            start = k
        elif not flag and start is not None:
            if k - start >= 1:
                pygame.draw.lines(surface, WHITE, False, pts[start:k + 1], thick)
            start = None
    if start is not None and len(pts) - start >= 2:
        pygame.draw.lines(surface, WHITE, False, pts[start:], thick)

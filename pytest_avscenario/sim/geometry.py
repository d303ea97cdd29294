"""Plane geometry shared across the simulator: angle wrapping and rectangle (footprint) overlap.

Headings are wrapped in the recorder, the lane tracker, the steering law, arc lanes, the
all-way-stop rule and the autopilot; footprints are tested for overlap when an agent is
placed or appears, and by the autopilot's parking planner. Each of these questions has one
answer here. Pure math and numpy: importing this module imports neither highway-env nor
pygame (behaviours and the steering law use it); only :func:`footprints_overlap` reaches
highway-env, when called.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

__all__ = ["wrap_to_pi", "heading_change", "box_corners", "boxes_overlap", "poses_hit_boxes",
           "footprints_overlap"]

_PI = math.pi
_TWO_PI = 2.0 * math.pi


def wrap_to_pi(angle: float) -> float:
    """``angle`` [rad] wrapped to [-pi, pi).

    The very formula of highway-env's ``utils.wrap_to_pi`` (so results are bit-identical to
    it), written out here because callers such as the behaviours must not import
    highway-env. A formula through ``atan2(sin, cos)`` would differ in the last bit and
    change trajectories.
    """
    return (angle + _PI) % _TWO_PI - _PI


def heading_change(geometry: Any) -> float:
    """Signed change of heading [rad] from the start to the end of a lane (left positive)."""
    return wrap_to_pi(float(geometry.heading_at(geometry.length))
                      - float(geometry.heading_at(0.0)))


# -- footprints ------------------------------------------------------------------------------


def footprints_overlap(a: Any, b: Any) -> bool:
    """Whether the footprints of two agents (highway-env vehicles) intersect now.

    The same separating-axis test highway-env's collision check applies each step, on the
    same polygons, so "free to appear here" and "would not collide here" agree. A broad
    phase on the centre distance skips far pairs.
    """
    if np.hypot(*(b.position - a.position)) > (b.diagonal + a.diagonal) / 2:
        return False
    # ``from highway_env.utils import`` (not ``from highway_env import utils``): the latter
    # would import the whole package with its gym environments (see _hwenv)
    from highway_env.utils import are_polygons_intersecting

    zero = np.zeros(2)
    return bool(are_polygons_intersecting(a.polygon(), b.polygon(), zero, zero)[0])


def box_corners(x: float, y: float, heading: float, half_length: float,
                half_width: float) -> list[tuple[float, float]]:
    """Corners [m] of a rectangle centred at (x, y) with the given heading [rad]."""
    c, s = math.cos(heading), math.sin(heading)
    return [(x + c * dl - s * dw, y + s * dl + c * dw)
            for dl, dw in ((half_length, half_width), (half_length, -half_width),
                           (-half_length, -half_width), (-half_length, half_width))]


def boxes_overlap(a: list[tuple[float, float]], b: list[tuple[float, float]]) -> bool:
    """Whether two rectangles (corner lists, :func:`box_corners`) overlap, touching included.

    A separating-axis test in plain Python floats: planners call it thousands of times per
    plan, where numpy's per-call overhead would dominate.
    """
    for poly in (a, b):
        for k in range(2):  # a rectangle has two edge directions
            ex = poly[k + 1][0] - poly[k][0]
            ey = poly[k + 1][1] - poly[k][1]
            pa = [ey * p[0] - ex * p[1] for p in a]
            pb = [ey * p[0] - ex * p[1] for p in b]
            if max(pa) < min(pb) or max(pb) < min(pa):
                return False
    return True


def poses_hit_boxes(x: np.ndarray, y: np.ndarray, h: np.ndarray, half: float, half_w: float,
                    boxes: Sequence[tuple[float, float, float, float]]) -> np.ndarray:
    """Per pose (arrays ``x``, ``y`` [m], heading ``h`` [rad]) of a ``2 half`` x ``2 half_w``
    rectangle, whether it overlaps any axis-aligned box ``(cx, cy, half_x, half_y)`` [m].

    The separating-axis test of :func:`boxes_overlap` vectorized over poses, for a box
    aligned with the axes (its two axes are x and y, so only the pose's two are computed).
    """
    c, s = np.abs(np.cos(h)), np.abs(np.sin(h))
    cs, sn = np.cos(h), np.sin(h)
    ex = half * c + half_w * s
    ey = half * s + half_w * c
    hit = np.zeros(x.shape, dtype=bool)
    for bx, by, bhx, bhy in boxes:
        dx, dy = bx - x, by - y
        sep = (np.abs(dx) > ex + bhx) | (np.abs(dy) > ey + bhy)
        sep |= np.abs(dx * cs + dy * sn) > half + bhx * c + bhy * s
        sep |= np.abs(dy * cs - dx * sn) > half_w + bhx * s + bhy * c
        hit |= ~sep
    return hit

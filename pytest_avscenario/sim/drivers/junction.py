"""The all-way stop ahead as the autopilot infers it from its route and what it perceives.

The traffic's ``turn`` behaviour reads the arrival order from the world's true state
(:class:`~pytest_avscenario.sim.right_of_way.AllWayStop`); the autopilot under test may not,
so :class:`Junction` rebuilds it from perception alone, applying the same rule
(:mod:`~pytest_avscenario.sim.right_of_way`).
"""

from __future__ import annotations

import math
from typing import Any

from ..geometry import heading_change
from ..right_of_way import has_entered, precedence, waiting_at_line
from .perception import Perceived

__all__ = ["Junction"]


class Junction:
    """The all-way stop behind one stop line of the route, as the autopilot infers it.

    From its own route alone: the box centre and half size from the connector after the line
    (straight: half its length; a turn: its radius -+ half a lane) and the distance from the
    line to the centre, assumed the same on every arm. From what it sees: when each other
    vehicle came to rest (< 0.5 m/s) facing the box with its front bumper between 1 m past
    and 4 m before where that arm's stop line would be (perception time, i.e. observation
    time minus latency), and when it entered (front more than 1 m past the line). Those
    thresholds and who goes first are :mod:`~pytest_avscenario.sim.right_of_way`'s, the rule
    the traffic's ``turn`` behaviour follows too; only what it knows differs.
    """

    def __init__(self, route: tuple, line: Any) -> None:
        j = line.route_index
        lane, conn = route[j], route[j + 1]
        x0, y0 = (float(v) for v in lane.position(lane.length, 0.0))
        h = float(lane.heading_at(lane.length))
        self.ca, self.sa = math.cos(h), math.sin(h)
        self.heading = h
        w = float(lane.width_at(0.0))
        x1, y1 = (float(v) for v in conn.position(conn.length, 0.0))
        turn = heading_change(conn)
        radius = float(getattr(conn, "radius", math.inf))
        if abs(turn) < 0.5 or not math.isfinite(radius):
            half = 0.5 * math.hypot(x1 - x0, y1 - y0)
        elif turn > 0.0:
            half = radius - 0.5 * w  # a left turn from the lane next to the centre line
        else:
            half = radius + 0.5 * w  # a right turn from the kerb lane
        self.half = half
        # Centre: half ahead of the box edge, half a lane left of our lane's centre line.
        self.cx = x0 + self.ca * half - self.sa * 0.5 * w
        self.cy = y0 + self.sa * half + self.ca * 0.5 * w
        self.d_line = float(lane.length - line.s) + half  # from a stop line to the centre [m]
        self.arrived: dict[str, tuple[float, float]] = {}  # name -> (came to rest [s], heading)
        self.entered: set[str] = set()
        self.t_me: float | None = None  # when we came to rest at our line [s]
        self.waited = 0.0  # [s] waiting for the right of way

    def observe(self, seen: Perceived, t_seen: float) -> None:
        """Note who came to rest at, or entered from, a stop line of this intersection."""
        present = set()
        for a in seen.agents:
            if a.ped:
                continue
            present.add(a.name)
            if a.name in self.entered:
                continue
            fx, fy = a.x + a.hl * a.c, a.y + a.hl * a.s
            dx, dy = self.cx - fx, self.cy - fy
            along = dx * a.c + dy * a.s
            if a.name in self.arrived:
                if has_entered(along, self.d_line):
                    del self.arrived[a.name]
                    self.entered.add(a.name)
                continue
            if a.c * self.ca + a.s * self.sa > 0.7:
                continue  # our own approach: a queue, not a rival
            if abs(dx * a.s - dy * a.c) > self.half:
                continue
            if waiting_at_line(along, self.d_line, math.hypot(a.vx, a.vy)):
                self.arrived[a.name] = (t_seen, math.atan2(a.s, a.c))
        for name in [n for n in self.arrived if n not in present]:
            del self.arrived[name]  # out of sight

    def first_to_go(self, seen: Perceived, patient: bool) -> bool:
        """Whether it is our turn: (a) nobody who came to rest before us (or at the same
        time on our right) is still waiting, unless ``patient`` is False; (b) nothing moves
        inside the box."""
        if patient and self.t_me is not None:
            for t_o, h_o in self.arrived.values():
                if precedence(self.t_me, self.heading, t_o, h_o) in ("earlier", "right"):
                    return False
        for a in seen.agents:
            if a.ped or math.hypot(a.vx, a.vy) < 0.3:
                continue
            # Its footprint in the box, or past its stop line on the way in.
            reach = self.half + 0.5 + a.hl
            if a.name in self.entered and (self.cx - a.x) * a.c + (self.cy - a.y) * a.s > 0.0:
                reach = max(reach, self.d_line + a.hl)
            dx, dy = a.x - self.cx, a.y - self.cy
            if abs(dx * self.ca + dy * self.sa) < reach and abs(dy * self.ca - dx * self.sa) < reach:
                return False
        return True

"""The all-way-stop rule: who is waiting at a stop line, who has entered, and who goes first.

Two places apply it: the ``turn`` behaviour (through :class:`AllWayStop`, the world's own
book of arrivals kept from the true state of every vehicle) and the built-in autopilot
(which infers the arrivals from what it perceives, see ``drivers/autopilot.py``). Both
must mean the same thing by "standing at the line", "inside" and "first to stop, first to
go; on a tie the one on the right", so the thresholds and the comparisons live here once.
Distances are along the approach toward the box, positive before the stop line.

Importing this module imports neither highway-env nor pygame (behaviours use it).
"""

from __future__ import annotations

import math
from typing import Any

from .geometry import heading_change

__all__ = ["STANDING", "BEFORE", "PAST", "TIE", "CONFLICT", "waiting_at_line", "has_entered",
           "precedence", "turn_of", "AllWayStop"]

STANDING = 0.5  # [m/s] below this a vehicle is standing
BEFORE, PAST = 4.0, 1.0  # [m] front bumper before / past the line that counts as "at" it
TIE = 0.2  # [s] arrivals this close together are simultaneous
CONFLICT = 3.0  # [m] connectors whose centre lines come this close cross or merge
_EPS = 1e-9  # [s] float slack on arrival times, so equal clocks compare as a tie


def waiting_at_line(front: float, line: float, speed: float) -> bool:
    """Whether a vehicle whose front bumper is at ``front`` stands at the stop line at
    ``line`` [m] (both measured to one reference along the approach), at ``speed`` [m/s]."""
    return speed < STANDING and line - PAST <= front <= line + BEFORE


def has_entered(front: float, line: float) -> bool:
    """Whether the front bumper at ``front`` is so far past the line at ``line`` [m] that the
    vehicle is in the box (same reference as :func:`waiting_at_line`)."""
    return front < line - PAST


def precedence(t_me: float, heading_me: float, t_other: float, heading_other: float) -> str:
    """How another vehicle waiting at another line of the intersection ranks against us.

    ``t_*`` [s] is when each came to rest at its line, ``heading_*`` [rad] its heading there.
    ``"earlier"``: it stopped first and goes first; on a tie (within :data:`TIE`)
    ``"right"``: it is on our right and goes first, ``"facing"``: it faces us (the rule for
    that is the caller's), ``"left"``: it is on our left and waits for us; ``"later"``: it
    stopped after us.
    """
    if t_other < t_me - TIE - _EPS:
        return "earlier"
    if t_other <= t_me + TIE + _EPS:
        side = math.sin(heading_other - heading_me)
        if side > 0.5:
            return "right"
        return "facing" if side >= -0.5 else "left"
    return "later"


def turn_of(geometry: Any) -> str:
    """"left", "right" or "straight": which way a connector lane turns (by more than 0.5 rad)."""
    dh = heading_change(geometry)
    return "left" if dh > 0.5 else "right" if dh < -0.5 else "straight"


class AllWayStop:
    """Who stopped when at the all-way stops of one world: the arrival order ``turn`` goes by.

    Every vehicle (the ego too, whatever drives it) standing (< 0.5 m/s) with its front bumper
    between 1 m past and 4 m before the stop line on its route is *waiting* there from the
    first such step on (a car queued behind another is further back and does not count yet);
    once its front is more than 1 m past the line, on the connector through the box, or on
    the exit with its rear still in the box, it is *inside*. Vehicles of one intersection are
    those whose connectors share its nodes; two connectors *conflict* when they come from
    different approaches and their centre lines come within 3 m.

    A vehicle waiting at a line may go when every vehicle that began waiting at another line
    of the same intersection more than 0.2 s earlier has entered, on a tie (within 0.2 s) the
    one on its right has entered (facing each other: the left turner yields to the other, else
    the one added to the world later yields), and nothing inside the box is on a conflicting
    path. One instance per world (``world.all_way_stop``), updated once per step by the first
    ``turn`` that acts.
    """

    VEHICLES = ("ego", "car", "truck", "bus")  # parked cars and pedestrians never queue at a stop

    def __init__(self, world: Any) -> None:
        self.world = world
        self.index = world.lane_index
        self.t: float | None = None
        self.waiting: dict[str, tuple[float, Any, float]] = {}  # name -> (since [s], connector, heading)
        self.inside: dict[str, Any] = {}  # name -> connector
        self.order: dict[str, int] = {}
        self._node: dict[str, str] = {}
        self._conflict: dict[tuple, bool] = {}
        parent: dict[str, str] = {}

        def find(n: str) -> str:
            while parent.setdefault(n, n) != n:
                n = parent[n]
            return n

        for lane in self.index.order:
            if lane.kind == "connector":
                a, b = find(lane.index[0]), find(lane.index[1])
                if a != b:
                    parent[max(a, b)] = min(a, b)
        self._node = {n: find(n) for n in parent}

    def update(self) -> None:
        """Refresh who waits where and who is inside (once per simulation step)."""
        w = self.world
        if self.t is not None and w.t == self.t:
            return
        if self.t is None or w.t < self.t:  # a new run
            self.waiting.clear()
        self.t = w.t
        self.inside = {}
        agents = w.agents
        self.order = {a.name: i for i, a in enumerate(agents)}
        for a in agents:
            if a.kind not in self.VEHICLES or not getattr(a, "active", True):
                self.waiting.pop(a.name, None)
                continue
            where = self._where(a)
            if where is None:
                self.waiting.pop(a.name, None)
            elif where[0] == "inside":
                self.waiting.pop(a.name, None)
                self.inside[a.name] = where[1]
            elif where[0] == "at line":
                self.waiting.setdefault(a.name, (w.t, where[1], where[2]))

    def _where(self, a: Any) -> tuple | None:
        plan, ri = a.plan, a.route_index
        if not plan:
            return None
        half = a.LENGTH / 2
        if plan[ri].kind == "connector":
            return ("inside", plan[ri])
        if ri > 0 and plan[ri - 1].kind == "connector" and a.route_s - half < 0.5:
            return ("inside", plan[ri - 1])
        found = a.stop_line_ahead()
        if found is None:
            return None
        d, j = found
        if j + 1 >= len(plan) or plan[j + 1].kind != "connector":
            return None
        d -= half
        if has_entered(d, 0.0):
            return ("inside", plan[j + 1])
        if waiting_at_line(d, 0.0, a.speed):
            g = plan[j].geometry
            return ("at line", plan[j + 1], float(g.heading_at(g.length)))
        return ("approach", plan[j + 1])

    def conflict(self, c1: Any, c2: Any) -> bool:
        """Whether connectors ``c1`` and ``c2`` of one intersection cross or merge."""
        if c1.index[0] == c2.index[0]:
            return False  # the same approach: a queue, car following's job
        if self._node.get(c1.index[0]) != self._node.get(c2.index[0]):
            return False  # another intersection
        key = (c1.index, c2.index)
        hit = self._conflict.get(key)
        if hit is None:
            p1, p2 = _centre_points(c1), _centre_points(c2)
            d2 = min((x1 - x2) ** 2 + (y1 - y2) ** 2 for x1, y1 in p1 for x2, y2 in p2)
            hit = self._conflict[key] = self._conflict[key[::-1]] = d2 < CONFLICT ** 2
        return hit

    def may_go(self, agent: Any, patient: bool = True) -> bool:
        """Whether ``agent``, waiting at its stop line, has the right of way now.

        With ``patient`` False (it has waited too long) only what is inside the box counts.
        """
        me = self.waiting.get(agent.name)
        if me is None:
            where = self._where(agent)
            if where is None:
                return True
            me = (self.world.t, where[1], 0.0)
        t_me, conn, h_me = me
        if patient:
            for name, (t_o, c_o, h_o) in self.waiting.items():
                if name == agent.name or c_o.index[0] == conn.index[0]:
                    continue
                if self._node.get(c_o.index[0]) != self._node.get(conn.index[0]):
                    continue
                rank = precedence(t_me, h_me, t_o, h_o)
                if rank in ("earlier", "right"):
                    return False
                if rank == "facing" and self.conflict(conn, c_o):
                    mine, theirs = turn_of(conn.geometry), turn_of(c_o.geometry)
                    if mine == "left" and theirs != "left":
                        return False
                    if (mine == "left") == (theirs == "left") and \
                            self.order.get(name, 0) < self.order.get(agent.name, 0):
                        return False
        for name, c_o in self.inside.items():
            if name != agent.name and self.conflict(conn, c_o):
                return False
        return True


def _centre_points(lane: Any, n: int = 24) -> list[tuple[float, float]]:
    g = lane.geometry
    out = []
    for k in range(n + 1):
        p = g.position(g.length * k / n, 0.0)
        out.append((float(p[0]), float(p[1])))
    return out

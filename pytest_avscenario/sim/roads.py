"""The three road types a scenario builds: straight, two-way and a four-way intersection.

``StraightRoad`` (one-way, n lanes), ``TwoWayRoad`` (n lanes each way, kerb-side parking)
and ``Intersection`` (four arms, one or two lanes per approach, through/left/right
connectors, stop lines, crosswalks) each build a highway-env ``RoadNetwork`` from our own lane
classes and hand out places (:mod:`.places`). World frame: x east, y north [m]; traffic keeps
right. A straight or two-way road runs west to east from x = 0; an intersection is centred on
the origin.

Their lanes are indexed and agents tracked on them by :class:`~.lanes.LaneIndex`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .errors import SimError
from .lanes import LaneIndex  # noqa: F401  (re-exported: its old home, bench/ patches it here)
from .places import Crosswalk, Lane, Path, Point, Route, StopLine

__all__ = ["StraightRoad", "TwoWayRoad", "Intersection", "LaneIndex", "DIRECTIONS"]

DIRECTIONS = ("north", "east", "south", "west")
_UNIT = {"north": (0.0, 1.0), "east": (1.0, 0.0), "south": (0.0, -1.0), "west": (-1.0, 0.0)}
_LEFT_OF = {"south": "west", "north": "east", "east": "south", "west": "north"}
_RIGHT_OF = {"south": "east", "north": "west", "east": "north", "west": "south"}
_OPPOSITE = {"north": "south", "south": "north", "east": "west", "west": "east"}
SIDEWALK = 2.0  # [m] how far beyond the kerb crosswalk paths start


def _check_median(median: Any, what: str, test: str) -> float:
    try:
        m = float(median)
    except (TypeError, ValueError):
        m = math.nan
    if not (math.isfinite(m) and m >= 0):
        raise SimError(f"{what}(median={median!r}): need a width >= 0 [m]", test=test)
    return m


class _Road:
    """Common part of the road types: its lanes, network and the owning world."""

    kind = ""

    def __init__(self, world: Any) -> None:
        self.world = world
        self.all_lanes: list[Lane] = []
        self.crosswalks: list[Crosswalk] = []
        self.stop_lines: list[StopLine] = []

    def _lane(self, net: Any, frm: str, to: str, geometry: Any, lane_id: str, kind: str,
              direction: str, group: str, number: int) -> Lane:
        net.add_lane(frm, to, geometry)
        i = len(net.graph[frm][to]) - 1
        lane = Lane(lane_id, (frm, to, i), geometry, kind=kind, direction=direction,
                    group=group, number=number)
        self.all_lanes.append(lane)
        return lane

    def _lane_of(self, i: int, direction: str, what: str, hint: str) -> Lane:
        """Lane ``i`` of the ``forward``/``backward`` lanes of a two-way road (``hint`` says
        which way forward is)."""
        lanes = {"forward": getattr(self, "forward", None),
                 "backward": getattr(self, "backward", None)}.get(direction)
        if lanes is None:
            raise SimError(f"{what}.lane(direction={direction!r}): use 'forward' or 'backward' "
                           f"({hint})", test=self.world.name)
        try:
            return lanes[i]
        except (IndexError, TypeError):
            raise SimError(f"{what}.lane({i!r}): each direction has lanes 0..{len(lanes) - 1}",
                           test=self.world.name) from None

    def default_route(self, lane: Lane) -> Route:
        """The route an agent placed on ``lane`` follows unless told otherwise (straight on)."""
        return Route(tuple(self.world.lane_index.continue_route(lane)))

    def _crosswalk_across(self, name: str, lanes: list[Lane], s_of: dict, start: np.ndarray,
                          end: np.ndarray, width: float, sides: tuple[str, str]) -> Crosswalk:
        cw = Crosswalk(name, Path.through([start, end]), float(width),
                       tuple((l, float(s_of[l.index])) for l in lanes), sides)
        self.crosswalks.append(cw)
        return cw


class StraightRoad(_Road):
    """A one-way road running east from x = 0: ``lanes`` lanes, lane 0 leftmost (north)."""

    kind = "straight"

    def __init__(self, world: Any, net: Any, lanes: int, length: float, lane_width: float,
                 speed_limit: float) -> None:
        from .engine import LineType, Straight

        super().__init__(world)
        if lanes < 1 or int(lanes) != lanes:
            raise SimError(f"straight_road(lanes={lanes!r}): need a whole number >= 1", test=world.name)
        if not length > 0:
            raise SimError(f"straight_road(length={length!r}): need > 0 m", test=world.name)
        self.length = float(length)
        self.lane_width = float(lane_width)
        self.lanes: list[Lane] = []
        for i in range(int(lanes)):
            y = -i * lane_width
            right = LineType.CONTINUOUS_LINE if i == lanes - 1 else LineType.STRIPED
            left = LineType.CONTINUOUS_LINE if i == 0 else LineType.NONE
            g = Straight((0.0, y), (length, y), width=lane_width, line_types=(right, left),
                         speed_limit=speed_limit)
            self.lanes.append(self._lane(net, "west", "east", g, f"lane[{i}]", "travel",
                                         "forward", "lanes", i))
        self._y_left = lane_width / 2
        self._y_right = -(lanes - 0.5) * lane_width

    def lane(self, i: int = 0) -> Lane:
        """Lane ``i`` (0 leftmost)."""
        try:
            return self.lanes[i]
        except (IndexError, TypeError):
            raise SimError(f"road.lane({i!r}): this road has lanes 0..{len(self.lanes) - 1}",
                           test=self.world.name) from None

    def crosswalk(self, s: float, width: float = 3.0) -> Crosswalk:
        """A crosswalk centred ``s`` metres from the start of the road, walked south to north."""
        s = float(s)
        if not 0 < s < self.length:
            raise SimError(f"crosswalk(s={s!r}): must lie within the road (0..{self.length} m)",
                           test=self.world.name)
        for lane in self.lanes:
            self.world.lane_index.add_stop(lane, s - width / 2, "crosswalk")
        return self._crosswalk_across(
            f"crosswalk@{s:g}", self.lanes, {l.index: s for l in self.lanes},
            np.array([s, self._y_right - SIDEWALK]), np.array([s, self._y_left + SIDEWALK]),
            width, ("south", "north"))


class TwoWayRoad(_Road):
    """A two-way road along x: forward lanes drive east south of y = 0, backward lanes west.

    Lanes are numbered from the centre line outward in each direction; a parking lane runs along
    each kerb (``parking_lane`` is the forward one, beside the ego's usual lane).
    """

    kind = "two_way"

    def __init__(self, world: Any, net: Any, lanes: int, length: float, parking: bool,
                 lane_width: float, parking_width: float, speed_limit: float,
                 median: float = 0.0) -> None:
        from .engine import LineType, Straight

        super().__init__(world)
        if lanes < 1 or int(lanes) != lanes:
            raise SimError(f"two_way_road(lanes={lanes!r}): need a whole number >= 1", test=world.name)
        if not length > 0:
            raise SimError(f"two_way_road(length={length!r}): need > 0 m", test=world.name)
        median = _check_median(median, "two_way_road", world.name)
        n = int(lanes)
        m2 = median / 2
        self.median = median
        self.length = float(length)
        self.lane_width = float(lane_width)
        self.forward: list[Lane] = []
        self.backward: list[Lane] = []
        self._parking: dict[str, Lane] = {}
        N, S, C = LineType.NONE, LineType.STRIPED, LineType.CONTINUOUS_LINE
        for i in range(n):
            off = m2 + (i + 0.5) * lane_width
            outer = (S if parking else C) if i == n - 1 else S
            g = Straight((0.0, -off), (length, -off), width=lane_width,
                         line_types=(outer, C if i == 0 else N), speed_limit=speed_limit)
            self.forward.append(self._lane(net, "west", "east", g, f"forward[{i}]", "travel",
                                           "forward", "forward", i))
            # With a median each direction draws its own continuous centre line.
            g = Straight((length, off), (0.0, off), width=lane_width,
                         line_types=(outer, C if (i == 0 and median > 0) else N),
                         speed_limit=speed_limit)
            self.backward.append(self._lane(net, "east", "west", g, f"backward[{i}]", "travel",
                                            "backward", "backward", i))
        edge = m2 + n * lane_width
        if parking:
            off = edge + parking_width / 2
            g = Straight((0.0, -off), (length, -off), width=parking_width,
                         line_types=(C, N), speed_limit=speed_limit)
            self._parking["forward"] = self._lane(net, "west.kerb", "east.kerb", g,
                                                  "parking.forward", "parking", "forward",
                                                  "parking.forward", 0)
            g = Straight((length, off), (0.0, off), width=parking_width,
                         line_types=(C, N), speed_limit=speed_limit)
            self._parking["backward"] = self._lane(net, "east.kerb", "west.kerb", g,
                                                   "parking.backward", "parking", "backward",
                                                   "parking.backward", 0)
            edge += parking_width
        self._edge = edge

    def lane(self, i: int = 0, direction: str = "forward") -> Lane:
        """Lane ``i`` (0 next to the centre line) of ``direction`` ("forward" east, "backward" west)."""
        return self._lane_of(i, direction, "road", "forward drives east")

    @property
    def parking_lane(self) -> Lane:
        """The forward direction's kerb-side parking lane."""
        return self.parking("forward")

    def parking(self, direction: str = "forward") -> Lane:
        """The kerb-side parking lane of ``direction``."""
        if direction not in self._parking:
            raise SimError("this road has no parking lanes (two_way_road(parking=True))"
                           if not self._parking else
                           f"parking({direction!r}): use 'forward' or 'backward'",
                           test=self.world.name)
        return self._parking[direction]

    def crosswalk(self, s: float, width: float = 3.0) -> Crosswalk:
        """A crosswalk ``s`` metres east of the road start, walked from the south kerb north."""
        s = float(s)
        if not 0 < s < self.length:
            raise SimError(f"crosswalk(s={s!r}): must lie within the road (0..{self.length} m)",
                           test=self.world.name)
        crossed = self.forward + self.backward + list(self._parking.values())
        s_of = {}
        for lane in crossed:
            ls = s if lane.direction == "forward" else self.length - s
            s_of[lane.index] = ls
            self.world.lane_index.add_stop(lane, ls - width / 2, "crosswalk")
        return self._crosswalk_across(
            f"crosswalk@{s:g}", crossed, s_of, np.array([s, -self._edge - SIDEWALK]),
            np.array([s, self._edge + SIDEWALK]), width, ("south", "north"))


class Intersection(_Road):
    """A four-way intersection centred on the origin; arms "north", "east", "south", "west".

    Each arm has ``lanes`` incoming and outgoing lanes of ``approach_length`` metres. Incoming
    lanes end at the box edge; a crosswalk lies across the last ``crosswalk_width`` metres of
    each arm and the stop line 1 m before it. Connectors: straight from every lane, left turns
    from lane 0 (next to the centre line), right turns from the outermost lane.
    """

    kind = "intersection"

    def __init__(self, world: Any, net: Any, lanes: int, approach_length: float, lane_width: float,
                 speed_limit: float, crosswalk_width: float, corner: float, median: float = 0.0,
                 at: Any = (0.0, 0.0), name: str = "", control: str = "stop") -> None:
        from .engine import Arc, LineType, Straight

        super().__init__(world)
        what = f"intersection({name!r})" if name else "intersection"
        if control not in ("stop", "signals"):
            raise SimError(f"{what}(control={control!r}): 'stop' (an all-way stop) or 'signals' "
                           "(traffic lights)", test=world.name)
        self.control = control
        self.traffic_lights = None  # made with the lane index when control="signals"
        if lanes not in (1, 2):
            raise SimError(f"{what}(lanes={lanes!r}): one or two lanes per approach",
                           test=world.name)
        if not approach_length > crosswalk_width + 2:
            raise SimError(f"{what}(approach_length={approach_length!r}): too short",
                           test=world.name)
        median = _check_median(median, what, world.name)
        try:
            o = np.asarray(at, dtype=float).reshape(2)
        except (TypeError, ValueError):
            o = np.array([math.nan, math.nan])
        if not np.all(np.isfinite(o)):
            raise SimError(f"{what}(at={at!r}): give the centre as (x, y) [m]", test=world.name)
        n, w, L = int(lanes), float(lane_width), float(approach_length)
        self.name = str(name)
        self.prefix = p_ = f"{name}." if name else ""
        self.n_lanes, self.lane_width, self.approach_length = n, w, L
        self.median = m2 = median / 2
        self.half = H = n * w + m2 + float(corner)
        self.crosswalk_width = float(crosswalk_width)
        self.origin = o
        N, S, C = LineType.NONE, LineType.STRIPED, LineType.CONTINUOUS_LINE
        # With a median both directions draw their own continuous centre line.
        inner_out = C if median > 0 else N
        self._in: dict[str, list[Lane]] = {}
        self._out: dict[str, list[Lane]] = {}
        self._conn: dict[tuple[str, str, int], Lane] = {}
        for d in DIRECTIONS:
            u = np.array(_UNIT[d])
            right_in = np.array([-u[1], u[0]])  # right of travel toward the centre (-u)
            self._in[d], self._out[d] = [], []
            for i in range(n):
                off = m2 + (i + 0.5) * w
                outer = C if i == n - 1 else S
                g = Straight(o + u * (H + L) + right_in * off, o + u * H + right_in * off, width=w,
                             line_types=(outer, C if i == 0 else N), speed_limit=speed_limit)
                self._in[d].append(self._lane(net, f"{p_}{d}.start", f"{p_}{d}.stop", g,
                                              f"{p_}{d}.in[{i}]", "travel", d, f"{p_}{d}.in", i))
                g = Straight(o + u * H - right_in * off, o + u * (H + L) - right_in * off, width=w,
                             line_types=(outer, inner_out if i == 0 else N),
                             speed_limit=speed_limit)
                self._out[d].append(self._lane(net, f"{p_}{d}.exit", f"{p_}{d}.end", g,
                                               f"{p_}{d}.out[{i}]", "travel", d, f"{p_}{d}.out", i))
        for d in DIRECTIONS:
            u = np.array(_UNIT[d])
            right_in = np.array([-u[1], u[0]])
            for turn, i_list in (("straight", range(n)), ("left", [0]), ("right", [n - 1])):
                d2 = {"straight": _OPPOSITE[d], "left": _LEFT_OF[d], "right": _RIGHT_OF[d]}[turn]
                u2 = np.array(_UNIT[d2])
                for i in i_list:
                    off = m2 + (i + 0.5) * w
                    p = o + u * H + right_in * off
                    if turn == "straight":
                        g = Straight(p, o + u2 * H + right_in * off, width=w, line_types=(N, N),
                                     speed_limit=speed_limit)
                    else:
                        c = o + u * H + u2 * H
                        radius = H - off if turn == "right" else H + off
                        phase = math.atan2(p[1] - c[1], p[0] - c[0])
                        sweep = math.pi / 2 if turn == "left" else -math.pi / 2
                        g = Arc(c, radius, phase, phase + sweep, clockwise=(turn == "left"),
                                width=w, line_types=(N, N), speed_limit=speed_limit)
                    self._conn[(d, turn, i)] = self._lane(
                        net, f"{p_}{d}.stop", f"{p_}{d2}.exit", g, f"{p_}{d}>{d2}[{i}]",
                        "connector", d, f"{p_}{d}>{d2}", i)
        self.centre = Point(float(o[0]), float(o[1]))

    def _after_index(self) -> None:
        """Register stop lines and crosswalks once the lane index exists."""
        idx = self.world.lane_index
        L, cw = self.approach_length, self.crosswalk_width
        span = self.n_lanes * self.lane_width + self.median + SIDEWALK
        for d in DIRECTIONS:
            u = np.array(_UNIT[d])
            right_in = np.array([-u[1], u[0]])
            for lane in self._in[d]:
                if self.control == "stop":
                    idx.add_stop(lane, L - cw - 1.0, "stop")
                idx.add_stop(lane, L - cw, "crosswalk")
                self.stop_lines.append(StopLine(lane, L - cw - 1.0, d))
            for lane in self._out[d]:
                idx.add_stop(lane, 0.0, "crosswalk")
            mid = self.origin + u * (self.half + cw / 2)
            sides = {"north": ("west", "east"), "south": ("west", "east"),
                     "east": ("south", "north"), "west": ("south", "north")}[d]
            # Walk from the first named side to the second.
            a_dir = np.array(_UNIT[sides[0]])
            s_of = {l.index: L - cw / 2 for l in self._in[d]}
            s_of.update({l.index: cw / 2 for l in self._out[d]})
            self._crosswalk_across(self.prefix + d, self._in[d] + self._out[d], s_of,
                                   mid + a_dir * span, mid - a_dir * span, cw, sides)
        if self.control == "signals":
            from .signals import intersection_lights

            self.traffic_lights = intersection_lights(self)

    def _arm(self, d: str) -> str:
        if d not in _UNIT:
            where = f" of intersection {self.name!r}" if self.name else ""
            raise SimError(f"unknown arm {d!r}{where}: use one of {list(DIRECTIONS)}",
                           test=self.world.name)
        return d

    def _pick(self, lanes: list[Lane], i: int, what: str) -> Lane:
        try:
            return lanes[i]
        except (IndexError, TypeError):
            raise SimError(f"{what}: lane {i!r} does not exist (lanes 0..{len(lanes) - 1})",
                           test=self.world.name) from None

    def approach(self, d: str, lane: int = 0) -> Lane:
        """Incoming lane ``lane`` (0 next to the centre line) of arm ``d``."""
        return self._pick(self._in[self._arm(d)], lane, f"approach({d!r})")

    def exit(self, d: str, lane: int = 0) -> Lane:
        """Outgoing lane ``lane`` of arm ``d``."""
        return self._pick(self._out[self._arm(d)], lane, f"exit({d!r})")

    def stop_line(self, d: str, lane: int = 0) -> StopLine:
        """The stop line of arm ``d`` on incoming lane ``lane``."""
        ln = self.approach(d, lane)
        return StopLine(ln, self.approach_length - self.crosswalk_width - 1.0, d)

    def crosswalk(self, d: str) -> Crosswalk:
        """The crosswalk across arm ``d`` (sides named by compass, e.g. "west"/"east")."""
        self._arm(d)
        return next(c for c in self.crosswalks if c.name == self.prefix + d)

    def turn_target(self, d: str, turn: str) -> str:
        """The arm a vehicle coming from ``d`` leaves by when it turns ``turn``."""
        table = {"straight": _OPPOSITE, "left": _LEFT_OF, "right": _RIGHT_OF}
        if turn not in table:
            raise SimError(f"unknown turn {turn!r}: use 'left', 'right' or 'straight'",
                           test=self.world.name)
        return table[turn][self._arm(d)]

    def connector(self, d: str, turn: str, lane: int | None = None) -> Lane:
        """The connector lane through the box from arm ``d`` turning ``turn``."""
        self.turn_target(d, turn)
        if lane is None:
            lane = {"left": 0, "right": self.n_lanes - 1}.get(turn, 0)
        key = (d, turn, lane)
        if key not in self._conn:
            allowed = sorted(i for (a, t, i) in self._conn if a == d and t == turn)
            raise SimError(f"no {turn} turn from lane {lane} of the {d} approach "
                           f"(from lanes {allowed})", test=self.world.name)
        return self._conn[key]

    def route(self, d: str, turn: str = "straight", lane: int | None = None) -> Route:
        """Approach lane, connector and exit lane from arm ``d`` turning ``turn``."""
        conn = self.connector(d, turn, lane)
        d2 = self.turn_target(d, turn)
        i = conn.number
        exit_lane = self._out[d2][min(i, self.n_lanes - 1)]
        return Route((self._in[d][i], conn, exit_lane), turn=turn)

    def arm_of(self, lane: Lane) -> str | None:
        """The arm whose approach ``lane`` is, or None."""
        for d in DIRECTIONS:
            if lane in self._in[d]:
                return d
        return None

    def owns(self, lane: Lane) -> bool:
        """Whether ``lane`` (an approach, connector or exit) belongs to this intersection."""
        return any(lane is l for l in self.all_lanes)

    def __repr__(self) -> str:
        c = self.centre
        return f"Intersection({self.name!r}, at=({c.x:g}, {c.y:g}))" if self.name else \
            "Intersection()"


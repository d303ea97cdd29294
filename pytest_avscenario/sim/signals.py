"""Traffic signals: the lights, stop signs and stop lines of a map file, and the lights' phases.

:func:`map_signals` reads the ``<signal>``, ``<signalReference>`` and ``<controller>`` elements
of an OpenDRIVE file (1.4-1.7) into :class:`MapSignals`: every signal with its id, type,
road/s/t, world position and heading, and the *stop positions* it rules — one per lane it
applies to, at the signal's s on that lane, measured along the lane in its direction of
travel. Which lanes a signal applies to is its ``<validity fromLane toLane>`` (lane 0, the
reference line, rules no lane: CARLA's exported lights stand on a pole with validity 0..0 and
name their lanes through ``<signalReference>`` elements on the junction's connecting roads);
without a validity element it applies to every lane driving in its ``orientation`` ("+": along
the reference line, "-": against it, "none": both). Controllers group the signals that switch
together; a junction's ``<controller sequence=...>`` orders its controllers.

OpenDRIVE gives no timing, so :class:`TrafficLights` runs a fixed-time plan a tester expects
(CARLA's defaults: 10 s green, 3 s amber, then red while the junction's other controllers
take their turn after a 2 s all-red clearance): the controllers of one junction get green one
after another in their sequence order, every junction starts its cycle ``offset`` seconds in
(``world.signals(green=..., amber=..., all_red=..., cycle=..., offset=...)``, a number for
every junction or ``{junction id: s}``), so a sampler can range over the phase a car arrives
in. A light's state is a pure function of the simulation time: deterministic, and computed for
a whole recording at once.

Types: OpenDRIVE/CARLA ``1000001`` (and other dynamic ``1000xxx``) traffic lights, ``206``
stop signs and ``294`` stop lines (the German catalogue both use). Stop signs and stop lines
are parsed and listed; the lights are the ones that switch. A malformed element raises a
:class:`~.opendrive.MapError` naming the file and the element. Nothing is written anywhere;
the file is read again (once per process per content), its digest
checked against the loaded map's (a file without ``<signal>`` or ``<controller>`` is not
parsed at all).
"""

from __future__ import annotations

import hashlib
import math
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping

import numpy as np

from .opendrive import DRIVABLE, MapData, MapError, xml_root
from .opendrive import _num as _float  # an attribute as a finite number, or a MapError naming it

__all__ = ["intersection_lights", "SignalData", "StopPosition", "ControllerData", "MapSignals", "map_signals",
           "TrafficLights", "LightAhead", "GREEN", "AMBER", "RED", "STATES", "must_stop",
           "TRAFFIC_LIGHT", "STOP_SIGN", "STOP_LINE", "AMBER_DECEL"]

TRAFFIC_LIGHT, STOP_SIGN, STOP_LINE = "traffic_light", "stop_sign", "stop_line"
GREEN, AMBER, RED = "green", "amber", "red"
#: state names by the code the recording keeps them as (``light.<id>`` signals: 0, 1, 2)
STATES = (GREEN, AMBER, RED)

#: [m/s^2] the deceleration the amber-time formula assumes a driver stops at (ITE's 10 ft/s^2)
AMBER_DECEL = 3.0
#: [s] default phase plan (CARLA's traffic-light defaults)
DEFAULT_GREEN, DEFAULT_AMBER, DEFAULT_ALL_RED = 10.0, 3.0, 2.0


def _kind(type_: str, dynamic: bool) -> str:
    if type_ == "206":
        return STOP_SIGN
    if type_ == "294":
        return STOP_LINE
    if type_.startswith("1000") or dynamic:
        return TRAFFIC_LIGHT
    return "other"


@dataclass(frozen=True)
class StopPosition:
    """Where traffic on ``lane`` (a ``"road/section/lane"`` id) stops for signal ``signal``:
    ``s`` [m] along the lane in its direction of travel, the point ``(x, y)`` [m] on its centre
    line there and the lane's ``heading`` [rad] and ``width`` [m]."""

    signal: str
    lane: str
    s: float
    x: float
    y: float
    heading: float
    width: float


@dataclass(frozen=True)
class SignalData:
    """One ``<signal>``: ``kind`` is :data:`TRAFFIC_LIGHT`, :data:`STOP_SIGN`,
    :data:`STOP_LINE` or "other"; ``x``/``y`` [m] its world position (reference line at ``s``
    plus ``t`` square to it), ``heading`` [rad] the direction it faces traffic from;
    ``lanes`` the validity lane ids of its own road (empty when it rules lanes only through
    references); ``stops`` every stop position it rules (its own and its references')."""

    id: str
    name: str
    type: str
    subtype: str
    kind: str
    road: str
    s: float
    t: float
    orientation: str
    dynamic: bool
    x: float
    y: float
    heading: float
    lanes: tuple[int, ...] = ()
    stops: tuple[StopPosition, ...] = ()


@dataclass(frozen=True)
class ControllerData:
    """One ``<controller>``: the signals that switch together; ``junction`` the junction that
    lists it ("" when none), ``sequence`` its place there (or its own attribute)."""

    id: str
    name: str
    signals: tuple[str, ...]
    junction: str = ""
    sequence: int = 0


@dataclass(frozen=True)
class MapSignals:
    """The signals of one map: ``signals`` by id, ``controllers`` by id (every traffic light
    has one: a light no controller lists gets its own, ``"signal:<id>"``), ``groups`` the
    controllers that take turns (a junction's, in sequence order; a controller of no junction
    alone)."""

    path: str
    signals: dict[str, SignalData]
    controllers: dict[str, ControllerData]
    groups: dict[str, tuple[str, ...]]
    #: what is computed from these signals alone, once per map and process (their lights'
    #: entries in a recording): every world on the map shares it
    memo: dict = field(default_factory=dict, compare=False, repr=False)

    def of_kind(self, kind: str) -> list[SignalData]:
        return [s for s in self.signals.values() if s.kind == kind]

    @property
    def stops(self) -> list[StopPosition]:
        """Every stop position of every signal."""
        return [p for s in self.signals.values() for p in s.stops]


# -- parsing -------------------------------------------------------------------------------------

_CACHE: dict[str, MapSignals] = {}
_LOCK = threading.Lock()


def map_signals(data: MapData) -> MapSignals:
    """The signals of the map ``data`` was loaded from (parsed once per process per content)."""
    with _LOCK:
        got = _CACHE.get(data.digest)
    if got is not None:
        return got
    try:
        blob = Path(data.path).read_bytes()
    except OSError as exc:
        raise MapError(f"map file {data.path}: cannot be read again for its signals ({exc})") from None
    if hashlib.sha256(blob).hexdigest() != data.digest:
        raise MapError(f"map file {data.path} changed since it was loaded; load it again")
    got = _parse(data, blob)
    with _LOCK:
        _CACHE[data.digest] = got
    return got


def _int(el: Any, attr: str, path: str, where: str) -> int:
    v = el.get(attr)
    try:
        return int(v)
    except (TypeError, ValueError):
        raise MapError(f"map file {path}: {where} has {attr}={v!r}, not a lane number") from None


class _Road:
    """What signals need of one road: its section bounds and its lanes by number per section."""

    def __init__(self, el: Any, data: MapData, path: str) -> None:
        self.id = el.get("id", "")
        self.length = _float(el, "length", path, f"road {self.id}")
        secs = el.findall("lanes/laneSection")
        self.starts = [_float(s, "s", path, f"road {self.id} <laneSection>") for s in secs]
        self.data = data

    def section(self, s: float) -> int:
        k = 0
        for i, s0 in enumerate(self.starts):
            if s0 <= s + 1e-9:
                k = i
        return k

    def bounds(self, k: int) -> tuple[float, float]:
        s1 = self.starts[k + 1] if k + 1 < len(self.starts) else self.length
        return self.starts[k], min(s1, self.length)

    def lanes_at(self, s: float) -> list[Any]:
        k = self.section(s)
        pre = f"{self.id}/{k}/"
        return [l for lid, l in self.data.lanes.items() if lid.startswith(pre)]

    def stop(self, signal: str, lane: Any, s: float) -> StopPosition:
        """The stop position on ``lane`` (LaneData) at the road's ``s``."""
        s0, s1 = self.bounds(lane.section)
        f = 0.0 if s1 - s0 <= 1e-9 else min(max((s - s0) / (s1 - s0), 0.0), 1.0)
        if not lane.forward:
            f = 1.0 - f
        n = len(lane.s)
        u = f * (n - 1)  # samples are equally spaced in the road's s
        i = min(int(u), n - 2)
        w = u - i
        sl = float(lane.s[i] + w * (lane.s[i + 1] - lane.s[i]))
        x = float(lane.xy[i, 0] + w * (lane.xy[i + 1, 0] - lane.xy[i, 0]))
        y = float(lane.xy[i, 1] + w * (lane.xy[i + 1, 1] - lane.xy[i, 1]))
        h = float(lane.heading[i] + w * (lane.heading[i + 1] - lane.heading[i]))
        wd = float(lane.width[i] + w * (lane.width[i + 1] - lane.width[i]))
        return StopPosition(signal, lane.id, sl, x, y, h, wd)


def _validity(el: Any, path: str, where: str) -> tuple[list[int], bool]:
    """(lane numbers, whether any validity element was given)."""
    vals = el.findall("validity")
    out: list[int] = []
    for v in vals:
        a = _int(v, "fromLane", path, where + " <validity>")
        b = _int(v, "toLane", path, where + " <validity>")
        lo, hi = min(a, b), max(a, b)
        out.extend(n for n in range(lo, hi + 1) if n != 0)
    return out, bool(vals)


def _ruled(road: _Road, s: float, numbers: list[int], given: bool, orientation: str) -> list[Any]:
    """The drivable lanes at ``s`` a signal (or reference) rules."""
    lanes = [l for l in road.lanes_at(s) if l.kind in DRIVABLE]
    if given:
        return [l for l in lanes if l.lane in numbers]
    if orientation == "+":
        return [l for l in lanes if l.forward]
    if orientation == "-":
        return [l for l in lanes if not l.forward]
    return lanes


def _parse(data: MapData, blob: bytes) -> MapSignals:
    path = data.path
    if b"<signal" not in blob and b"<controller" not in blob:
        return MapSignals(path, {}, {}, {})  # most maps: no need to parse the file again
    root = xml_root(path, blob)
    roads: dict[str, _Road] = {}
    raw: list[tuple[Any, _Road]] = []
    refs: list[tuple[Any, _Road]] = []
    for rel in root.findall("road"):
        road = _Road(rel, data, path)
        roads[road.id] = road
        raw.extend((e, road) for e in rel.findall("signals/signal"))
        refs.extend((e, road) for e in rel.findall("signals/signalReference"))
    stops: dict[str, dict[str, StopPosition]] = {}
    made: dict[str, dict[str, Any]] = {}

    def add(stop: StopPosition) -> None:
        mine = stops.setdefault(stop.signal, {})
        old = mine.get(stop.lane)
        if old is None or stop.s < old.s:  # several references to one lane: the first
            mine[stop.lane] = stop

    for el, road in raw:
        sid = el.get("id")
        where = f"road {road.id} <signal id={sid!r}>"
        if not sid:
            raise MapError(f"map file {path}: road {road.id} has a <signal> without an id")
        if sid in made:
            raise MapError(f"map file {path}: {where}: the id is used by another signal too "
                           f"(road {made[sid]['road']})")
        s = _float(el, "s", path, where)
        t = _float(el, "t", path, where, 0.0)
        h_off = _float(el, "hOffset", path, where, 0.0)
        orientation = el.get("orientation", "+")
        if orientation not in ("+", "-", "none"):
            raise MapError(f"map file {path}: {where} has orientation={orientation!r}, "
                           "not '+', '-' or 'none'")
        if s < -1e-6 or s > road.length + 1.0:
            raise MapError(f"map file {path}: {where} has s={s:g}, outside its road "
                           f"(0..{road.length:g} m)")
        x, y, h = (float(a[0]) for a in data.reference[road.id](np.array([min(max(s, 0.0), road.length)])))
        facing = h + h_off + (math.pi if orientation == "-" else 0.0)
        dyn = el.get("dynamic", "no") == "yes"
        numbers, given = _validity(el, path, where)
        lanes = _ruled(road, s, numbers, given, orientation)
        for l in lanes:
            add(road.stop(sid, l, s))
        made[sid] = dict(id=sid, name=el.get("name", ""), type=el.get("type", ""),
                         subtype=el.get("subtype", ""),
                         kind=_kind(el.get("type", ""), dyn), road=road.id, s=s, t=t,
                         orientation=orientation, dynamic=dyn,
                         x=x - t * math.sin(h), y=y + t * math.cos(h),
                         heading=math.atan2(math.sin(facing), math.cos(facing)),
                         lanes=tuple(sorted(l.lane for l in lanes)))
    for el, road in refs:
        sid = el.get("id")
        where = f"road {road.id} <signalReference id={sid!r}>"
        if sid not in made:
            raise MapError(f"map file {path}: {where} refers to no <signal> of the file")
        s = _float(el, "s", path, where)
        orientation = el.get("orientation", "+")
        numbers, given = _validity(el, path, where)
        for l in _ruled(road, min(max(s, 0.0), road.length), numbers, given, orientation):
            add(road.stop(sid, l, min(max(s, 0.0), road.length)))
    signals = {sid: SignalData(**d, stops=tuple(sorted(stops.get(sid, {}).values(),
                                                       key=lambda p: p.lane)))
               for sid, d in made.items()}
    # controllers
    in_junction: dict[str, tuple[str, int]] = {}
    for j in root.findall("junction"):
        for c in j.findall("controller"):
            cid = c.get("id")
            if cid:
                seq = c.get("sequence")
                in_junction[cid] = (j.get("id", ""), int(seq) if seq and seq.lstrip("-").isdigit() else 0)
    controllers: dict[str, ControllerData] = {}
    for c in root.findall("controller"):
        cid = c.get("id")
        where = f"<controller id={cid!r}>"
        if not cid:
            raise MapError(f"map file {path}: a <controller> without an id")
        ids: list[str] = []
        for ctl in c.findall("control"):
            sid = ctl.get("signalId")
            if sid not in signals:
                raise MapError(f"map file {path}: {where} controls signal {sid!r}, which the "
                               "file does not have")
            if sid not in ids:
                ids.append(sid)
        junction, seq = in_junction.get(cid, ("", None))
        if seq is None:
            own = c.get("sequence", "0")
            seq = int(own) if own.lstrip("-").isdigit() else 0
        controllers[cid] = ControllerData(cid, c.get("name", ""), tuple(ids), junction, seq)
    ruled = {sid for c in controllers.values() for sid in c.signals}
    for sid, sg in signals.items():
        if sg.kind == TRAFFIC_LIGHT and sid not in ruled:
            controllers[f"signal:{sid}"] = ControllerData(f"signal:{sid}", "", (sid,))
    groups: dict[str, list[ControllerData]] = {}
    for c in controllers.values():
        if not any(signals[s].kind == TRAFFIC_LIGHT for s in c.signals):
            continue
        groups.setdefault(c.junction or f"controller:{c.id}", []).append(c)
    return MapSignals(path, signals, controllers,
                      {g: tuple(c.id for c in sorted(cs, key=lambda c: (c.sequence, c.id)))
                       for g, cs in groups.items()})


# -- the lights' phases ---------------------------------------------------------------------------


@dataclass(frozen=True)
class LightAhead:
    """A traffic light on an agent's route ahead: its stop position ``stop`` and ``state``
    now; ``route_index`` and ``s`` [m] place the stop on the route (the driver's observation
    carries these)."""

    route_index: int
    s: float
    state: str
    signal: str


def must_stop(state: str, d: float, v: float, comfort_decel: float, max_decel: float,
              committed: bool) -> bool:
    """Whether a driver whose front bumper is ``d`` [m] before a light's stop position, at
    ``v`` [m/s], stops for a light in ``state``: never on green; on amber when it can stop
    there at ``comfort_decel`` [m/s^2] (else it goes on, ``committed``); on red unless it
    went on at amber (``committed``), is past the line, or could not stop even at
    ``max_decel``. (Drivers aim a little before the line; the choice is made on the line.)"""
    if state == GREEN or committed or d <= 0.0:
        return False
    need = v * v / (2.0 * d)
    if state == AMBER:
        return need <= comfort_decel
    return need <= max_decel


def _light_tables(signals: MapSignals) -> tuple[dict, dict, dict, dict]:
    """(lights by id, controller of each light, each controller's (junction, turn, turns),
    stops by lane id: ``[(s, light)]`` sorted by s) of ``signals``."""
    lights = {sid: s for sid, s in signals.signals.items() if s.kind == TRAFFIC_LIGHT}
    controller_of: dict[str, str] = {}
    phase: dict[str, tuple[str, int, int]] = {}  # controller -> (group, j, n)
    for g, cids in signals.groups.items():
        for j, cid in enumerate(cids):
            phase[cid] = (g, j, len(cids))
            for sid in signals.controllers[cid].signals:
                controller_of.setdefault(sid, cid)
    stops: dict[str, list[tuple[float, str]]] = {}
    for sid, sg in lights.items():
        if sid not in controller_of:
            continue
        for p in sg.stops:
            stops.setdefault(p.lane, []).append((p.s, sid))
    for v in stops.values():
        v.sort()
    return lights, controller_of, phase, stops


class TrafficLights:
    """The lights of one world and their fixed-time plan (see the module doc).

    ``stops`` maps a lane id to its ``[(s [m], signal id)]`` stop positions (traffic lights
    only), sorted by s. ``state(signal, t)`` is "green", "amber" or "red"; ``codes(signal, t)``
    the same for an array of times as 0/1/2. ``lights``, ``controller_of``, ``phase`` and
    ``stops`` are shared by every world on the map (read them, do not change them); the plan
    (``green``, ``amber``, ``all_red``, ``offset``, ``offsets``, ``phase_share``) is set
    through :meth:`configure` and :meth:`amber_at`, or by assigning a field.
    """

    def __init__(self, signals: MapSignals) -> None:
        self.map = signals
        # what follows from the map's signals alone is made once per map and process and
        # shared by every world on it (read-only: a world's plan lives in the fields below)
        got = signals.memo.get("lights")
        if got is None:
            got = signals.memo["lights"] = _light_tables(signals)
        self.lights, self.controller_of, self.phase, self.stops = got
        self.green, self.amber, self.all_red = DEFAULT_GREEN, DEFAULT_AMBER, DEFAULT_ALL_RED
        self.offsets: dict[str, float] = {}
        self.offset = 0.0
        self.phase_share = 0.0

    #: the fields of the plan: setting one drops the states and constants worked out so far
    _PLAN = frozenset({"green", "amber", "all_red", "offsets", "offset", "phase_share"})

    def __setattr__(self, name: str, value: Any) -> None:
        object.__setattr__(self, name, value)
        if name in TrafficLights._PLAN:
            object.__setattr__(self, "_consts", {})
            object.__setattr__(self, "_valid", {})  # signal -> (state, from, until) [s]

    def configure(self, *, green: float | None = None, amber: float | None = None,
                  all_red: float | None = None, cycle: float | None = None,
                  offset: Any = None, phase: float | None = None,
                  test: str = "") -> "TrafficLights":
        """Set the plan: ``green``, ``amber``, ``all_red`` [s] per turn; ``cycle`` [s] (a
        two-controller junction's whole cycle; sets green = cycle / 2 - amber - all_red);
        ``offset`` [s] into every junction's cycle at t = 0 (a number) or per junction
        (``{junction id: s}``, others 0); ``phase`` the same as a share of each junction's
        cycle (0..1, added to the offset: a sampler's unit range over every phase)."""
        from .errors import SimError

        def num(name: str, v: Any, positive: bool) -> float:
            try:
                x = float(v)
            except (TypeError, ValueError):
                x = math.nan
            if isinstance(v, bool) or not math.isfinite(x) or x < 0 or (positive and x == 0):
                raise SimError(f"world.signals({name}={v!r}): need a finite number of seconds "
                               f"{'> 0' if positive else '>= 0'}", test=test)
            return x

        if amber is not None:
            self.amber = num("amber", amber, False)
        if all_red is not None:
            self.all_red = num("all_red", all_red, False)
        if green is not None:
            self.green = num("green", green, True)
        if cycle is not None:
            c = num("cycle", cycle, True)
            g = c / 2 - self.amber - self.all_red
            if g <= 0:
                raise SimError(f"world.signals(cycle={cycle!r}): a cycle of two turns needs more "
                               f"than 2 x (amber + all_red) = {2 * (self.amber + self.all_red):g} s",
                               test=test)
            self.green = g
        if phase is not None:
            f = num("phase", phase, False)
            if f > 1.0:
                raise SimError(f"world.signals(phase={phase!r}): a share of the cycle, 0..1",
                               test=test)
            self.phase_share = f
        if offset is not None:
            if isinstance(offset, Mapping):
                unknown = [k for k in offset if str(k) not in self.map.groups]
                if unknown:
                    raise SimError(f"world.signals(offset=...): no signalled junction "
                                   f"{unknown[0]!r}; the map's are {sorted(self.map.groups)}",
                                   test=test)
                self.offsets = {str(k): num(f"offset[{k!r}]", v, False) for k, v in offset.items()}
            else:
                self.offset = num("offset", offset, False)
        return self

    def amber_at(self, signal: str, t: float) -> "TrafficLights":
        """Shift the cycle of ``signal``'s junction so that ``signal`` turns amber at ``t``
        [s] (after the plan's green; the junction's other controllers keep their turns)."""
        from .errors import SimError

        cid = self.controller_of.get(str(signal))
        if cid is None:
            raise SimError(f"amber_at({signal!r}): no traffic light {signal!r} with a controller; "
                           f"the lights are {sorted(self.controller_of)[:8]}...")
        g, j, _ = self.phase[cid]
        self.offsets[g] = float(np.mod(self.green + j * self.slot - float(t), self.cycle_of(g))) \
            - self.phase_share * self.cycle_of(g)
        self.offsets = self.offsets  # the plan changed (in place): drop what was worked out
        return self

    def first_on(self, lanes: Iterable[Any]) -> str | None:
        """The first traffic light ruling any of ``lanes`` (lanes or lane ids, in order)."""
        for lane in lanes:
            got = self.stops.get(getattr(lane, "id", lane))
            if got:
                return got[0][1]
        return None

    @property
    def slot(self) -> float:
        """[s] one controller's turn: green, amber, all-red."""
        return self.green + self.amber + self.all_red

    def cycle_of(self, group: str) -> float:
        """[s] the cycle of a junction (a lone controller alternates with an all-red turn)."""
        n = len(self.map.groups[group])
        return max(n, 2) * self.slot

    def _offset(self, group: str) -> float:
        return self.offsets.get(group, self.offset) + self.phase_share * self.cycle_of(group)

    def codes(self, signal: str, t: Any) -> np.ndarray:
        """State codes (0 green, 1 amber, 2 red) of ``signal`` at times ``t`` [s]."""
        t = np.asarray(t, dtype=float)
        cid = self.controller_of.get(signal)
        if cid is None:
            return np.zeros(t.shape, dtype=np.int8)
        g, j, n = self.phase[cid]
        tau = np.mod(t + self._offset(g) - j * self.slot, self.cycle_of(g))
        # a hair of slack: a phase boundary that a sum of steps reaches lands on its side
        tau = np.where(tau > self.cycle_of(g) - 1e-9, 0.0, tau)
        return np.where(tau < self.green - 1e-9, 0,
                        np.where(tau < self.green + self.amber - 1e-9, 1, 2)).astype(np.int8)

    def state(self, signal: str, t: float) -> str:
        """The state of ``signal`` at ``t`` [s] ("green", "amber", "red"); as :meth:`codes`."""
        got = self._valid.get(signal)
        if got is not None and got[1] <= t < got[2]:
            return got[0]
        state, until = self._state(signal, t)
        self._valid[signal] = (state, t, until)
        return state

    def states(self, signals: Iterable[str], t: float) -> tuple[list[str], float]:
        """The states of ``signals`` at ``t`` [s], and a time [s] before which none of them
        changes (a driver's observation is made again only then)."""
        out = []
        until = math.inf
        valid = self._valid
        for sid in signals:
            out.append(self.state(sid, t))
            u = valid[sid][2]
            if u < until:
                until = u
        return out, until

    def _state(self, signal: str, t: float) -> tuple[str, float]:
        # (the state, and a time before which it stays: the phase grows with t as t does, so
        # until the next threshold less a microsecond — rounding is a million times less —
        # the same arithmetic gives the same state)
        c = self._consts.get(signal)
        if c is None:
            c = self._consts[signal] = self._constants(signal)
        if c is None:
            return GREEN, math.inf
        off, shift, cyc, top, green_end, amber_end = c
        tau = math.fmod(t + off - shift, cyc)
        if tau < 0:
            tau += cyc
        if tau > top:
            return GREEN, t  # (as at phase 0; the cycle's wrap is next)
        if tau < green_end:
            return GREEN, t + (green_end - tau) - 1e-6
        if tau < amber_end:
            return AMBER, t + (amber_end - tau) - 1e-6
        return RED, t + (top - tau) - 1e-6

    def _constants(self, signal: str) -> tuple[float, ...] | None:
        """The plan's numbers :meth:`_state` uses for ``signal`` (None: no controller), each
        computed as :meth:`codes` computes it; kept until the plan changes (every step asks
        for the states of the same few lights)."""
        cid = self.controller_of.get(signal)
        if cid is None:
            return None
        g, j, n = self.phase[cid]
        cyc = self.cycle_of(g)
        return (self._offset(g), j * self.slot, cyc, cyc - 1e-9, self.green - 1e-9,
                self.green + self.amber - 1e-9)

    def on_lane(self, lane_id: str) -> list[tuple[float, str]]:
        return self.stops.get(lane_id, [])

    def ahead(self, plan: list[Any], route_index: int, horizon: float = 150.0) -> list[tuple[int, float, float, str]]:
        """The light stops on ``plan`` from lane ``route_index`` on, within ``horizon`` [m] of
        that lane's end: ``(plan index, s on that lane, distance from the start of lane
        route_index [m], signal)``."""
        out = []
        acc = 0.0
        limit = plan[route_index].length + horizon
        for j in range(route_index, len(plan)):
            if acc > limit:
                break
            lane = plan[j]
            for s, sid in self.stops.get(lane.id, ()):
                out.append((j, s, acc + s, sid))
            acc += lane.length
        return out

    def record(self, t: np.ndarray, lanes: Iterable[str]) -> tuple[dict[str, np.ndarray], list[dict]]:
        """The recording of the lights of every junction one of whose lights rules any of
        ``lanes`` (the whole junction, so pictures show all its heads): per light a
        ``light.<id>`` series of state codes over ``t``, and the meta entries ``{"id",
        "controller", "x", "y", "heading", "stops": [{"lane", "s", "x", "y", "heading",
        "width"}]}``. A light's ``stops`` list is made once per map and process and shared by
        every recording (read it, do not change it), as :func:`.recording.road_meta` shares a
        lane's points; each entry's own dict is new."""
        by_lane, entries = self._recordable()
        groups = set()
        for lane in lanes:
            got = by_lane.get(lane)
            if got:
                groups |= got
        mine = [(sid, e) for sid, g, e in entries if g in groups]
        if not mine:
            return {}, []
        sids = tuple(sid for sid, _ in mine)
        t = np.asarray(t, dtype=float)
        # every case of a campaign records the same times under the same plan: the codes are
        # worked out once per map, times and plan (a copy as floats goes into each recording)
        memo = self.map.memo.setdefault("codes", {})
        key = (sids, t.tobytes(), self._plan_key())
        codes = memo.get(key)
        if codes is None:
            if len(memo) >= 16:
                memo.clear()
            codes = memo[key] = self._codes_many(list(sids), t)
        codes = codes.astype(float)
        series = {name: row for (_, (_, _, _, _, _, name)), row in zip(mine, codes)}
        meta = [{"id": sid, "controller": cid, "x": x, "y": y, "heading": h, "stops": stops}
                for sid, (cid, x, y, h, stops, _) in mine]
        return series, meta

    def _plan_key(self) -> tuple:
        """Every field of the plan, as a key."""
        return (self.green, self.amber, self.all_red, self.offset, self.phase_share,
                tuple(sorted(self.offsets.items())))

    def _recordable(self) -> tuple[dict[str, set], list[tuple[str, str, tuple]]]:
        """(lane id -> the junctions whose lights rule it, [(signal, junction, its meta entry
        as plain values with its stops' list, its series' name)] in the lights' order): what
        :meth:`record` writes of the map's lights, made once (the lights and their stops never
        change; the plan does)."""
        got = self.map.memo.get("record")
        if got is None:
            by_lane: dict[str, set] = {}
            entries = []
            for sid, sg in self.lights.items():
                cid = self.controller_of.get(sid)
                if cid is None:
                    continue
                g = self.phase[cid][0]
                for p in sg.stops:
                    by_lane.setdefault(p.lane, set()).add(g)
                entries.append((sid, g, (cid, round(sg.x, 3), round(sg.y, 3),
                                         round(sg.heading, 4),
                                         [{"lane": p.lane, "s": round(p.s, 4),
                                           "x": round(p.x, 3), "y": round(p.y, 3),
                                           "heading": round(p.heading, 4),
                                           "width": round(p.width, 3)} for p in sg.stops],
                                         f"light.{sid}")))
            got = self.map.memo["record"] = (by_lane, entries)
        return got

    def _codes_many(self, signals: list[str], t: Any) -> np.ndarray:
        """:meth:`codes` of each of ``signals`` (controlled lights) as the rows of one
        ``(len(signals), len(t))`` array, the same arithmetic element by element."""
        t = np.asarray(t, dtype=float)
        off, shift, cyc = [], [], []
        for sid in signals:
            g, j, _ = self.phase[self.controller_of[sid]]
            off.append(self._offset(g))
            shift.append(j * self.slot)
            cyc.append(self.cycle_of(g))
        off, shift, cyc = (np.asarray(v, dtype=float)[:, None] for v in (off, shift, cyc))
        tau = np.mod(t[None, :] + off - shift, cyc)
        tau = np.where(tau > cyc - 1e-9, 0.0, tau)
        return np.where(tau < self.green - 1e-9, 0,
                        np.where(tau < self.green + self.amber - 1e-9, 1, 2)).astype(np.int8)


def intersection_lights(inter: Any) -> TrafficLights:
    """The lights of a built four-way intersection (``world.intersection(control="signals")``):
    one per arm, standing at the right kerb beside its stop line and ruling every incoming
    lane of the arm at the stop line; north and south on one controller, east and west on
    the other, taking turns (the map plan: green, amber, all-red)."""
    p_ = inter.prefix
    signals: dict[str, SignalData] = {}
    s_line = inter.approach_length - inter.crosswalk_width - 1.0
    for d, lanes in inter._in.items():
        kerb = lanes[-1].geometry  # the outermost lane: the head stands right of it
        head = kerb.position(s_line, -(kerb.width_at(s_line) / 2 + 1.5))
        facing = float(kerb.heading_at(s_line)) + math.pi
        sid = f"{p_}{d}"
        stops = []
        for lane in lanes:
            g = lane.geometry
            x, y = g.position(s_line, 0.0)
            stops.append(StopPosition(sid, lane.id, s_line, float(x), float(y),
                                      float(g.heading_at(s_line)), float(g.width_at(s_line))))
        signals[sid] = SignalData(sid, f"{d} approach", "1000001", "-1", TRAFFIC_LIGHT, "",
                                  s_line, 0.0, "+", True, float(head[0]), float(head[1]),
                                  math.atan2(math.sin(facing), math.cos(facing)), (),
                                  tuple(stops))
    group = inter.name or "intersection"
    controllers = {
        f"{p_}north-south": ControllerData(f"{p_}north-south", "north-south",
                                           (f"{p_}north", f"{p_}south"), group, 0),
        f"{p_}east-west": ControllerData(f"{p_}east-west", "east-west",
                                         (f"{p_}east", f"{p_}west"), group, 1),
    }
    return TrafficLights(MapSignals("", signals, controllers,
                                    {group: (f"{p_}north-south", f"{p_}east-west")}))

"""Recording a run: per-step kinematics and flags of every agent into preallocated arrays.

The world writes one sample per step (:meth:`Recorder.write`), then :meth:`Recorder.finish`
turns the arrays into the :class:`~pytest_avscenario.trajectory.Trajectory` that monitors
read: the contract between the simulator and the monitors. Agents absent at a step (not yet
appeared, or gone) are recorded with NaN kinematics and ``present`` False, so every agent has
one row for the whole run.

The ego's *decisions* go into the trajectory's ``meta["decisions"]`` (plain JSON, so they
travel wherever the trajectory does): a driver that decides discretely (``highway_env_agent``)
keeps ``ego.decisions``, a list of ``(t [s], action)``; a driver with a ``last_reason`` (the
autopilot, the careful reference driver) says why it chose its last command. Only changes
are kept (the decision in force until the next one), so a 1-Hz agent that says ``IDLE`` for
a minute costs one entry.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..trajectory import Trajectory
from .geometry import wrap_to_pi

__all__ = ["Recorder", "action_label", "road_meta", "map_sidewalks"]

_ABSENT = (math.nan,) * 7 + (-1,)


class Recorder:
    """Fills preallocated ``(T, A, k)`` arrays each step and builds the Trajectory at the end."""

    def __init__(self, world: Any, agents: list[Any], n: int) -> None:
        self.world = world
        self.agents = agents
        self.code = world.lane_index.code
        A = len(agents)
        self.kin = np.empty((n, A, 8))  # x, y, vx, vy, speed, heading, lane_offset, lane code
        self.flags = np.zeros((n, A, 3), dtype=bool)  # crashed, on_road, present
        self.buses = [a for a in agents if a.kind == "bus"]
        self.arm = np.zeros((n, len(self.buses)))
        self.cmd = np.zeros((n, 2))  # ego commanded acceleration, steering
        drv = getattr(agents[0], "driver", None)
        # a user policy is wrapped (PolicyDriver.target): its reason is the wrapped object's
        self.why = next((d for d in (drv, getattr(drv, "target", None))
                         if isinstance(getattr(d, "last_reason", None), str)), None)
        self.reasons: list[list[Any]] = []

    def write(self, k: int) -> None:
        code = self.code
        rows = []
        fl = []
        for a in self.agents:
            if not a.active:
                rows.append(_ABSENT)
                fl.append((False, False, False))
                continue
            p = a.position
            h = a.heading
            v = a.speed
            c = math.cos(h)
            s = math.sin(h)
            li = a.lane_index
            rows.append((p[0], p[1], v * c, v * s, v, wrap_to_pi(h),
                         a.lane_r if li is not None else math.nan,
                         code[li] if li is not None else -1))
            fl.append((a.crashed, a.is_on_road, True))
        self.kin[k] = rows
        self.flags[k] = fl
        if self.buses:
            self.arm[k] = [b.stop_arm for b in self.buses]
        act = self.agents[0].action
        self.cmd[k] = (act["acceleration"], act["steering"])
        if self.why is not None and k > 0:
            # the reason of the command applied from t[k-1] on (sample 0 precedes any command)
            why = self.why.last_reason
            if not self.reasons or self.reasons[-1][1] != why:
                self.reasons.append([round((k - 1) * self.world.dt, 6), str(why)])

    def finish(self, n: int, seconds: float, stopped: str | None) -> Trajectory:
        w = self.world
        kin = self.kin[:n].transpose(1, 0, 2)  # (A, T, 8)
        flags = self.flags[:n].transpose(1, 0, 2)
        ids = getattr(w.lane_index, "id_array", None)  # a map's: made once per process
        if ids is None:
            ids = np.asarray([l.id for l in w.lane_index.order] + [""])
        codes = kin[:, :, 7].astype(int)
        lane = ids[codes]  # -1 picks the trailing "" entry
        t = np.arange(n) * w.dt
        ego = self.agents[0]
        signals = {f"{b.name}.stop_arm": self.arm[:n, i].copy() for i, b in enumerate(self.buses)}
        # Command at step k is what the ego applied from t[k-1] to t[k]; sample 0 repeats step 1.
        cmd = self.cmd[:n].copy()
        if n > 1:
            cmd[0] = cmd[1]
        signals[f"{ego.name}.acceleration"] = cmd[:, 0]
        signals[f"{ego.name}.steering"] = cmd[:, 1]
        last = ego.plan[-1]
        reached = bool(ego.route_index == len(ego.plan) - 1
                       and ego.route_s >= last.length - ego.LENGTH / 2)
        meta = {
            "dt": w.dt, "seed": w.seed, "test": w.name, "seconds": seconds,
            "road": w.road.kind, "ego_driver": repr(ego.driver),
            "ego_route": [l.id for l in ego.plan],
            "ego_reached_route_end": reached,
            "ego_route_index": int(ego.route_index),
            "stopped_early": stopped,
            "crashed": [a.name for a in self.agents if a.crashed],
            "crosswalks": [c.name for c in getattr(w.road, "crosswalks", [])],
            **({"intersections": list(w.road.intersections)} if w.road.kind == "network" else {}),
        }
        meta.update(road_meta(w.lane_index, set(lane.ravel().tolist()) | set(meta["ego_route"])))
        if w.road.kind == "map":  # the sidewalks beside those lanes, for on_sidewalk
            meta["lanes"].update(map_sidewalks(w.road.data, meta["lanes"]))
        lights = w.traffic_lights
        if lights is not None:  # the lights ruling the lanes recorded: states per sample
            series, entries = lights.record(t, meta["lanes"])
            if entries:
                signals.update(series)
                meta["lights"] = entries
        decisions = _decisions(ego, self.reasons, float(t[-1]) if n else 0.0)
        if decisions is not None:
            meta["decisions"] = decisions
        return Trajectory(
            t=t, names=tuple(a.name for a in self.agents), kinds=tuple(a.kind for a in self.agents),
            length=np.array([float(a.LENGTH) for a in self.agents]),
            width=np.array([float(a.WIDTH) for a in self.agents]),
            x=np.ascontiguousarray(kin[:, :, 0]), y=np.ascontiguousarray(kin[:, :, 1]),
            vx=np.ascontiguousarray(kin[:, :, 2]), vy=np.ascontiguousarray(kin[:, :, 3]),
            speed=np.ascontiguousarray(kin[:, :, 4]), heading=np.ascontiguousarray(kin[:, :, 5]),
            lane=lane, lane_offset=np.ascontiguousarray(kin[:, :, 6]),
            crashed=np.ascontiguousarray(flags[:, :, 0]),
            present=np.ascontiguousarray(flags[:, :, 2]),
            on_road=np.ascontiguousarray(flags[:, :, 1]),
            signals=signals, meta=meta,
        )


#: [m] spacing of the points that describe a curved lane's centre line in the recording
LANE_POINT_SPACING_M = 1.0


def road_meta(index: Any, ids: set[str]) -> dict[str, Any]:
    """The road as the rule monitors read it, for the lanes named in ``ids`` (the lanes any
    agent was on, and the ego's route): ``{"lanes": {id: {"kind", "group", "width" [m] (at
    s = 0), "xy": centre line points [m], and for a lane whose width varies along it
    "widths": the width [m] at each point}}, "stops": [{"lane", "s" [m], "kind"}]}``.

    Any lane geometry with ``position(s, r)``, ``heading_at(s)``, ``length`` and
    ``width_at(s)`` is written the same way (a straight lane as its two ends, anything else
    as points every :data:`LANE_POINT_SPACING_M`), so lanes of a map need nothing more.
    A map lane's ``xy`` and ``widths`` lists are the same objects in every recording on the
    map in a process: read them, do not change them in place."""
    lanes: dict[str, Any] = {}
    stops: list[dict[str, Any]] = []
    # a map's lanes are shared by every world that loads the map and never change: their
    # entries are computed once per process, all at the first recording on the map
    # (``MapLaneIndex.lane_records``; ~25 ms for Town06's 467 lanes, a tenth of its load),
    # and kept as the recording holds them (lists of [x, y] and of widths: 1.7 MB for
    # Town06's 12,652 points), so every recording that names a lane shares its lists: the
    # same values without ~2,000 new lists a case on a map's default route of ~50 lanes (they
    # were most of the garbage collector's work on a map). Readers take them as read-only.
    memo = getattr(index, "lane_records", None)
    if memo is not None and not memo:
        memo.update((lane.id, _listed(_lane_record(lane))) for lane in index.order)
    order = index.order
    codes = getattr(index, "id_code", None)  # a map's: lane id -> place in order, made once
    if codes is not None:  # the few lanes named, in the index's order, not a scan of all
        order = [order[i] for i in sorted(codes[k] for k in ids if k in codes)]
    for lane in order:
        if lane.id not in ids:
            continue
        for s, kind in index.stop_marks.get(lane.index, ()):
            stops.append({"lane": lane.id, "s": round(float(s), 6), "kind": kind})
        got = memo.get(lane.id) if memo is not None else None
        if got is None:
            got = _listed(_lane_record(lane))
            if memo is not None:
                memo[lane.id] = got
        kind, group, width, xy, widths = got
        lanes[lane.id] = {"kind": kind, "group": group, "width": width, "xy": xy}
        if widths is not None:
            lanes[lane.id]["widths"] = widths
    return {"lanes": lanes, "stops": stops}


def _listed(record: tuple) -> tuple[str, str, float, list, list | None]:
    """A :func:`_lane_record` with its points and widths as the recording's lists."""
    kind, group, width, xy, widths = record
    return kind, group, width, xy.tolist(), None if widths is None else widths.tolist()


def _lane_record(lane: Any) -> tuple[str, str, float, np.ndarray, np.ndarray | None]:
    """(kind, group, width at s = 0 [m], centre line points [m] rounded to 0.1 mm, the
    width [m] at each point, rounded to a micrometre, or None where it is the same all
    along) of one lane. A lane whose width varies is written as points every
    :data:`LANE_POINT_SPACING_M` even when straight, so the width between two points is
    their linear interpolation."""
    g = lane.geometry
    L = float(g.length)
    ends = np.array([g.position(0.0, 0.0), g.position(L, 0.0)], dtype=float)
    mid = np.asarray(g.position(L / 2, 0.0), dtype=float)
    straight = (abs(wrap_to_pi(g.heading_at(L) - g.heading_at(0.0))) < 1e-9
                and float(np.hypot(*(mid - ends.mean(axis=0)))) < 1e-6)
    many_w = getattr(g, "widths_at", None)  # a map lane's vectorized width_at(s)
    if many_w is not None:
        varies = not getattr(g, "width_constant", False)
    else:  # the built roads' lanes: one width each, checked at both ends and the middle
        varies = len({float(g.width_at(s)) for s in (0.0, L / 2, L)}) > 1
    n = 2 if straight and not varies else \
        int(min(max(math.ceil(L / LANE_POINT_SPACING_M) + 1, 3), 2000))
    ss = np.linspace(0.0, L, n)
    many = getattr(g, "positions", None)  # a map lane's vectorized position(s, 0)
    if n == 2:
        xy = ends
    elif many is not None:
        xy = many(ss)
    else:
        xy = np.array([g.position(s, 0.0) for s in ss])
    widths = None
    if varies:
        widths = np.round(many_w(ss) if many_w is not None
                          else np.array([g.width_at(s) for s in ss], dtype=float), 6)
    return lane.kind, lane.group, round(float(g.width_at(0.0)), 6), np.round(xy, 4), widths


def map_sidewalks(data: Any, lanes: dict[str, Any]) -> dict[str, Any]:
    """The sidewalk lanes of a map (:class:`~.opendrive.MapData`) in the lane sections of
    ``lanes`` (the recorded ones), written as :func:`road_meta` writes a lane (``kind``
    "sidewalk"; centre line points about every :data:`LANE_POINT_SPACING_M`; ``width`` the
    narrowest along it, and ``widths`` the width at each point where it varies)."""
    every = _SIDEWALKS.get(id(data))
    if every is None or every[0] is not data:  # once per map and process: its lanes never change
        walks = _sidewalks(data)
        by_section: dict[tuple, list[int]] = {}
        for i, walk in enumerate(walks):
            by_section.setdefault(walk[1], []).append(i)
        every = (data, walks, {}, by_section)
        _SIDEWALKS[id(data)] = every
    listed = every[2]  # a sidewalk's points as lists, made at its first recording and shared
    sections = {(l.road, l.section) for l in (data.lanes.get(k) for k in lanes) if l is not None}
    by_section = every[3]
    out: dict[str, Any] = {}
    for i in sorted(i for section in sections for i in by_section.get(section, ())):
        k, section, width, xy, widths = every[1][i]
        if k not in lanes:
            pts = listed.get(i)
            if pts is None:
                pts = listed[i] = (xy.tolist(), None if widths is None else widths.tolist())
            out[k] = {"kind": "sidewalk", "group": "", "width": width, "xy": pts[0]}
            if pts[1] is not None:
                out[k]["widths"] = pts[1]
    return out


_SIDEWALKS: dict[int, tuple[Any, list, dict, dict]] = {}


def _sidewalks(data: Any) -> list[tuple[str, tuple, float, np.ndarray, np.ndarray | None]]:
    """(id, (road, section), narrowest width [m], points [m], the width [m] at each point or
    None where it is the same all along) of every sidewalk lane of a map, in file order."""
    out = []
    for k, l in data.lanes.items():
        if l.kind != "sidewalk":
            continue
        step = max(int(round(LANE_POINT_SPACING_M / max(float(l.s[1] - l.s[0]), 1e-9))), 1) \
            if len(l.s) > 1 else 1
        keep = np.unique(np.r_[np.arange(0, len(l.s), step), len(l.s) - 1])
        widths = np.round(l.width[keep], 6)
        out.append((k, (l.road, l.section), round(float(l.width.min()), 6),
                    np.round(l.xy[keep], 4), widths if np.ptp(widths) > 0 else None))
    return out


def _decisions(ego: Any, reasons: list[list[Any]], t_end: float) -> dict[str, Any] | None:
    """``{"source", "changes": [[t, label], ...]}`` of the ego's decisions up to ``t_end``
    [s], changes only: a discretely deciding driver's actions (``source`` "action"), else its
    driver's reasons ("reason"); None when it has neither."""
    made = getattr(ego, "decisions", None)
    if isinstance(made, list) and made:
        at = getattr(getattr(ego, "session", None), "action_type", None)
        changes: list[list[Any]] = []
        for t, action in made:
            if t > t_end + 1e-9:
                break
            label = action_label(action, at)
            if not changes or changes[-1][1] != label:
                changes.append([round(float(t), 6), label])
        return {"source": "action", "changes": changes}
    if reasons:
        return {"source": "reason", "changes": reasons}
    return None


def action_label(action: Any, action_type: Any = None) -> str:
    """A highway-env action as the card shows it: a ``DiscreteMetaAction``'s name
    (``LANE_LEFT``), or the normalised command [-1, 1] of a continuous or discretised action,
    to one decimal (``acceleration +0.3, steering -0.1``; the model's own frame) — so a
    continuous policy's jitter below 0.05 is not a new decision."""
    if isinstance(action, str):  # already a name
        return action
    names = getattr(action_type, "actions", None)
    if isinstance(names, dict) and not isinstance(action, (list, np.ndarray)):
        try:
            return str(names[int(action)])
        except (KeyError, TypeError, ValueError):
            pass
    parts = ["acceleration"] * bool(getattr(action_type, "longitudinal", True)) \
        + ["steering"] * bool(getattr(action_type, "lateral", True))
    try:
        values = np.asarray(action, dtype=float).reshape(-1)
    except (TypeError, ValueError):  # not a number: the driver's own word for it
        return str(action)
    per_axis = getattr(action_type, "actions_per_axis", None)
    if values.size == 1 and per_axis:  # DiscreteAction: an index into a grid of commands
        import itertools

        axes = [np.linspace(-1.0, 1.0, int(per_axis))] * len(parts)
        values = np.asarray(list(itertools.product(*axes))[int(values[0])], dtype=float)
    if values.size != len(parts):
        parts = [f"u{i}" for i in range(values.size)]
    return ", ".join(f"{p} {v + 0.0:+.1f}" for p, v in zip(parts, np.round(values, 1)))

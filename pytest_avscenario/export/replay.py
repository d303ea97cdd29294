"""An exported scenario played back in the plugin's own simulator, from the files alone.

:func:`replay_world` reads a ``.xosc`` written by :mod:`.openscenario` and the ``.xodr`` it
names, builds a :class:`~pytest_avscenario.sim.world.World` with the same road, places every
entity at its ``Init`` state and gives it what its actions say: a ``SpeedAction`` to 0 m/s at
a linear rate on a simulation-time trigger becomes ``b.brake_at(t, decel)``, a relative
``LaneChangeAction`` on a time trigger ``b.change_lane``, no action ``b.keep_lane()``, and a
``FollowTrajectoryAction`` is tracked step by step (the ego's by a driver, others' by a
behaviour) with the one-step inverse of highway-env's kinematic bicycle. It shows that the
file says what the case did: run it (:func:`replay`) and compare the first violation.

It reads what this package writes on a one-way straight road or a four-way intersection
(agents placed by ``LanePosition`` on its arms and connecting roads, routes from their
``AssignRouteAction``), not any OpenSCENARIO file: anything else raises
``NotImplementedError`` naming what it met. What the intersection's file does not say (its
crosswalks' width, 3 m, and speed limit, 13.9 m/s) takes ``world.intersection``'s defaults:
neither moves an agent that follows its recorded trajectory.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..sim import behaviors as b
from .openscenario import centre_from_rear_axle

__all__ = ["replay_world", "replay", "RecordedPath"]


class RecordedPath:
    """Vertices ``(t [s], x, y [m] of the centre, heading [rad])`` tracked exactly: at step k
    the acceleration that gives the speed the vertices' spacing asks for next, and the
    steering that turns to the next vertex's heading."""

    def __init__(self, t: np.ndarray, x: np.ndarray, y: np.ndarray, h: np.ndarray) -> None:
        self.t, self.x, self.y, self.h = t, x, y, h
        step = np.hypot(np.diff(x), np.diff(y))
        self.v = step / np.diff(t)  # speed on each interval [m/s]

    def command(self, now: float, speed: float, heading: float, length: float,
                dt: float) -> tuple[float, float]:
        k = int(np.searchsorted(self.t, now + 1e-9)) - 1
        k = min(max(k, 0), len(self.t) - 1)
        v_next = float(self.v[k + 1]) if k + 1 < len(self.v) else float(self.v[-1]) if len(self.v) else 0.0
        acc = (v_next - speed) / dt
        h_next = float(self.h[min(k + 1, len(self.h) - 1)])
        turn = math.atan2(math.sin(h_next - heading), math.cos(h_next - heading))
        v_ref = speed if abs(speed) > 1e-3 else 1e-3
        sin_beta = max(-1.0, min(1.0, turn / dt * (0.5 * length) / v_ref))
        return acc, math.atan(2.0 * math.tan(math.asin(sin_beta)))


class _EgoDriver:
    """The ego driver that follows a recorded path (the part a team replaces)."""

    def __init__(self, path: RecordedPath, name: str) -> None:
        self.path, self.name, self.world = path, name, None

    def reset(self, world: Any) -> None:
        self.world = world

    def act(self, observation: Any) -> tuple[float, float]:
        w = self.world
        ego = w.agent(self.name)
        return self.path.command(w.t, float(ego.speed), float(ego.heading), float(ego.LENGTH), w.dt)


@dataclass(frozen=True)
class FollowRecorded(b.Behavior):
    """A non-ego agent tracking a recorded path (see :class:`RecordedPath`)."""

    path: Any = None

    def control(self, agent, world):
        return self.path.command(world.t, float(agent.speed), float(agent.heading),
                                 float(agent.LENGTH), world.dt)


def _f(el: ET.Element, attr: str) -> float:
    return float(el.get(attr))


def _time_of(trigger: ET.Element | None) -> float | None:
    cond = trigger.find(".//SimulationTimeCondition") if trigger is not None else None
    return None if cond is None else _f(cond, "value")


def _road(xodr: Path) -> tuple[str, dict[str, float]]:
    """The built road a file written by :mod:`.opendrive` describes: ``("straight", {lanes,
    lane_width, length})`` for one one-way straight road, ``("intersection", {lanes,
    lane_width, approach_length, median, corner})`` for four arms around a junction."""
    from .opendrive import HEADER_NAME

    root = ET.parse(xodr).getroot()
    if root.find("header") is None or root.find("header").get("name") != HEADER_NAME:
        return "map", {"path": str(xodr.resolve())}  # a map file the case was built on
    roads = root.findall("road")
    junction = root.find("junction")
    if junction is not None:
        arms = [r for r in roads if r.get("junction") == "-1"]
        if len(arms) != 4:
            raise NotImplementedError(f"{xodr.name}: a junction with {len(arms)} arms; the "
                                      "replay reads the four-way intersection")
        arm = arms[0]
        g = arm.find("planView/geometry")
        left = arm.findall("lanes/laneSection/left/lane")
        driving = [l for l in left if l.get("type") == "driving"]
        median = [l for l in left if l.get("type") == "median"]
        w = _f(driving[0].find("width"), "a")
        m = _f(median[0].find("width"), "a") if median else 0.0
        half = math.hypot(_f(g, "x"), _f(g, "y"))  # the box edge: arms start there
        return "intersection", {"lanes": len(driving), "lane_width": w,
                                "approach_length": _f(arm, "length"), "median": 2 * m,
                                "corner": half - len(driving) * w - m}
    if len(roads) != 1:
        raise NotImplementedError(f"{xodr.name}: {len(roads)} roads and no junction; the "
                                  "replay reads one straight one-way road or an intersection")
    road = roads[0]
    geoms = road.findall("planView/geometry")
    if len(geoms) != 1 or geoms[0].find("line") is None or _f(geoms[0], "hdg") != 0.0:
        raise NotImplementedError(f"{xodr.name}: not one straight line heading east")
    if road.find("lanes/laneSection/left") is not None:
        raise NotImplementedError(f"{xodr.name}: lanes on the left (a two-way road)")
    right = road.findall("lanes/laneSection/right/lane")
    widths = {_f(l.find("width"), "a") for l in right}
    if not right or len(widths) != 1:
        raise NotImplementedError(f"{xodr.name}: lanes of different widths")
    return "straight", {"lanes": len(right), "lane_width": widths.pop(),
                        "length": _f(road, "length")}


def _position(pos: ET.Element, lane_at: Any) -> tuple[float, float, float, Any]:
    """``(x, y, heading, world lane or None)`` of a ``Position`` element: a WorldPosition, or
    a LanePosition (``lane_at`` gives its lane and point)."""
    wp = pos.find("WorldPosition")
    if wp is not None:
        return _f(wp, "x"), _f(wp, "y"), _f(wp, "h"), None
    lp = pos.find("LanePosition")
    if lp is None:
        raise NotImplementedError(f"a {pos[0].tag} is not replayed")
    lane, x, y = lane_at(lp)
    orient = lp.find("Orientation")
    if orient is None or orient.get("type") != "absolute":
        raise NotImplementedError("a LanePosition without an absolute heading is not replayed")
    return x, y, _f(orient, "h"), lane


def replay_world(xosc: str | Path, seed: int = 0) -> tuple[Any, float, float]:
    """The world an exported ``.xosc`` describes, ready to run, its stop time [s] and its
    step [s] (the ego's trajectory's vertex spacing)."""
    from ..sim.places import Route
    from ..sim.world import World
    from .opendrive import road_xodr

    xosc = Path(xosc)
    root = ET.parse(xosc).getroot()
    logic = root.find("RoadNetwork/LogicFile")
    kind, spec = _road(xosc.parent / logic.get("filepath"))
    world = World(seed)
    if kind == "map":
        road = world.map(spec["path"])
        rmap = None
    else:
        road = world.intersection(**spec) if kind == "intersection" else world.straight_road(**spec)
        _, rmap = road_xodr(road)  # the same numbering as the file: (road, lane) -> world lane
    lanes = {lane.id: lane for lane in road.all_lanes}

    def lane_at(lp: ET.Element) -> tuple[Any, float, float]:
        """The world lane and point (x, y) of a LanePosition."""
        from .opendrive import map_point, world_xy

        rid, lid, s, off = lp.get("roadId"), int(lp.get("laneId")), _f(lp, "s"), _f(lp, "offset")
        if rmap is None:
            lane_id, x, y = map_point(road, rid, lid, s, off)
            return lanes[lane_id], x, y
        x, y = world_xy(rmap, int(rid), lid, s, off)
        lane_of = {ref: lane_id for lane_id, ref in rmap.lanes.items()}
        return lanes[lane_of[(int(rid), lid)]], x, y
    sizes: dict[str, tuple[str, float, float]] = {}
    for obj in root.findall("Entities/ScenarioObject"):
        veh = obj.find("Vehicle")
        if veh is None:
            raise NotImplementedError(f"entity {obj.get('name')}: only vehicles replay")
        dim = veh.find("BoundingBox/Dimensions")
        sizes[obj.get("name")] = (veh.get("vehicleCategory"), _f(dim, "length"), _f(dim, "width"))
    init: dict[str, dict[str, Any]] = {}
    for priv in root.findall("Storyboard/Init/Actions/Private"):
        x, y, h, ref = _position(priv.find(".//TeleportAction/Position"), lane_at)
        speed = priv.find(".//AbsoluteTargetSpeed")
        route = [lane_at(p)[0]
                 for p in priv.findall(".//AssignRouteAction//Waypoint/Position/LanePosition")]
        init[priv.get("entityRef")] = {"x": x, "y": y, "h": h, "ref": ref,
                                      "v": _f(speed, "value") if speed is not None else 0.0,
                                      "route": Route(tuple(route)) if route else None}
    events: dict[str, list[ET.Element]] = {}
    for mg in root.iter("ManeuverGroup"):
        who = mg.find("Actors/EntityRef").get("entityRef")
        events.setdefault(who, []).extend(mg.iter("Event"))
    stop = _time_of(root.find("Storyboard/StopTrigger"))
    step = 0.1
    for name, (cat, L, W) in sizes.items():
        st = init[name]
        x, y = centre_from_rear_axle(st["x"], st["y"], st["h"], L)
        if st["ref"] is not None:
            lane = st["ref"]
            s = lane.geometry.local_coordinates((float(x), float(y)))[0]
        elif kind == "straight":
            n, w = int(spec["lanes"]), spec["lane_width"]
            lane, s = road.lane(min(max(int(round(-y / w)), 0), n - 1)), float(x)
        else:
            raise NotImplementedError(f"{name}: a WorldPosition start at an intersection")
        beh, path = None, None
        for ev in events.get(name, []):
            t0 = _time_of(ev.find("StartTrigger"))
            poly = ev.find(".//FollowTrajectoryAction//Polyline")
            speed = ev.find(".//SpeedAction")
            lc = ev.find(".//LaneChangeAction")
            if poly is not None:
                vs = poly.findall("Vertex")
                t = np.array([_f(v, "time") for v in vs])
                wp = [v.find("Position/WorldPosition") for v in vs]
                h = np.array([_f(p, "h") for p in wp])
                cx, cy = centre_from_rear_axle(np.array([_f(p, "x") for p in wp]),
                                               np.array([_f(p, "y") for p in wp]), h, L)
                path = RecordedPath(t, cx, cy, h)
                if name == "ego" and len(t) > 1:
                    step = float(t[1] - t[0])
            elif speed is not None and t0 is not None:
                target = _f(speed.find(".//AbsoluteTargetSpeed"), "value")
                dyn = speed.find("SpeedActionDynamics")
                if target != 0.0 or dyn.get("dynamicsDimension") != "rate":
                    raise NotImplementedError(f"{name}: a SpeedAction other than a linear "
                                              "brake to 0 m/s")
                beh = b.brake_at(t0, decel=_f(dyn, "value"))
            elif lc is not None and t0 is not None and lc.find(".//RelativeTargetLane") is not None:
                rel = lc.find(".//RelativeTargetLane")
                if rel.get("entityRef") != name:
                    raise NotImplementedError(f"{name}: a lane change relative to another entity")
                dyn = lc.find("LaneChangeActionDynamics")
                beh = b.change_lane("left" if int(rel.get("value")) > 0 else "right", at=t0,
                                    duration=_f(dyn, "value"))
            else:
                raise NotImplementedError(f"{name}: event {ev.get('name')!r} is not replayed")
        route = st["route"]
        if name == "ego":
            if path is None:
                raise NotImplementedError("the ego has no FollowTrajectoryAction")
            world.ego(lane, s=float(s), speed=st["v"], driver=_EgoDriver(path, name), name=name,
                      route=route)
        elif path is not None:
            world.car(lane, s=float(s), speed=st["v"], behavior=FollowRecorded(path=path),
                      name=name, route=route)
        elif cat in ("bus", "truck"):
            world.vehicle(lane, s=float(s), speed=st["v"], behavior=beh, kind="truck",
                          length=L, width=W, name=name, route=route)
        else:
            world.car(lane, s=float(s), speed=st["v"], behavior=beh, name=name, route=route)
    return world, float(stop if stop is not None else 10.0), step


def replay(xosc: str | Path, seed: int = 0) -> Any:
    """Run :func:`replay_world` to its stop time; returns the recorded trajectory."""
    world, seconds, dt = replay_world(xosc, seed)
    return world.run(seconds=seconds, dt=dt)

"""One counterexample written as ASAM OpenSCENARIO 1.3 (.xosc), with scenariogeneration.

What goes in, for a world that has run (its road, its agents with their bound behaviours,
its recorded :class:`~pytest_avscenario.trajectory.Trajectory`):

* ``ParameterDeclarations``: the case's parameters with their values (units in a comment:
  OpenSCENARIO 1.x declarations carry no unit);
* ``Entities``: every agent, vehicles with their size, pedestrians;
* ``Init``: each agent's recorded state at its first step (position, heading, speed), the
  position as a ``LanePosition`` on the road written (or the map referenced) where the agent
  is on one of its lanes, else a ``WorldPosition``; an agent whose route runs through a
  junction also gets it as an ``AssignRouteAction``;
* the ``Storyboard``: behaviours the format has one-to-one written as actions with their
  triggers (:data:`MAPPED`), the ego's recorded trajectory as a timed
  ``FollowTrajectoryAction`` (a team replaces it with its own controller; a comment says so),
  every other agent whose behaviour has no equivalent as its recorded trajectory (listed in a
  comment and in :attr:`Export.trajectories`), and a ``StopTrigger`` at the recording's end.

Frames: the world's frame is OpenSCENARIO's world frame as it is (x east, y north [m], heading
counter-clockwise from east [rad]; highway-env only draws y down). OpenSCENARIO places a
vehicle by its reference point, the centre of the rear axle; highway-env's kinematic bicycle
has its axles at the ends of the body (wheelbase = length, the centre midway), so the rear
axle is half a length behind the recorded centre: ``x_ref = x - L/2 cos h``,
``y_ref = y - L/2 sin h``, and the ``BoundingBox`` centre is ``L/2`` ahead of it. A
pedestrian's reference point is its centre.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

__all__ = ["Export", "scenario_xosc", "MAPPED", "rear_axle", "centre_from_rear_axle"]

#: behaviours written as OpenSCENARIO actions, and what they become
MAPPED = {
    "BrakeAt": "SpeedAction (linear, rate = decel) to 0 m/s",
    "ChangeLane": "LaneChangeAction (sinusoidal over duration, or lane width / lateral speed)",
    "CutIn": "LaneChangeAction relative to the ego's lane",
    "SpeedProfile": "SpeedProfileAction (by time) with DynamicsConstraints",
    "KeepLane": "its initial speed (plus a SpeedAction when it cruises at another speed)",
    "Stopped": "a standing vehicle (speed 0)",
}
#: heights [m] written in bounding boxes (the world is flat)
HEIGHT_M = {"ego": 1.5, "car": 1.5, "parked": 1.5, "truck": 3.5, "bus": 3.2, "pedestrian": 1.8}


@dataclass
class Export:
    """What :func:`scenario_xosc` wrote: the document, which agents follow their recorded
    trajectories (``trajectories``: name -> why) and which got actions (``actions``:
    name -> behaviour)."""

    xml: bytes
    actions: dict[str, str] = field(default_factory=dict)
    trajectories: dict[str, str] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    routes: dict[str, list[str]] = field(default_factory=dict)  # name -> its lanes (AssignRouteAction)


def rear_axle(x: Any, y: Any, heading: Any, length: Any) -> tuple[Any, Any]:
    """OpenSCENARIO's reference point (the rear axle's centre) of a vehicle whose centre is at
    ``(x, y)`` [m]: half a length behind it along ``heading`` [rad]."""
    half = np.asarray(length) / 2
    return x - half * np.cos(heading), y - half * np.sin(heading)


def centre_from_rear_axle(x: Any, y: Any, heading: Any, length: Any) -> tuple[Any, Any]:
    """Inverse of :func:`rear_axle`."""
    half = np.asarray(length) / 2
    return x + half * np.cos(heading), y + half * np.sin(heading)


def _xosc() -> Any:
    from ._writers import load

    return load()[1]


def _param_type(value: Any, minor: int) -> tuple[Any, str]:
    P = _xosc().ParameterType
    if isinstance(value, (bool, np.bool_)):
        return P.boolean, "true" if value else "false"
    if isinstance(value, (int, np.integer)):
        return (P.int if minor >= 2 else P.integer), str(int(value))
    if isinstance(value, (float, np.floating)):
        return P.double, repr(float(value))
    return P.string, str(value)


def _entity(agent_kind: str, name: str, length: float, width: float) -> Any:
    xosc = _xosc()
    h = HEIGHT_M.get(agent_kind, 1.5)
    if agent_kind == "pedestrian":
        bb = xosc.BoundingBox(width, length, h, 0.0, 0.0, h / 2)
        return xosc.Pedestrian(name, 75.0, xosc.PedestrianCategory.pedestrian, bb, model=name)
    cat = {"bus": xosc.VehicleCategory.bus, "truck": xosc.VehicleCategory.truck}.get(
        agent_kind, xosc.VehicleCategory.car)
    bb = xosc.BoundingBox(width, length, h, length / 2, 0.0, h / 2)
    front = xosc.Axle(0.6, 0.7, width * 0.85, length, 0.35)
    rear = xosc.Axle(0.0, 0.7, width * 0.85, 0.0, 0.35)
    return xosc.Vehicle(name, cat, bb, front, rear, 60.0, 10.0, 10.0)


def _rule_at_least(minor: int) -> Any:
    # OpenSCENARIO 1.0 has no greaterOrEqual: "after t" there (a step later at worst)
    xosc = _xosc()
    return xosc.Rule.greaterOrEqual if minor >= 1 else xosc.Rule.greaterThan


def _time_trigger(name: str, t: float, minor: int) -> Any:
    xosc = _xosc()
    return xosc.ValueTrigger(name, 0, xosc.ConditionEdge.none,
                             xosc.SimulationTimeCondition(float(t), _rule_at_least(minor)))


def _trigger_of(name: str, agent: str, at: float, when: Any, minor: int) -> tuple[Any, str] | None:
    """The start trigger of a behaviour's manoeuvre: ``at`` [s] after the start, or its
    ``when`` trigger; None when the trigger has no OpenSCENARIO equivalent."""
    xosc = _xosc()
    if when is None:
        return _time_trigger(name, at, minor), f"t >= {at:g} s"
    kind = type(when).__name__
    if at and at > 0:
        return None  # "not before at, and when ..." needs two conditions in one group
    if kind == "GapBelow":
        cond = xosc.RelativeDistanceCondition(
            float(when.metres), xosc.Rule.lessThan, xosc.RelativeDistanceType.longitudinal,
            when.other, alongroute=False, freespace=True,
            coordinate_system=xosc.CoordinateSystem.entity)
        return (xosc.EntityTrigger(name, 0, xosc.ConditionEdge.none, cond, agent),
                f"bumper-to-bumper gap to {when.other} < {when.metres:g} m")
    if kind == "TimeGapBelow":
        # OpenSCENARIO's time headway divides the free space by the triggering entity's
        # speed: the other agent (the one that comes up behind) triggers it
        cond = xosc.TimeHeadwayCondition(agent, float(when.seconds), xosc.Rule.lessThan,
                                         alongroute=False, freespace=True,
                                         coordinate_system=xosc.CoordinateSystem.entity)
        return (xosc.EntityTrigger(name, 0, xosc.ConditionEdge.none, cond, when.other),
                f"time headway of {when.other} to it < {when.seconds:g} s")
    return None


def _actions(agent: Any, beh: Any, rmap: Any, lane_width: float,
             minor: int) -> tuple[list, str] | None:
    """``[(event name, action, trigger)]`` and a description for behaviour ``beh``, or None
    when it has no one-to-one equivalent (the agent then follows its trajectory)."""
    xosc = _xosc()
    kind = type(beh).__name__ if beh is not None else "None"
    name = agent.name
    if kind == "Stopped" or (kind == "KeepLane" and beh.speed is None):
        return [], MAPPED[kind]
    if kind == "KeepLane":
        dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.linear, xosc.DynamicsDimension.rate,
                                      1.5)
        return [(f"{name}_cruise", xosc.AbsoluteSpeedAction(float(beh.speed), dyn),
                 _time_trigger(f"{name}_cruise_start", 0.0, minor))], "keep_lane at a set speed"
    if kind == "BrakeAt":
        if beh.at is not None or beh.speed is not None:
            return None
        trig = _trigger_of(f"{name}_brake_start", name, beh.t or 0.0, beh.when, minor) \
            if beh.when is not None else _trigger_of(f"{name}_brake_start", name, beh.t, None, minor)
        if trig is None:
            return None
        dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.linear, xosc.DynamicsDimension.rate,
                                      float(beh.decel))
        return [(f"{name}_brake", xosc.AbsoluteSpeedAction(0.0, dyn), trig[0])], \
            f"brake_at: {MAPPED[kind]} when {trig[1]}"
    if kind in ("ChangeLane", "CutIn"):
        if beh.speed is not None:
            return None
        trig = _trigger_of(f"{name}_lane_change_start", name, float(beh.at), beh.when, minor)
        if trig is None:
            return None
        if beh.lateral_speed is not None:
            dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.linear, xosc.DynamicsDimension.time,
                                          lane_width / float(beh.lateral_speed))
        else:
            dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.sinusoidal,
                                          xosc.DynamicsDimension.time, float(beh.duration))
        to = beh.to
        if kind == "CutIn" and to == "ego":
            action = xosc.RelativeLaneChangeAction(0, "ego", dyn)
        elif to in ("left", "right"):
            action = xosc.RelativeLaneChangeAction(1 if to == "left" else -1, name, dyn)
        else:
            lane_id = getattr(to, "id", None)
            target = rmap.lanes.get(lane_id) if lane_id is not None else None
            if target is None:
                return None
            action = xosc.AbsoluteLaneChangeAction(target[1], dyn)
        return [(f"{name}_lane_change", action, trig[0])], f"{kind}: {MAPPED[kind]} when {trig[1]}"
    if kind == "SpeedProfile":
        if beh.by != "time" or minor < 2:  # SpeedProfileAction is OpenSCENARIO 1.2
            return None
        pts = [(float(x), float(v)) for x, v in beh.points]
        times = [pts[0][0]] + [b[0] - a[0] for a, b in zip(pts, pts[1:])]
        cons = xosc.DynamicsConstraints(max_acceleration=float(beh.max_accel),
                                        max_deceleration=float(beh.max_decel))
        action = xosc.SpeedProfileAction([v for _, v in pts], xosc.FollowingMode.follow,
                                         times=times, dynamics_constraint=cons)
        return [(f"{name}_speed_profile", action, _time_trigger(f"{name}_profile_start", 0.0, minor))], \
            MAPPED[kind]
    return None


def _world_position(x: float, y: float, h: float) -> Any:
    return _xosc().WorldPosition(float(x), float(y), 0.0, float(h), 0.0, 0.0)


def _nm(v: float) -> float:
    """A length [m] to the nanometre: what a projection leaves below that is rounding noise."""
    return round(float(v), 9) + 0.0


def _start_position(rmap: Any, lane_id: str, x: float, y: float, h: float) -> Any:
    """Where an agent starts: a ``LanePosition`` (road, lane, s, offset from the lane's centre
    along the road's t axis; heading absolute) when the point lies on a road the export
    wrote or the map it references, else a ``WorldPosition``."""
    from .opendrive import lane_position

    xosc = _xosc()
    at = lane_position(rmap, lane_id, float(x), float(y))
    if at is None:
        return _world_position(x, y, h)
    rid, lid, s, offset = at
    return xosc.LanePosition(_nm(s), _nm(offset), int(lid), str(rid),
                             xosc.Orientation(h=float(h), reference=xosc.ReferenceContext.absolute))


def _route(rmap: Any, agent: Any, name: str) -> Any:
    """The agent's planned lanes as an OpenSCENARIO ``Route`` (a waypoint at the middle of
    each lane) when it runs through a junction the export wrote, else None."""
    from .opendrive import lane_position

    xosc = _xosc()
    plan = list(getattr(agent, "plan", None) or ())
    if len(plan) < 2 or not any(getattr(l, "kind", "") == "connector" or getattr(l, "junction", "")
                                for l in plan):
        return None
    route = xosc.Route(f"{name}_route")
    for lane in plan:
        g = lane.geometry
        mid = float(g.length) / 2
        px, py = (float(v) for v in g.position(mid, 0.0))
        at = lane_position(rmap, lane.id, px, py)
        if at is None:
            return None
        rid, lid, s, offset = at
        route.add_waypoint(xosc.LanePosition(_nm(s), _nm(offset), int(lid), str(rid)),
                           xosc.RouteStrategy.shortest)
    return route


def _follow_trajectory(name: str, t: np.ndarray, x: np.ndarray, y: np.ndarray,
                       h: np.ndarray) -> Any:
    xosc = _xosc()
    poly = xosc.Polyline([round(float(v), 9) for v in t],  # whole nanoseconds
                         [_world_position(a, b, c) for a, b, c in zip(x, y, h)])
    traj = xosc.Trajectory(f"{name}_recorded", False)
    traj.add_shape(poly)
    return xosc.FollowTrajectoryAction(traj, xosc.FollowingMode.position,
                                       xosc.ReferenceContext.absolute, 1, 0)


def scenario_xosc(world: Any, params: Mapping[str, Any], *, units: Mapping[str, str] | None = None,
                  road_file: str | None, rmap: Any, title: str = "counterexample",
                  description: str = "", minor: int = 3) -> Export:
    """The OpenSCENARIO document of ``world`` (run, with its trajectory) for a case with
    ``params`` (``units``: parameter -> unit text), its road in ``road_file`` (a path relative
    to the .xosc) whose lanes ``rmap`` (:class:`~.opendrive.RoadMap`) says. ``minor``: the
    OpenSCENARIO 1.x revision, 3 (esmini and most tools) or 0 (CARLA's ScenarioRunner reads
    1.0 only: no SpeedProfileAction there, so a speed profile becomes its trajectory)."""
    if minor not in (0, 1, 2, 3):
        raise ValueError(f"OpenSCENARIO 1.{minor}: write 1.0 to 1.3")
    xosc = _xosc()
    traj = world.trajectory
    if traj is None:
        raise ValueError("the world has not run: nothing to export")
    units = dict(units or {})
    out = Export(xml=b"", notes=list(rmap.notes))
    decl = xosc.ParameterDeclarations()
    for k, v in params.items():
        ptype, text = _param_type(v, minor)
        decl.add_parameter(xosc.Parameter(str(k), ptype, text))
    entities = xosc.Entities()
    init = xosc.Init()
    agents = {a.name: a for a in world.agents}
    lane_width = float(getattr(world.road, "lane_width", 3.5) or 3.5)
    t = np.asarray(traj.t, dtype=float)
    events: dict[str, list] = {}
    for i, name in enumerate(traj.names):
        kind = traj.kinds[i]
        L, W = float(traj.length[i]), float(traj.width[i])
        ent = _entity(kind, name, L, W)
        if kind == "ego":  # how CARLA's ScenarioRunner tells the ego (a hero vehicle)
            ent.add_property("type", "ego_vehicle")
        entities.add_scenario_object(name, ent)
        present = np.asarray(traj.present[i], dtype=bool)
        if not present.any():
            out.trajectories[name] = "never on the road"
            continue
        steps = np.flatnonzero(present)
        x, y, h = traj.x[i, steps], traj.y[i, steps], traj.heading[i, steps]
        if kind != "pedestrian":
            x, y = rear_axle(x, y, h, L)
        k0 = steps[0]
        agent = agents.get(name)
        init.add_init_action(name, xosc.TeleportAction(
            _start_position(rmap, str(traj.lane[i, k0]), x[0], y[0], h[0])))
        route = _route(rmap, agent, name)
        if route is not None:
            init.add_init_action(name, xosc.AssignRouteAction(route))
            out.routes[name] = [lane.id for lane in agent.plan]
        init.add_init_action(name, xosc.AbsoluteSpeedAction(
            float(traj.speed[i, k0]), xosc.TransitionDynamics(
                xosc.DynamicsShapes.step, xosc.DynamicsDimension.time, 0)))
        mapped = None
        why = ""
        if kind == "ego":
            why = "the AV under test: its recorded trajectory; replace it with your controller"
        elif k0 > 0 or not present[k0:].all():
            why = (f"on the road only from t = {t[k0]:g} s to {t[steps[-1]]:g} s "
                   "(appears or leaves during the run)")
        elif not rmap.exact:
            why = "its road is not written whole"
        elif agent is None:
            why = "not an agent of the world"
        else:
            mapped = _actions(agent, agent.behavior, rmap, lane_width, minor)
            if mapped is None:
                beh = agent.behavior
                why = f"behaviour {type(beh).__name__} has no OpenSCENARIO equivalent"
        if mapped is not None:
            events[name] = mapped[0]
            out.actions[name] = mapped[1]
        else:
            out.trajectories[name] = why
            events[name] = [(f"{name}_follow_recorded",
                             _follow_trajectory(name, t[steps], x, y, h),
                             _time_trigger(f"{name}_follow_start", 0.0, minor))]
    act = xosc.Act("counterexample", _time_trigger("act_start", 0.0, minor))
    for name, evs in events.items():
        if not evs:
            continue
        mg = xosc.ManeuverGroup(f"{name}_group")
        mg.add_actor(name)
        man = xosc.Maneuver(f"{name}_maneuver")
        for ev_name, action, trigger in evs:
            ev = xosc.Event(ev_name, xosc.Priority.override if minor >= 2 else
                            xosc.Priority.overwrite)
            ev.add_action(f"{ev_name}_action", action)
            ev.add_trigger(trigger)
            man.add_event(ev)
        mg.add_maneuver(man)
        act.add_maneuver_group(mg)
    story = xosc.Story("counterexample_story")
    story.add_act(act)
    t_end = float(t[-1]) if t.size else 0.0
    stop = xosc.ValueTrigger("stop", 0, xosc.ConditionEdge.rising,
                             xosc.SimulationTimeCondition(t_end, _rule_at_least(minor)),
                             "stop")
    sb = xosc.StoryBoard(init, stop)
    sb.add_story(story)
    road = xosc.RoadNetwork(roadfile=road_file)
    sce = xosc.Scenario(title, "pytest-avscenario", decl, entities, sb, road, xosc.Catalog(),
                        osc_minor_version=minor)
    root = sce.get_element()
    header = root.find("FileHeader")
    if header is not None:
        header.set("date", "1970-01-01T00:00:00")  # the same case writes the same file
        if description:
            header.set("description", description)
    _comment(root, out, units, params, t_end)
    ET.indent(root)
    _one_line_vertices(root)
    out.xml = ET.tostring(root, encoding="utf-8", xml_declaration=True) + b"\n"
    return out


def _one_line_vertices(root: ET.Element) -> None:
    """Each trajectory ``Vertex`` on one line: the indentation of its three nested elements was
    about 40 % of a recorded trajectory's bytes (a 120-step case: ~77 kB an .xosc)."""
    for vertex in root.iter("Vertex"):
        for inner in vertex.iter():
            if inner is not vertex:
                inner.text = None
                inner.tail = None
        vertex.text = None


def _note(text: str) -> ET.Element:
    """An XML comment (which may not hold \"--\" nor end in \"-\")."""
    return ET.Comment(text.replace("--", "- ").rstrip("-") + " ")


def _comment(root: ET.Element, out: Export, units: Mapping[str, str],
             params: Mapping[str, Any], t_end: float) -> None:
    top = [" Exported by pytest-avscenario. Frame: x east, y north [m], heading",
           " counter-clockwise from east [rad]; vehicles placed by the centre of the rear axle",
           " (half a length behind the body's centre), pedestrians by their centre. ",
           f" The recording stops at t = {t_end:g} s (the StopTrigger). "]
    for line in reversed(top):
        root.insert(0, _note(line))
    decl = root.find("ParameterDeclarations")
    if decl is not None:
        for name in reversed(list(params)):
            names = [e.get("name") for e in decl]
            if units.get(name) and name in names:
                decl.insert(names.index(name), _note(f" {name} [{units[name]}]"))
    story = root.find("Storyboard/Story")
    sb = root.find("Storyboard")
    notes = [" The ego follows its recorded trajectory (FollowTrajectoryAction, absolute time):",
             " replace that action with your own controller to test your stack in this case. "]
    others = {k: v for k, v in out.trajectories.items() if k != "ego"}
    if others:
        notes.append(" Agents following their recorded trajectories (no one-to-one equivalent):")
        notes.extend(f"   {k}: {v}" for k, v in others.items())
    if out.actions:
        notes.append(" Agents driven by actions:")
        notes.extend(f"   {k}: {v}" for k, v in out.actions.items())
    notes.extend(f" {n}" for n in out.notes)
    if sb is not None and story is not None:
        idx = list(sb).index(story)
        for line in reversed(notes):
            sb.insert(idx, _note(line))

"""A clip: the compact, JSON-coded recording of one run that a counterexample's card plays
and its annotated still shows.

:func:`clip_data` turns a world (or a bare :class:`~pytest_avscenario.trajectory.Trajectory`)
and the run's evidence (:class:`~pytest_avscenario.monitors.evidence.Evidence`, computed by
the monitors: this module imports neither them nor the report) into plain JSON data: the road
drawn once (lane centre lines with their widths and markings, intersection boxes,
crosswalks, stop lines), every agent's position, heading and speed at a decimated rate
(:data:`CLIP_HZ`, plus the steps of the first violation and first contact), the critical
agent, the violated metrics, and per frame the distance, footprint gap and time to collision
between the ego and the critical agent, with ρ(t) of the violated monitors that have one, and
the ego's decisions (the recording's ``meta["decisions"]``: a discretely deciding agent's
actions or its driver's reasons, as changes). :func:`frame_lines` is the text shown beside a
frame; the still (:func:`~pytest_avscenario.sim.render.render_moment`) and the card's player
(:mod:`pytest_avscenario.report.player`) both show exactly these values.
:func:`pytest_avscenario.report.recording.recording_data` composes the two for a case.

The data is made small enough to keep one per counterexample: times in centiseconds,
positions and metric values in centimetres (or centiseconds), headings in degrees, speeds in
decimetres per second, each series stored as its first value followed by differences
(``null`` where the agent is absent or a value infinite) with runs of equal items as
``[item, count]``, an agent's series only from its first frame ``k0`` to its last, the road
in decimetres, the decisions as a table of labels and ``[centiseconds, label number]`` per
change. :func:`decoded` gives plain values.
"""

from __future__ import annotations

import json
import math
from typing import Any, Mapping, Sequence

import numpy as np

from ..trajectory import Trajectory

__all__ = ["CLIP_HZ", "ARROW_S", "clip_data", "dumps", "undelta", "moment_step",
           "frame_lines", "decoded", "view_spec", "decision_at"]

#: frames per second of a clip (the simulation records 10 Hz by default)
CLIP_HZ = 5.0

#: a velocity arrow is as long as the distance the agent covers in this many seconds [s]
ARROW_S = 1.0

#: view of a clip without a road: this wide [m], following the ego
_BARE_WIDTH_M = 120.0


def _delta(values: np.ndarray, present: np.ndarray) -> list[Any]:
    """Integers as first value + differences; ``None`` at absent steps (the next present value
    is a difference from the last present one); a run of three or more equal items as
    ``[item, count]`` (a parked car is ``[x0, [0, n]]``)."""
    items: list[int | None] = []
    last = 0
    for v, p in zip(values.tolist(), present.tolist()):
        if not p or not math.isfinite(v):
            items.append(None)
            continue
        iv = int(round(v))
        items.append(iv - last)
        last = iv
    out: list[Any] = []
    i = 0
    while i < len(items):
        j = i
        while j < len(items) and items[j] == items[i]:
            j += 1
        out.extend([[items[i], j - i]] if j - i >= 3 else items[i:j])
        i = j
    return out


def undelta(series: Sequence[Any], scale: float = 1.0) -> list[float | None]:
    """The values of a series coded by :func:`_delta` (``None`` stays ``None``), divided by
    ``scale``."""
    out: list[float | None] = []
    acc = 0
    for item in series:
        d, n = item if isinstance(item, list) else (item, 1)
        for _ in range(n):
            if d is None:
                out.append(None)
                continue
            acc += d
            out.append(acc / scale)
    return out


def _cm(values: np.ndarray) -> list[int | None]:
    """Hundredths (centimetres, centiseconds), delta-coded; ``None`` where not finite."""
    values = np.asarray(values, dtype=float)
    return _delta(values * 100, np.isfinite(values))


def moment_step(traj: Trajectory, violations: Mapping[str, Mapping[str, Any]] | None,
                fallback_t: float | None = None) -> int:
    """The step a still shows: the first violation; without a violation time, the first
    contact (a crash flag); then ``fallback_t`` [s] (e.g. the worst ρ's moment); else the end."""
    times = [float(w["t"]) for w in (violations or {}).values() if w.get("t") is not None]
    if times:
        t = min(times)
    else:
        crashed = np.flatnonzero(traj.crashed.any(axis=0))
        if crashed.size:
            return int(crashed[0])
        if fallback_t is None:
            return traj.n_steps - 1
        t = float(fallback_t)
    return int(np.argmin(np.abs(traj.t - t)))


def _lane_points(lane: Any) -> list[tuple[float, float]]:
    """A lane's centre line as few points as draw it within 5 cm."""
    g = lane.geometry
    length = float(lane.length)
    from highway_env.road.lane import StraightLane

    if isinstance(g, StraightLane):  # its two ends draw it exactly: no sampling
        return [tuple(map(float, g.position(s, 0.0))) for s in (0.0, length)]
    n = max(2, int(math.ceil(length / 2.0)) + 1)
    pts = [tuple(map(float, g.position(s, 0.0))) for s in np.linspace(0.0, length, n)]
    if n > 2:
        from shapely.geometry import LineString

        pts = [tuple(p) for p in LineString(pts).simplify(0.05).coords]
    return pts


def _dm(points: Sequence[Sequence[float]]) -> list[int]:
    """Points as decimetres, first point absolute and the others as differences."""
    out: list[int] = []
    lx = ly = 0
    for x, y in points:
        ix, iy = int(round(x * 10)), int(round(y * 10))
        out += [ix - lx, iy - ly]
        lx, ly = ix, iy
    return out


def _road(world: Any) -> dict[str, Any]:
    """Each lane as ``[width, parking (0/1), left line, right line, x0, y0, dx1, dy1, …]``
    (highway-env's line types: 0 none, 1 striped, 2 and 3 continuous; points as :func:`_dm`);
    intersection boxes ``[cx, cy, half]``, crosswalks ``[x0, y0, x1, y1, width]``, stop
    lines and lane ends ``[x0, y0, x1, y1]`` in metres."""
    road = world.road
    lanes = []
    order = world.lane_index.order
    if road.kind == "map":  # a map has hundreds of lanes: only those near the agents' paths
        from .map_render import lanes_near

        tr = world.trajectory
        order = lanes_near(road, np.column_stack([tr.x.ravel(), tr.y.ravel()])[::5], 40.0)
    for lane in order:
        types = [int(getattr(t, "value", t)) for t in getattr(lane.geometry, "line_types", (0, 0))]
        lanes.append([round(lane.width, 2), int(lane.kind == "parking"), *types[:2], *_dm(_lane_points(lane))])
    boxes = ([road] if road.kind == "intersection" else
             list(road.intersections.values()) if road.kind == "network" else [])
    out: dict[str, Any] = {
        "lanes": lanes,
        "boxes": [[round(float(b.centre.x), 2), round(float(b.centre.y), 2), round(float(b.half), 2)]
                  for b in boxes],
        "crosswalks": [],
        "stop_lines": [],
    }
    for cw in getattr(road, "crosswalks", []):
        pts = cw.path.array
        out["crosswalks"].append([round(float(v), 2) for v in (*pts[0], *pts[-1])] + [round(cw.width, 2)])
    for sl in getattr(road, "stop_lines", []):
        g, w = sl.lane.geometry, sl.lane.width
        a, b = g.position(sl.s, -w / 2), g.position(sl.s, w / 2)
        out["stop_lines"].append([round(float(v), 2) for v in (*a, *b)])
    ends = getattr(road, "lane_ends", [])
    if ends:  # where a lane ends with traffic in it (a lane drop, an acceleration lane)
        out["lane_ends"] = []
        for end in ends:
            g, w = end.lane.geometry, end.lane.width
            a, b = g.position(end.s, -w / 2), g.position(end.s, w / 2)
            out["lane_ends"].append([round(float(v), 2) for v in (*a, *b)])
    return out


def view_spec(world: Any) -> tuple[tuple[int, int], float, float | None, float | None, float, bool]:
    """(size [px], scale [px/m], fixed centre x, fixed centre y, lead [m], along heading) of a
    world's frames.

    The whole intersection; on a road network a 110 m square following the ego; a 133 m
    window following the ego on other roads, ``lead`` metres ahead of it in x — on a highway
    (bends, ramps) ahead along its heading and following it both ways. A centre coordinate
    that is None follows the ego (the card's player draws the same view).
    """
    road = world.road
    box = world.lane_index.boxes
    if road.kind == "intersection":
        size = (640, 640)
        half = road.half + min(road.approach_length, 28.0)
        return size, size[0] / (2 * half), 0.0, 0.0, 0.0, False
    if road.kind == "network":
        return (640, 640), 640 / 110.0, None, None, 0.0, False
    size, scale = (800, 320), 6.0
    if road.kind in ("highway", "map"):
        return size, scale, None, None, size[0] / scale / 6, True
    return size, scale, None, float(box[:, 1].min() + box[:, 3].max()) / 2, size[0] / scale / 6, False


def _view(world: Any | None) -> dict[str, Any]:
    """Canvas size [px], scale [px/m] and the view's centre: fixed coordinates, or following
    the ego (``cx``/``cy`` None) ``ahead`` metres ahead of it in x (``along``: along its
    heading); as the still's view."""
    if world is None:
        return {"size": [800, 480], "scale": 800 / _BARE_WIDTH_M, "cx": None, "cy": None, "ahead": 0.0,
                "along": False}
    size, scale, cx, cy, ahead, along = view_spec(world)
    return {"size": list(size), "scale": round(scale, 4),
            "cx": None if cx is None else round(cx, 2), "cy": None if cy is None else round(cy, 2),
            "ahead": round(ahead, 2), "along": along}


def clip_data(source: Any, *, violations: Mapping[str, Mapping[str, Any]] | None = None,
              evidence: Any = None, title: str = "", hz: float = CLIP_HZ,
              fallback_t: float | None = None, case: str | None = None) -> dict[str, Any]:
    """The clip of one recorded run as plain JSON data.

    ``source``: a world after its run, or a Trajectory (then no road is drawn). ``violations``:
    ``{metric: {"t", "agent", "threshold", "rho"}}`` as a case row holds them; the earliest one
    gives the first violation. ``evidence``: the run's
    :class:`~pytest_avscenario.monitors.evidence.Evidence` (the critical agent, the values
    toward it, ρ(t) of violated monitors; None: no values). ``hz``: frames per second (the
    steps of the first violation and the first contact are always frames). ``fallback_t``
    [s]: the moment to start at when nothing says when the violation happened. ``case``:
    which case the run is when a reader could take it for another (``"minimized"``: the
    card's numbers are the case as found's); its lines say so.
    """
    world = None if isinstance(source, Trajectory) else source
    traj: Trajectory = source if world is None else world.trajectory
    if traj is None:
        raise ValueError("nothing to replay: the world has not run")
    T = traj.n_steps
    moment = moment_step(traj, violations, fallback_t)
    every = max(1, int(round(1.0 / (float(hz) * traj.dt)))) if traj.dt > 0 else 1
    contact = np.flatnonzero(traj.crashed.any(axis=0))[:1].tolist()  # the first contact is a frame too
    steps = np.array(sorted(set(range(0, T, every)) | {moment, T - 1, *contact}), dtype=int)
    k_first = int(np.searchsorted(steps, moment))
    crit = None if evidence is None else evidence.critical

    agents = []
    arms = {name[: -len(".stop_arm")]: v for name, v in traj.signals.items() if name.endswith(".stop_arm")}
    for i, name in enumerate(traj.names):
        present = traj.present[i, steps]
        crashed = np.flatnonzero(traj.crashed[i, steps] & present)
        # series cover the frames from the agent's first appearance to its last (agents
        # spawned near the ego live for a short part of a long run)
        seen = np.flatnonzero(present)
        k0, k1 = (int(seen[0]), int(seen[-1]) + 1) if seen.size else (0, 0)
        span, here = steps[k0:k1], present[k0:k1]
        agent = {
            "name": name, "kind": traj.kinds[i],
            "L": round(float(traj.length[i]), 2), "W": round(float(traj.width[i]), 2),
            "k0": k0,
            "x": _delta(traj.x[i, span] * 100, here), "y": _delta(traj.y[i, span] * 100, here),
            "h": _delta(np.degrees(traj.heading[i, span]), here),
            "v": _delta(traj.speed[i, span] * 10, here),
            "crash": int(crashed[0]) if crashed.size else None,
        }
        if name in arms:
            out = arms[name][steps] > 0.5
            agent["arm"] = [int(k) for k in np.flatnonzero(out)]
        agents.append(agent)

    viol = []
    for metric, where in (violations or {}).items():
        rho = where.get("rho")
        viol.append({"metric": metric, "t": where.get("t"), "agent": where.get("agent"),
                     "threshold": where.get("threshold"),
                     "rho": None if rho is None or not math.isfinite(rho) else round(float(rho), 3)})
    viol.sort(key=lambda v: (v["t"] is None, v["t"] if v["t"] is not None else 0.0, v["metric"]))

    values: dict[str, Any] = {}
    rho_t: dict[str, Any] = {}
    if evidence is not None and crit is not None:
        values = {"d": _cm(evidence.distance_m[steps]), "gap": _cm(evidence.gap_m[steps]),
                  "ttc": _cm(evidence.ttc_s[steps]), "radius": evidence.radius_m}
        rho_t = {name: _cm(per[steps]) for name, per in evidence.rho_t.items()}

    data: dict[str, Any] = {
        "format": 1,
        "title": title,
        "t": _cm(traj.t[steps]),
        "first": k_first,
        "first_t": round(float(traj.t[moment]), 2),
        "first_kind": "violation" if viol and any(v["t"] is not None for v in viol) else
                      "contact" if traj.crashed.any() else "moment",
        "critical": traj.names[crit] if crit is not None else None,
        "arrow_s": ARROW_S,
        "view": _view(world),
        "agents": agents,
        "violations": viol,
        "values": values,
        "rho_t": rho_t,
    }
    lights = _lights(traj, steps)
    if lights:
        data["lights"] = lights
    if case:
        data["case"] = str(case)
    decisions = _decisions(traj)
    if decisions is not None:
        data["decisions"] = decisions
    if world is not None:
        data["road"] = _road(world)
    return data


def _lights(traj: Trajectory, steps: np.ndarray) -> list[dict[str, Any]]:
    """The recorded traffic lights: ``{"id", "x", "y" (its head) [m], "stops": [[ax, ay, bx,
    by], ...] (a bar across each lane it stops) [m], "at": [[frame, state code], ...]}``
    (the state from that frame on: 0 green, 1 amber, 2 red)."""
    out = []
    for light in (traj.meta or {}).get("lights", ()):
        codes = traj.signals.get(f"light.{light['id']}")
        if codes is None:
            continue
        per = np.asarray(codes)[steps].astype(int)
        change = np.concatenate([[0], np.flatnonzero(per[1:] != per[:-1]) + 1])
        bars = []
        for stop in light.get("stops", ()):
            h, half = stop["heading"], stop["width"] / 2
            nx, ny = -math.sin(h) * half, math.cos(h) * half
            bars.append([round(float(v), 2) for v in (stop["x"] + nx, stop["y"] + ny,
                                                      stop["x"] - nx, stop["y"] - ny)])
        out.append({"id": str(light["id"]), "x": round(float(light["x"]), 2),
                    "y": round(float(light["y"]), 2), "stops": bars,
                    "at": [[int(k), int(per[k])] for k in change]})
    return out


def _decisions(traj: Trajectory) -> dict[str, Any] | None:
    """The ego's decisions as ``{"source", "labels", "at": [[t_cs, label number], ...]}``: each
    label written once, however often it recurs (an agent alternating two actions)."""
    made = (traj.meta or {}).get("decisions")
    if not made or not made.get("changes"):
        return None
    labels: list[str] = []
    at = []
    for t, label in made["changes"]:
        label = str(label)
        if label not in labels:
            labels.append(label)
        at.append([int(round(float(t) * 100)), labels.index(label)])
    return {"source": str(made.get("source", "action")), "labels": labels, "at": at}


def decision_at(data: Mapping[str, Any], t: float) -> tuple[float, str] | None:
    """``(since [s], label)`` of the ego's decision in force at ``t`` [s] in clip ``data``
    (coded or decoded alike), or None before the first one or without decisions."""
    made = data.get("decisions")
    if not made:
        return None
    now = None
    for cs, i in made["at"]:
        if cs > round(t * 100):
            break
        now = (cs / 100, made["labels"][i])
    return now


def dumps(data: Mapping[str, Any]) -> str:
    """Compact JSON text of clip data (no spaces; NaN/inf were made ``null`` already)."""
    return json.dumps(data, separators=(",", ":"), allow_nan=False)


def decoded(data: Mapping[str, Any]) -> dict[str, Any]:
    """Clip ``data`` with plain per-frame values: ``t`` [s]; each agent's x, y [m], heading
    [deg], speed [m/s] over every frame (``None`` where absent); the metric values [m, s]."""
    t = undelta(data["t"], 100)
    n = len(t)  # frames: the coded series may be shorter (runs)

    def frames(a: Mapping[str, Any], key: str, scale: float) -> list[float | None]:
        body = undelta(a[key], scale)
        return [None] * a["k0"] + body + [None] * (n - a["k0"] - len(body))

    out = dict(data)
    out["t"] = t
    out["agents"] = [{**a, "x": frames(a, "x", 100), "y": frames(a, "y", 100), "h": frames(a, "h", 1),
                      "v": frames(a, "v", 10)} for a in data["agents"]]
    values = data.get("values") or {}
    out["values"] = {k: (undelta(v, 100) if isinstance(v, list) else v) for k, v in values.items()}
    out["rho_t"] = {k: undelta(v, 100) for k, v in (data.get("rho_t") or {}).items()}
    return out


def _num(v: float | None, unit: str, digits: int = 2) -> str:
    return "—" if v is None else f"{v:.{digits}f} {unit}"


def frame_lines(data: Mapping[str, Any], k: int) -> list[str]:
    """The text shown beside frame ``k``: its time (and whether it is the first violation),
    distance, gap and TTC to the critical agent, the ego's decision in force (and since when),
    ρ(t) of the violated metrics that have one and each violated metric's ρ over the run. The
    card's player script writes the same lines.
    ``data`` as :func:`decoded` gives it."""
    t = data["t"][k]
    mark = f" — first {data['first_kind']}" if k == data["first"] and data["first_kind"] != "moment" else ""
    lines = [f"t = {t:.2f} s{mark}"]
    values, crit = data.get("values") or {}, data.get("critical")
    if crit and values:
        ttc = values["ttc"][k]
        d = values["d"][k]
        ttc_text = "—" if d is None else ("∞" if ttc is None else f"{ttc:.2f} s")
        lines.append(f"{crit}: distance {_num(d, 'm')}, gap {_num(values['gap'][k], 'm')}, TTC {ttc_text}")
    made = decision_at(data, t)
    if made is not None:
        what = "decision" if data["decisions"]["source"] == "action" else "reason"
        lines.append(f"{data['agents'][0]['name']} {what}: {made[1]} (since {made[0]:.2f} s)")
    of = f" ({data['case']} case)" if data.get("case") else ""  # "minimized": not the case as found
    for v in data["violations"]:
        per = (data.get("rho_t") or {}).get(v["metric"])
        now = f"ρ(t) {per[k]:+.2f}, " if per is not None and per[k] is not None else ""
        when = "" if v["t"] is None else f", first at {v['t']:.2f} s"
        rho = "—" if v["rho"] is None else f"{v['rho']:+.3f}"  # as the card and the terminal
        lines.append(f"{v['metric']}: {now}run ρ {rho}{when}{of}")
    return lines

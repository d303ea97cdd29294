"""The road as the rule monitors see it: lane centre lines, widths, kinds and stop marks,
read from the recording, and where each agent is on its lane.

The simulator writes the lanes any agent was on and the ego's route into the trajectory's
``meta`` (``sim/recording.py``, :func:`road_meta`): ``meta["lanes"]`` maps a lane id (the id
in ``Trajectory.lane``) to ``{"kind": "travel" | "connector" | "parking" | ..., "group": the
carriageway (lanes side by side with one direction share it), "width": [m], "xy": centre line
points [m] in the direction of travel, and for a lane whose width varies along it (a map's)
"widths": the width [m] at each point}``, ``meta["stops"]`` lists ``{"lane", "s" [m along
it], "kind": "stop" | "crosswalk"}`` and ``meta["ego_route"]`` the ego's route lane ids. A
lane of any origin (built roads, OpenDRIVE maps) is a polyline there, so the monitors need
nothing but these four facts per lane: the closest lane (the recorded ``lane``), its heading
and width where the agent is, and whether the agent is on the drivable area (the recorded
``on_road``). A trajectory built by hand gives the same ``meta`` to use these monitors.
Map lanes plug in by being written the same way; a map's recording also lists the sidewalk
lanes beside the lanes driven (``"kind": "sidewalk"``, :func:`~..sim.recording.map_sidewalks`),
and ``meta["road"]`` says "map".

Projections are computed once per trajectory and shared by every monitor that needs them
(:func:`.base.memo`); a lane's polyline is built when a monitor first reads it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from ..trajectory import Trajectory
from .base import MonitorError, memo

__all__ = ["LanePolyline", "LaneFrame", "RoadLanes", "lanes_of", "lane_frame", "route_of",
           "route_line", "ego_ok", "frame_projection", "ego_lane_all_along"]


@dataclass(frozen=True)
class LanePolyline:
    """One lane's centre line ``xy`` ``(N, 2)`` [m], its arc length ``cum`` ``(N,)`` [m],
    width [m] (at its start), kind and carriageway group; ``widths`` ``(N,)`` [m] the width
    at each point for a lane whose width varies along it (None: ``width`` all along)."""

    id: str
    xy: np.ndarray
    cum: np.ndarray
    width: float
    kind: str = "travel"
    group: str = ""
    #: the width [m] at each point of ``xy`` where it varies along the lane (a map lane)
    widths: np.ndarray | None = None
    #: the segments' lengths [m] ``(N-1,)`` when known (a lane read from the recording)
    seg: np.ndarray | None = field(default=None, compare=False, repr=False)

    @property
    def length(self) -> float:
        return float(self.cum[-1])

    def width_at(self, s: np.ndarray) -> np.ndarray:
        """The lane's width [m] at arc lengths ``s`` [m]: linear between its points, the end
        points' width before the start and past the end."""
        s = np.asarray(s, dtype=float)
        if self.widths is None:
            return np.full(s.shape, self.width)
        return np.interp(s, self.cum, self.widths)

    def project(self, x: np.ndarray, y: np.ndarray, heading: bool = True
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Arc length ``s`` [m] (extended linearly before the start and past the end), signed
        offset ``r`` [m] (positive left of travel) and the lane heading [rad] at the closest
        point of each of the points ``x``, ``y`` (None without ``heading``)."""
        if self.xy.shape[0] == 2:  # a straight lane: its one segment extends both ways
            return self._project_line(x, y, heading)
        return self._project_segments(x, y, heading)

    def _project_segments(self, x: np.ndarray, y: np.ndarray, heading: bool = True
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """:meth:`project` by a search of every segment (any polyline)."""
        a = self.xy[:-1]
        d = self.xy[1:] - a
        dd = np.einsum("ij,ij->i", d, d)
        px = x[:, None] - a[None, :, 0]
        py = y[:, None] - a[None, :, 1]
        u = (px * d[None, :, 0] + py * d[None, :, 1]) / dd[None, :]
        # the first and last segments extend beyond the lane's ends (s < 0, s > length)
        lo = np.where(np.arange(d.shape[0]) == 0, -np.inf, 0.0)
        hi = np.where(np.arange(d.shape[0]) == d.shape[0] - 1, np.inf, 1.0)
        uc = np.clip(u, lo[None, :], hi[None, :])
        ex = px - uc * d[None, :, 0]
        ey = py - uc * d[None, :, 1]
        k = np.argmin(ex * ex + ey * ey, axis=1) if d.shape[0] > 1 else np.zeros(x.shape, int)
        rows = np.arange(x.shape[0])
        seg = np.sqrt(dd[k])
        uk = uc[rows, k]
        s = self.cum[k] + uk * seg
        dxk, dyk = d[k, 0] / seg, d[k, 1] / seg
        r = dxk * py[rows, k] - dyk * px[rows, k]
        return s, r, np.arctan2(dyk, dxk) if heading else None

    def _project_line(self, x: np.ndarray, y: np.ndarray, heading: bool = True
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """:meth:`project` on a lane of one segment, with the same arithmetic (no closest
        segment to look for, no clipping: the segment extends both ways)."""
        ax, ay, bx, by = self.xy[:2].ravel().tolist()  # float64 arithmetic, as Python floats
        dx, dy = bx - ax, by - ay
        px = x - ax
        py = y - ay
        seg = math.sqrt(dx * dx + dy * dy)
        u = (px * dx + py * dy) / (dx * dx + dy * dy)
        s = self.cum[0] + u * seg
        dxk, dyk = dx / seg, dy / seg
        r = dxk * py - dyk * px
        if not heading:
            return s, r, None
        return s, r, np.arctan2(np.full(x.shape, dyk), np.full(x.shape, dxk))


def _polyline(lane_id: str, data: Mapping[str, Any]) -> LanePolyline:
    try:
        xy = np.asarray(data["xy"], dtype=float).reshape(-1, 2)
        width = float(data["width"])
        widths = data.get("widths")
        if widths is not None:
            widths = np.asarray(widths, dtype=float).reshape(-1)
    except (KeyError, TypeError, ValueError) as exc:
        raise MonitorError(
            f"lane {lane_id!r} in the trajectory's meta['lanes'] needs 'xy' (centre line points "
            f"[m]) and 'width' [m] (and 'widths', if given, a width [m] per point): "
            f"{exc}") from None
    if xy.shape[0] < 2 or not np.isfinite(xy).all():
        raise MonitorError(f"lane {lane_id!r} in meta['lanes'] needs >= 2 finite points")
    if widths is not None and (widths.shape[0] != xy.shape[0] or not np.isfinite(widths).all()
                               or (widths < 0).any()):
        raise MonitorError(f"lane {lane_id!r} in meta['lanes']: 'widths' needs one finite width "
                           f">= 0 [m] per point of 'xy' ({xy.shape[0]}), got "
                           f"{widths.shape[0]}")
    d = xy[1:] - xy[:-1]  # np.diff's arithmetic
    seg = np.hypot(d[:, 0], d[:, 1])
    apart = seg > 1e-9  # repeated points have no direction
    if not apart.all():
        keep = np.concatenate([[True], apart])
        xy = xy[keep]
        if widths is not None:
            widths = widths[keep]
        if xy.shape[0] < 2:
            raise MonitorError(f"lane {lane_id!r} in meta['lanes'] has zero length")
        d = xy[1:] - xy[:-1]
        seg = np.hypot(d[:, 0], d[:, 1])
    cum = np.zeros(xy.shape[0])
    np.cumsum(seg, out=cum[1:])
    return LanePolyline(lane_id, xy, cum, width, str(data.get("kind", "travel")),
                        str(data.get("group", "")), widths=widths, seg=seg)


class RoadLanes(Mapping[str, LanePolyline]):
    """The lanes of ``meta["lanes"]`` by id, each made a :class:`LanePolyline` when first
    read: a map's recording lists every lane any agent was on, and most monitors need the
    shape of only the ego's few (the kinds and groups of all come from the plain data)."""

    def __init__(self, raw: Mapping[Any, Any]) -> None:
        self._raw = {str(k): v for k, v in raw.items()}
        self._built: dict[str, LanePolyline] = {}

    def __getitem__(self, lane_id: str) -> LanePolyline:
        got = self._built.get(lane_id)
        if got is None:
            got = self._built[lane_id] = _polyline(lane_id, self._raw[lane_id])
        return got

    def __contains__(self, lane_id: object) -> bool:
        return lane_id in self._raw

    def __iter__(self):
        return iter(self._raw)

    def __len__(self) -> int:
        return len(self._raw)

    def _field(self, lane_id: str, key: str, default: str) -> str:
        data = self._raw[lane_id]
        if not isinstance(data, Mapping):
            raise MonitorError(f"lane {lane_id!r} in the trajectory's meta['lanes'] must be a "
                               f"dict with 'xy' and 'width', got {type(data).__name__}")
        return str(data.get(key, default))

    def kind(self, lane_id: str) -> str:
        """The lane's kind ("travel", "connector", "parking"...) without building its shape."""
        return self._field(lane_id, "kind", "travel")

    def group(self, lane_id: str) -> str:
        """The lane's carriageway group ("" when none) without building its shape."""
        return self._field(lane_id, "group", "")


def lanes_of(traj: Trajectory, monitor: str = "") -> RoadLanes:
    """The lanes recorded in ``traj.meta["lanes"]`` by id (shared per trajectory; a lane's
    polyline is built when first read, and a malformed lane raises a :class:`MonitorError`
    then); a :class:`MonitorError` naming ``monitor`` when the recording has none."""
    cache = memo(traj)
    got = cache.get("road.lanes")
    if got is not None:
        return got
    raw = traj.meta.get("lanes")
    if not isinstance(raw, Mapping) or not raw:
        raise MonitorError(
            f"monitor {monitor!r} needs the road: the trajectory's meta has no 'lanes' (the "
            "simulator records them; by hand give meta={'lanes': {id: {'xy': [[x, y], ...], "
            "'width': w}}, ...})")
    got = cache["road.lanes"] = RoadLanes(raw)
    return got


@dataclass(frozen=True)
class LaneFrame:
    """The ego's place on its recorded lane, ``(T,)`` each: ``s`` [m] along it, ``r`` [m]
    left of its centre line, the lane's ``heading`` [rad] and ``width`` [m] there; NaN where
    the ego is absent or on no known lane. (The rules judge the ego; projecting only its row
    keeps them cheap.)"""

    s: np.ndarray
    r: np.ndarray
    heading: np.ndarray
    width: np.ndarray


def lane_frame(traj: Trajectory, monitor: str = "") -> LaneFrame:
    """The ego's :class:`LaneFrame` in ``traj`` (computed once per trajectory, one vectorized
    projection per lane it was on)."""
    cache = memo(traj)
    got = cache.get("road.frame")
    if got is not None:
        return got
    lanes = lanes_of(traj, monitor)
    T = traj.n_steps
    lane = traj.lane[0]
    ok = ego_ok(traj)
    # the ego changes lanes a few times a run: runs of one lane id, not a sort of every sample
    changed = lane[1:] != lane[:-1]
    if T and not changed.any() and ok.all() and str(lane[0]) in lanes:
        # one known lane all along (a scenario on one lane): project every sample at once
        poly = lanes[str(lane[0])]
        s, r, h = poly.project(traj.x[0], traj.y[0])
        got = cache["road.frame"] = LaneFrame(s, r, h, poly.width_at(s))
        cache["road.frame_lane"] = poly  # the frame is this lane's projection of every sample
        return got
    s, r, h, w = (np.full(T, np.nan) for _ in range(4))
    change = np.flatnonzero(changed) + 1
    ids = set(lane[np.concatenate([[0], change])].tolist()) if T else set()
    for lid in ids:
        if lid not in lanes:
            continue
        poly = lanes[lid]
        sel = ok & (lane == lid)
        if not sel.any():
            continue
        s[sel], r[sel], h[sel] = poly.project(traj.x[0, sel], traj.y[0, sel])
        w[sel] = poly.width_at(s[sel])
    got = cache["road.frame"] = LaneFrame(s, r, h, w)
    return got


def ego_ok(traj: Trajectory) -> np.ndarray:
    """``(T,)`` the samples where the ego is present with a finite position (shared per
    trajectory)."""
    cache = memo(traj)
    got = cache.get("road.ego_ok")
    if got is None:
        got = traj.present[0] & np.isfinite(traj.x[0]) & np.isfinite(traj.y[0])
        cache["road.ego_ok"] = got
    return got


def frame_projection(traj: Trajectory, poly: LanePolyline) -> LaneFrame | None:
    """The ego's :class:`LaneFrame` when it is ``poly``'s projection of every sample (the ego
    kept that one lane, present all along), else None: then ``poly.project`` of the ego's
    positions gives the frame's values, bit for bit."""
    cache = memo(traj)
    if "road.frame" not in cache:
        return None
    return cache["road.frame"] if cache.get("road.frame_lane") is poly else None


def ego_lane_all_along(traj: Trajectory) -> str | None:
    """The id of the one lane the ego was on at every sample, when its lane frame (already
    computed) found one; None otherwise (not computed yet, or the ego changed lanes)."""
    poly = memo(traj).get("road.frame_lane")
    return None if poly is None else poly.id


def route_line(traj: Trajectory, monitor: str = "") -> tuple[list[LanePolyline], np.ndarray,
                                                             np.ndarray]:
    """The ego's route lanes and their centre lines joined: ``(lanes, xy (N, 2) [m], arc
    length (N,) [m])``, repeated points dropped (shared per trajectory; a route of one lane
    is that lane's own arrays)."""
    cache = memo(traj)
    got = cache.get("road.route_line")
    if got is not None:
        return got
    route = route_of(traj, monitor)
    one = route[0]
    if len(route) == 1 and one.seg is not None and (one.seg > 1e-9).all():
        # its points are apart already: the joined line is the lane (same arithmetic below)
        xy, cum = one.xy, one.cum
    else:
        xy = np.concatenate([l.xy if i == 0 else l.xy[1:] for i, l in enumerate(route)])
        keep = np.concatenate([[True], np.hypot(*np.diff(xy, axis=0).T) > 1e-9])
        xy = xy[keep]
        cum = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
    got = cache["road.route_line"] = (route, xy, cum)
    return got


def route_of(traj: Trajectory, monitor: str = "") -> list[LanePolyline]:
    """The ego's route lanes in order (``meta["ego_route"]``), as recorded polylines."""
    ids = traj.meta.get("ego_route")
    if not ids:
        raise MonitorError(
            f"monitor {monitor!r} needs the ego's route: the trajectory's meta has no "
            "'ego_route' (the simulator records it; by hand give meta={'ego_route': [lane ids]})")
    lanes = lanes_of(traj, monitor)
    missing = [i for i in ids if i not in lanes]
    if missing:
        raise MonitorError(f"monitor {monitor!r}: route lanes {missing} are not in meta['lanes']")
    return [lanes[i] for i in ids]

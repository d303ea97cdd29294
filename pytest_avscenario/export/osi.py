"""A case's recording as an ASAM OSI trace: one ``osi3.SensorView`` per recorded step.

The single-channel binary format (``.osi``): each serialized message is preceded by its
length as a four-byte little-endian unsigned integer. The file is named as OSI's trace-file
naming convention asks, ``<timestamp>_sv_<osi-version>_<protobuf-version>_<frames>_<name>.osi``
(versions without dots, e.g. ``20261125T160000Z_sv_370_2931_121_following.osi``). The
timestamp is when the trace was written (UTC).

The messages are built by :mod:`pytest_avscenario.stack.frame`, the same code that talks to a
stack out of process: objects at the centre of their 3-D box in the world frame (x east,
y north, yaw counter-clockwise), the ego as host vehicle 1. The road's lanes and lane
boundaries are static for a case and go in the first message's ground truth only: with them
in every message a 15-s trace at an intersection (151 frames) is 2.9 MB, without 88 kB (a
reader keeps them from the first message, as OSI's static ground truth is meant to be kept).
Only the lanes within :data:`LANE_RADIUS` (50 m) of the ego's recorded path, and those an
agent was recorded on, go in: on a map (Town06: 1,000+ lanes over kilometres) the whole
network would make every trace megabytes, most of it roads the case never came near.
"""

from __future__ import annotations

import datetime as _dt
import re
import struct
from types import SimpleNamespace
from typing import Any, Iterator

import numpy as np

__all__ = ["trace_name", "trace_bytes", "read_trace"]


def _versions() -> tuple[str, str]:
    import google.protobuf

    from ..stack import wire

    osi = "".join(str(v) for v in wire.osi_version())
    proto = "".join(google.protobuf.__version__.split(".")[:3])
    return osi, proto


def trace_name(frames: int, custom: str, when: _dt.datetime | None = None) -> str:
    """The file name OSI's convention gives a SensorView trace of ``frames`` messages."""
    when = when or _dt.datetime.now(_dt.timezone.utc)
    osi, proto = _versions()
    custom = re.sub(r"[^A-Za-z0-9-]+", "-", custom).strip("-")[-120:] or "case"
    return f"{when.strftime('%Y%m%dT%H%M%SZ')}_sv_{osi}_{proto}_{int(frames)}_{custom}.osi"


#: [m] lanes whose centre line comes this close to the ego's recorded path go in the trace
LANE_RADIUS = 50.0


def lanes_near_path(lanes: Any, traj: Any, radius: float = LANE_RADIUS) -> tuple:
    """The lanes (of a :class:`~pytest_avscenario.sim.view.SceneView`) within ``radius`` [m]
    of the ego's recorded path, and every lane an agent was recorded on, in their order."""
    from shapely import LineString, Point, STRtree

    keep = {str(v) for v in np.asarray(traj.lane).ravel().tolist() if v}
    ok = np.asarray(traj.present[0], dtype=bool) & np.isfinite(traj.x[0]) & np.isfinite(traj.y[0])
    xy = np.stack([traj.x[0][ok], traj.y[0][ok]], axis=1)
    lanes = tuple(lanes)
    if len(xy):
        path = LineString(xy) if len(np.unique(xy, axis=0)) > 1 else Point(xy[0])
        tree = STRtree([LineString(l.centre_line) if len(l.centre_line) > 1
                        else Point(l.centre_line[0]) for l in lanes])
        keep.update(lanes[int(k)].id for k in tree.query(path, predicate="dwithin",
                                                         distance=radius))
    return tuple(l for l in lanes if l.id in keep)


def trace_bytes(world: Any) -> tuple[bytes, int]:
    """The ``.osi`` contents of ``world``'s recording (every step, agents present then; the
    lanes in the first message) and the number of frames."""
    from ..stack import frame, wire

    traj = world.trajectory
    if traj is None:
        raise ValueError("the world has not run: no recording to trace")
    view = world.view()
    near = lanes_near_path(view.lanes, traj)
    static = frame.lane_ground_truth(SimpleNamespace(lanes=near))
    ids = {name: i + 1 for i, name in enumerate(traj.names)}  # ego first: host vehicle 1
    lane_ids = {lane.id: frame.LANE_ID0 + i for i, lane in enumerate(near)}
    acc = np.zeros_like(traj.speed)
    if traj.n_steps > 1:
        acc[:, :-1] = np.diff(traj.speed, axis=1) / np.diff(traj.t)
    out = bytearray()
    for k, t in enumerate(traj.t):
        sv, gt = frame.new_sensor_view(wire.ns(t))
        for i, name in enumerate(traj.names):
            if not traj.present[i, k]:
                continue
            a = float(acc[i, k]) if np.isfinite(acc[i, k]) else 0.0
            flags = None
            if traj.kinds[i] == "bus" and f"{name}.stop_arm" in traj.signals:
                flags = {"stop_arm": bool(traj.signals[f"{name}.stop_arm"][k])}
            frame.set_object(gt.moving_object.add(), ids[name], name, traj.kinds[i],
                             float(traj.x[i, k]), float(traj.y[i, k]), float(traj.heading[i, k]),
                             float(traj.speed[i, k]), float(traj.length[i]), float(traj.width[i]),
                             a, lane_ids.get(str(traj.lane[i, k])), flags)
        msg = sv.SerializeToString() + (static if k == 0 else b"")
        out += struct.pack("<I", len(msg)) + msg
    return bytes(out), traj.n_steps


def read_trace(data: bytes) -> Iterator[Any]:
    """The ``osi3.SensorView`` messages of a ``.osi`` trace's bytes, in order."""
    from osi3 import osi_sensorview_pb2

    i = 0
    while i < len(data):
        if i + 4 > len(data):
            raise ValueError(f"truncated OSI trace: {len(data) - i} stray bytes at offset {i}")
        (n,) = struct.unpack_from("<I", data, i)
        i += 4
        if i + n > len(data):
            raise ValueError(f"truncated OSI trace: a message of {n} bytes at offset {i - 4}")
        sv = osi_sensorview_pb2.SensorView()
        sv.ParseFromString(data[i:i + n])
        i += n
        yield sv

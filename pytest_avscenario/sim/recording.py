"""Recording a run: per-step kinematics and flags of every agent into preallocated arrays.

The world writes one sample per step (:meth:`Recorder.write`), then :meth:`Recorder.finish`
turns the arrays into the :class:`~pytest_avscenario.trajectory.Trajectory` that monitors
read: the contract between the simulator and the monitors. Agents absent at a step (not yet
appeared, or gone) are recorded with NaN kinematics and ``present`` False, so every agent has
one row for the whole run.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..trajectory import Trajectory
from .geometry import wrap_to_pi

__all__ = ["Recorder"]

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

    def finish(self, n: int, seconds: float, stopped: str | None) -> Trajectory:
        w = self.world
        kin = self.kin[:n].transpose(1, 0, 2)  # (A, T, 8)
        flags = self.flags[:n].transpose(1, 0, 2)
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

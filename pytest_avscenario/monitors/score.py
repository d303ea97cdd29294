"""The CARLA Leaderboard's driving score of one recorded run, and of a campaign.

The Leaderboard (2.0, ``leaderboard/utils/statistics_manager.py``) scores a route as route
completion × infraction penalty, the penalty the product of one factor per infraction:
collision with a pedestrian 0.5, with a vehicle 0.6, with a static object 0.65, running a
red light 0.7, a stop sign 0.8, a scenario timeout 0.7; driving outside the route's lanes
multiplies by (1 - the share of the distance driven there), and a mean speed below the
surrounding traffic's by (1 - 0.3 × (1 - the ratio)). A campaign's score is the mean of its
routes'. Here the route is the ego's recorded route and every infraction is read off the
trajectory with the rule monitors:

* a collision is a footprint contact with another agent (its ``kind`` decides the factor:
  pedestrian, parked → static, anything else → vehicle; each agent once), or a crash the
  simulator recorded for the ego that no agent's footprint explains (static);
* a stop sign is each stop line :func:`.rules.stop_crossings` finds run;
* a red light is each traffic light's stop position the ego crossed on red
  (:func:`.signals.red_light_crossings`, the recording's ``meta["lights"]``);
* a scenario timeout is a run that ends with the ego standing for :data:`TIMEOUT_STAND_S`
  or more short of its route's end;

The score needs the road in the recording (``meta["lanes"]``, ``meta["ego_route"]``); a
trajectory without it has no score (None).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Iterable, Mapping

import numpy as np

from ..trajectory import Trajectory
from .base import MonitorError
from .metrics import footprint_separation
from .rules import (
    STANDING_MPS,
    outside_route_fraction,
    route_fraction,
    standing_time,
    stop_crossings,
    traffic_speed_ratio,
)
from .signals import red_light_crossings

__all__ = ["PENALTIES", "DrivingScore", "driving_score", "campaign_score", "TIMEOUT_STAND_S"]

#: the Leaderboard's factor per infraction
PENALTIES: Mapping[str, float] = {
    "collision_pedestrian": 0.5,
    "collision_vehicle": 0.6,
    "collision_static": 0.65,
    "red_light": 0.7,
    "stop": 0.8,
    "scenario_timeout": 0.7,
}
#: the Leaderboard's floor of the minimum-speed factor (a standing ego gets 0.7)
MIN_SPEED_FLOOR = 0.7
#: [s] a run that ends with the ego standing this long short of its route's end timed out
TIMEOUT_STAND_S = 10.0
#: [m] footprints this close count as a contact (highway-env stops colliding vehicles with
#: their outlines touching, about -0 m apart)
CONTACT_M = 1e-6


@dataclass(frozen=True)
class DrivingScore:
    """``score`` = ``route_completion`` × ``penalty`` (all 0..1); ``infractions`` lists
    ``{"kind", "factor", "t", "agent"}`` in time order."""

    score: float
    route_completion: float
    penalty: float
    infractions: tuple[Mapping[str, Any], ...] = field(default_factory=tuple)

    def to_json(self) -> dict[str, Any]:
        return {"score": self.score, "route_completion": self.route_completion,
                "penalty": self.penalty, "infractions": [dict(i) for i in self.infractions]}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> "DrivingScore":
        return cls(float(data["score"]), float(data["route_completion"]),
                   float(data["penalty"]), tuple(dict(i) for i in data.get("infractions", ())))


def _collisions(traj: Trajectory) -> list[dict[str, Any]]:
    out = []
    if traj.n_agents > 1:
        sep = footprint_separation(traj)
        touch = sep <= CONTACT_M
        for row in np.flatnonzero(touch.any(axis=1)):
            k = int(np.argmax(touch[row]))
            kind = traj.kinds[row + 1]
            what = ("collision_pedestrian" if kind == "pedestrian"
                    else "collision_static" if kind == "parked" else "collision_vehicle")
            out.append({"kind": what, "t": float(traj.t[k]), "agent": traj.names[row + 1]})
    crashed = traj.crashed[0] & traj.present[0]
    if crashed.any() and not out:
        # a crash the simulator saw that no recorded footprint explains: the road's furniture
        # or something unrecorded
        k = int(np.argmax(crashed))
        out.append({"kind": "collision_static", "t": float(traj.t[k]), "agent": None})
    return out


def driving_score(traj: Trajectory) -> DrivingScore | None:
    """The Leaderboard's driving score of ``traj`` (see the module); None when the recording
    has no road or route to measure the route's completion on."""
    if not traj.meta.get("lanes") or not traj.meta.get("ego_route") or not traj.present[0].any():
        return None
    try:
        completion, _, _ = route_fraction(traj)
        infractions = _collisions(traj)
        for lane_id, k, vmin in stop_crossings(traj):
            if vmin >= STANDING_MPS:
                infractions.append({"kind": "stop", "t": float(traj.t[k]), "agent": None,
                                    "detail": f"{lane_id} at {vmin:.3g} m/s"})
        for p in red_light_crossings(traj):
            if p.ran:
                infractions.append({"kind": "red_light", "t": p.t, "agent": None,
                                    "detail": f"light {p.light} on {p.lane}"})
        stood = standing_time(traj, 0.1)
        last = int(np.flatnonzero(traj.present[0])[-1])
        if completion < 1.0 and stood[last] >= TIMEOUT_STAND_S:
            infractions.append({"kind": "scenario_timeout", "t": float(traj.t[last]),
                                "agent": None})
        for inf in infractions:
            inf["factor"] = PENALTIES[inf["kind"]]
        outside = outside_route_fraction(traj)
        if outside > 0:
            infractions.append({"kind": "outside_route_lanes", "t": None, "agent": None,
                                "factor": 1.0 - outside, "detail": f"{100 * outside:.3g}%"})
        ratio, _, _ = traffic_speed_ratio(traj)
        if math.isfinite(ratio) and ratio < 1.0:
            infractions.append({"kind": "min_speed", "t": None, "agent": None,
                                "factor": 1.0 - (1.0 - MIN_SPEED_FLOOR) * (1.0 - ratio),
                                "detail": f"{100 * ratio:.3g}% of traffic"})
    except MonitorError:
        return None
    infractions.sort(key=lambda i: (i["t"] is None, i["t"] or 0.0))
    penalty = float(np.prod([i["factor"] for i in infractions])) if infractions else 1.0
    return DrivingScore(max(completion * penalty, 0.0), completion, penalty, tuple(infractions))


def campaign_score(scores: Iterable[float | None]) -> float | None:
    """The Leaderboard's global score: the mean of the cases' scores (None without any)."""
    got = [float(s) for s in scores if s is not None]
    return float(np.mean(got)) if got else None

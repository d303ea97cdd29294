"""Monitors: what turns a recorded trajectory into verdicts.

Every monitor returns a robustness value ``rho`` (``rho >= 0`` holds, ``rho < 0`` violated,
``|rho|`` by how much, in the metric's unit) plus where and when the worst value happened and
against which agent (:class:`MonitorResult`). Monitors read only
:class:`~pytest_avscenario.trajectory.Trajectory` (build one from plain numpy arrays with
``Trajectory.from_arrays(t, agents={"ego": {"x": ..., "y": ...}, "lead": {...}})``), never
the simulator, and are vectorized over steps and agents.

* the paper's four metrics: :func:`distance`, :func:`ttc`, :func:`progress`,
  :func:`lane_keeping`; beside them :func:`collision`, :func:`time_headway`,
  :func:`off_road`, :func:`reaches`;
* signal temporal logic over signals of the trajectory: :func:`always`, :func:`eventually`,
  :func:`until`, :func:`and_`, :func:`or_`, :func:`not_`, :func:`implies` with signal
  builders such as :func:`ego_speed` and :func:`gap`;
* Responsibility-Sensitive Safety (Shalev-Shwartz et al. 2017): :func:`rss`, a monitor of
  the margin to the RSS-safe longitudinal and lateral distances, and :func:`rss_blame`, who
  entered an RSS-unsafe state by their own responsibility first; the paper's formulas
  :func:`safe_longitudinal_distance`, :func:`safe_opposite_distance`,
  :func:`safe_lateral_distance` with their :class:`RSSParams`;
* the rules of the road under CARLA ScenarioRunner's names (:mod:`.rules`):
  :func:`off_road`, :func:`on_sidewalk`, :func:`wrong_way`, :func:`outside_route_lanes`,
  :func:`ran_stop`, :func:`route_completion`, :func:`blocked`, :func:`min_speed_route`,
  :func:`ran_red_light` (:mod:`.signals`: where the world has traffic lights); and
  the Leaderboard's :func:`driving_score` (:mod:`.score`);
* criticality measures under CommonRoad-CriMe's names (:mod:`.criticality`): :func:`ettc`
  (TTC with accelerations), :func:`required_deceleration`, :func:`brake_threat_number`,
  :func:`time_to_brake`, :func:`time_to_steer`, :func:`post_encroachment_time`;
* :func:`as_monitor` makes a plain function ``trajectory -> float`` a monitor;
* :class:`MonitorSet` evaluates several into a :class:`Verdict` and carries their priority;
* :func:`rho_to_json` / :func:`rho_from_json` / :func:`rho_to_str` / :func:`rho_from_str`
  write ``±inf`` explicitly in every report.

Without a simulator (positions [m], velocities [m/s]; NaN and ``present=False`` where an
agent is not in the scene)::

    import numpy as np
    from pytest_avscenario.trajectory import Trajectory
    from pytest_avscenario.monitors import MonitorSet, distance, ttc, always, gap

    t = np.arange(0, 10, 0.1)
    traj = Trajectory.from_arrays(t, agents={
        "ego": {"x": 12 * t, "y": 0 * t, "vx": 12.0, "vy": 0.0, "lane_offset": 0.1},
        "lead": {"x": 30 + 8 * t, "y": 0 * t, "vx": 8.0, "vy": 0.0},
    })
    MonitorSet([distance(5.0), ttc(2.0), always(gap("lead") >= 5.0).named("gap")],
               priority=["ttc", "distance"]).evaluate(traj).rho
"""

from .base import FunctionMonitor, Monitor, MonitorError, MonitorResult, as_monitor
from .metrics import (
    collision,
    distance,
    lane_keeping,
    off_road,
    progress,
    reaches,
    time_headway,
    ttc,
)
from .stl import (
    Formula,
    Signal,
    always,
    and_,
    ego_acceleration,
    ego_speed,
    eventually,
    gap,
    headway_to,
    implies,
    lane_offset,
    not_,
    or_,
    predicate,
    signal,
    ttc_to,
    until,
)
from .rss import (
    RSSBlame,
    RSSEpisode,
    RSSParams,
    rss,
    rss_blame,
    rss_margins,
    safe_lateral_distance,
    safe_longitudinal_distance,
    safe_opposite_distance,
)
from .rules import (
    blocked,
    min_speed_route,
    on_sidewalk,
    outside_route_lanes,
    ran_stop,
    route_completion,
    wrong_way,
)
from .criticality import (
    brake_threat_number,
    ettc,
    post_encroachment_time,
    required_deceleration,
    time_to_brake,
    time_to_steer,
)
from .signals import ran_red_light
from .score import DrivingScore, driving_score
from ..codec import rho_from_json, rho_from_str, rho_to_json, rho_to_str
from .sets import MonitorSet, Verdict

__all__ = [
    "Monitor", "MonitorError", "MonitorResult", "FunctionMonitor", "as_monitor",
    "distance", "ttc", "progress", "lane_keeping",
    "collision", "time_headway", "off_road", "reaches",
    "rss", "rss_blame", "rss_margins", "RSSParams", "RSSBlame", "RSSEpisode",
    "safe_longitudinal_distance", "safe_opposite_distance", "safe_lateral_distance",
    "Formula", "Signal", "always", "eventually", "until", "and_", "or_", "not_", "implies",
    "ego_speed", "ego_acceleration", "lane_offset", "gap", "ttc_to", "headway_to", "signal",
    "predicate",
    "on_sidewalk", "wrong_way", "outside_route_lanes", "ran_stop", "route_completion",
    "blocked", "min_speed_route", "ran_red_light",
    "ettc", "required_deceleration", "brake_threat_number", "time_to_brake", "time_to_steer",
    "post_encroachment_time", "DrivingScore", "driving_score",
    "MonitorSet", "Verdict",
    "rho_to_json", "rho_from_json", "rho_to_str", "rho_from_str",
]

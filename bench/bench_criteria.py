"""Benchmark: the traffic-rule criteria, the criticality measures and the driving score on a
300-step, 5-agent trajectory.

The scene of ``bench_monitors.py`` (a three-lane highway, one car absent for the first half)
with the road the simulator records (``meta["lanes"]``, the ego's route, a stop line the ego
drives over) and a pedestrian crossing the ego's path (so post-encroachment time has a
crossing to measure). Every call gets a fresh copy of the trajectory, so the per-trajectory
caches (lane projections, lead kinematics) are paid in every repetition, as in a run. The
anchor is the paper's four metrics on the same trajectory in the same process.
Times are CPU time of the calling thread (median; the minimum beside it is what a quiet
machine approaches). Target: all new monitors together under 2 ms, printed as PASS / MISS with
the ratio to the anchor.

    python bench/bench_criteria.py [--steps 300] [--agents 5] [--repeat 200]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_monitors import scene  # noqa: E402

from pytest_avscenario.monitors import (  # noqa: E402
    blocked,
    brake_threat_number,
    distance,
    driving_score,
    ettc,
    lane_keeping,
    min_speed_route,
    off_road,
    on_sidewalk,
    outside_route_lanes,
    post_encroachment_time,
    progress,
    ran_stop,
    required_deceleration,
    route_completion,
    time_to_brake,
    time_to_steer,
    ttc,
    wrong_way,
)
from pytest_avscenario.trajectory import Trajectory  # noqa: E402


def road_scene(steps: int, agents: int) -> Trajectory:
    """``scene`` with a recorded road and a pedestrian crossing the ego's lane."""
    base = scene(steps, agents - 1)
    t = base.t
    spec = {}
    for i, name in enumerate(base.names):
        spec[name] = {k: getattr(base, k)[i] for k in ("x", "y", "vx", "vy", "lane",
                                                      "lane_offset", "present")}
    # the pedestrian crosses the ego's lane where the ego is halfway through the run
    x_mid = float(base.x[0, steps // 2])
    spec["ped"] = {"x": np.full(steps, x_mid + 10.0), "y": -6.0 + 1.5 * t,
                   "vx": np.zeros(steps), "vy": np.full(steps, 1.5), "kind": "pedestrian",
                   "length": 0.5, "width": 0.5}
    lanes = {f"hw/{k}": {"xy": [[-100.0, 4.0 * k], [2000.0, 4.0 * k]], "width": 4.0,
                         "group": "hw", "kind": "travel"} for k in range(3)}
    ego_lane = str(base.lane[0, 0])
    x0 = float(base.x[0, 0])
    meta = {"lanes": lanes, "ego_route": [ego_lane],
            "stops": [{"lane": ego_lane, "s": x0 + 100.0 + 30.0, "kind": "stop"}]}
    return Trajectory.from_arrays(t, spec, meta=meta)


NEW = {
    "off_road": off_road(), "on_sidewalk": on_sidewalk(), "wrong_way": wrong_way(),
    "outside_route_lanes": outside_route_lanes(), "ran_stop": ran_stop(),
    "route_completion": route_completion(0.5), "blocked": blocked(),
    "min_speed_route": min_speed_route(0.5),
    "post_encroachment_time": post_encroachment_time(1.0),
    "required_deceleration": required_deceleration(4.0),
    "brake_threat_number": brake_threat_number(), "ettc": ettc(2.0),
    "time_to_brake": time_to_brake(1.0), "time_to_steer": time_to_steer(0.5),
}
PAPER = [distance(5.0), ttc(2.0), progress(11.0), lane_keeping(0.5)]


def fresh(traj: Trajectory) -> Trajectory:
    return dataclasses.replace(traj)  # a new object: the per-trajectory caches start cold


def time_ms(fn, repeat: int, *, both: bool = False):
    """Median CPU time [ms] of one call (with ``both``: median and minimum): the thread's
    own CPU clock, since on a machine shared by many processes the wall clock mostly
    measures waiting for a core."""
    out = []
    for _ in range(repeat):
        t0 = time.thread_time()
        fn()
        out.append(time.thread_time() - t0)
    med = 1000 * statistics.median(out)
    return (med, 1000 * min(out)) if both else med


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--agents", type=int, default=5, help="ego, traffic and one pedestrian")
    ap.add_argument("--repeat", type=int, default=200)
    args = ap.parse_args()
    traj = road_scene(args.steps, args.agents)
    print(f"{args.steps} steps x {traj.n_agents} agents, Python {platform.python_version()}, "
          f"numpy {np.__version__}, median of {args.repeat}")
    for name, m in NEW.items():  # every monitor gives a verdict here
        r = m.evaluate(fresh(traj))
        print(f"  {name:24s} rho {r.rho:10.4g}  {r.detail[:70]}")
    print(f"  driving score {driving_score(fresh(traj)).score:.3g}")

    def new_all():
        tr = fresh(traj)
        for m in NEW.values():
            m.evaluate(tr)

    def paper():
        tr = fresh(traj)
        for m in PAPER:
            m.evaluate(tr)

    for _ in range(20):  # warm up
        new_all(), paper()
    each = {name: time_ms(lambda m=m: m.evaluate(fresh(traj)), args.repeat)
            for name, m in NEW.items()}
    a, a_min = time_ms(new_all, args.repeat, both=True)
    s = time_ms(lambda: driving_score(fresh(traj)), args.repeat)
    p, p_min = time_ms(paper, args.repeat, both=True)
    for name, ms in each.items():
        print(f"  {name:24s} {ms:7.3f} ms (alone, cold caches)")
    print(f"driving score alone: {s:.3f} ms")
    print(f"anchor, the paper's four metrics: {p:.3f} ms (min {p_min:.3f})")
    print(f"all {len(NEW)} new monitors together: {a:.3f} ms (min {a_min:.3f}); "
          f"new / anchor = {a / p:.2f} (min / min {a_min / p_min:.2f}); "
          f"target <= 2 ms: {'PASS' if a <= 2.0 else 'MISS'}")


if __name__ == "__main__":
    main()

"""Benchmark: every new monitor of issue #31 (the traffic-rule criteria, ``ran_red_light``,
the criticality measures) and the driving score on a 300-step, 5-agent trajectory.

The scene of ``bench_monitors.py`` (a three-lane highway, one car absent for the first half)
with the road the simulator records (``meta["lanes"]``, the ego's route, a stop line the ego
drives over), a pedestrian crossing the ego's path (so post-encroachment time has a
crossing to measure) and a traffic light on the ego's route that turns red as it approaches
(so ``ran_red_light`` computes every part of its measure). Every call gets a fresh copy of
the trajectory, so the per-trajectory caches (lane projections, lead kinematics) are paid in
every repetition, as in a run. The anchor is the paper's four metrics on the same trajectory
in the same process, timed in turns with the new monitors. Times are CPU time of the calling
thread (median; the minimum beside it is what a quiet machine approaches). Target: all new
monitors together under 2 ms, printed as PASS / MISS with the ratio to the anchor. The 14
monitors without ``ran_red_light`` (what this benchmark timed before the light was added) are
printed too.

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
    ran_red_light,
    ran_stop,
    required_deceleration,
    route_completion,
    time_to_brake,
    time_to_steer,
    ttc,
    wrong_way,
)
from pytest_avscenario.trajectory import Trajectory  # noqa: E402


def road_scene(steps: int, agents: int, seed: int = 0) -> Trajectory:
    """``scene`` with a recorded road and a pedestrian crossing the ego's lane."""
    base = scene(steps, agents - 1, seed)
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


def light_scene(steps: int, agents: int, seed: int = 0) -> Trajectory:
    """``road_scene`` with a traffic light on the ego's route, 200 m ahead of its start, that
    turns red a fifth into the run (the ego runs it, so every part of ``ran_red_light`` is
    computed)."""
    traj = road_scene(steps, agents, seed)
    lane = traj.meta["ego_route"][0]
    x0 = float(traj.x[0, 0])
    s = x0 + 100.0 + 100.0  # the stop position's x; the lanes start at x = -100
    codes = np.where(np.arange(steps) >= steps // 5, 2.0, 0.0)
    meta = dict(traj.meta)
    meta["lights"] = [{"id": "1", "controller": "c", "x": s, "y": -3.0, "heading": 0.0,
                       "stops": [{"lane": lane, "s": s + 100.0, "x": s, "y": 0.0,
                                  "heading": 0.0, "width": 4.0}]}]
    return dataclasses.replace(traj, meta=meta, signals={**traj.signals, "light.1": codes})


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
#: every new monitor: the 14 above and the red-light criterion (issue #31's "all new monitors")
ALL = {**NEW, "ran_red_light": ran_red_light()}
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


def time_interleaved(fns, repeat: int) -> list[float]:
    """Median and minimum CPU time [ms] of each of ``fns``, called in turns (one call of each
    per round), so that a changing load on the machine falls on all of them alike."""
    out = [[] for _ in fns]
    for _ in range(repeat):
        for fn, acc in zip(fns, out):
            t0 = time.thread_time()
            fn()
            acc.append(time.thread_time() - t0)
    res = []
    for acc in out:
        res += [1000 * statistics.median(acc), 1000 * min(acc)]
    return res


def count_instructions(args, calls: int = 100) -> None:
    """Instructions per call of each workload under callgrind: a run of ``calls`` calls minus
    a run of none (imports and set-up cancel out)."""
    import re
    import subprocess
    import tempfile

    def run(only: str, n: int) -> int:
        with tempfile.TemporaryDirectory() as tmp:
            cmd = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={tmp}/out",
                   sys.executable, os.path.abspath(__file__), "--steps", str(args.steps),
                   "--agents", str(args.agents), "--only", only, "--calls", str(n)]
            err = subprocess.run(cmd, capture_output=True, text=True, check=True).stderr
        return int(re.search(r"Collected : (\d+)", err).group(1))

    got = {}
    for only in ("all", "14", "paper"):
        got[only] = (run(only, calls) - run(only, 0)) / calls
    print(f"instructions per call (callgrind, {calls} calls minus none): all {len(ALL)} new "
          f"{got['all'] / 1e6:.3f} M, the {len(NEW)} without ran_red_light "
          f"{got['14'] / 1e6:.3f} M, anchor {got['paper'] / 1e6:.3f} M; new / anchor "
          f"{got['all'] / got['paper']:.2f}")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--agents", type=int, default=5, help="ego, traffic and one pedestrian")
    ap.add_argument("--repeat", type=int, default=200)
    ap.add_argument("--instructions", action="store_true",
                    help="count instructions per call with valgrind's callgrind instead "
                         "(robust to the machine's load; ~2 minutes)")
    ap.add_argument("--only", choices=["all", "14", "paper"], help=argparse.SUPPRESS)
    ap.add_argument("--calls", type=int, default=0, help=argparse.SUPPRESS)
    args = ap.parse_args()
    traj = light_scene(args.steps, args.agents)
    if args.only:  # one workload N times, nothing else: what --instructions counts
        mons = {"all": list(ALL.values()), "14": list(NEW.values()), "paper": PAPER}[args.only]
        for _ in range(args.calls):
            tr = fresh(traj)
            for m in mons:
                m.evaluate(tr)
        return
    if args.instructions:
        count_instructions(args)
        return
    print(f"{args.steps} steps x {traj.n_agents} agents, Python {platform.python_version()}, "
          f"numpy {np.__version__}, median of {args.repeat}")
    for name, m in ALL.items():  # every monitor gives a verdict here
        r = m.evaluate(fresh(traj))
        print(f"  {name:24s} rho {r.rho:10.4g}  {r.detail[:70]}")
    print(f"  driving score {driving_score(fresh(traj)).score:.3g}")

    def run(monitors):
        def go():
            tr = fresh(traj)
            for m in monitors:
                m.evaluate(tr)
        return go

    new_all, new_14, paper = run(list(ALL.values())), run(list(NEW.values())), run(PAPER)
    for _ in range(20):  # warm up
        new_all(), paper()
    each = {name: time_ms(lambda m=m: m.evaluate(fresh(traj)), args.repeat)
            for name, m in ALL.items()}
    s = time_ms(lambda: driving_score(fresh(traj)), args.repeat)
    # the goal's figure and its anchor, taken in turns so that both see the same load
    a, a_min, p, p_min, o, o_min = time_interleaved([new_all, paper, new_14], args.repeat)
    for name, ms in each.items():
        print(f"  {name:24s} {ms:7.3f} ms (alone, cold caches)")
    print(f"driving score alone: {s:.3f} ms")
    print(f"anchor, the paper's four metrics: {p:.3f} ms (min {p_min:.3f})")
    print(f"the {len(NEW)} monitors without ran_red_light (the figure before 2026-11-28): "
          f"{o:.3f} ms (min {o_min:.3f}); / anchor = {o / p:.2f}")
    print(f"all {len(ALL)} new monitors together: {a:.3f} ms (min {a_min:.3f}); "
          f"new / anchor = {a / p:.2f} (min / min {a_min / p_min:.2f}); "
          f"target <= 2 ms: {'PASS' if a <= 2.0 else 'MISS'}")


if __name__ == "__main__":
    main()

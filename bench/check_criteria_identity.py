"""Identity check for the criteria monitors: every monitor's verdict on a corpus of
trajectories, written to a file by one version of the code and compared by another.

A change that only makes the monitors faster must leave every result as it was, bit for bit:
ρ, threshold, t, agent, detail, the first violation (``first_violation``), ``series()``, the
error text of a trajectory a monitor refuses, and the driving score. Each monitor is
evaluated alone on a fresh copy of each trajectory, and all of them in turn on one copy (so
the shared per-trajectory values are read by the monitors in every order that matters).

The corpus: the scene of ``bench_criteria.py`` at several sizes and seeds, with and without
its traffic light and stop line; random braking leads, crossings and light runs built by
hand; and, with ``--from-tests``, every trajectory the rule, criticality and signal tests
hand to a monitor (simulated intersections and map roads among them), collected by running
those tests in process.

    python bench/check_criteria_identity.py --from-tests --write /tmp/before.json   # old code
    python bench/check_criteria_identity.py --from-tests --compare /tmp/before.json # new code

Run it with ``PYTHONPATH`` pointing at the tree under test.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_criteria import light_scene, road_scene  # noqa: E402

from pytest_avscenario.monitors import (  # noqa: E402
    blocked,
    brake_threat_number,
    driving_score,
    ettc,
    min_speed_route,
    off_road,
    on_sidewalk,
    outside_route_lanes,
    post_encroachment_time,
    ran_red_light,
    ran_stop,
    required_deceleration,
    route_completion,
    time_to_brake,
    time_to_steer,
    wrong_way,
)
from pytest_avscenario.monitors.base import Monitor, first_violation  # noqa: E402
from pytest_avscenario.trajectory import Trajectory  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def monitors() -> list[Monitor]:
    """The criteria with their defaults and with other parameters."""
    return [
        off_road(), on_sidewalk(), wrong_way(), outside_route_lanes(), ran_stop(),
        route_completion(0.5), blocked(), min_speed_route(0.5), post_encroachment_time(1.0),
        required_deceleration(4.0), brake_threat_number(), ettc(2.0), time_to_brake(1.0),
        time_to_steer(0.5), ran_red_light(),
        on_sidewalk(3.0, name="on_sidewalk_3"), wrong_way(45.0, name="wrong_way_45"),
        ran_stop(0.1, before=6.0, past=0.0, name="ran_stop_carla"),
        route_completion(1.0, name="route_completion_1"),
        blocked(2.0, 0.5, name="blocked_2"), min_speed_route(1.0, name="min_speed_route_1"),
        post_encroachment_time(2.0, min_angle_deg=60.0, name="pet_60"),
        required_deceleration(2.0, name="a_req_2"),
        brake_threat_number(0.5, max_decel=6.0, name="btn_6"), ettc(5.0, name="ettc_5"),
        time_to_brake(0.5, max_decel=5.0, name="ttb_5"),
        time_to_steer(1.0, max_lat_accel=3.0, name="tts_3"),
        ran_red_light("front", name="ran_red_light_front"),
    ]


# -- the corpus ----------------------------------------------------------------------------------

ROAD = {
    "lanes": {
        "a": {"xy": [[0, 0], [200, 0]], "width": 3.5, "group": "east", "kind": "travel"},
        "b": {"xy": [[0, -3.5], [200, -3.5]], "width": 3.5, "group": "east", "kind": "travel"},
        "w": {"xy": [[200, 3.5], [0, 3.5]], "width": 3.5, "group": "west", "kind": "travel"},
        "c": {"xy": [[200, 0], [260, 10], [300, 40]], "width": 3.5, "group": "north"},
    },
    "stops": [{"lane": "a", "s": 50.0, "kind": "stop"}, {"lane": "c", "s": 30.0, "kind": "stop"}],
    "ego_route": ["a", "c"],
    "lights": [{"id": "7", "controller": "c", "x": 120, "y": 3, "heading": math.pi,
                "stops": [{"lane": "a", "s": 120.0, "x": 120, "y": 0, "heading": 0,
                           "width": 3.5}]}],
}


def _following(rng: np.random.Generator) -> Trajectory:
    """An ego behind a lead that brakes (or speeds up), another car beside, a car oncoming;
    lanes known or not, the ego changing lanes in some."""
    dt = float(rng.choice([0.05, 0.1]))
    t = np.arange(0.0, 12.0, dt)
    v_e, v_l = rng.uniform(5, 25), rng.uniform(0, 20)
    a_e, a_l = rng.uniform(-2, 2), float(rng.choice([0.0, -2.0, -6.0, 1.0]))
    gap = rng.uniform(2, 60)
    ve = np.maximum(v_e + a_e * t, 0.0)
    vl = np.maximum(v_l + a_l * t, 0.0)
    xe = np.concatenate([[0.0], np.cumsum(ve[1:] * dt)])
    xl = gap + 5.0 + np.concatenate([[0.0], np.cumsum(vl[1:] * dt)])
    wob = rng.uniform(0, 0.8) * np.sin(t * rng.uniform(0.2, 1.5))
    lane_e = np.where(wob > 0.5, "b", "a") if rng.random() < 0.5 else "a"
    stand = rng.random() < 0.3
    if stand:  # stands for a while in the middle
        ve = np.where((t > 3) & (t < 7), 0.0, ve)
        xe = np.concatenate([[0.0], np.cumsum(ve[1:] * dt)])
    agents = {
        "ego": {"x": xe, "y": wob, "vx": ve, "vy": np.gradient(wob, t), "lane": lane_e,
                "on_road": np.abs(wob) < 0.7},
        "lead": {"x": xl, "y": 0 * t, "vx": vl, "vy": 0 * t,
                 "lane": "a" if rng.random() < 0.8 else ""},
        "side": {"x": xe + rng.uniform(-10, 10), "y": -3.5 + 0 * t, "vx": ve, "vy": 0 * t,
                 "lane": "b"},
        "onc": {"x": 250 - 12 * t, "y": 3.5 + 0 * t, "vx": -12.0, "vy": 0.0, "lane": "w",
                "kind": "truck"},
    }
    codes = np.where(t >= rng.uniform(0, 10), 2.0, np.where(t >= rng.uniform(0, 6), 1.0, 0.0))
    return Trajectory.from_arrays(t, agents, signals={"light.7": codes}, meta=ROAD)


def _crossing(rng: np.random.Generator) -> Trajectory:
    t = np.arange(0.0, 8.0, 0.1)
    agents = {"ego": {"x": -30 + rng.uniform(6, 12) * t, "y": 0.3 * np.sin(t), "lane": "a"}}
    for a in range(4):
        ang = float(rng.choice([0.0, math.pi / 2, -math.pi / 2, 0.6, math.pi]))
        v = rng.uniform(1, 12)
        x0, y0 = rng.uniform(-10, 30), rng.uniform(-25, 25)
        present = t >= rng.uniform(0, 3)
        agents[f"a{a}"] = {"x": np.where(present, x0 + v * math.cos(ang) * t, np.nan),
                           "y": np.where(present, y0 + v * math.sin(ang) * t, np.nan),
                           "vx": v * math.cos(ang), "vy": v * math.sin(ang), "heading": ang,
                           "present": present, "kind": "pedestrian" if a == 0 else "car"}
    return Trajectory.from_arrays(t, agents, meta=ROAD if rng.random() < 0.5 else {})


def corpus(from_tests: bool) -> list[tuple[str, Trajectory]]:
    out = []
    for steps, agents in ((300, 5), (300, 3), (60, 5), (1000, 5), (300, 8), (2, 2)):
        for seed in (0, 1):
            out.append((f"bench {steps}x{agents} seed {seed}", road_scene(steps, agents, seed)))
            out.append((f"bench+light {steps}x{agents} seed {seed}",
                        light_scene(steps, agents, seed)))
    rng = np.random.default_rng(31)
    out += [(f"following {i}", _following(rng)) for i in range(24)]
    out += [(f"crossing {i}", _crossing(rng)) for i in range(12)]
    if from_tests:
        out += [(f"test {i}: {name}", tr) for i, (name, tr) in enumerate(_from_tests())]
    return out


def _from_tests() -> list[tuple[str, Trajectory]]:
    """Every distinct trajectory the rule, criticality and signal tests give a monitor."""
    import pytest

    seen: dict[int, tuple[str, Trajectory]] = {}
    evaluate = Monitor.evaluate

    class Collect:
        current = ""

        def pytest_runtest_setup(self, item):
            Collect.current = item.nodeid.split("::")[-1]

    def spy(self, traj):
        if isinstance(traj, Trajectory) and id(traj) not in seen:
            seen[id(traj)] = (Collect.current, traj)
        return evaluate(self, traj)

    Monitor.evaluate = spy
    try:
        code = pytest.main(["-q", "-p", "no:cacheprovider", "-p", "no:randomly", "-x",
                            "-k", "not pytester and not scenario and not campaign",
                            os.path.join(ROOT, "tests", "test_monitors_criteria.py"),
                            os.path.join(ROOT, "tests", "test_monitors_criteria_shared.py"),
                            os.path.join(ROOT, "tests", "test_signals.py")],
                           plugins=[Collect()])
    finally:
        Monitor.evaluate = evaluate
    if code not in (0, 5):
        raise SystemExit(f"the tests the corpus comes from failed (exit {code})")
    return list(seen.values())


# -- the verdicts ---------------------------------------------------------------------------------

def _r(x):
    """A value as exact text (repr of floats round-trips)."""
    if x is None or isinstance(x, (str, bool, int)):
        return x
    if isinstance(x, (float, np.floating)):
        return repr(float(x))
    if isinstance(x, np.ndarray):
        return [repr(float(v)) for v in x.ravel()]
    if isinstance(x, (tuple, list)):
        return [_r(v) for v in x]
    if isinstance(x, dict):
        return {k: _r(v) for k, v in x.items()}
    return repr(x)


def verdict(m: Monitor, traj: Trajectory) -> dict:
    try:
        r = m.evaluate(traj)
    except Exception as exc:
        return {"error": f"{type(exc).__name__}: {exc}"}
    out = {"rho": _r(r.rho), "threshold": _r(r.threshold), "t": _r(r.t), "agent": r.agent,
           "detail": r.detail}
    try:
        out["first"] = _r(first_violation(m, dataclasses.replace(traj), r))
    except Exception as exc:
        out["first"] = f"{type(exc).__name__}: {exc}"
    try:
        out["series"] = _r(m.series(dataclasses.replace(traj)))
    except Exception as exc:
        out["series"] = f"{type(exc).__name__}: {exc}"
    return out


def results(from_tests: bool) -> dict:
    out = {}
    mons = monitors()
    for name, traj in corpus(from_tests):
        alone = {m.name: verdict(m, dataclasses.replace(traj)) for m in mons}
        shared = dataclasses.replace(traj)
        together = {m.name: verdict(m, shared) for m in reversed(mons)}
        try:
            ds = driving_score(dataclasses.replace(traj))
            score = None if ds is None else _r(ds.to_json())
        except Exception as exc:
            score = f"{type(exc).__name__}: {exc}"
        key = name
        while key in out:
            key += "'"
        out[key] = {"alone": alone, "together": together, "score": score}
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--from-tests", action="store_true",
                    help="add the trajectories the criteria and signal tests build")
    g = ap.add_mutually_exclusive_group(required=True)
    g.add_argument("--write", metavar="FILE")
    g.add_argument("--compare", metavar="FILE")
    args = ap.parse_args()
    got = results(args.from_tests)
    n_traj = len(got)
    n_verdicts = sum(len(v["alone"]) + len(v["together"]) + 1 for v in got.values())
    if args.write:
        with open(args.write, "w") as fh:
            json.dump(got, fh, sort_keys=True)
        print(f"wrote {n_verdicts} verdicts of {len(monitors())} monitors on {n_traj} "
              f"trajectories to {args.write}")
        return
    with open(args.compare) as fh:
        want = json.load(fh)
    got = json.loads(json.dumps(got, sort_keys=True))
    diff = []
    for traj in sorted(set(want) | set(got)):
        a, b = want.get(traj), got.get(traj)
        if a == b:
            continue
        if a is None or b is None:
            diff.append(f"{traj}: only in {'the new' if a is None else 'the old'} results")
            continue
        for part in ("alone", "together"):
            for m in sorted(set(a[part]) | set(b[part])):
                if a[part].get(m) != b[part].get(m):
                    fields = [k for k in set(a[part].get(m) or {}) | set(b[part].get(m) or {})
                              if (a[part].get(m) or {}).get(k) != (b[part].get(m) or {}).get(k)]
                    diff.append(f"{traj} / {m} ({part}): {sorted(fields)}")
        if a["score"] != b["score"]:
            diff.append(f"{traj} / driving score")
    erred = sum(1 for v in got.values() for r in v["alone"].values() if "error" in r)
    print(f"{n_verdicts} verdicts of {len(monitors())} monitors on {n_traj} trajectories "
          f"({erred} refusals among them): "
          + ("identical" if not diff else f"{len(diff)} differ"))
    for line in diff[:40]:
        print("  " + line)
    sys.exit(1 if diff else 0)


if __name__ == "__main__":
    main()

"""OpenDRIVE maps: load time, closest-lane query, and a case on Town06 against a built road.

Three measurements, CPU time (``time.process_time``: what machine load disturbs least) with
wall time beside it:

1. **Load** — each map of ``../shared/maps`` read into lanes in a fresh process (the
   once-per-process cost a campaign pays), median of ``--repeats``; with ``--pyxodr`` also
   with pyxodr evaluating the reference lines (the ``maps`` extra), its import timed apart.
2. **Closest lane** — ``--queries`` random points over Town06's extent: the map's shapely
   STRtree (``MapData.closest``; ``MapRoad.closest`` adds the lane coordinates) against
   highway-env's own ``RoadNetwork.get_closest_lane_index`` on the same lanes (a scan of
   every lane).
3. **A case** — vehicle following driven by the autopilot for 12 s (a lead 25 m ahead at
   8 m/s): on a Town06 driving lane (the lane drawn per case from all its driving lanes of
   100 m or more, as ``example_tests/test_maps_town06_following.py`` does) against the same
   on ``world.straight_road`` (the anchor), ``--cases`` each, interleaved, after one warm-up
   of each; the built road gets the speed limit of the case's map lane (the autopilot
   cruises at it). The ratio is the result.

Each goal of the maps issue is printed with PASS or MISS: Town06 loaded in <= 1.5 s (CPU),
a closest-lane query <= 0.5 ms, a case on Town06 <= 1.5x the same case on the built road.

    python bench/bench_maps.py --repeats 3 --queries 2000 --cases 20 --pyxodr

``--callgrind N`` counts instead the instructions of N cases of each kind under valgrind's
callgrind (machine load does not change them): three processes with ``PYTHONHASHSEED=0``
that each make the map and run one warm-up case of each kind, then N map cases, N built-road
cases, or nothing; a kind's count is its process's total less the last one's (~3 minutes).

    python bench/bench_maps.py --callgrind 10
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SHARED = ROOT.parent / "shared" / "maps"
TOWN06 = ROOT / "example_tests" / "maps" / "Town06.xodr"

LOAD = """
import json, sys, time
from pytest_avscenario.sim import opendrive
t0, c0 = time.perf_counter(), time.process_time()
ev = sys.argv[2]
if ev == "pyxodr":
    import pyxodr.road_objects.road  # noqa: F401  (its import: matplotlib, scipy, rich)
t1, c1 = time.perf_counter(), time.process_time()
data = opendrive.load(sys.argv[1], evaluator=ev)
t2, c2 = time.perf_counter(), time.process_time()
print(json.dumps({"import_wall": t1 - t0, "import_cpu": c1 - c0, "wall": t2 - t1,
                  "cpu": c2 - c1, "lanes": len(data.lanes),
                  "driving": len(data.of_kind("driving"))}))
"""


def load_times(path: Path, evaluator: str, repeats: int) -> dict:
    runs = []
    for _ in range(repeats):
        out = subprocess.run([sys.executable, "-c", LOAD, str(path), evaluator], cwd=ROOT,
                             capture_output=True, text=True, check=True,
                             env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"})
        runs.append(json.loads(out.stdout))
    med = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
    return med


def queries(n: int) -> dict:
    import numpy as np

    from pytest_avscenario.sim import World

    world = World(0, name="bench")
    town = world.map(TOWN06)
    data = town.data
    pts = np.concatenate([l.xy for l in data.lanes.values()])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    rng = np.random.default_rng(0)
    xy = rng.uniform(lo, hi, size=(n, 2))
    data.closest(0.0, 0.0)  # build the tree once
    out = {}
    c0 = time.process_time()
    for x, y in xy:
        data.closest(x, y)
    out["strtree_ms"] = (time.process_time() - c0) / n * 1e3
    c0 = time.process_time()
    for x, y in xy:
        town.closest(x, y)
    out["strtree_spot_ms"] = (time.process_time() - c0) / n * 1e3
    net = town.net
    m = max(n // 20, 20)
    c0 = time.process_time()
    agree = 0
    for x, y in xy[:m]:
        idx = net.get_closest_lane_index(np.array([x, y]))
        agree += town.world.lane_index.lanes[idx].id == town.closest(x, y).lane.id
    out["highway_env_ms"] = (time.process_time() - c0) / m * 1e3
    out["agree"] = f"{agree}/{m}"
    out["lanes"] = len(town.all_lanes)
    return out


def _case(kind: str, k: int, lanes: list[str]) -> float:
    from pytest_avscenario.sim import World

    world = World(k, name="bench", driver="autopilot")
    if kind == "map":
        town = world.map(TOWN06)
        start = town.lane(lanes[k % len(lanes)]).at(10.0)
        world.ego(start, speed=12.0)
        world.car(town.ahead(start, 25.0), speed=8.0)
    else:  # the same speed limit as the map lane of this case: the autopilot cruises at it
        road = world.straight_road(lanes=1, length=400, speed_limit=_LIMITS[lanes[k % len(lanes)]])
        world.ego(road.lane(0), s=10.0, speed=12.0)
        world.car(road.lane(0), s=35.0, speed=8.0)
    world.run(seconds=12)
    return world.trajectory.t[-1]


_LIMITS: dict[str, float] = {}

CALLGRIND = """
import sys
sys.path.insert(0, sys.argv[1])
import bench_maps as bm
from pytest_avscenario.sim import World
from pytest_avscenario.sim.opendrive import MapLane
lanes = list(MapLane(bm.TOWN06, kind="driving", min_length=100).options)
town = World(0).map(bm.TOWN06)
bm._LIMITS.update({l: town.lane(l).speed_limit for l in lanes})
bm._case("map", 0, lanes)
bm._case("built", 0, lanes)
for k in range(int(sys.argv[3]) if sys.argv[2] != "none" else 0):
    bm._case(sys.argv[2], k + 1, lanes)
"""


def instructions(n: int) -> dict:
    """Instructions [M] of ``n`` map and ``n`` built-road cases, counted by callgrind."""
    import os
    import re
    import tempfile

    procs = {}
    with tempfile.TemporaryDirectory() as tmp:
        for kind in ("map", "built", "none"):
            env = dict(os.environ, PYTHONHASHSEED="0", PYTHONPATH=str(ROOT))
            procs[kind] = subprocess.Popen(
                ["valgrind", "--tool=callgrind", f"--callgrind-out-file={tmp}/{kind}.out",
                 sys.executable, "-c", CALLGRIND, str(Path(__file__).parent), kind, str(n)],
                cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        total = {}
        for kind, proc in procs.items():
            err = proc.communicate()[1]
            got = re.search(r"Collected : (\d+)", err)
            if proc.returncode or got is None:
                raise SystemExit(f"callgrind of the {kind} cases failed:\n{err[-2000:]}")
            total[kind] = int(got.group(1))
    out = {k: (total[k] - total["none"]) / 1e6 for k in ("map", "built")}
    out["ratio"] = out["map"] / out["built"]
    return out


def cases(n: int) -> dict:
    from pytest_avscenario.sim import World
    from pytest_avscenario.sim.opendrive import MapLane

    lanes = list(MapLane(TOWN06, kind="driving", min_length=100).options)
    town = World(0).map(TOWN06)
    _LIMITS.update({l: town.lane(l).speed_limit for l in lanes})
    _case("map", 0, lanes)
    _case("built", 0, lanes)
    cpu = {"map": [], "built": []}
    for k in range(n):
        for kind in ("built", "map"):
            c0 = time.process_time()
            _case(kind, k + 1, lanes)
            cpu[kind].append(time.process_time() - c0)
    med = {k: statistics.median(v) for k, v in cpu.items()}
    return {"map_ms": med["map"] * 1e3, "built_ms": med["built"] * 1e3,
            "ratio": med["map"] / med["built"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--queries", type=int, default=2000)
    ap.add_argument("--cases", type=int, default=20)
    ap.add_argument("--pyxodr", action="store_true", help="also load with pyxodr")
    ap.add_argument("--callgrind", type=int, metavar="N",
                    help="only count the instructions of N cases of each kind (valgrind)")
    args = ap.parse_args()
    sys.path.insert(0, str(ROOT))
    if args.callgrind:
        c = instructions(args.callgrind)
        print(f"## instructions of {args.callgrind} cases (callgrind, after one warm-up of each)")
        print(f"Town06 lane: {c['map']:.1f} M; built straight road: {c['built']:.1f} M; "
              f"ratio {c['ratio']:.3f} ({'PASS' if c['ratio'] <= 1.5 else 'MISS'}, goal <= 1.5)")
        return
    maps = sorted(SHARED.glob("*.xodr")) if SHARED.is_dir() else [TOWN06]
    print("## load (fresh process, median of", args.repeats, "runs) [s]")
    print(f"{'map':44s} {'lanes':>6s} {'driving':>7s} {'cpu':>6s} {'wall':>6s}"
          + ("  pyxodr cpu  wall  (its import cpu)" if args.pyxodr else ""))
    town_cpu = None
    for path in maps:
        r = load_times(path, "numpy", args.repeats)
        if path.name == TOWN06.name:
            town_cpu = r["cpu"]
        line = f"{path.name:44s} {r['lanes']:6.0f} {r['driving']:7.0f} {r['cpu']:6.3f} {r['wall']:6.3f}"
        if args.pyxodr:
            p = load_times(path, "pyxodr", args.repeats)
            line += f"  {p['cpu']:10.3f} {p['wall']:5.3f}  ({p['import_cpu']:.2f})"
        print(line, flush=True)
    q = queries(args.queries)
    print(f"\n## closest lane on Town06 ({q['lanes']} drivable lanes, {args.queries} points)")
    print(f"STRtree: {q['strtree_ms']:.3f} ms/query; with the lane coordinates "
          f"{q['strtree_spot_ms']:.3f} ms; highway-env's get_closest_lane_index "
          f"{q['highway_env_ms']:.2f} ms (same lane for {q['agree']})")
    c = cases(args.cases)
    print(f"\n## a 12-s vehicle-following case, autopilot, median CPU of {args.cases}")
    print(f"Town06 lane: {c['map_ms']:.1f} ms; built straight road: {c['built_ms']:.1f} ms; "
          f"ratio {c['ratio']:.2f}")
    print("\n## goals")
    if town_cpu is None:
        town_cpu = load_times(TOWN06, "numpy", args.repeats)["cpu"]
    for label, value, goal, unit in (
            ("Town06 load, CPU", town_cpu, 1.5, " s"),
            ("closest-lane query", q["strtree_ms"], 0.5, " ms"),
            ("a case on Town06 / on the built road", c["ratio"], 1.5, "x")):
        print(f"{'PASS' if value <= goal else 'MISS'}  {label}: {value:.3g}{unit} "
              f"(goal <= {goal:g}{unit})")


if __name__ == "__main__":
    main()

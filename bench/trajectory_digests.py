"""Digests of recorded trajectories, to check that a change leaves every case bit-identical.

A digest is the SHA-256 of every array of a trajectory (times, kinematics, lanes, flags,
signals) and of its meta as sorted JSON. Two uses:

* a script: ``PYTHONPATH=TREE python bench/trajectory_digests.py OUT.jsonl`` runs (with
  the package of TREE) the Town06 and built-road
  cases of ``bench_maps.py`` (``--cases``, after the same warm-up) and a 40-s drive on each
  Town06 driving lane of 100 m or more (ego at 20 m/s wanting 30 m/s: its route's curves,
  lights and lane ends), one line per run;
* a pytest plugin: with ``bench`` on ``PYTHONPATH`` and ``AVS_DIGESTS=DIR``, ``-p
  trajectory_digests`` writes a line per ``World.run`` of a pytest run (any scenario test,
  e.g. ``example_tests/test_maps_*.py -m scenario --avs-seed=0 -n 0``) to ``DIR/<pid>.jsonl``
  and the outcome of each test to ``DIR/<pid>.outcomes``.

``python bench/trajectory_digests.py --compare A B`` compares two such files or folders
(runs as a multiset of test, seed and digest; outcomes as a set). Run it serially to compare
campaigns of an adaptive sampler (``mab``): under xdist its cases depend on the order
results come back.
"""

from __future__ import annotations

import argparse
import glob
import hashlib
import json
import os
import sys
from pathlib import Path

import numpy as np

FIELDS = ("t", "length", "width", "x", "y", "vx", "vy", "speed", "heading", "lane",
          "lane_offset", "crashed", "present", "on_road")


def digest(tr) -> str:
    """SHA-256 over every array of trajectory ``tr`` and its meta (sorted JSON)."""
    h = hashlib.sha256()
    for f in FIELDS:
        a = np.asarray(getattr(tr, f))
        h.update(f"{f}{a.dtype}{a.shape}".encode())
        h.update(a.tobytes())
    for k in sorted(tr.signals):
        h.update(k.encode())
        h.update(np.asarray(tr.signals[k]).tobytes())
    h.update(json.dumps(tr.meta, sort_keys=True, default=repr).encode())
    h.update(repr((tr.names, tr.kinds)).encode())
    return h.hexdigest()


def _line(world, tr) -> str:
    seed = world.seed
    return json.dumps({"name": world.name, "seed": repr(seed), "steps": len(tr.t),
                       "digest": digest(tr)})


def _record_runs(sink) -> None:
    """Make every ``World.run`` write its digest line to ``sink(line)``."""
    from pytest_avscenario.sim import World

    run = World.run

    def recorded(self, *args, **kwargs):
        tr = run(self, *args, **kwargs)
        sink(_line(self, tr))
        return tr

    World.run = recorded


# -- as a pytest plugin ------------------------------------------------------------------------
_DIR = os.environ.get("AVS_DIGESTS")


def pytest_configure(config) -> None:
    if _DIR:
        def sink(line: str) -> None:
            with open(os.path.join(_DIR, f"{os.getpid()}.jsonl"), "a") as f:
                f.write(line + "\n")
        _record_runs(sink)


def pytest_runtest_logreport(report) -> None:
    if _DIR and (report.when == "call" or report.outcome != "passed"):
        with open(os.path.join(_DIR, f"{os.getpid()}.outcomes"), "a") as f:
            f.write(json.dumps([report.nodeid, report.when, report.outcome]) + "\n")


# -- as a script -------------------------------------------------------------------------------
def _load(path: str) -> tuple[list, list]:
    files = sorted(glob.glob(os.path.join(path, "*.jsonl"))) if os.path.isdir(path) else [path]
    runs = [json.loads(l) for f in files for l in open(f)]
    outs = sorted(tuple(json.loads(l)) for f in glob.glob(os.path.join(path, "*.outcomes"))
                  for l in open(f)) if os.path.isdir(path) else []
    return runs, outs


def compare(a: str, b: str) -> bool:
    (ra, oa), (rb, ob) = _load(a), _load(b)
    key = lambda r: (r["name"], r["seed"], r["digest"])  # noqa: E731
    same = sorted(map(key, ra)) == sorted(map(key, rb))
    print(f"runs: {len(ra)} / {len(rb)}, identical: {same}; "
          f"outcomes: {len(oa)} / {len(ob)}, identical: {oa == ob}")
    return same and oa == ob


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", nargs="?", help="file to write the digests to")
    ap.add_argument("--cases", type=int, default=20)
    ap.add_argument("--compare", nargs=2, metavar=("A", "B"))
    args = ap.parse_args()
    if args.compare:
        raise SystemExit(0 if compare(*args.compare) else 1)
    if not args.out:
        ap.error("give OUT or --compare A B")
    # the package is the one on PYTHONPATH (or installed): run this file against any tree
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import bench_maps as bm
    from pytest_avscenario.sim import World
    from pytest_avscenario.sim.opendrive import MapLane

    with open(args.out, "w") as out:
        _record_runs(lambda line: out.write(line + "\n"))
        lanes = list(MapLane(bm.TOWN06, kind="driving", min_length=100).options)
        town = World(0).map(bm.TOWN06)
        bm._LIMITS.update({l: town.lane(l).speed_limit for l in lanes})
        for k in range(args.cases + 1):
            bm._case("map", k, lanes)
            bm._case("built", k, lanes)
        for k, name in enumerate(lanes):
            world = World(1000 + k, name="long", driver="autopilot")
            start = world.map(bm.TOWN06).lane(name).at(10.0)
            world.ego(start, speed=20.0, target_speed=30.0)
            world.run(seconds=40)
    print(f"{2 * (args.cases + 1) + len(lanes)} runs written to {args.out}")


if __name__ == "__main__":
    main()

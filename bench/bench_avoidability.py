"""Which failures matter, measured: the share of reported counterexamples that no careful
driver could avoid, with active samplers told everything (``unavoidable="keep"``) and told
nothing of unfair cases (``"discard"``), and what the avoidability check costs.

Two scenarios, each a real pytest run of a scenario test under the bandit (``mab``), shrinking
and the replay database off, the built-in autopilot as the AV under test:

* scenario 2 of the example suite (vehicle following, ``example_tests/test_02_...``);
* a highway cut-in (below): a car in the next lane, ``gap`` m ahead and ``dv`` m/s slower,
  changes into the ego's lane ``at`` s into the run, within ``duration`` s.

For each (scenario, mode, seed) the error table gives the counterexamples and their
``avoidable`` verdicts; "unavoidable" counts counterexamples whose every violated metric the
careful reference driver violates too. The cost: the same run (the same cases: under "keep"
the check changes nothing the sampler is told) with ``--avs-reference-driver none``; the
difference of the two pytest processes' CPU times per counterexample judged, against the
mean CPU time of one case of the run without the check.

    python bench/bench_avoidability.py [--seeds 3] [--samples 60]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

CUT_IN = '''
from pytest_avscenario import Uniform, scenario
from pytest_avscenario.monitors import collision, distance, ttc
from pytest_avscenario.sim import behaviors as b


@scenario(
    gap=Uniform(2.0, 40.0, nominal=30.0),      # [m] cutter's centre ahead of the ego's
    dv=Uniform(0.0, 10.0, nominal=2.0),        # [m/s] cutter slower than the ego
    at=Uniform(0.0, 4.0, nominal=2.0),         # [s] when the lane change starts
    duration=Uniform(1.5, 4.0, nominal=3.0),   # [s] how long it takes
    samples=60, sampler="mab",
    monitors=[collision(), distance(5.0), ttc(2.0)],
    priority=["collision", "distance", "ttc"],
)
def test_highway_cut_in(case, world):
    road = world.straight_road(lanes=2, length=600)
    world.ego(road.lane(1), s=30.0, speed=25.0)
    world.car(road.lane(0), s=30.0 + case.gap, speed=25.0 - case.dv,
              behavior=b.change_lane(to=1, at=case.at, duration=case.duration), name="cutter")
    world.run(seconds=12)
'''


def run(test: str, cwd: Path, seed: int, samples: int, *extra: str) -> tuple[list[dict], float]:
    # the report of each run goes to a folder of its own, outside the repository
    report = Path(tempfile.mkdtemp(prefix=f"avs-bench-{seed}-")) / "report"
    cmd = [sys.executable, "-m", "pytest", test, "-q", "-p", "no:xdist", "-p", "no:cacheprovider",
           "-m", "scenario or not scenario", f"--avs-seed={seed}", "--avs-sampler=mab",
           f"--avs-samples={samples}", "--avs-shrink-budget=0", "--avs-db=none",
           f"--avs-report={report}", *extra]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(cmd, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    # CPU time of the pytest process: the shared machine's load does not inflate it
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    rows = [json.loads(line) for line in (report / "errors.jsonl").read_text().splitlines()]
    return rows, cpu


def simulation_cost(n: int) -> tuple[float, float]:
    """CPU seconds per simulation of scenario 2's body with the autopilot as the ego, and with
    the careful reference driver as the ego (the avoidability check's one extra simulation),
    on the same ``n`` Halton cases, in this process."""
    sys.path.insert(0, str(ROOT / "example_tests"))
    from test_02_vehicle_following import test_vehicle_following as body

    from pytest_avscenario.case import Case, stable_seed
    from pytest_avscenario.runner import run_case
    from pytest_avscenario.samplers import make
    from pytest_avscenario.sim import World

    spec = body.pytestmark[0].args[0]
    from pytest_avscenario.monitors import MonitorSet
    from pytest_avscenario.space import FeatureSpace

    space = FeatureSpace(spec.parameters)
    monitors = MonitorSet(spec.monitors)
    cases = [Case(space.from_unit(u), index=k, seed=stable_seed("bench", k), sampler="halton")
             for k, u in enumerate(make("halton", space, seed=0).sample_unit(n))]
    out = []
    for ego in (None, "careful"):
        t0 = time.process_time()
        for c in cases:
            run_case(body, ("case", "world"), {}, c, monitors,
                     lambda c, ego=ego: World(seed=c.seed, rng=c.rng, driver="autopilot", ego_driver=ego))
        out.append((time.process_time() - t0) / n)
    return out[0], out[1]


def shares(rows: list[dict]) -> tuple[int, int, int]:
    """(counterexamples, judged, unavoidable)."""
    fails = [r for r in rows if r["verdict"] == "fail"]
    judged = [r for r in fails if r.get("avoidable")]
    unavoidable = [r for r in judged if all(v is False for v in r["avoidable"].values())]
    return len(fails), len(judged), len(unavoidable)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--samples", type=int, default=60)
    args = ap.parse_args()
    seeds = list(range(1, args.seeds + 1))
    with tempfile.TemporaryDirectory() as tmp:
        tmp_path = Path(tmp)
        (tmp_path / "test_cut_in.py").write_text(CUT_IN)
        scenarios = [
            ("scenario 2 (vehicle following)", str(ROOT / "example_tests" / "test_02_vehicle_following.py"),
             ROOT / "example_tests"),
            ("highway cut-in", str(tmp_path / "test_cut_in.py"), tmp_path),
        ]
        print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, load {os.getloadavg()[0]:.1f}, "
              f"mab, {args.samples} cases, seeds {seeds}")
        print("| scenario | mode | counterexamples | judged | unavoidable | share unavoidable |")
        print("|---|---|---|---|---|---|")
        cost = []
        for name, test, cwd in scenarios:
            for mode in ("keep", "discard"):
                totals = [0, 0, 0]
                for seed in seeds:
                    rows, cpu = run(test, cwd, seed, args.samples, f"--avs-unavoidable={mode}")
                    totals = [a + b for a, b in zip(totals, shares(rows))]
                    if mode == "keep":
                        _, cpu_off = run(test, cwd, seed, args.samples, "--avs-reference-driver=none")
                        n_fail, n_judged, _ = shares(rows)
                        per_case = cpu_off / max(1, len(rows))
                        if n_judged:
                            cost.append(((cpu - cpu_off) / n_judged) / per_case)
                n, j, u = totals
                print(f"| {name} | {mode} | {n} | {j} | {u} | {u / j:.0%} |" if j else
                      f"| {name} | {mode} | {n} | 0 | 0 | — |", flush=True)
        case_s, ref_s = simulation_cost(60)
        print(f"\none simulation of scenario 2 in this process (CPU, 60 Halton cases): autopilot "
              f"ego {case_s * 1e3:.1f} ms, careful reference ego {ref_s * 1e3:.1f} ms — the check "
              f"costs {ref_s / case_s:.2f} of a case's simulation per counterexample judged")
        if cost:
            print(f"\ncost of the check per counterexample judged, in cases (CPU time, with vs "
                  f"without the reference): median {statistics.median(cost):.2f}, "
                  f"range {min(cost):.2f}–{max(cost):.2f} over {len(cost)} runs")


if __name__ == "__main__":
    main()

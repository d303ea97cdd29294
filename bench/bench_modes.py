"""Benchmark of the failure modes: what grouping a campaign's counterexamples costs at the end
of a run, against the rest of that campaign's summary.

A campaign of N cases over 6 parameters (4 continuous with units, an integer, a categorical)
in which three regions fail: distance with the lead car (gap small and the lead braking
hard), ttc with a cut-in car (fast on a wet or icy road) and lane with nobody (few lanes,
strong wind). Timed, median of ``--repeats``: ``failure_modes`` alone, ``summarize`` without
modes (ε-coverage, the mesh cross-check and the covered fraction: the summary the run already
paid for), and ``summarize`` with them. Also printed: the modes found, to see they are the
three planted regions. Run from the repository root:

    python bench/bench_modes.py                      # 300 cases, 5 repeats
    python bench/bench_modes.py --cases 3000 --repeats 3
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pytest_avscenario.outcome import CaseRow  # noqa: E402
from pytest_avscenario.report.modes import failure_modes  # noqa: E402
from pytest_avscenario.report.summary import TestInfo, summarize  # noqa: E402
from pytest_avscenario.space import Choice, FeatureSpace, IntRange, Uniform  # noqa: E402

TEST = "bench/test_highway.py::test_cut_in"
METRICS = ("distance", "ttc", "lane")


def space() -> FeatureSpace:
    return FeatureSpace({
        "gap": Uniform(5.0, 60.0, unit="m"), "lead_decel": Uniform(0.5, 8.0, unit="m/s^2"),
        "speed": Uniform(10.0, 35.0, unit="m/s"), "wind": Uniform(0.0, 20.0, unit="m/s"),
        "lanes": IntRange(1, 4), "road": Choice(["dry", "wet", "icy"]),
    })


def campaign(n: int, seed: int = 0) -> list[CaseRow]:
    from scipy.stats import qmc

    sp = space()
    fails = {
        "distance": (lambda p: p["gap"] < 18.0 and p["lead_decel"] > 5.0, "lead"),
        "ttc": (lambda p: p["speed"] > 28.0 and p["road"] != "dry", "cut_in"),
        "lane": (lambda p: p["lanes"] <= 2 and p["wind"] > 15.0, None),
    }
    rows = []
    for i, u in enumerate(qmc.Halton(sp.d, scramble=True, seed=seed).random(n)):
        p = sp.from_unit(u)
        rho = {m: (-1.0 if f(p) else 1.0) for m, (f, _) in fails.items()}
        where = {m: {"t": 3.0, "agent": fails[m][1], "threshold": 0.0} for m, v in rho.items() if v < 0}
        rows.append(CaseRow(test=TEST, item=f"{TEST}[halton-{i:03d}]", sampler="halton", index=i, seed=i,
                            origin="sampled", params=p, rho=rho, verdict="fail" if where else "pass",
                            sim_time_s=0.02, violations=where or None))
    return rows


from bench_coverage import timed  # noqa: E402  (this folder is on sys.path when run as a script)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=300)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    rows, sp = campaign(args.cases), space()
    info = {TEST: TestInfo(METRICS, sp, ("halton",))}
    summarize(rows[:20], info)  # warm up scipy's import

    t_modes, modes = timed(lambda: failure_modes(rows, sp, METRICS), args.repeats)
    t_plain, _ = timed(lambda: summarize(rows, info, modes=False), args.repeats)
    t_full, (s,) = timed(lambda: summarize(rows, info), args.repeats)
    failing = sum(r.verdict == "fail" for r in rows)
    print(f"{args.cases} cases x {sp.d} parameters, {failing} counterexamples; median of {args.repeats}")
    print(f"  failure_modes                  {1000 * t_modes:8.1f} ms")
    print(f"  summarize without modes        {1000 * t_plain:8.1f} ms")
    print(f"  summarize with modes           {1000 * t_full:8.1f} ms   (+{100 * (t_full / t_plain - 1):.0f}%)")
    print(f"  modes: {len(s.modes)}")
    for m in modes:
        print(f"    {m.id} {m.what:>22}  {m.count:4d} ({100 * m.share:3.0f}%)  precision {m.precision:.2f}  "
              f"recall {m.recall:.2f}  {m.rule}")


if __name__ == "__main__":
    main()

"""Benchmark of the report's numerical and I/O parts: ε-coverage and the error table.

Target from the issue: ε-coverage of 10,000 samples in 4-D in under 1 s. Also measured:
the same in 2/3/6-D, the mesh covering-radius cross-check, the covered fraction, the cost of
one durable ``ErrorTable.append`` (flush + fsync of two files), and the whole end-of-run
summary for a test with 1,000 cases. Run from the repository root:

    python bench/bench_coverage.py            # full run, ~20 s on 2 cores
    python bench/bench_coverage.py --quick    # fewer repeats
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pytest_avscenario.report.coverage import (  # noqa: E402
    covering_radius_bounds,
    epsilon_coverage,
    fraction_within,
)
from pytest_avscenario.report.summary import TestInfo, summarize  # noqa: E402
from pytest_avscenario.report.table import ErrorTable  # noqa: E402


def timed(fn, repeats):
    times, value = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        value = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), value


def halton(n, d, seed=0):
    from scipy.stats import qmc

    return qmc.Halton(d, scramble=True, seed=seed).random(n)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    repeats = 1 if args.quick else 3
    epsilon_coverage(np.random.default_rng(0).random((10, 2)))  # warm up scipy's import

    print("ε-coverage (tol 0.01), median of", repeats)
    print(f"{'d':>2} {'n':>6} {'sampler':>8} {'eps':>7} {'time s':>7}   {'mesh r [lo, hi]':>22} {'time s':>7}  {'frac≤eps/2':>10} {'time s':>7}")
    for d in (2, 3, 4, 6):
        for name, pts in (("random", np.random.default_rng(1).random((10_000, d))), ("halton", halton(10_000, d))):
            t_eps, eps = timed(lambda: epsilon_coverage(pts, tol=0.01), repeats)
            t_cr, (lo, hi) = timed(lambda: covering_radius_bounds(pts), 1)
            t_fr, frac = timed(lambda: fraction_within(pts, eps / 2), repeats)
            print(f"{d:>2} {len(pts):>6} {name:>8} {eps:7.4f} {t_eps:7.3f}   [{lo:.4f}, {hi:.4f}]{'':>6} {t_cr:7.3f}  {frac:10.3f} {t_fr:7.3f}")

    print("\npaper's setting: first 60 points, 3-D, mesh 51^3 vs estimator (tol 0.05 / 0.01)")
    for name, pts in (("random", np.random.default_rng(2).random((60, 3))), ("halton", halton(60, 3, seed=2))):
        lo, _ = covering_radius_bounds(pts, 51)
        print(f"  {name:>7}: mesh-51 r = {lo:.3f}, ε(0.05) = {epsilon_coverage(pts, 0.05):.3f}, "
              f"ε(0.01) = {epsilon_coverage(pts, 0.01):.3f}")

    with tempfile.TemporaryDirectory() as tmp:
        rng = np.random.default_rng(3)
        rows = [
            {"test": "bench.py::test_follow", "item": f"bench.py::test_follow[{i}]", "sampler": "halton",
             "index": i, "seed": i, "origin": "sampled",
             "params": {"gap": float(rng.uniform(10, 40)), "speed": float(rng.uniform(5, 15)),
                        "brake_at": float(rng.uniform(1, 5)), "weather": "dry"},
             "rho": {"distance": float(rng.normal()), "ttc": math.inf, "progress": 2.0, "lane": 0.1},
             "verdict": "pass", "sim_time_s": 0.02, "error": None}
            for i in range(1000)
        ]
        for fsync in (True, False):
            with ErrorTable(Path(tmp) / f"fs{fsync}", fsync=fsync) as table:
                t0 = time.perf_counter()
                for r in rows:
                    table.append(r)
                per = (time.perf_counter() - t0) / len(rows)
            print(f"\nErrorTable.append (JSONL + CSV, flush{' + fsync' if fsync else ''}): {per * 1e3:.3f} ms per row")
        from pytest_avscenario.space import Choice, FeatureSpace, Uniform

        space = FeatureSpace({"gap": Uniform(10, 40), "speed": Uniform(5, 15), "brake_at": Uniform(1, 5),
                              "weather": Choice(["dry"])})
        info = {"bench.py::test_follow": TestInfo(("progress", "distance", "ttc", "lane"), space)}
        t_sum, _ = timed(lambda: summarize(rows, info), repeats)
        print(f"summarize 1,000 cases (3 continuous dims; ε + mesh r + covered fraction): {t_sum:.3f} s")


if __name__ == "__main__":
    main()

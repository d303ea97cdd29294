#!/usr/bin/env python3
"""The ``bo`` sampler's cost per ask as cases pile up, its search power, and mixed spaces —
the current code against an earlier commit, in one run.

1. Milliseconds per ask with 150 / 500 / 1000 / 2000 cases told: the history is told through
   ``tell`` (cases of a seeded random sampler, 3-D ball rho), then ``--asks`` asks, each
   followed by its tell, are timed one by one (CPU time: the 2 cores are shared; wall time
   beside it). Median and mean: the mean includes the asks that re-optimize the GP's
   hyperparameters.
2. Samples to the first counterexample on the 3-D ball of bench/bench_samplers.py (its
   ``ball_center`` and radius, imported from it; 20 seeds, budget 300).
3. The same search at a tight cap (``max_points=30``, so the fitting subset matters within the
   budget), 8 seeds, budget 300: a 3-D ball of radius 0.03, and "decoys" — that ball plus
   three other basins whose rho bottoms out at +0.05 (a falsifier must leave them).
4. 120 ask/tell pairs on a mixed space (Uniform + IntRange + Choice) and on an all-Uniform
   space of the same dimension: CPU seconds, asks still pending, cases in the GP's last fit.

The earlier commit's package is exported with ``git archive`` to a temporary directory; each
side runs in its own subprocess (this file with ``--worker``), the two alternating part by
part so both see the same machine load. BLAS is pinned to one thread, as in bench_samplers.

Usage (repository root):  python bench/bench_bo.py [--before a734ac2] [--asks 50] [--quick]
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import importlib.util  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
SIZES = (150, 500, 1000, 2000)


def _bench_samplers():
    spec = importlib.util.spec_from_file_location("bench_samplers", HERE / "bench_samplers.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


# -- worker: runs one part with whichever pytest_avscenario is first on sys.path ---------------

def part_ask(n_told: int, n_asks: int) -> dict:
    from pytest_avscenario import samplers
    from pytest_avscenario.space import Uniform

    bs = _bench_samplers()
    space = {f"x{i}": Uniform(0.0, 1.0) for i in range(3)}
    keys = list(space)
    c = bs.ball_center(0)

    def rho(p):
        return float(np.linalg.norm(np.asarray([p[k] for k in keys]) - c) - bs.R)

    s = samplers.make("bo", space, seed=0)
    history = samplers.make("random", space, seed=1)
    for _ in range(n_told):
        p = history.ask()
        s.tell(p, rho(p))
    cpu, wall = [], []
    for _ in range(n_asks):
        t0, w0 = time.process_time(), time.perf_counter()
        p = s.ask()
        cpu.append(1e3 * (time.process_time() - t0))
        wall.append(1e3 * (time.perf_counter() - w0))
        s.tell(p, rho(p))
    return {"cpu_ms": cpu, "wall_ms": wall}


def part_search(seeds: int, budget: int) -> dict:
    from pytest_avscenario import samplers
    from pytest_avscenario.space import Uniform

    bs = _bench_samplers()
    space = {f"x{i}": Uniform(0.0, 1.0) for i in range(3)}
    keys = list(space)
    firsts = []
    t0 = time.process_time()
    for seed in range(seeds):
        c = bs.ball_center(seed)
        s = samplers.make("bo", space, seed=seed)
        first = budget
        for i in range(budget):
            p = s.ask()
            r = float(np.linalg.norm(np.asarray([p[k] for k in keys]) - c) - bs.R)
            s.tell(p, r)
            if r < 0:
                first = i + 1
                break
        firsts.append(first)
    return {"firsts": firsts, "cpu_s": time.process_time() - t0}


def part_cap(max_points: int, seeds: int, budget: int) -> dict:
    from pytest_avscenario import samplers
    from pytest_avscenario.space import Uniform

    space = {f"x{i}": Uniform(0.0, 1.0) for i in range(3)}
    keys = list(space)
    out = {}
    for problem in ("ball", "decoys"):
        firsts = []
        for seed in range(seeds):
            C = np.random.default_rng(1000 + seed).uniform(0.15, 0.85, (4, 3))
            s = samplers.make("bo", space, seed=seed, max_points=max_points)
            first = budget
            for i in range(budget):
                p = s.ask()
                d = np.linalg.norm(C - np.asarray([p[k] for k in keys]), axis=1)
                r = float(d[0] - 0.03 if problem == "ball" else min(d[0] - 0.03, d[1:].min() + 0.05))
                s.tell(p, r)
                if r < 0:
                    first = i + 1
                    break
            firsts.append(first)
        out[problem] = firsts
    return out


def part_mixed(pairs: int) -> dict:
    from pytest_avscenario import samplers
    from pytest_avscenario.space import Choice, IntRange, Uniform

    spaces = {
        "mixed": {"gap_m": Uniform(5.0, 50.0), "lane": IntRange(0, 3),
                  "weather": Choice(["dry", "wet", "icy"])},
        "continuous": {"gap_m": Uniform(5.0, 50.0), "lane": Uniform(0.0, 3.0),
                       "weather": Uniform(0.0, 2.0)},
    }
    code = {"dry": 0.0, "wet": 1.0, "icy": 2.0}
    out = {}
    for name, space in spaces.items():
        s = samplers.make("bo", space, seed=0)
        t0 = time.process_time()
        for _ in range(pairs):
            p = s.ask()
            w = code.get(p["weather"], p["weather"])
            s.tell(p, float(p["gap_m"] / 10.0 - abs(p["lane"] - 2) - w))
        out[name] = {"cpu_s": time.process_time() - t0, "pending": len(s.pending),
                     "told": len(s.X), "last_fit": len(s.gp.X)}
    return out


def worker(args: argparse.Namespace) -> None:
    sys.path.insert(0, args.code)
    import pytest_avscenario

    assert Path(pytest_avscenario.__file__).resolve().is_relative_to(Path(args.code).resolve())
    if args.part == "ask":
        res = part_ask(args.told, args.asks)
    elif args.part == "search":
        res = part_search(args.seeds, args.budget)
    elif args.part == "cap":
        res = part_cap(30, args.cap_seeds, args.budget)
    else:
        res = part_mixed(args.pairs)
    print(json.dumps(res))


# -- controller -----------------------------------------------------------------------------

def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--code", default=str(ROOT), help=argparse.SUPPRESS)
    ap.add_argument("--part", default="ask", help=argparse.SUPPRESS)
    ap.add_argument("--told", type=int, default=150, help=argparse.SUPPRESS)
    ap.add_argument("--before", default="a734ac2", help="commit to compare with")
    ap.add_argument("--asks", type=int, default=50, help="asks timed per history size")
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--budget", type=int, default=300)
    ap.add_argument("--pairs", type=int, default=120)
    ap.add_argument("--cap-seeds", type=int, default=8)
    ap.add_argument("--quick", action="store_true", help="10 asks, 5 seeds, 60 pairs, 3 cap seeds")
    args = ap.parse_args()
    if args.quick:
        args.asks, args.seeds, args.pairs, args.cap_seeds = 10, 5, 60, 3
    if args.worker:
        worker(args)
        return

    tmp = tempfile.TemporaryDirectory()
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", args.before, "pytest_avscenario"],
                             capture_output=True, check=True).stdout
    subprocess.run(["tar", "-x", "-C", tmp.name], input=archive, check=True)
    rev = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                         capture_output=True, text=True, check=True).stdout.strip()
    dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "pytest_avscenario"],
                           capture_output=True, text=True, check=True).stdout.strip()
    sides = {f"before ({args.before})": tmp.name,
             f"after ({rev}{'+dirty' if dirty else ''})": str(ROOT)}

    def run(code: str, part: str, **extra) -> dict:
        cmd = [sys.executable, __file__, "--worker", "--code", code, "--part", part,
               "--asks", str(args.asks), "--seeds", str(args.seeds),
               "--budget", str(args.budget), "--pairs", str(args.pairs),
               "--cap-seeds", str(args.cap_seeds)]
        for k, v in extra.items():
            cmd += [f"--{k}", str(v)]
        proc = subprocess.run(cmd, capture_output=True, text=True, cwd=tempfile.gettempdir())
        if proc.returncode:
            sys.exit(f"worker {part} failed:\n{proc.stderr[-3000:]}")
        return json.loads(proc.stdout)

    t0 = time.perf_counter()
    load0 = os.getloadavg()[0]
    asks = {side: {} for side in sides}
    for n in SIZES:
        for side, code in sides.items():
            asks[side][n] = run(code, "ask", told=n)
    search = {side: run(code, "search") for side, code in sides.items()}
    cap = {side: run(code, "cap") for side, code in sides.items()}
    mixed = {side: run(code, "mixed") for side, code in sides.items()}
    load1 = os.getloadavg()[0]

    print(f"bo, 3-D ball objective; {args.asks} asks timed per size; BLAS 1 thread; "
          f"load average {load0:.1f} -> {load1:.1f}; {time.perf_counter() - t0:.0f} s\n")
    print("ms per ask (CPU; median / mean over the asks, wall median in brackets)\n")
    print("| code | " + " | ".join(f"{n} told" for n in SIZES) + " |")
    print("|---" * (len(SIZES) + 1) + "|")
    for side in sides:
        cells = []
        for n in SIZES:
            r = asks[side][n]
            cells.append(f"{statistics.median(r['cpu_ms']):.1f} / {statistics.mean(r['cpu_ms']):.1f}"
                         f" ({statistics.median(r['wall_ms']):.1f})")
        print(f"| {side} | " + " | ".join(cells) + " |")

    print(f"\nsamples to the first counterexample, 3-D ball r=0.1, {args.seeds} seeds, budget "
          f"{args.budget}\n")
    print("| code | mean | median | not found | CPU s (all seeds) |\n|---|---|---|---|---|")
    for side, r in search.items():
        f = r["firsts"]
        print(f"| {side} | {statistics.mean(f):.1f} | {statistics.median(f):.1f} | "
              f"{sum(x >= args.budget for x in f)}/{len(f)} | {r['cpu_s']:.1f} |")
    for side, r in search.items():
        print(f"  {side} firsts: {r['firsts']}")

    print(f"\nthe same at max_points=30, r=0.03, {len(next(iter(cap.values()))['ball'])} seeds, "
          f"budget {args.budget}: samples to the first counterexample\n")
    print("| code | problem | mean | median | not found |\n|---|---|---|---|---|")
    for side, r in cap.items():
        for problem, f in r.items():
            print(f"| {side} | {problem} | {statistics.mean(f):.1f} | {statistics.median(f):.1f} | "
                  f"{sum(x >= args.budget for x in f)}/{len(f)} |")
    for side, r in cap.items():
        print(f"  {side}: {r}")

    print(f"\n{args.pairs} ask/tell pairs, Uniform + IntRange + Choice vs 3 x Uniform\n")
    print("| code | space | CPU s | pending at the end | cases told | cases in the last fit |")
    print("|---|---|---|---|---|---|")
    for side, r in mixed.items():
        for space, m in r.items():
            print(f"| {side} | {space} | {m['cpu_s']:.1f} | {m['pending']} | {m['told']} | "
                  f"{m['last_fit']} |")


if __name__ == "__main__":
    main()

"""Benchmark: ``ran_red_light`` and the driving score's red-light check on the 300-step,
5-agent trajectory of ``bench_criteria.py``, with a traffic light on the ego's route that
turns red as the ego approaches it (so every part of the measure is computed).

Times are CPU time of the calling thread (median), every call on a fresh copy of the
trajectory (cold per-trajectory caches, as in a run). The anchor is the paper's four metrics
on the same trajectory in the same process.

    python bench/bench_signals.py [--steps 300] [--agents 5] [--repeat 200]
"""

from __future__ import annotations

import argparse
import os
import platform
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_criteria import PAPER, fresh, light_scene, time_ms  # noqa: E402

from pytest_avscenario.monitors import driving_score, ran_red_light  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--agents", type=int, default=5)
    ap.add_argument("--repeat", type=int, default=200)
    args = ap.parse_args()
    traj = light_scene(args.steps, args.agents)
    m = ran_red_light()
    r = m.evaluate(fresh(traj))
    print(f"{args.steps} steps x {traj.n_agents} agents, Python {platform.python_version()}, "
          f"numpy {np.__version__}, median of {args.repeat}")
    print(f"  ran_red_light rho {r.rho:.4g}: {r.detail[:90]}")
    for _ in range(20):
        m.evaluate(fresh(traj))
    a = time_ms(lambda: m.evaluate(fresh(traj)), args.repeat)
    s = time_ms(lambda: driving_score(fresh(traj)), args.repeat)
    p = time_ms(lambda: [q.evaluate(t) for t in [fresh(traj)] for q in PAPER], args.repeat)
    print(f"ran_red_light: {a:.3f} ms (cold caches)")
    print(f"driving score with the light: {s:.3f} ms")
    print(f"anchor, the paper's four metrics: {p:.3f} ms (ratio ran_red_light / anchor "
          f"{a / p:.2f})")


if __name__ == "__main__":
    main()

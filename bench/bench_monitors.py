"""Benchmark: the paper's four metrics on a 300-step, 5-agent trajectory.

Times ``distance``, ``ttc``, ``progress`` and ``lane_keeping`` (through ``Monitor.evaluate``,
validation included) against a plain per-step Python loop of the same definitions, in the
same process, checks both give the same rho, and prints the ratio. Target: the four
vectorized metrics in under 2 ms together.

    python bench/bench_monitors.py [--steps 300] [--agents 5] [--repeat 200]
"""

from __future__ import annotations

import argparse
import math
import platform
import statistics
import time

import numpy as np

from pytest_avscenario.monitors import (
    MonitorSet,
    always,
    collision,
    distance,
    ego_speed,
    eventually,
    gap,
    implies,
    lane_keeping,
    progress,
    time_headway,
    ttc,
    until,
)
from pytest_avscenario.trajectory import Trajectory


def scene(steps: int, agents: int, seed: int = 0) -> Trajectory:
    """A multi-lane highway: ego and traffic at random speeds, gentle lateral wobble; one
    car appears halfway through (absent steps are part of the workload)."""
    rng = np.random.default_rng(seed)
    t = np.arange(steps) * 0.1
    spec = {}
    for a in range(agents):
        v = rng.uniform(8, 30)
        lane_y = 4.0 * rng.integers(0, 3)
        wobble = 0.3 * np.sin(t * rng.uniform(0.2, 1.0) + rng.uniform(0, 6))
        x = rng.uniform(0, 80) + v * t
        d = {"x": x, "y": lane_y + wobble, "vx": np.full(steps, v),
             "vy": np.gradient(wobble, t), "lane": f"hw/{int(lane_y // 4)}", "lane_offset": wobble}
        if a == agents - 1 and a > 0:
            present = t >= t[steps // 2]
            d = {k: (np.where(present, val, np.nan) if isinstance(val, np.ndarray) else val)
                 for k, val in d.items()}
            d["present"] = present
        spec["ego" if a == 0 else f"car{a}"] = d
    return Trajectory.from_arrays(t, spec)


def loop_baseline(traj: Trajectory) -> dict[str, float]:
    """The same four definitions, one step and one agent at a time in pure Python."""
    T, A = traj.n_steps, traj.n_agents
    x, y, vx, vy = (getattr(traj, k).tolist() for k in ("x", "y", "vx", "vy"))
    present = traj.present.tolist()
    dmin, tmin = math.inf, math.inf
    for k in range(T):
        if not present[0][k]:
            continue
        for a in range(1, A):
            if not present[a][k]:
                continue
            dpx, dpy = x[a][k] - x[0][k], y[a][k] - y[0][k]
            d = math.hypot(dpx, dpy)
            dmin = min(dmin, d)
            dvx, dvy = vx[a][k] - vx[0][k], vy[a][k] - vy[0][k]
            qa = dvx * dvx + dvy * dvy
            qb = 2 * (dpx * dvx + dpy * dvy)
            qc = dpx * dpx + dpy * dpy - 25.0
            if qc <= 0:
                ttc_k = 0.0
            elif qa == 0 or qb * qb - 4 * qa * qc < 0:
                ttc_k = math.inf
            else:
                r = math.sqrt(qb * qb - 4 * qa * qc)
                t1, t2 = (-qb - r) / (2 * qa), (-qb + r) / (2 * qa)
                ttc_k = math.inf if t2 <= 0 else t1
            tmin = min(tmin, ttc_k)
    ks = [k for k in range(T) if present[0][k]]
    prog = math.hypot(x[0][ks[-1]] - x[0][ks[0]], y[0][ks[-1]] - y[0][ks[0]])
    offs = traj.lane_offset[0].tolist()
    total, n = 0.0, 0
    for k in ks:
        total += abs(offs[k])
        n += 1
    return {"distance": dmin - 5.0, "ttc": tmin - 2.0, "progress": prog - 11.0,
            "lane_keeping": 0.5 - total / n}


def timeit(fn, repeat: int) -> tuple[float, float]:
    fn()  # warm-up (imports, caches)
    samples = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - t0)
    return statistics.median(samples), min(samples)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--agents", type=int, default=5)
    ap.add_argument("--repeat", type=int, default=200)
    args = ap.parse_args()

    traj = scene(args.steps, args.agents)
    ms = MonitorSet([distance(5.0), ttc(2.0), progress(11.0), lane_keeping(0.5)])
    vec = ms.evaluate(traj).rho
    ref = loop_baseline(traj)
    for k in vec:
        assert math.isclose(vec[k], ref[k], rel_tol=1e-9, abs_tol=1e-9) or vec[k] == ref[k], (k, vec[k], ref[k])

    print(f"python {platform.python_version()}, numpy {np.__version__}, {platform.machine()}")
    print(f"trajectory: {args.steps} steps x {args.agents} agents; rho = "
          + ", ".join(f"{k} {v:.3g}" for k, v in vec.items()))
    per = {}
    for m in ms.monitors:
        per[m.name] = timeit(lambda m=m: m.evaluate(traj), args.repeat)
    total_med, total_min = timeit(lambda: ms.evaluate(traj), args.repeat)
    loop_med, loop_min = timeit(lambda: loop_baseline(traj), max(20, args.repeat // 5))
    for name, (med, mn) in per.items():
        print(f"  {name:13s} median {med * 1e3:7.3f} ms  (min {mn * 1e3:.3f})")
    print(f"  {'all four':13s} median {total_med * 1e3:7.3f} ms  (min {total_min * 1e3:.3f})"
          f"  [target < 2 ms: {'ok' if total_med < 2e-3 else 'MISSED'}]")
    print(f"  {'python loop':13s} median {loop_med * 1e3:7.3f} ms  (min {loop_min * 1e3:.3f})")
    print(f"  loop / vectorized = {loop_med / total_med:.1f}x")

    extras = [
        distance(5.0, footprint=True).named("distance(footprint)"),
        collision(), time_headway(1.0),
        always(implies(gap() <= 15.0, eventually(ego_speed() <= 9.0, (0, 2.0)))).named(
            "always(gap<=15 -> eventually[0,2] speed<=9)"),
        until(ego_speed() <= 40.0, gap() <= 10.0).named("until(speed<=40, gap<=10)"),
        until(ego_speed() <= 40.0, gap() <= 10.0, (0, 3.0)).named("until[0,3](speed<=40, gap<=10)"),
    ]
    print("  other monitors (not part of the 2-ms budget):")
    for m in extras:
        med, mn = timeit(lambda m=m: m.evaluate(traj), max(20, args.repeat // 4))
        print(f"    {m.name:44s} median {med * 1e3:7.3f} ms")


if __name__ == "__main__":
    main()

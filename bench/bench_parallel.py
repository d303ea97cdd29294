"""Does ``-n 2`` pay? Serial against pytest-xdist ``-n 2``, interleaved, and the controller's cost per item.

Run ``python bench/bench_parallel.py`` (``--repeats N``, default 2; ``--cases N``, default
5000; ``--skip-examples``, ``--skip-campaign``; ``--controller N`` only measures the
controller's CPU per item on an N-case trivial campaign). Every pair of runs is serial then
``-n 2``, back to back, so both see the same machine:

1. *examples*: ``pytest example_tests -m scenario --avs-seed=0`` (the quick example suite),
   with ``--avs-db=none`` and the report in a temporary folder (nothing in the repo changes);
2. *campaign*: one vehicle-following test of ``--cases`` Halton cases (the scenario of
   ``bench_scale.py``, ~32 % failing), report on, no database, no shrinking;
3. *controller*: ``--controller`` cases (default 2000) of a trivial body (two parameters, an
   assert, 30 % failing), where the controller's work per item is all there is to see.

Per run: *wall* (the whole command), *cpu* (user+system of the process tree,
``getrusage(RUSAGE_CHILDREN)``), and from a ``-p`` plugin in the process that runs the
session (the controller under xdist): its own CPU (``RUSAGE_SELF``, main thread and the
execnet thread that receives the workers' reports) from the first to the last call report,
divided by the items — the *controller's CPU per item* — and the items per second it
received meanwhile; *ctl end s*, that process's CPU after the last call report (the end of
the run: under xdist, not the helpers' that make plots ahead, whose CPU is in *cpu*), and *end
wall s*, the wall time from the last call report to the process's end. The goal line of each size: ``-n 2`` wall / serial wall (median of the
pairs) against 0.65, PASS or MISS. The machine is shared: the load average is printed with
every run; when it is high, read the CPU columns.
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

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))

from bench_scale import SCENARIO, TRIVIAL  # noqa: E402  (the same scenarios as the scale benchmark)

GOAL = 0.65

# Loaded with -p in every process; only the one that runs the session writes.
CONTROLLER_PLUGIN = '''
import json, os, resource, time

_t = {"n": 0}


def _cpu():
    ru = resource.getrusage(resource.RUSAGE_SELF)
    return ru.ru_utime + ru.ru_stime


def pytest_runtest_logreport(report):
    if report.when != "call" or "PYTEST_XDIST_WORKER" in os.environ:
        return
    _t["n"] += 1
    now = (_cpu(), time.thread_time(), time.perf_counter())
    if _t["n"] == 1:
        _t["first"] = now
    _t["last"] = now


def pytest_unconfigure(config):
    if "PYTEST_XDIST_WORKER" in os.environ or not _t["n"] or not os.environ.get("AVS_BENCH_CTL"):
        return
    with open(os.environ["AVS_BENCH_CTL"], "w") as f:
        json.dump({"n": _t["n"], "first": _t["first"], "last": _t["last"], "end_cpu": _cpu(),
                   "end_wall": time.perf_counter() - _t["last"][2]}, f)
'''


def load() -> str:
    return " ".join(f"{x:.1f}" for x in os.getloadavg())


def _children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def run(args: list[str], cwd: Path, tmp: Path, tag: str, pythonpath: str) -> dict:
    ctl = tmp / f"ctl-{tag}.json"
    ctl.unlink(missing_ok=True)
    env = dict(os.environ, AVS_BENCH_CTL=str(ctl), PYTHONPATH=pythonpath)
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "avs_bench_ctl", "-q",
           "--tb=line", "-rN", "--avs-db=none", f"--avs-report={tmp / ('rep-' + tag)}", *args]
    cpu0, t0 = _children_cpu(), time.perf_counter()
    proc = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True)
    wall, cpu = time.perf_counter() - t0, _children_cpu() - cpu0
    if proc.returncode not in (0, 1):
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}")
    c = json.loads(ctl.read_text())
    n = c["n"]
    span = c["last"][2] - c["first"][2]
    return {"wall": wall, "cpu": cpu, "n": n,
            "ctl_us": 1e6 * (c["last"][0] - c["first"][0]) / max(1, n - 1),
            "ctl_main_us": 1e6 * (c["last"][1] - c["first"][1]) / max(1, n - 1),
            "ctl_end_s": c["end_cpu"] - c["last"][0], "end_wall_s": c["end_wall"],
            "rate": (n - 1) / span if span > 0 else float("nan"),
            "summary": (proc.stdout.strip().splitlines() or ["?"])[-1]}


def pairs(name: str, cwd: Path, tmp: Path, args: list[str], repeats: int, pythonpath: str) -> None:
    res: dict[str, list[dict]] = {"serial": [], "-n 2": []}
    print(f"\n{name}: pytest {' '.join(args)}", flush=True)
    print(f"  {'':<10}{'wall s':>8}{'cpu s':>8}{'items':>7}{'items/s':>9}{'ctl us/item':>12}"
          f"{'(main thr)':>11}{'ctl end s':>10}{'end wall s':>11}  load / outcome")
    for r in range(repeats):
        for mode, extra in (("serial", []), ("-n 2", ["-n", "2"])):
            x = run([*args, *extra], cwd, tmp, f"{name}-{r}-{mode.strip('-').replace(' ', '')}", pythonpath)
            res[mode].append(x)
            print(f"  {mode:<10}{x['wall']:8.1f}{x['cpu']:8.1f}{x['n']:7d}{x['rate']:9.1f}"
                  f"{x['ctl_us']:12.0f}{x['ctl_main_us']:11.0f}{x['ctl_end_s']:10.1f}{x['end_wall_s']:11.1f}  "
                  f"load {load()}; {x['summary']}", flush=True)
    ratios = [p["wall"] / s["wall"] for s, p in zip(res["serial"], res["-n 2"])]
    cpu_ratios = [p["cpu"] / s["cpu"] for s, p in zip(res["serial"], res["-n 2"])]
    ratio = statistics.median(ratios)
    ctl = statistics.median(x["ctl_us"] for x in res["-n 2"])
    rate = statistics.median(x["rate"] for x in res["-n 2"])
    print(f"  {name}: -n 2 wall / serial wall = {ratio:.2f} (pairs {' '.join(f'{v:.2f}' for v in ratios)}) "
          f"goal <= {GOAL}: {'PASS' if ratio <= GOAL else 'MISS'}; cpu -n 2 / serial "
          f"{statistics.median(cpu_ratios):.2f}; controller {ctl:.0f} us CPU per item at {rate:.1f} "
          f"items/s = {ctl * rate / 1e4:.1f} % of a core", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--cases", type=int, default=5000)
    ap.add_argument("--controller", type=int, default=2000, help="trivial cases for the controller's cost")
    ap.add_argument("--skip-examples", action="store_true")
    ap.add_argument("--skip-campaign", action="store_true")
    ap.add_argument("--skip-controller", action="store_true")
    args = ap.parse_args()
    print(f"load average {load()} on {os.cpu_count()} cores; python {sys.version.split()[0]}; "
          f"PYTHONDONTWRITEBYTECODE={os.environ.get('PYTHONDONTWRITEBYTECODE', '')!r} "
          "(set: every process rewrites the plugin's asserts anew)")
    with tempfile.TemporaryDirectory(prefix="avs-bench-parallel-") as tmp_s:
        tmp = Path(tmp_s)
        (tmp / "avs_bench_ctl.py").write_text(CONTROLLER_PLUGIN)
        path = f"{tmp}:{ROOT}"
        if not args.skip_controller:
            d = tmp / "trivial"
            d.mkdir()
            (d / "test_trivial.py").write_text(TRIVIAL.format(cases=args.controller))
            pairs(f"trivial {args.controller}", d, tmp, ["--avs-seed=1", "--avs-shrink-budget=0"],
                  args.repeats, f"{d}:{path}")
        if not args.skip_examples:
            pairs("examples", ROOT, tmp, ["example_tests", "-m", "scenario", "--avs-seed=0"],
                  args.repeats, path)
        if not args.skip_campaign:
            d = tmp / "campaign"
            d.mkdir()
            (d / "test_vehicle_following.py").write_text(SCENARIO.format(cases=args.cases))
            (d / "subscenarios.py").write_text((ROOT / "example_tests" / "subscenarios.py").read_text())
            pairs(f"campaign {args.cases}", d, tmp, ["--avs-seed=1", "--avs-shrink-budget=0"],
                  args.repeats, f"{d}:{path}")


if __name__ == "__main__":
    main()

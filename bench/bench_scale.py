"""Scale-out: 40 vehicle-following cases serial, under pytest-xdist ``-n 2`` and on Dask.

Run ``python bench/bench_scale.py`` (``--repeats N``, default 3; ``--cases N``, default 40;
``--modes`` instead checks what each ``--dist`` mode of pytest-xdist does with passive and
active samplers). The script writes a scenario file like
``example_tests/test_02_vehicle_following.py`` (40 Halton cases, five monitors) into a temp
dir and runs it with ``--avs-db=none --avs-shrink-budget=0 --avs-report=none`` so only the
simulations and their judging are measured:

1. ``pytest`` (serial), ``pytest -n 2`` and ``pytest --avs-executor=dask`` (the plugin's own
   LocalCluster: one worker per core, 2 on this machine), interleaved, ``--repeats`` times:
   * *wall*: the whole command, as a user waits for it (interpreter, plugin, collection,
     workers or cluster start, the first case's highway-env import, 40 cases);
   * *cases*: first item's call start to last item's call end, from the reports' own
     timestamps (also under xdist, where the controller receives the workers' reports);
     it includes each process's first highway-env import, as a user's run does;
   * *cpu*: user+system CPU of the whole process tree (pytest, its xdist workers or Dask
     worker processes), from ``getrusage(RUSAGE_CHILDREN)``: what the parallelism costs.
2. Per-case overhead of the Dask path against the in-process path, through the executor API
   (no pytest): the same 40 jobs run by ``InProcessExecutor``; by ``DaskExecutor`` with one
   worker one at a time (round-trip latency: submit, simulate there, return); and prefetched
   (pipelined, as the plugin runs passive cases), with one and with two workers, one case
   per Dask task and in the executor's automatic chunks. Wall time
   per case, and CPU per case summed over the client (which hosts the local scheduler) and
   the workers, so the overhead is visible even when other jobs load the machine.

3. ``--memory 1000,10000``: peak RSS and the time after the last case of a trivial campaign
   (two Halton parameters, a body that asserts, 30 % failing, report on, no shrinking and no
   database), serial and ``-n 2``: ``ru_maxrss`` of the largest process (the pytest process;
   under xdist the largest of controller and workers) and the time from the last call's end
   to the process's exit (the report, pytest's summary, the interpreter's end), with the
   pytest process's CPU time for it (serial), the peak RSS every 10,000 items, and the goals
   of issue #35 (500 MB, 30 s at 100,000 cases) PASS/MISS when 100,000 is among the sizes.
   After a 50-case warm-up, with a bytecode cache of the run's own (as a developer's machine
   has one); ``--memory-pytest-args`` gives pytest's options (default ``-q --tb=line -rN``).

Medians over repeats. The machine is shared: the load average is printed with the numbers;
compare ratios from one run, not absolute times across runs.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

SCENARIO = '''
from pytest_avscenario import Uniform, scenario
from pytest_avscenario.monitors import collision, distance, lane_keeping, progress, ttc

from subscenarios import slow_down


@scenario(
    gap=Uniform(8.0, 40.0, nominal=30.0),
    lead_speed=Uniform(5.0, 15.0, nominal=10.0),
    brake_at=Uniform(1.0, 5.0, nominal=3.0),
    lead_decel=Uniform(1.0, 8.0, nominal=2.5),
    lead_final_speed=Uniform(0.0, 8.0, nominal=5.0),
    samples={cases},
    sampler="halton",
    monitors=[progress(11.0), distance(5.0), ttc(2.0), lane_keeping(0.5), collision()],
    priority=["collision", "distance", "ttc", "progress", "lane_keeping"],
)
def test_vehicle_following(case, world):
    road = world.straight_road(lanes=1, length=400)
    world.ego(road.lane(0), s=20.0, speed=12.0)
    world.car(road.lane(0), s=20.0 + case.gap, speed=case.lead_speed,
              behavior=slow_down(case.brake_at, case.lead_decel, case.lead_final_speed))
    world.run(seconds=12)
'''

# A plugin module loaded with -p: records each call phase's start and stop (the controller
# sees the workers' reports under xdist, with the times they were taken).
TIMING_PLUGIN = '''
import json, os

_spans = []

def pytest_runtest_logreport(report):
    if report.when == "call":
        _spans.append((report.start, report.stop))

def pytest_sessionfinish(session):
    if hasattr(session.config, "workerinput") or not _spans:
        return
    with open(os.environ["AVS_BENCH_TIMING"], "w") as f:
        json.dump({"first_start": min(s for s, _ in _spans), "last_stop": max(e for _, e in _spans),
                   "n": len(_spans)}, f)
'''

COMMON = ["-p", "no:cacheprovider", "-p", "avs_bench_timing", "-q", "--avs-seed=1",
          "--avs-db=none", "--avs-shrink-budget=0", "--avs-report=none"]
MODES = {"serial": [], "xdist -n 2": ["-n", "2"], "dask 2 workers": ["--avs-executor=dask"]}


def load() -> str:
    return " ".join(f"{x:.1f}" for x in os.getloadavg())


def write_suite(where: Path, cases: int, name: str = "") -> Path:
    d = where / (name or f"suite{cases}")
    d.mkdir()
    (d / "test_vehicle_following.py").write_text(SCENARIO.format(cases=cases))
    shutil.copy(ROOT / "example_tests" / "subscenarios.py", d / "subscenarios.py")
    (d / "avs_bench_timing.py").write_text(TIMING_PLUGIN)
    return d


def _children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def run_pytest(suite: Path, extra: list[str], timing: Path) -> dict:
    stats = timing.with_name("dask-stats.json")
    env = dict(os.environ, AVS_BENCH_TIMING=str(timing), PYTHONPATH=str(suite),
               AVS_DASK_STATS=str(stats))
    if stats.exists():
        stats.unlink()
    if timing.exists():
        timing.unlink()
    cpu0, t0 = _children_cpu(), time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "pytest", *COMMON, *extra], cwd=suite, env=env,
                          capture_output=True, text=True)
    wall, cpu = time.perf_counter() - t0, _children_cpu() - cpu0
    last = proc.stdout.strip().splitlines()[-1] if proc.stdout.strip() else proc.stderr[-300:]
    if proc.returncode not in (0, 1):
        raise SystemExit(f"pytest {' '.join(extra)} failed ({proc.returncode}):\n"
                         f"{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}")
    span = json.loads(timing.read_text())
    if stats.exists():  # the Dask executor's counters: did the cases start ahead?
        counters = json.loads(stats.read_text())
        last += (f"; dask: {counters.get('prefetched', 0)} prefetched in "
                 f"{counters.get('tasks', 0)} tasks, {counters.get('on_demand', 0)} on demand")
    return {"wall": wall, "cases": span["last_stop"] - span["first_start"], "cpu": cpu,
            "n": span["n"], "summary": last}


def bench_pytest(tmp: Path, cases: int, repeats: int) -> dict[str, float]:
    suite = write_suite(tmp, cases)
    timing = tmp / "timing.json"
    runs: dict[str, dict[str, list[float]]] = {m: collections.defaultdict(list) for m in MODES}
    loads = []
    for r in range(repeats):
        for mode, extra in MODES.items():
            loads.append(os.getloadavg()[0])
            res = run_pytest(suite, extra, timing)
            assert res["n"] == cases, res
            for k in ("wall", "cases", "cpu"):
                runs[mode][k].append(res[k])
            print(f"  repeat {r + 1} {mode:<15} wall {res['wall']:6.2f} s  cases {res['cases']:6.2f} s"
                  f"  cpu {res['cpu']:6.2f} s  ({res['summary']})  load {load()}", flush=True)
    print(f"\n{cases} cases, medians of {repeats}; load average (1 min) before the runs "
          f"{min(loads):.1f}-{max(loads):.1f} on {os.cpu_count()} cores")
    base = {k: statistics.median(v) for k, v in runs["serial"].items()}
    print(f"{'':<16}{'wall s':>8}{'speed-up':>10}{'cases s':>9}{'speed-up':>10}{'cpu s':>8}")
    for mode in MODES:
        med = {k: statistics.median(v) for k, v in runs[mode].items()}
        best = min(runs[mode]["cases"])
        print(f"{mode:<16}{med['wall']:8.2f}{base['wall'] / med['wall']:10.2f}"
              f"{med['cases']:9.2f}{base['cases'] / med['cases']:10.2f}{med['cpu']:8.2f}"
              f"   (cases: best {best:.2f} s, all {' '.join(f'{v:.2f}' for v in runs[mode]['cases'])})")
    return {mode: statistics.median(runs[mode]["wall"]) for mode in MODES}


def fit(walls: dict[int, dict[str, float]]) -> None:
    """wall = fixed + N x per-case from the smallest and largest N: where scale-out pays."""
    lo, hi = min(walls), max(walls)
    per = {m: (walls[hi][m] - walls[lo][m]) / (hi - lo) for m in MODES}
    fixed = {m: walls[lo][m] - lo * per[m] for m in MODES}
    print(f"\nfit from N={lo} and N={hi}: wall = fixed + N x per-case")
    for m in MODES:
        ratio = per["serial"] / per[m] if per[m] > 0 else float("nan")
        print(f"  {m:<16} fixed {fixed[m]:6.2f} s  per case {1e3 * per[m]:6.2f} ms  "
              f"per-case speed-up {ratio:5.2f}")


def bench_overhead(tmp: Path, cases: int, repeats: int) -> None:
    """Per case: in-process vs Dask round trip (1 worker) vs Dask prefetched (1 and 2 workers)."""
    from pytest_avscenario import samplers
    from pytest_avscenario.case import Case, stable_seed
    from pytest_avscenario.executors import CaseJob, InProcessExecutor
    from pytest_avscenario.executors.dask import DaskExecutor
    from pytest_avscenario.executors.remote import import_test_module
    from pytest_avscenario.monitors import MonitorSet
    from pytest_avscenario.sim import World
    from pytest_avscenario.space import FeatureSpace

    suite = write_suite(tmp, cases, name="api")
    path = suite / "test_vehicle_following.py"
    func = import_test_module(str(path), str(suite)).test_vehicle_following
    spec = func.pytestmark[0].args[0]
    space = FeatureSpace(spec.parameters)
    monitors = MonitorSet(list(spec.monitors), priority=spec.priority)
    points = samplers.make("halton", space, seed=1).sample_unit(cases)

    def jobs(tag: str) -> list[CaseJob]:
        out = []
        for k, u in enumerate(points):
            case = Case(space.from_unit(u), k, stable_seed(1, k), "halton", test=tag)
            out.append(CaseJob(
                nodeid=f"{path.name}::test_vehicle_following[{tag}-{k:03d}]", module_path=str(path),
                rootdir=str(suite), function="test_vehicle_following", func=func,
                argnames=("case", "world"), fixtures={}, case=case, monitor_set=monitors,
                driver="autopilot",
                make_world=lambda c: World(seed=c.seed, rng=c.rng, driver="autopilot")))
        return out

    def timed(fn, ex=None) -> tuple[float, float]:
        """Wall and CPU seconds per case: this process, plus the workers' when on Dask."""
        workers_cpu = (lambda: sum(ex._client.run(time.process_time).values())) if ex else (lambda: 0.0)
        c0, w0, t0 = time.process_time(), workers_cpu(), time.perf_counter()
        fn()
        wall = time.perf_counter() - t0
        return wall / cases, (time.process_time() - c0 + workers_cpu() - w0) / cases

    inproc = InProcessExecutor()
    InProcessExecutor().run(jobs("warm")[0])  # imports
    results: dict[str, list[tuple[float, float]]] = collections.defaultdict(list)
    sim_remote: list[float] = []
    for workers in (1, 2):
        ex = DaskExecutor(n_workers=workers)
        try:
            for w in ex._warm:  # the warm-up scenes: imports done before timing
                w.result()
            ex.run(jobs("warm-dask")[0])
            for r in range(repeats):
                local_jobs = jobs(f"local{workers}{r}")
                results["in-process"].append(timed(lambda: [inproc.run(j) for j in local_jobs]))
                if workers == 1:
                    one = jobs(f"rt{r}")
                    outs: list = []
                    results["dask round trip, 1 worker"].append(
                        timed(lambda: outs.extend(ex.run(j) for j in one), ex))
                    sim_remote.extend(o.sim_time_s for o in outs)
                plural = "s" if workers > 1 else ""
                for chunk in (1, None):
                    ahead = jobs(f"pf{workers}{r}{chunk}")
                    ex.chunk_size = chunk

                    def prefetched() -> None:
                        ex.prefetch(ahead)
                        for j in ahead:
                            ex.run(j)

                    how = "one case per task" if chunk == 1 else "chunked (auto)"
                    results[f"dask prefetched, {workers} worker{plural}, {how}"].append(
                        timed(prefetched, ex))
                print(f"  overhead repeat {r + 1}, {workers} worker(s), load {load()}", flush=True)
        finally:
            ex.close()
    base_wall = statistics.median(w for w, _ in results["in-process"])
    base_cpu = statistics.median(c for _, c in results["in-process"])
    print(f"\nper case, medians of {repeats} x {cases} cases (load {load()}); the case's own time "
          f"(sim_time_s) on the worker: median {1e3 * statistics.median(sim_remote):.1f} ms")
    print(f"  {'':<48} {'wall ms':>8} {'vs in-process':>14} {'cpu ms':>8} {'vs in-process':>14}")
    for name, values in results.items():
        wall = statistics.median(w for w, _ in values)
        cpu = statistics.median(c for _, c in values)
        print(f"  {name:<48} {1e3 * wall:8.1f} {1e3 * (wall - base_wall):+14.1f} "
              f"{1e3 * cpu:8.1f} {1e3 * (cpu - base_cpu):+14.1f}")


MODES_FILE = '''
import json, os
from pytest_avscenario import scenario, Uniform

def _log(case):
    with open(os.environ["AVS_RECORD"], "a") as f:
        f.write(json.dumps({{"item": case.test, "params": case.params,
                            "worker": os.environ.get("PYTEST_XDIST_WORKER", "-")}}) + "\\n")

@scenario(x=Uniform(0, 1), y=Uniform(0, 1), samples=30, sampler="halton")
def test_passive(case):
    _log(case)

@scenario(x=Uniform(0, 1), y=Uniform(0, 1), samples=8, sampler="mab")
def test_active(case):
    import time; time.sleep({sleep})  # slower than the passive cases: work gets stolen
    _log(case)
'''


def check_modes(tmp: Path) -> None:
    """Which worker ran which case under each --dist mode; same parameters as serial?"""
    suite = tmp / "modes"
    suite.mkdir()
    (suite / "test_modes.py").write_text(MODES_FILE.format(sleep=0.3))

    def run(extra: list[str], tag: str) -> tuple[list[dict], str]:
        rec = suite / f"rec-{tag}.jsonl"
        env = dict(os.environ, AVS_RECORD=str(rec))
        proc = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-q",
                               "--avs-seed=4", "--avs-db=none", "--avs-report=none", *extra],
                              cwd=suite, env=env, capture_output=True, text=True)
        return [json.loads(x) for x in rec.read_text().splitlines()], proc.stdout.strip().splitlines()[-1]

    serial, _ = run([], "serial")
    ref = {r["item"]: r["params"] for r in serial}
    # "active on": simulations of the active campaign per worker (a worker given case k first
    # simulates the earlier cases it has not run); "= serial": active ids whose every
    # simulation had the serial run's parameters; "sims": active simulations in all (serial: 8)
    print(f"{'--dist':<11}{'passive on':<14}{'active on':<16}{'active = serial':<17}{'active sims':<12}")
    for mode in ("load", "loadscope", "loadfile", "worksteal"):
        rows, summary = run(["-n", "2", f"--dist={mode}"], mode)
        on = collections.defaultdict(collections.Counter)
        differ = set()
        for r in rows:
            fn = r["item"].split("::")[1].split("[")[0]
            on[fn][r["worker"]] += 1
            if fn == "test_active" and r["params"] != ref[r["item"]]:
                differ.add(r["item"])
        active = [r for r in rows if "test_active" in r["item"]]
        same = len({r["item"] for r in active} - differ)
        fmt = lambda c: " ".join(f"{w}:{n}" for w, n in sorted(c.items()))  # noqa: E731
        print(f"{mode:<11}{fmt(on['test_passive']):<14}{fmt(on['test_active']):<16}"
              f"{same}/8{'':<13}{len(active):<12}{summary}")


TRIVIAL = '''
from pytest_avscenario import Uniform, scenario


@scenario(x=Uniform(0.0, 1.0), y=Uniform(0.0, 1.0), samples={cases}, sampler="halton")
def test_trivial(case):
    assert case.x < 0.7
'''

# -p plugin of the memory benchmark: the process's CPU time and peak RSS when the last case
# ends, and a line every 10,000 items (a long run that is stopped still tells its growth)
MEMORY_PLUGIN = '''
import atexit, json, os, resource, time

_seen = {"n": 0, "first_start": None, "last_stop": 0.0, "cpu_last": 0.0, "rss_last_kb": 0}

def _cpu():
    ru = resource.getrusage(resource.RUSAGE_SELF)
    return ru.ru_utime + ru.ru_stime

def pytest_runtest_logreport(report):
    if report.when != "call":
        return
    _seen["n"] += 1
    if _seen["first_start"] is None:
        _seen["first_start"] = report.start
    _seen["last_stop"] = max(_seen["last_stop"], report.stop)
    _seen["cpu_last"] = _cpu()
    _seen["rss_last_kb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    if _seen["n"] % 10000 == 0:
        with open(os.environ["AVS_BENCH_PROGRESS"], "a") as f:
            f.write(f"{_seen['n']} items: peak RSS {_seen['rss_last_kb'] / 1024:.0f} MB, "
                    f"cpu {_seen['cpu_last']:.1f} s, {time.strftime('%H:%M:%S')}\\n")

def pytest_sessionfinish(session):
    _seen["cpu_sessionfinish"] = _cpu()

def _write():
    if hasattr(_config, "workerinput") or not _seen["n"]:
        return
    _seen["cpu_atexit"] = _cpu()
    # the pytest process's own peak, and its helpers' (the report's, a serial run's too)
    _seen["rss_self_kb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    _seen["rss_helpers_kb"] = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    with open(os.environ["AVS_BENCH_TIMING"], "w") as f:
        json.dump(_seen, f)

_config = None

def pytest_configure(config):
    global _config
    _config = config
    atexit.register(_write)
'''

#: the goals of issue #35 (items 1 and 2) at 100,000 cases
GOAL_RSS_MB, GOAL_END_S, GOAL_AT = 500, 30.0, 100_000


def bench_memory(tmp: Path, sizes: list[int], parallel: list[str], pytest_args: list[str]) -> None:
    """Peak RSS and the time after the last case, per campaign size, serial and -n N."""
    # as on a developer's machine: the bytecode of the plugin and of pytest's rewritten
    # modules is cached (in a folder of this run's, so nothing outside it is written); the
    # first run fills the cache, a warm-up of 50 cases runs before the measured ones
    cache = tmp / "pycache"
    base_env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    base_env["PYTHONPYCACHEPREFIX"] = str(cache)
    print(f"pytest options: {' '.join(pytest_args)}")
    print(f"{'cases':>8} {'mode':<8} {'peak RSS MB':>12} {'after last s':>13} "
          f"{'(cpu s)':>8} {'cases s':>8} {'ms/case':>8} {'(cpu ms)':>9} {'wall s':>8}  load")
    # after last: from the last case's end to the process's exit, wall (cpu: the pytest
    # process's, serial only); ms/case: the cases' span per case, wall (cpu: the process's
    # CPU up to the last case, start-up and collection included, per case)
    results: dict[tuple[int, str], dict[str, float]] = {}
    for n in [50, *sizes]:
        d = tmp / f"mem{n}"
        d.mkdir()
        (d / "test_trivial.py").write_text(TRIVIAL.format(cases=n))
        (d / "avs_bench_memory.py").write_text(MEMORY_PLUGIN)
        for mode in parallel:
            timing, progress = d / f"timing-{mode}.json", d / f"progress-{mode}.txt"
            extra = [] if mode == "serial" else ["-n", mode]
            cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "avs_bench_memory",
                   *pytest_args, "--avs-seed=1", "--avs-db=none", "--avs-shrink-budget=0",
                   f"--avs-report={d}/rep-{mode}", *extra]
            script = (f"import resource, subprocess, sys, time; t0 = time.time(); "
                      f"p = subprocess.run({cmd!r}, stdout=subprocess.DEVNULL); end = time.time(); "
                      f"ru = resource.getrusage(resource.RUSAGE_CHILDREN); "
                      f"print(ru.ru_maxrss, end - t0, end, ru.ru_utime + ru.ru_stime, p.returncode)")
            env = dict(base_env, AVS_BENCH_TIMING=str(timing), AVS_BENCH_PROGRESS=str(progress),
                       PYTHONPATH=f"{d}:{ROOT}")
            out = subprocess.run([sys.executable, "-c", script], cwd=d, env=env, capture_output=True,
                                 text=True, check=True).stdout.split()
            span = json.loads(timing.read_text())
            assert span["n"] == n and out[4] == "1", (span, out)
            rss, wall, end, cpu_all = int(out[0]) / 1024, float(out[1]), float(out[2]), float(out[3])
            cases = span["last_stop"] - span["first_start"]
            after = end - span["last_stop"]
            # the CPU after the last case: the pytest process's whole CPU less its CPU then
            # (serial only: under xdist the children's CPU includes the workers')
            after_cpu = cpu_all - span["cpu_last"] if mode == "serial" else float("nan")
            res = {"rss": rss, "after": after, "after_cpu": after_cpu, "cases": cases, "wall": wall,
                   "rss_last": span["rss_last_kb"] / 1024}
            if n == 50:
                continue  # the warm-up
            results[(n, mode)] = res
            per_case_cpu = (span["cpu_last"] / n) if mode == "serial" else float("nan")
            print(f"{n:>8} {mode:<8} {rss:>12.0f} {after:>13.1f} {after_cpu:>8.1f} "
                  f"{cases:>8.1f} {1e3 * cases / n:>8.2f} {1e3 * per_case_cpu:>9.2f} {wall:>8.1f}  {load()}",
                  flush=True)
            if "rss_self_kb" in span:
                print(f"{'':>10}peak RSS of the pytest process {span['rss_self_kb'] / 1024:.0f} MB, "
                      f"of its largest helper process {span['rss_helpers_kb'] / 1024:.0f} MB "
                      f"(helpers still running at its exit not counted)")
            if progress.exists():
                for line in progress.read_text().splitlines():
                    print(f"{'':>10}{line}")
    for mode in parallel:
        sized = sorted(n for n, m in results if m == mode)
        if len(sized) >= 2:
            lo, hi = sized[0], sized[-1]
            growth = (results[(hi, mode)]["rss"] - results[(lo, mode)]["rss"]) * 1024 / (hi - lo)
            slope = (results[(hi, mode)]["after"] - results[(lo, mode)]["after"]) / (hi - lo)
            print(f"{mode}: peak RSS grows {growth:.2f} KB per case ({lo:,} -> {hi:,}); the time after "
                  f"the last case {1e3 * slope:.2f} ms per case")
        top = max(sized, default=None)
        if top is None:
            continue
        r = results[(top, mode)]
        if top >= GOAL_AT:
            verdict = "PASS" if r["rss"] <= GOAL_RSS_MB else "MISS"
            print(f"goal {mode}: peak RSS at {top:,} cases {r['rss']:.0f} MB <= {GOAL_RSS_MB} MB: {verdict}")
            verdict = "PASS" if r["after"] <= GOAL_END_S else "MISS"
            print(f"goal {mode}: after the last case at {top:,} cases {r['after']:.1f} s "
                  f"(cpu {r['after_cpu']:.1f} s) <= {GOAL_END_S:.0f} s: {verdict}")
        else:
            print(f"goal {mode}: not judged (the goals are stated at {GOAL_AT:,} cases; the largest "
                  f"size run is {top:,})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--cases", default="40",
                    help="cases per run; a comma list (40,400) also fits wall = fixed + N x per-case")
    ap.add_argument("--modes", action="store_true", help="check the --dist modes instead")
    ap.add_argument("--skip-overhead", action="store_true")
    ap.add_argument("--memory", default="", help="peak RSS and end-of-run time at these sizes (1000,10000)")
    ap.add_argument("--memory-modes", default="serial,2", help="serial and/or worker counts for --memory")
    ap.add_argument("--memory-pytest-args", default="-q --tb=line -rN",
                    help="pytest's own options for --memory (the README's advice for huge campaigns)")
    ap.add_argument("--skip-pytest", action="store_true")
    args = ap.parse_args()
    print(f"load average {load()} on {os.cpu_count()} cores; python {sys.version.split()[0]}")
    if len(os.sched_getaffinity(0)) != 2:
        print("note: the Dask LocalCluster starts one worker per core, not 2, on this machine")
    with tempfile.TemporaryDirectory(prefix="avs-bench-scale-") as tmp:
        if args.modes:
            check_modes(Path(tmp))
            return
        if args.memory:
            bench_memory(Path(tmp), [int(x) for x in args.memory.split(",")],
                         args.memory_modes.split(","), args.memory_pytest_args.split())
            return
        sizes = [int(x) for x in str(args.cases).split(",")]
        if not args.skip_pytest:
            walls = {n: bench_pytest(Path(tmp), n, args.repeats) for n in sizes}
            if len(sizes) > 1:
                fit(walls)
        if not args.skip_overhead:
            bench_overhead(Path(tmp), sizes[0], args.repeats)


if __name__ == "__main__":
    main()

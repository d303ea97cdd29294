"""The product against its anchor: vehicle following through pytest vs Scenic + VerifAI.

Same work on both sides (DESIGN.md, "Anchors to beat"): ego and lead on a straight lane,
gap U[10, 40] m, lead speed U[5, 15] m/s, lead brakes after U[1, 5] s, ego at 12 m/s, 10 s
at 0.1 s, monitor = min centre distance - 5 m. Ours: a real scenario test run by pytest with
the built-in autopilot (shrinking and the replay database off, the report on), measured as

* per case, inside pytest: the marginal wall time of N cases over 1 case (collection and
  start-up cancel out), and the in-body simulation time the error table records;
* cold start: from launching a fresh ``pytest`` process to its first case being done (what
  Scenic's cold start measures: imports, compilation, first sample); the process exit,
  after the report is written, is printed too.

Theirs: ``../shared/anchors/scenic/run_falsify.py`` (per-sample time) and ``cold_start.py``
in the anchor's own virtual environment (``~/.venvs/verifai``), in the same run.

    python bench/bench_end_to_end.py [--cases 60] [--repeats 3] [--anchor-venv ~/.venvs/verifai]
"""

from __future__ import annotations

import argparse
import json
import resource
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ANCHORS = HERE.parent.parent / "shared" / "anchors" / "scenic"

SCENARIO = """
import os, time
from pytest_avscenario import Uniform, scenario
from pytest_avscenario.sim import behaviors as b

def min_distance(traj):
    import numpy as np
    d = np.hypot(traj.x[0] - traj.x[1], traj.y[0] - traj.y[1])
    return float(np.nanmin(d) - 5.0)

@scenario(gap=Uniform(10.0, 40.0), lead_speed=Uniform(5.0, 15.0), brake_at=Uniform(1.0, 5.0),
          samples={n}, sampler="halton", monitors=[min_distance])
def test_follow(case, world):
    road = world.straight_road(lanes=1, length=400)
    world.ego(road.lane(0), s=20.0, speed=12.0)
    world.car(road.lane(0), s=20.0 + case.gap, speed=case.lead_speed,
              behavior=b.brake_at(case.brake_at, decel=6.0))
    world.run(seconds=10)
    stamp = os.environ.get("AVS_BENCH_STAMP")
    if stamp and not os.path.exists(stamp):
        with open(stamp, "w") as f:
            f.write(repr(time.time()))  # wall clock when the first case is done
"""

FLAGS = ["-q", "-p", "no:cacheprovider", "--avs-seed=0", "--avs-db=none",
         "--avs-shrink-budget=0", "--avs-gifs=0"]


def child_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run_pytest(directory: Path, n: int) -> tuple[float, float, float, list[dict]]:
    """(wall time to exit, wall time to the first case done, CPU time, the error-table rows)."""
    (directory / "test_follow.py").write_text(SCENARIO.format(n=n))
    report = directory / "avs-report"
    stamp = directory / "first-case.txt"
    shutil.rmtree(report, ignore_errors=True)
    stamp.unlink(missing_ok=True)
    env = dict(os.environ, AVS_BENCH_STAMP=str(stamp))
    launched = time.time()
    c0, t0 = child_cpu(), time.perf_counter()
    subprocess.run([sys.executable, "-m", "pytest", *FLAGS, "test_follow.py"], cwd=directory,
                   capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    cpu = child_cpu() - c0
    first = float(stamp.read_text()) - launched
    rows = [json.loads(l) for l in (report / "errors.jsonl").read_text().splitlines()]
    assert len(rows) == n, f"expected {n} rows, got {len(rows)}"
    return wall, first, cpu, rows


def anchor(venv: Path, script: str, *args: str) -> dict:
    work = Path(tempfile.mkdtemp(prefix="scenic-anchor-"))
    try:
        for f in ANCHORS.iterdir():
            shutil.copy(f, work / f.name)
        py = venv / "bin" / "python"
        if script == "run_falsify.py":  # warm the map cache once, as the anchor was measured
            subprocess.run([str(py), script, "halton", "2"], cwd=work, capture_output=True)
        out = subprocess.run([str(py), script, *args], cwd=work, capture_output=True, text=True)
        line = [l for l in out.stdout.splitlines() if l.startswith("{")]
        if not line:
            raise RuntimeError(f"{script} printed no JSON: {out.stderr[-800:]}")
        return json.loads(line[-1])
    finally:
        shutil.rmtree(work, ignore_errors=True)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", type=int, default=60)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--anchor-venv", default=str(Path.home() / ".venvs" / "verifai"))
    args = ap.parse_args()
    venv = Path(args.anchor_venv)

    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        one, first, many, body, cpu_one, cpu_many = [], [], [], [], [], []
        for _ in range(args.repeats):
            w1, f1, c1, _rows = run_pytest(d, 1)
            wn, _f, cn, rows = run_pytest(d, args.cases)
            one.append(w1)
            first.append(f1)
            many.append(wn)
            cpu_one.append(c1)
            cpu_many.append(cn)
            body.append(statistics.median(r["sim_time_s"] for r in rows))
        exit_one = statistics.median(one)
        cold = statistics.median(first)
        per_case = (statistics.median(many) - exit_one) / (args.cases - 1)
        per_case_cpu = (statistics.median(cpu_many) - statistics.median(cpu_one)) / (args.cases - 1)
        per_body = statistics.median(body)
    print(f"ours  per case through pytest (marginal, {args.cases} cases): {per_case * 1e3:.1f} ms wall, "
          f"{per_case_cpu * 1e3:.1f} ms CPU")
    print(f"ours  per case, test body (build + simulate + record), median: {per_body * 1e3:.1f} ms")
    print(f"ours  cold start, fresh pytest process to its first case done: {cold:.2f} s "
          f"(to exit, report written: {exit_one:.2f} s)")

    if not (venv / "bin" / "python").exists():
        print(f"anchor venv {venv} missing: see ../shared/anchors/README.md")
        return
    samples = [anchor(venv, "run_falsify.py", "halton", "30") for _ in range(args.repeats)]
    colds = [anchor(venv, "cold_start.py") for _ in range(args.repeats)]
    theirs_ms = statistics.median(s["per_sample_s"] for s in samples) * 1e3
    theirs_cold = statistics.median(sum(v for v in c.values()) for c in colds)
    print(f"anchor per sample (30 halton samples): {theirs_ms:.1f} ms, of which simulation "
          f"{statistics.median(s['simulate_total_s'] / s['n_iters'] for s in samples) * 1e3:.1f} ms")
    print(f"anchor cold start (import + compile + first sample): {theirs_cold:.2f} s   raw: {json.dumps(colds[-1])}")
    print(f"ratio per case, ours/anchor: {per_case * 1e3 / theirs_ms:.3f}  (target <= 0.2)")
    print(f"ratio cold start, ours/anchor: {cold / theirs_cold:.3f}  (target < 0.5)")
    print(f"load: {os.getloadavg()}")


if __name__ == "__main__":
    main()

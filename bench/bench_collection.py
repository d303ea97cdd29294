"""Collection cost of scenario expansion, and what loading the plugin imports.

Writes a throwaway suite of 10 scenario tests x 100 Halton cases and times
``pytest --co -q`` on it in fresh processes (median of repeats), next to the same command on
a plain suite of 1000 ordinary parametrized tests (the anchor: pytest's own expansion cost).
Then checks with ``python -X importtime`` which heavy modules a plain run imports.

    python bench/bench_collection.py [--repeats 5]
"""

from __future__ import annotations

import argparse
import resource
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

SCENARIO_SUITE = """
from pytest_avscenario import scenario, Uniform, Choice, IntRange
""" + "".join(
    f"""
@scenario(gap=Uniform(10, 40), speed=Uniform(5, 15), brake=Uniform(1, 5),
          road=Choice(["dry", "wet"]), lanes=IntRange(1, 3), samples=100)
def test_scenario_{i}(case):
    pass
"""
    for i in range(10)
)

PLAIN_SUITE = """
import pytest
""" + "".join(
    f"""
@pytest.mark.parametrize("k", range(100))
def test_plain_{i}(k):
    pass
"""
    for i in range(10)
)

HEAVY = ("highway_env", "pygame", "matplotlib", "pandas", "scipy")


def child_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def time_collect(path: Path, repeats: int) -> tuple[float, float, str]:
    """Median wall time and median CPU time (user + system) of ``pytest --co -q`` on ``path``.

    CPU time is what to compare on a shared machine: other processes stretch the wall clock."""
    walls, cpus, last = [], [], ""
    for _ in range(repeats):
        c0, t0 = child_cpu(), time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "pytest", "--co", "-q", "-p", "no:cacheprovider", str(path)],
                              capture_output=True, text=True, cwd=path.parent)
        walls.append(time.perf_counter() - t0)
        cpus.append(child_cpu() - c0)
        last = proc.stdout.strip().splitlines()[-1]
    return statistics.median(walls), statistics.median(cpus), last


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        (d / "test_scen.py").write_text(SCENARIO_SUITE)
        (d / "test_plain.py").write_text(PLAIN_SUITE)
        (d / "test_nothing.py").write_text("def test_x():\n    pass\n")
        t_scen, c_scen, out_scen = time_collect(d / "test_scen.py", args.repeats)
        t_plain, c_plain, out_plain = time_collect(d / "test_plain.py", args.repeats)
        t_empty, c_empty, _ = time_collect(d / "test_nothing.py", args.repeats)
        print("                                                 wall     CPU")
        print(f"pytest --co -q, 10 scenario tests x 100 cases:  {t_scen:.3f} s  {c_scen:.3f} s  ({out_scen})")
        print(f"pytest --co -q, 10 plain tests x 100 params:    {t_plain:.3f} s  {c_plain:.3f} s  ({out_plain})")
        print(f"pytest --co -q, one plain test (process start): {t_empty:.3f} s  {c_empty:.3f} s")
        print(f"scenario expansion over plain parametrize (CPU): {c_scen / c_plain:.2f}x; "
              f"collecting the 1000 scenario cases beyond process start: {c_scen - c_empty:.3f} s CPU")
        proc = subprocess.run([sys.executable, "-X", "importtime", "-m", "pytest", "--co", "-q",
                               "-p", "no:cacheprovider", str(d / "test_nothing.py")],
                              capture_output=True, text=True, cwd=d)
        imported = {line.split("|")[-1].strip().split(".")[0] for line in proc.stderr.splitlines()
                    if line.startswith("import time:")}
        found = [m for m in HEAVY if m in imported]
        own = [line for line in proc.stderr.splitlines() if "pytest_avscenario" in line]
        cum = sum(int(l.split("|")[1]) for l in own) if own else 0
        print(f"heavy modules imported by a plain run: {found or 'none'}; "
              f"plugin's own import (self time summed): {cum / 1000:.1f} ms")


if __name__ == "__main__":
    main()

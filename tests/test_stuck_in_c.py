"""A case stuck in one C call that holds the interpreter still ends, and keeps its row.

``sum(range(10**10))`` never returns to Python for minutes: no SIGALRM handler, no watchdog
thread and no SIGTERM watcher can run meanwhile. The plugin's sentinel process
(pytest_plugin/lastresort.py) holds the case's error row from the start of the case; it
writes it and kills the process when the case is still running GRACE_S + LAST_RESORT_S
after its time limit. Serially the run ends killed (never status 0) with every row on disk;
under xdist the worker is replaced and the controller records the row the worker's sentinel
left for it.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time

import pytest

from pytest_avscenario.runner import GRACE_S, LAST_RESORT_S

IN_C = """
from pytest_avscenario import scenario, Uniform

class Stuck:
    name = "stuck"
    def __init__(self, index):
        self.index = index
    def act(self, obs):
        if self.index == 1 and obs.t > 0.25:
            sum(range(10**10))  # one C call of minutes that never lets go of the interpreter
        return 0.0, 0.0

@scenario(gap=Uniform(30, 50), samples=3, sampler="halton", monitors=[], case_timeout=3)
def test_in_c(case, world):
    road = world.straight_road(lanes=1, length=300)
    world.ego(road.lane(0), s=10.0, speed=8.0, driver=Stuck(case.index))
    world.car(road.lane(0), s=10.0 + case.gap, speed=9.0)
    world.run(seconds=1)
"""


def _rows(path) -> list[dict]:
    table = path / "rep" / "errors.jsonl"
    return [json.loads(line) for line in table.read_text().splitlines()] if table.exists() else []


def test_serially_the_run_is_killed_after_the_grace_with_the_row_written(pytester):
    pytester.makepyfile(test_stuck=IN_C)
    start = time.monotonic()
    proc = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:xdist",
                           "--avs-db=none", "--avs-report=rep", "--avs-shrink-budget=0"],
                          cwd=pytester.path, capture_output=True, text=True, timeout=120)
    took = time.monotonic() - start
    out = proc.stdout + proc.stderr
    assert proc.returncode != 0, out[-3000:]
    assert took < 40, took  # the case alone would run for minutes
    rows = _rows(pytester.path)
    assert [r["item"].split("::")[1] for r in rows] == ["test_in_c[halton-000]", "test_in_c[halton-001]"]
    assert rows[0]["verdict"] == "pass"
    stuck = rows[1]
    assert stuck["verdict"] == "error" and stuck["test"] == "test_stuck.py::test_in_c"
    assert "past its time limit of 3 s and never returned to Python" in stuck["error"], stuck
    assert stuck["params"]["gap"] > 0  # the case's parameters, not an empty row
    assert stuck["sim_time_s"] == pytest.approx(3 + GRACE_S + LAST_RESORT_S)
    # what the terminal shows: what happened, and where the process was stuck
    assert "did not return to Python" in out and "its error row is written" in out, out[-3000:]
    assert "in act" in out  # the Python traceback of the stuck thread


@pytest.mark.slow
def test_under_xdist_the_stuck_worker_is_replaced_and_the_case_keeps_its_row(pytester):
    pytester.makepyfile(test_stuck=IN_C)
    proc = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-n", "2",
                           "--avs-db=none", "--avs-report=rep", "--avs-shrink-budget=0"],
                          cwd=pytester.path, capture_output=True, text=True, timeout=180)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 1, out[-3000:]
    rows = {r["item"].split("::")[1]: r for r in _rows(pytester.path)}
    assert sorted(rows) == [f"test_in_c[halton-00{i}]" for i in range(3)], out[-3000:]
    stuck = rows["test_in_c[halton-001]"]
    # the worker's own row, left with the controller before it was killed: the time limit
    # named and the case's parameters, not the generic row of a worker that died
    assert stuck["verdict"] == "error" and stuck["params"]["gap"] > 0, stuck
    assert "past its time limit of 3 s and never returned to Python" in stuck["error"], stuck
    assert [rows[f"test_in_c[halton-00{i}]"]["verdict"] for i in (0, 2)] == ["pass", "pass"]
    assert "replacing crashed worker" in out

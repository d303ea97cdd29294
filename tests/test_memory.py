"""Constant memory per case: nothing of a case outlives its item except its row (issue #35).

A campaign of N cases used to keep every case's simulated world (its road, vehicles and
trajectory) until the end of the run, 0.22 MB per case; a 100,000-case campaign needed ~21 GB.
These runs count, after each item, the worlds and trajectories still alive in the process
and look into the item's stash. Memory numbers (peak RSS at 1k to 100k cases) are in
bench/README.md, "Memory and the end of the run".
"""

from __future__ import annotations

import json

PROBE = """
import gc, json, os, sys
import pytest

LOG = os.environ["AVS_MEMORY_LOG"]


@pytest.hookimpl(wrapper=True)
def pytest_runtest_protocol(item, nextitem):
    result = yield
    from pytest_avscenario.pytest_plugin import stash
    from pytest_avscenario.sim import World
    from pytest_avscenario.trajectory import Trajectory

    # pytest keeps the last failure's exception for post-mortem debugging (one, not per case)
    sys.last_type = sys.last_value = sys.last_traceback = None
    if hasattr(sys, "last_exc"):
        sys.last_exc = None
    gc.collect()
    alive = [type(o).__name__ for o in gc.get_objects() if isinstance(o, (World, Trajectory))]
    kept = [name for name, key in (("result", stash.result_key), ("row", stash.row_key))
            if key in item.stash]
    with open(LOG, "a") as f:
        f.write(json.dumps({"item": item.nodeid, "alive": alive, "stash": kept}) + "\\n")
    return result
"""

SCENARIO = """
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import collision, distance


@scenario(gap=Uniform(6.0, 30.0), lead_speed=Uniform(0.0, 8.0), samples=8,
          sampler=["halton", "mab"], monitors=[distance(5.0), collision()])
def test_follow(case, world):
    road = world.straight_road(lanes=1, length=200)
    world.ego(road.lane(0), s=10.0, speed=10.0)
    world.car(road.lane(0), s=10.0 + case.gap, speed=case.lead_speed)
    world.run(seconds=2)
    assert case.gap > 8.0  # the body's own failure too: its frames hold the world
"""


def test_no_world_or_trajectory_outlives_its_item(pytester, monkeypatch):
    """Passing, violating and asserting cases, a passive and an active sampler (whose earlier
    cases may be simulated ahead of their items), failures minimized and drawn into a report:
    after each item no world or trajectory of any case is alive, and the item's stash no longer
    holds its outcome or its sent row; every row still reaches the error table."""
    log = pytester.path / "memory.jsonl"
    monkeypatch.setenv("AVS_MEMORY_LOG", str(log))
    pytester.makeconftest(PROBE)
    pytester.makepyfile(test_follow=SCENARIO)
    # in a subprocess: an in-process run records every hook call (and so every case's frames)
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider", "--avs-seed=2", "--avs-db=none",
                                "--avs-shrink-budget=2", "--avs-report=rep", "-q", "-k", "not mab-000")  # case 0 is simulated ahead
    outcomes = result.parseoutcomes()
    assert outcomes.get("failed", 0) >= 2 and outcomes.get("passed", 0) >= 3, result.outlines
    entries = [json.loads(line) for line in log.read_text().splitlines()]
    assert len(entries) == 15
    assert [e for e in entries if e["alive"]] == [], "worlds or trajectories outlived their items"
    assert [e for e in entries if e["stash"]] == []
    # one case left out: a re-run, reported in rep/rerun
    rows = (pytester.path / "rep" / "rerun" / "errors.jsonl").read_text().splitlines()
    assert len([r for r in rows if json.loads(r)["origin"] != "shrink"]) == 15
    # the failures' pictures are still drawn (before the world goes)
    assert list((pytester.path / "rep" / "rerun" / "cases").glob("*.moment.png"))


TERMINAL_PROBE = """
import json, os
import pytest


@pytest.hookimpl(trylast=True)
def pytest_terminal_summary(terminalreporter):
    kept = {key: sorted({(r.nodeid.partition("[")[0].rpartition("::")[2], r.when) for r in reports
                         if hasattr(r, "when")})
            for key, reports in terminalreporter.stats.items()}
    with open(os.environ["AVS_TERMINAL_LOG"], "w") as f:
        json.dump(kept, f)
"""

QUIET = """
import pytest
from pytest_avscenario import scenario, Uniform


@pytest.fixture
def noisy():
    yield
    print("teardown output of a fixture")


@scenario(x=Uniform(0.0, 1.0), samples=6, sampler="halton")
def test_quiet(case):
    assert case.x < 0.5


@scenario(x=Uniform(0.0, 1.0), samples=4, sampler="halton")
def test_noisy(case, noisy):
    assert case.x < 0.5


def test_plain():
    pass
"""


def test_terminal_reporter_forgets_quiet_setup_and_teardown_reports(pytester, monkeypatch):
    """pytest's terminal reporter kept three reports per item to the end of the run; a
    scenario case's passed setup and teardown, once handled, are forgotten unless its
    teardown printed something, which the failures summary still shows under each failure."""
    log = pytester.path / "terminal.json"
    monkeypatch.setenv("AVS_TERMINAL_LOG", str(log))
    pytester.makepyfile(avs_terminal_probe=TERMINAL_PROBE, test_quiet=QUIET)
    monkeypatch.syspath_prepend(pytester.path)
    result = pytester.runpytest("-p", "avs_terminal_probe", "--avs-report=none", "--avs-db=none",
                                "--avs-shrink-budget=0", "-p", "no:cacheprovider")
    result.assert_outcomes(passed=6, failed=5)
    kept = json.loads(log.read_text())
    # the plain test keeps its setup and teardown; the quiet campaign keeps neither; the
    # noisy one keeps its teardowns (their output), not its setups
    assert kept[""] == [["test_noisy", "teardown"], ["test_plain", "setup"],
                                            ["test_plain", "teardown"]]
    assert kept["failed"] == [["test_noisy", "call"], ["test_quiet", "call"]]
    assert kept["passed"] == [["test_noisy", "call"], ["test_plain", "call"],
                                                  ["test_quiet", "call"]]
    # each failure of the noisy campaign still shows its teardown's output in the summary
    out = result.stdout.str()
    assert out.count("Captured stdout teardown") == 2, out

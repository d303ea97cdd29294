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


KEPT_PROBE = """
import json, os, sys, types
import pytest

_seen = {}
_copies = []  # alive to the end: a copy's id must not be reused


def _size(obj, seen):
    # the bytes of obj and what it holds that no earlier case's objects hold already
    if id(obj) in seen or obj is None or type(obj) in (bool, int) and -5 <= obj <= 256:
        return 0
    seen.add(id(obj))
    size = sys.getsizeof(obj)
    if isinstance(obj, types.MappingProxyType):  # and the dict it shows
        _copies.append(dict(obj))
        size += _size(_copies[-1], seen)
    elif isinstance(obj, dict):
        size += sum(_size(k, seen) + _size(v, seen) for k, v in obj.items())
    elif isinstance(obj, (list, tuple, set, frozenset)):
        size += sum(_size(v, seen) for v in obj)
    elif hasattr(obj, "__slots__") and not isinstance(obj, type):
        size += sum(_size(getattr(obj, s, None), seen) for c in type(obj).__mro__
                    for s in getattr(c, "__slots__", ()) if isinstance(s, str))
    elif hasattr(obj, "__dict__") and not isinstance(obj, type):
        size += _size(obj.__dict__, seen)
    return size


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_logreport(report):
    if report.when == "call":  # what every plugin sees while it handles the report
        _seen[report.nodeid] = sorted(report.keywords)


@pytest.hookimpl(trylast=True)
def pytest_terminal_summary(terminalreporter, config):
    from pytest_avscenario.pytest_plugin.stash import controller_key

    # what a case of the second half adds, beyond what the first half's cases share with it
    kept = [r for reps in terminalreporter.stats.values() for r in reps
            if getattr(r, "when", None) == "call" and "::test_many[" in r.nodeid]
    rows = {r.item: r for r in config.stash[controller_key].rows}
    kept.sort(key=lambda r: r.nodeid)
    seen = set()
    for r in kept[: len(kept) // 2]:
        _size(r, seen), _size(rows[r.nodeid], seen)
    late = kept[len(kept) // 2:]
    # the strings of the item (its node id, name, parameter id) are the item's, kept anyway
    for r in late:
        seen.update({id(r.nodeid), id(r.location), id(r.location[2])})
        if hasattr(r, "id"):  # pytest >= 9.2: the item's structured node id, which it shares
            seen.add(id(r.id))
    passed = [r for r in late if r.passed]  # a failure's longrepr is what pytest shows of it
    report_bytes = sum(_size(r, seen) for r in passed) / len(passed)
    row_bytes = sum(_size(rows[r.nodeid], seen) for r in late) / len(late)
    with open(os.environ["AVS_KEPT_LOG"], "w") as f:
        json.dump({"report_bytes": report_bytes, "row_bytes": row_bytes,
                   "keywords_same": all(sorted(r.keywords) == _seen[r.nodeid] for r in kept),
                   "params": [dict(rows[r.nodeid].params) for r in kept[:2]]}, f)
"""

MANY = """
from pytest_avscenario import scenario, Uniform


@scenario(x=Uniform(0.0, 1.0), y=Uniform(0.0, 1.0), samples=40, sampler="halton")
def test_many(case):
    assert case.x < 0.7


def test_plain():
    pass
"""


def test_what_stays_of_a_case_is_small_and_reads_the_same(pytester, monkeypatch):
    """pytest's terminal reporter keeps every case's call report and the controller every
    row to the end of the run: per case, a report keeps no keywords dict, sections or
    property lists of its own and a row's parameters and ρ no dict of their own (a passed
    case's report and row: 1.5 KB before, 0.9 KB now). What pytest and a user read from them is the same: the keywords, the
    summary line, ``-rA``, JUnit, ``--lf`` and the rows' parameters."""
    log = pytester.path / "kept.json"
    monkeypatch.setenv("AVS_KEPT_LOG", str(log))
    pytester.makepyfile(avs_kept_probe=KEPT_PROBE, test_many=MANY)
    monkeypatch.syspath_prepend(pytester.path)
    result = pytester.runpytest("-p", "avs_kept_probe", "--avs-report=rep", "--avs-db=none",
                                "--avs-shrink-budget=0", "--avs-seed=3", "-rA", "--junitxml=j.xml")
    result.assert_outcomes(passed=30, failed=11)
    kept = json.loads(log.read_text())
    assert kept["keywords_same"]
    assert kept["report_bytes"] < 500, kept  # 835 bytes before (384 now)
    assert kept["row_bytes"] < 600, kept  # 696 bytes before (520 now)
    assert kept["params"][0] == {"x": 0.5, "y": 1 / 3}
    out = result.stdout.str()
    assert out.count("PASSED test_many.py::test_many[halton-") == 29
    assert out.count("FAILED test_many.py::test_many[halton-") == 11
    result.stdout.fnmatch_lines(["*11 failed, 30 passed*"])
    from xml.etree import ElementTree

    suite = ElementTree.parse(pytester.path / "j.xml").getroot().find("testsuite")
    assert (suite.get("tests"), suite.get("failures")) == ("41", "11")
    again = pytester.runpytest("--lf", "--avs-report=none", "--avs-db=none", "--avs-shrink-budget=0",
                               "--avs-seed=3", "-q")
    again.assert_outcomes(failed=11)


ITEMS_PROBE = """
import json
import os

import pytest


_collected = {}


def pytest_collection_finish(session):
    for item in session.items:
        _collected[item.nodeid] = sorted((k, repr(v)) for k, v in item.keywords.items())


@pytest.hookimpl(trylast=True)
def pytest_terminal_summary(terminalreporter, config):
    items = terminalreporter._session.items
    out = {"keywords_same": all(sorted((k, repr(v)) for k, v in item.keywords.items()) == _collected[item.nodeid]
                                for item in items)}
    for item in items:
        out[item.name] = {
            "stash": len(item.stash._storage),
            "extra": len(item.extra_keyword_matches),
            "lists": [type(item._report_sections).__name__, type(item.user_properties).__name__],
            "slot": None if not hasattr(item, "callspec") else repr(item.callspec.params.get("case")),
            "keywords": sorted(item.keywords)[:2],
            "keywords_kind": type(item.keywords).__name__,
            "location": list(item.location),
        }
    with open(os.environ["AVS_ITEMS_LOG"], "w") as f:
        json.dump(out, f)
"""


def test_a_finished_cases_item_keeps_nothing_of_its_run(pytester, monkeypatch):
    """``session.items`` holds every item to the end of the run: once a scenario case's
    protocol has ended, its item keeps no stash entries, no case slot (the row holds its
    parameters) and no lists of its own; its name, keywords and location read the same.
    A plain test's item is left as pytest made it."""
    log = pytester.path / "items.json"
    monkeypatch.setenv("AVS_ITEMS_LOG", str(log))
    pytester.makepyfile(avs_items_probe=ITEMS_PROBE, test_many=MANY)
    monkeypatch.syspath_prepend(pytester.path)
    result = pytester.runpytest("-p", "avs_items_probe", "--avs-report=none", "--avs-db=none",
                                "--avs-shrink-budget=0", "--avs-seed=3")
    result.assert_outcomes(passed=30, failed=11)
    items = json.loads(log.read_text())
    assert items.pop("keywords_same")
    cases = [v for k, v in items.items() if k.startswith("test_many[")]
    assert len(cases) == 40
    assert all(c["stash"] == 0 and c["extra"] == 0 and c["slot"] == "None" and c["lists"][1] == "tuple"
               and c["keywords_kind"] != "NodeKeywords" for c in cases), cases[0]
    # a passed case printed nothing: no section list either (a failure's sections stay)
    assert sum(c["lists"][0] == "tuple" for c in cases) >= 29
    assert items["test_many[halton-005]"]["location"][2] == "test_many[halton-005]"
    assert "halton-005" in items["test_many[halton-005]"]["keywords"] or \
        "halton-005" in str(items["test_many[halton-005]"])
    plain = items["test_plain"]
    assert plain["slot"] is None and plain["lists"] == ["list", "list"] and plain["stash"] > 0
    assert plain["keywords_kind"] == "NodeKeywords"
    # a re-run of the failed cases (pytest's cache, written at the end) and -k still select them
    again = pytester.runpytest("--lf", "--avs-report=none", "--avs-db=none", "--avs-shrink-budget=0",
                               "--avs-seed=3", "-q")
    again.assert_outcomes(failed=11)
    picked = pytester.runpytest("-k", "halton-005", "--avs-report=none", "--avs-db=none",
                                "--avs-shrink-budget=0", "--avs-seed=3", "-q")
    picked.assert_outcomes(passed=1)


WORKER_PROBE = """
import json
import os

import pytest


@pytest.hookimpl(trylast=True)
def pytest_sessionfinish(session):
    worker = getattr(session.config, "workerinput", None)
    if worker is None:
        return
    tr = session.config.pluginmanager.get_plugin("terminalreporter")
    kept = [r for reports in tr.stats.values() for r in reports
            if getattr(r, "when", None) == "call" and "test_many[" in r.nodeid]
    out = {"kept": len(kept),
           "with_row": sum(getattr(r, "avs_row", None) is not None for r in kept),
           "with_avs_properties": sum(any(str(n).startswith("avs.") for n, _ in r.user_properties)
                                      for r in kept),
           "keywords_kinds": sorted({type(r.keywords).__name__ for r in kept})}
    with open(os.path.join(os.environ["AVS_WORKER_LOG"], worker["workerid"] + ".json"), "w") as f:
        json.dump(out, f)
"""


def test_an_xdist_workers_kept_reports_are_made_small_after_they_are_sent(pytester, monkeypatch):
    """An xdist worker's terminal reporter keeps every report of its cases to the end of the
    run too (100,000 cases under ``-n 2``: ~3.5 KB a case, each worker 594 MB): once xdist has
    sent a report, the worker's copy keeps no row and no case properties and its keywords are
    the shared view. What crossed to the controller is whole: its JUnit has the cases'
    ``avs.*`` properties, its summary and ``-rA`` the outcomes."""
    monkeypatch.setenv("AVS_WORKER_LOG", str(pytester.path))
    pytester.makepyfile(avs_worker_probe=WORKER_PROBE, test_many=MANY)
    monkeypatch.syspath_prepend(pytester.path)
    result = pytester.runpytest_subprocess("-p", "avs_worker_probe", "-n", "2", "--avs-report=rep",
                                           "--avs-db=none", "--avs-shrink-budget=0", "--avs-seed=3",
                                           "-rA", "--junitxml=j.xml")
    result.assert_outcomes(passed=30, failed=11)
    logs = [json.loads((pytester.path / f"gw{i}.json").read_text()) for i in range(2)]
    assert sum(log["kept"] for log in logs) == 40, logs
    assert all(log["with_row"] == 0 and log["with_avs_properties"] == 0 for log in logs), logs
    assert all(log["keywords_kinds"] == ["CaseKeywords"] for log in logs if log["kept"]), logs
    assert result.stdout.str().count("FAILED test_many.py::test_many[halton-") == 11
    xml = (pytester.path / "j.xml").read_text()
    assert xml.count('<property name="avs.') >= 40, xml[:2000]

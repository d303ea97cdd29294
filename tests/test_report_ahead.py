"""Under xdist a finished test's plots and ε-coverage are made while other tests still run
(report.ahead), and they are the serial run's: the same pictures, byte for byte, the same ε."""

import json
import re

import pytest

QUICK = """
from pytest_avscenario import Choice, Uniform, scenario


@scenario(x=Uniform(0.0, 1.0, unit="m"), y=Uniform(0.0, 1.0), c=Choice(["a", "b", "c"]),
          samples=12, sampler=["halton", "random"])
def test_one(case):
    assert case.x < 0.7


@scenario(x=Uniform(0.0, 1.0), y=Uniform(0.0, 1.0, unit="s"), samples=8, sampler="halton")
def test_two(case):
    assert case.x + case.y < 1.5
"""

# runs on the other worker (--dist loadfile): its one case waits for test_one's plot, which
# a run that draws every plot after the last case would only make once this case had ended
WAITS = """
import time
from pathlib import Path

from pytest_avscenario import Uniform, scenario
from pytest_avscenario.report.plots import plot_paths


@scenario(x=Uniform(0.0, 1.0), samples=1, sampler="halton")
def test_waits(case):
    plot = plot_paths(Path("parallel").resolve(), "test_quick.py::test_one")["space"]
    for _ in range(900):
        if plot.exists():
            return
        time.sleep(0.1)
    raise AssertionError(f"{plot} was not drawn while this case ran")
"""


def test_a_finished_tests_plots_are_drawn_while_others_run_and_equal_the_serial_runs(pytester):
    pytest.importorskip("xdist")
    pytester.makepyfile(test_quick=QUICK)
    serial = pytester.runpytest_subprocess("test_quick.py", "-p", "no:xdist", "--avs-seed=4", "--avs-db=none",
                                           "--avs-report=serial")
    serial.assert_outcomes(passed=24, failed=8)
    pytester.makepyfile(test_waits=WAITS)
    parallel = pytester.runpytest_subprocess("-n", "2", "--dist", "loadfile", "--avs-seed=4", "--avs-db=none",
                                             "--avs-report=parallel")
    parallel.assert_outcomes(passed=25, failed=8)

    plots = sorted(p.name for p in (pytester.path / "serial" / "plots").iterdir())
    assert len(plots) == 2 and all(p.endswith(".space.png") for p in plots)  # no metrics: no ρ plot
    for name in plots:
        assert (pytester.path / "parallel" / "plots" / name).read_bytes() == \
            (pytester.path / "serial" / "plots" / name).read_bytes(), name

    def coverage(folder):
        tests = json.loads((pytester.path / folder / "summary.json").read_text())["tests"]
        return {(t["test"], t["sampler"]): (t["epsilon"], t["covering_radius"], t["fraction_within"])
                for t in tests if t["test"].startswith("test_quick.py")}

    assert coverage("parallel") == coverage("serial")
    assert len(coverage("serial")) == 3 and all(v[0] is not None for v in coverage("serial").values())
    index = (pytester.path / "parallel" / "index.html").read_text()
    assert all(f"plots/{name}" in index for name in plots)


def _rows(n, test="t.py::test_x"):
    from pytest_avscenario.outcome import CaseRow

    return [CaseRow(test=test, item=f"{test}[halton-{i:03d}]", sampler="halton", index=i, seed=i,
                    origin="sampled", params={"gap": (i * 0.37) % 1 * 30, "speed": (i * 0.61) % 1 * 10},
                    rho={"distance": (i * 0.37) % 1 - 0.3}, verdict="fail" if (i * 0.37) % 1 < 0.3 else "pass")
            for i in range(n)]


def _table(directory, rows):
    """The error table a run writes, holding ``rows`` (the helpers read a test's rows there)."""
    from pytest_avscenario.report.table import ErrorTable

    table = ErrorTable(directory)
    for row in rows:
        table.append(row)
    table.close()


def test_the_helpers_plots_and_coverage_are_those_made_here_and_taken_for_the_same_rows_only(tmp_path):
    from pytest_avscenario import Uniform
    from pytest_avscenario.report.ahead import ReportAhead
    from pytest_avscenario.report.plots import plot_test
    from pytest_avscenario.report.summary import campaign_coverage
    from pytest_avscenario.space import FeatureSpace

    space = FeatureSpace({"gap": Uniform(0.0, 30.0, unit="m"), "speed": Uniform(0.0, 10.0)})
    info = {"metrics": ["distance"], "space": space.describe()}
    rows = _rows(25)
    _table(tmp_path / "ahead", rows[:10] + _rows(5, test="t.py::test_other") + rows[10:])
    ahead = ReportAhead(tmp_path / "ahead", 1)
    try:
        paths = ahead.submit("t.py::test_x", rows, info)
        assert sorted(p.name for p in paths) == sorted(p.name for p in ahead.plots("t.py::test_x", rows, info).values())
        here = plot_test(tmp_path / "here", "t.py::test_x", rows, metrics=("distance",), units={"gap": "m"})
        made = ahead.plots("t.py::test_x", rows, info)
        assert set(made) == set(here) == {"space", "rho"}
        assert all(made[k].read_bytes() == here[k].read_bytes() for k in here)
        assert ahead.coverage("t.py::test_x", "halton", rows, info) == campaign_coverage(rows, space)
        # not the rows it was made from (a row more, or another order), or another declaration:
        # made again at the end
        assert ahead.plots("t.py::test_x", _rows(26), info) is None
        assert ahead.plots("t.py::test_x", rows[::-1], info) is None
        assert ahead.coverage("t.py::test_x", "halton", rows[:-1], info) is None
        assert ahead.plots("t.py::test_x", rows, dict(info)) is None
        assert ahead.plots("t.py::test_other", rows, info) is None
    finally:
        ahead.close()


def test_the_helpers_failure_modes_are_those_made_here_and_taken_for_the_same_rows_and_order_only(tmp_path):
    # a campaign's failure modes are the largest part of the end of a run of many
    # counterexamples: the helper makes them with the campaign's ε, from the error table
    from pytest_avscenario import Uniform
    from pytest_avscenario.report.ahead import ReportAhead
    from pytest_avscenario.report.modes import failure_modes
    from pytest_avscenario.space import FeatureSpace

    space = FeatureSpace({"gap": Uniform(0.0, 30.0, unit="m"), "speed": Uniform(0.0, 10.0)})
    info = {"metrics": ["distance"], "space": space.describe()}
    rows = _rows(60)
    _table(tmp_path, rows[:10] + _rows(5, test="t.py::test_other") + rows[10:])
    ahead = ReportAhead(tmp_path, 1)
    try:
        ahead.submit("t.py::test_x", rows, info)
        made = ahead.modes("t.py::test_x", "halton", rows, ("distance",), info)
        here = tuple(failure_modes(rows, space, ["distance"]))
        assert made == here and len(here) >= 1 and sum(m.count for m in here) == sum(r.verdict == "fail" for r in rows)
        # not the rows, the metric order or the declaration it was made from: made again at the end
        assert ahead.modes("t.py::test_x", "halton", rows[::-1], ("distance",), info) is None
        assert ahead.modes("t.py::test_x", "halton", rows[:-1], ("distance",), info) is None
        assert ahead.modes("t.py::test_x", "halton", rows, ("other", "distance"), info) is None
        assert ahead.modes("t.py::test_x", "halton", rows, ("distance",), dict(info)) is None
        assert ahead.modes("t.py::test_x", "random", rows, ("distance",), info) is None
    finally:
        ahead.close()


def test_what_the_helpers_made_from_other_rows_than_this_process_holds_is_made_again(tmp_path):
    # the error table lost a row (a full disk) or holds one this process does not (a row
    # written from outside it): the helper's plots and ε are not those of these rows
    from pytest_avscenario import Uniform
    from pytest_avscenario.report.ahead import ReportAhead
    from pytest_avscenario.space import FeatureSpace

    info = {"metrics": ["distance"], "space": FeatureSpace({"gap": Uniform(0.0, 30.0), "speed": Uniform(0.0, 10.0)}).describe()}
    rows = _rows(25)
    _table(tmp_path / "ahead", rows[:-1])
    ahead = ReportAhead(tmp_path / "ahead", 1)
    try:
        ahead.submit("t.py::test_x", rows, info)
        assert ahead.plots("t.py::test_x", rows, info) is None
        assert ahead.coverage("t.py::test_x", "halton", rows, info) is None
    finally:
        ahead.close()


def test_a_line_still_being_written_is_not_read(tmp_path):
    from pytest_avscenario.report.ahead import table_rows

    rows = _rows(3)
    _table(tmp_path, rows)
    with open(tmp_path / "errors.jsonl", "a", encoding="utf-8") as fh:
        fh.write('{"test": "t.py::test_x", "item": "t.py::test_x[halton-0')
    assert [d["item"] for d in table_rows(tmp_path / "errors.jsonl", "t.py::test_x")] == [r.item for r in rows]


def test_cancelled_helpers_end_at_once(tmp_path):
    from pytest_avscenario.report.ahead import ReportAhead

    _table(tmp_path, _rows(400))
    ahead = ReportAhead(tmp_path, 1)
    ahead.submit("t.py::test_x", _rows(400), {"metrics": ["distance"], "space": {}})
    processes = list(ahead._pool._processes.values())
    paths = ahead.cancel()
    assert len(paths) == 2 and all(not p.is_alive() for p in processes)


SERIAL_CONFTEST = """
import os
import sys

from pytest_avscenario.pytest_plugin import controller

if os.environ.get("AVS_TEST_SERIAL_AHEAD"):
    controller.SERIAL_AHEAD_MIN_ROWS = 1


def pytest_unconfigure(config):
    with open(os.environ["AVS_TEST_MODULES"], "w") as fh:
        fh.write(" ".join(m for m in ("matplotlib", "scipy") if m in sys.modules))
"""


def test_a_large_serial_run_draws_in_a_helper_and_its_report_is_the_same(pytester, monkeypatch):
    # a serial run of many cases (here: a threshold of one row) makes its plots and ε in a
    # helper process: the pytest process never imports matplotlib or scipy, and every file
    # of the report is the one drawn in the pytest process, byte for byte
    pytester.makepyfile(test_quick=QUICK)
    pytester.makeconftest(SERIAL_CONFTEST)
    outs = {}
    for name, helper in (("here", ""), ("helper", "1")):
        monkeypatch.setenv("AVS_TEST_SERIAL_AHEAD", helper)
        monkeypatch.setenv("AVS_TEST_MODULES", str(pytester.path / f"{name}.modules"))
        run = pytester.runpytest_subprocess("-p", "no:xdist", "--avs-seed=4", "--avs-db=none", "--avs-shrink-budget=0",
                                           f"--avs-report={name}")
        run.assert_outcomes(passed=24, failed=8)
        outs[name] = (pytester.path / f"{name}.modules").read_text().split()
    assert outs == {"here": ["matplotlib", "scipy"], "helper": []}

    def files(folder):
        root = pytester.path / folder
        return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
                if p.is_file() and p.suffix in (".json", ".html", ".png") and not p.name.startswith(".")}

    def timeless(data):  # the cases' measured simulation times differ from run to run
        if isinstance(data, dict):
            return {k: timeless(v) for k, v in data.items() if k != "sim_time_s"}
        return [timeless(v) for v in data] if isinstance(data, list) else data

    here, helper = files("here"), files("helper")
    assert sorted(here) == sorted(helper)
    for files_ in (here, helper):
        files_["summary.json"] = timeless(json.loads(files_["summary.json"]))
        for name in [n for n in files_ if n.endswith(".html")]:
            files_[name] = re.sub(rb"simulated in [0-9.]+ s", b"simulated in - s", files_[name])
    assert sum(name.endswith(".space.png") for name in here) == 2 and "summary.json" in here
    assert [name for name in here if here[name] != helper[name]] == []

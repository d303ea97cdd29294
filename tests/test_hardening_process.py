"""Issue #32: the process family — os._exit in a body, Ctrl-C while the report is written, a
body that forks, and what an interrupted run's summary and exit status say. Every run here is
a real subprocess, bounded in time, and leaves no process behind."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys

import pytest

from test_stopping import ctrl_c_as_at_a_terminal, junit_cases, rows_of, start, wait_for_rows

FOUR = """
import os
from pytest_avscenario import scenario, Uniform

@scenario(x=Uniform(0, 1), samples=4, sampler="halton")
def test_x(case):
    {body}
"""


@pytest.mark.parametrize("status", [0, 3])
def test_os_exit_in_a_body_stops_the_run_as_interrupted_with_its_row_and_report(pytester, status):
    # serially, os._exit(0) in case 1 ended the process: exit 0, 1 of 4 rows, no JUnit file
    pytester.makepyfile(FOUR.format(body=f"if case.index == 1:\n        os._exit({status})"))
    result = pytester.runpytest_subprocess("--avs-db=none", "-p", "no:xdist", "-p", "no:cacheprovider",
                                           "--junitxml=out.xml", timeout=120)
    assert result.ret == pytest.ExitCode.INTERRUPTED
    rows = rows_of(pytester.path)
    # the case that called it is an error row saying so; the run stopped after it
    assert [r["verdict"] for r in rows] == ["pass", "error"]
    assert f"os._exit({status}) called" in rows[1]["error"]
    assert junit_cases(pytester.path / "out.xml") == 2
    summary = json.loads((pytester.path / "avs-report" / "summary.json").read_text())
    assert summary["interrupted"] is True and "os._exit" in summary["stopped"]
    assert summary["tests"][0]["samples"] == 2


MIXED = """
import os
from pytest_avscenario import scenario, Uniform

@scenario(x=Uniform(0, 1), samples=3, sampler="halton")
def test_a(case):
    pass

def test_plain():
    {body}

@scenario(y=Uniform(0, 1), samples=3, sampler="halton")
def test_b(case):
    pass
"""


def test_os_exit_in_a_plain_test_beside_scenario_tests_stops_the_run_as_interrupted(pytester):
    # serially, os._exit(0) in a plain test ended the process: exit 0, 3 of 6 rows, no JUnit file
    pytester.makepyfile(MIXED.format(body="os._exit(0)"))
    result = pytester.runpytest_subprocess("--avs-db=none", "-p", "no:xdist", "-p", "no:cacheprovider",
                                           "--junitxml=out.xml", timeout=120)
    assert result.ret == pytest.ExitCode.INTERRUPTED
    assert [r["item"].rpartition("::")[2] for r in rows_of(pytester.path)] == [
        "test_a[halton-000]", "test_a[halton-001]", "test_a[halton-002]"]
    assert junit_cases(pytester.path / "out.xml") == 4  # the plain test's failure included
    result.stdout.fnmatch_lines(["*os._exit(0) called while the test ran*",
                                 "*Interrupted: os._exit(0) called in test_*.py::test_plain*"])
    summary = json.loads((pytester.path / "avs-report" / "summary.json").read_text())
    assert summary["interrupted"] is True and "os._exit" in summary["stopped"]


def test_without_scenario_tests_os_exit_is_left_alone(pytester):
    pytester.makepyfile("import os\n\ndef test_plain():\n    os._exit(5)\n")
    result = pytester.runpytest_subprocess("-p", "no:xdist", "-p", "no:cacheprovider", timeout=120)
    assert result.ret == 5


@pytest.mark.parametrize("xdist", [False, True], ids=["serial", "xdist"])
def test_a_forked_child_that_returns_into_pytest_writes_no_rows_and_runs_nothing_more(pytester, xdist):
    # a body that forks and lets the child return gave 7 rows for 4 items; under -n 2, 5 rows
    # and 5 "passed" (the child sent its item's setup report through the worker's channel)
    pytester.makepyfile(FOUR.format(body="""if case.index == 1:
        pid = os.fork()
        if pid:
            os.waitpid(pid, 0)"""))
    result = pytester.runpytest_subprocess("--avs-db=none", *(("-n", "2") if xdist else ("-p", "no:xdist")),
                                           "-p", "no:cacheprovider", "--junitxml=out.xml", timeout=120)
    assert result.ret == pytest.ExitCode.OK
    result.assert_outcomes(passed=4)
    rows = rows_of(pytester.path)
    assert sorted(r["index"] for r in rows) == [0, 1, 2, 3]
    assert junit_cases(pytester.path / "out.xml") == 4
    if not xdist:  # an xdist worker's stderr is its own
        assert "returned into pytest; it is ended here" in result.stderr.str()


def test_a_forked_child_may_still_end_itself_with_os_exit(pytester):
    pytester.makepyfile(FOUR.format(body="""pid = os.fork()
    if pid == 0:
        os._exit(7)
    assert os.waitpid(pid, 0)[1] >> 8 == 7"""))
    result = pytester.runpytest_subprocess("--avs-db=none", "-p", "no:xdist", "-p", "no:cacheprovider",
                                           timeout=120)
    result.assert_outcomes(passed=4)
    assert len(rows_of(pytester.path)) == 4


@pytest.mark.parametrize("xdist", [[], ["-n", "2"]], ids=["serial", "xdist"])
def test_ctrl_c_while_the_report_is_written_finishes_the_report(pytester, xdist):
    # a raw traceback, no summary.json, no index.html, no JUnit file (SIGTERM worked)
    if xdist:
        pytest.importorskip("xdist")
    pytester.makeconftest("""
import os
import signal
import pytest

@pytest.hookimpl(wrapper=True)
def pytest_sessionfinish(session):
    if not hasattr(session.config, "workerinput"):
        os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C as the report is being built
    return (yield)
""")
    pytester.makepyfile(FOUR.format(body="assert case.x < 0.6"))
    args = xdist or ["-p", "no:xdist"]
    result = pytester.runpytest_subprocess("--avs-db=none", "-p", "no:cacheprovider", *args,
                                           "--junitxml=out.xml", timeout=120)
    assert result.ret == pytest.ExitCode.INTERRUPTED
    assert "Traceback" not in result.stdout.str() + result.stderr.str()
    report = pytester.path / "avs-report"
    summary = json.loads((report / "summary.json").read_text())
    assert summary["tests"][0]["samples"] == 4
    assert (report / "index.html").exists() and junit_cases(pytester.path / "out.xml") == 4


def test_ctrl_c_while_the_report_helper_draws_finishes_the_report(pytester):
    # a large serial run (here: from one row on) draws its plots in a helper process; a
    # Ctrl-C while the pytest process writes the cards ends the run as it ends one that draws
    # in process: status 2, no traceback, the report and JUnit written, the plot the helper drew
    pytester.makeconftest("""
import os
import signal
import sys

from pytest_avscenario.pytest_plugin import controller

controller.SERIAL_AHEAD_MIN_ROWS = 1
_sent = []


def pytest_avscenario_card_sections(config, row):
    if not _sent:  # Ctrl-C while the report is written, the helper at work
        _sent.append(1)
        os.kill(os.getpid(), signal.SIGINT)
    return []


def pytest_unconfigure(config):
    with open("modules.txt", "w") as fh:
        fh.write(" ".join(m for m in ("matplotlib", "scipy") if m in sys.modules))
""")
    pytester.makepyfile(FOUR.format(body="assert case.x < 0.6"))
    result = pytester.runpytest_subprocess("--avs-db=none", "-p", "no:cacheprovider", "-p", "no:xdist",
                                           "--junitxml=out.xml", timeout=120)
    assert result.ret == pytest.ExitCode.INTERRUPTED
    assert "Traceback" not in result.stdout.str() + result.stderr.str()
    assert (pytester.path / "modules.txt").read_text() == ""  # drawn by the helper
    report = pytester.path / "avs-report"
    assert json.loads((report / "summary.json").read_text())["tests"][0]["samples"] == 4
    assert (report / "index.html").exists() and junit_cases(pytester.path / "out.xml") == 4
    assert len(list((report / "plots").glob("*.space.png"))) == 1


def test_an_interrupted_run_says_so_and_never_exits_0(pytester):
    # a run stopped after its first case (pytest.exit with status 0, as a CI step might)
    # wrote "accepted" and no mark that most cases never ran
    pytester.makepyfile(FOUR.format(body="""if case.index == 1:
        import pytest
        pytest.exit("enough", returncode=0)"""))
    result = pytester.runpytest_subprocess("--avs-db=none", "-p", "no:xdist", "-p", "no:cacheprovider",
                                           timeout=120)
    assert result.ret == pytest.ExitCode.INTERRUPTED
    summary = json.loads((pytester.path / "avs-report" / "summary.json").read_text())
    assert summary["interrupted"] is True and "enough" in summary["stopped"]
    # ...and that summary is no baseline unless asked for
    again = pytester.runpytest_subprocess("--avs-db=none", "-p", "no:xdist", "-p", "no:cacheprovider",
                                          "--avs-baseline=avs-report/summary.json", "--avs-report=two",
                                          timeout=120)
    assert again.ret == pytest.ExitCode.USAGE_ERROR
    assert "interrupted" in again.stderr.str()


def test_a_finished_run_is_not_marked_interrupted(pytester):
    pytester.makepyfile(FOUR.format(body="pass"))
    result = pytester.runpytest_subprocess("--avs-db=none", "-p", "no:xdist", "-p", "no:cacheprovider",
                                           timeout=120)
    assert result.ret == pytest.ExitCode.OK
    assert "interrupted" not in json.loads((pytester.path / "avs-report" / "summary.json").read_text())


def test_sigterm_to_a_campaign_writes_a_report_without_pictures_marked_interrupted(pytester):
    # the stop at scale (#32 item 6; speed in bench/bench_stop.py): an interrupted run's report
    # keeps summary.json, index.html and the error table and leaves the pictures out
    pytester.makepyfile("""
import time
from pytest_avscenario import scenario, Uniform

@scenario(x=Uniform(0, 1), samples=300, sampler="halton")
def test_many(case):
    time.sleep(0.02)
""")
    proc = start(pytester, "-p", "no:xdist", "--avs-db=none", "--junitxml=out.xml")
    try:
        wait_for_rows(pytester, proc, 20)
        proc.send_signal(signal.SIGTERM)
        out = proc.communicate(timeout=60)[0].decode()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == pytest.ExitCode.INTERRUPTED, out
    report = pytester.path / "avs-report"
    summary = json.loads((report / "summary.json").read_text())
    assert summary["interrupted"] is True and "SIGTERM" in summary["stopped"]
    assert summary["tests"][0]["samples"] == len(rows_of(pytester.path)) == junit_cases(pytester.path / "out.xml")
    assert (report / "index.html").exists() and not list(report.rglob("*.png"))


def test_the_space_plot_scales_its_axis_once_not_per_value(monkeypatch):
    # the O(n²) behind a 108 s stop at 32,210 rows: every value divided by a scale computed
    # again from all values
    from types import SimpleNamespace

    from pytest_avscenario.report import plots

    calls = []
    real = plots._axis_scale
    monkeypatch.setattr(plots, "_axis_scale", lambda numbers: calls.append(1) or real(numbers))
    rows = [SimpleNamespace(params={"x": i / 1000, "w": f"c{i % 3}"}) for i in range(1000)]
    values, labels = plots._axis_values(rows, "x")
    assert len(calls) == 1 and labels is None and values[500] == 0.5
    values, labels = plots._axis_values(rows, "w")
    assert labels == ["c0", "c1", "c2"] and [round(v) for v in values[:3]] == [0, 1, 2]


MANY_SLEEPING = """
import time
from pytest_avscenario import scenario, Uniform

@scenario(x=Uniform(0, 1), samples=300, sampler="halton")
def test_many(case):
    time.sleep(0.05)
"""

# which processes were the workers, and what each worker's end told other plugins (the hook
# through which pytest-cov takes a worker's coverage data)
WORKERS_NOTED = """
import os

def pytest_configure(config):
    if hasattr(config, "workerinput"):
        with open(config.rootpath / "worker-pids.txt", "a") as f:
            f.write(f"{os.getpid()}\\n")

def pytest_testnodedown(node, error):
    with open(node.config.rootpath / "nodes-down.txt", "a") as f:
        f.write(f"{node.gateway.id} {error}\\n")
"""


def stop_an_xdist_run(pytester, stop) -> tuple[str, int]:
    """A 300-case run under -n 2 in a process group of its own (as a terminal's foreground
    job), stopped by ``stop(pid)`` once 10 rows are on disk; its output and exit status."""
    pytester.makepyfile(MANY_SLEEPING)
    pytester.makeconftest(WORKERS_NOTED)

    def own_group_with_ctrl_c():
        ctrl_c_as_at_a_terminal()
        os.setsid()  # a terminal's Ctrl-C goes to the whole foreground process group

    proc = subprocess.Popen(
        [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-n", "2", "--avs-db=none",
         "--junitxml=out.xml"], cwd=pytester.path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
        preexec_fn=own_group_with_ctrl_c)
    try:
        wait_for_rows(pytester, proc, 10)
        stop(proc.pid)
        out = proc.communicate(timeout=120)[0].decode()
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    return out, proc.returncode


def assert_stopped_whole(pytester, out: str, status: int) -> None:
    """Status 2, one line per worker saying where it stopped and nothing more of theirs, every
    finished case's row (on disk, in JUnit, in pytest's count), the report written whole, each
    worker's end given to the plugins, and no worker process left behind."""
    assert status == pytest.ExitCode.INTERRUPTED, out
    workers = sorted(line for line in out.splitlines() if "avscenario: worker gw" in line)
    assert len(workers) == 2, out
    assert all(re.search(r"worker gw[01] interrupted (at test_\S+\.py::test_many\[halton-\d+\]|between tests)", w)
               for w in workers), workers
    assert "Traceback" not in out and "node down" not in out, out
    assert len(out.splitlines()) < 40, out  # the header, the table, the summary: no tracebacks
    rows = rows_of(pytester.path)
    assert 10 <= len(rows) < 300
    assert len({r["item"] for r in rows}) == len(rows)
    assert junit_cases(pytester.path / "out.xml") == len(rows)
    # pytest counts an item passed at its call report; a case's row travels with its setup
    # report (the case runs there): a worker stopped between the two has one row more
    passed = int(re.search(r"\b(\d+) passed\b", out.splitlines()[-1]).group(1))
    assert passed <= len(rows) <= passed + 2, out
    summary = json.loads((pytester.path / "avs-report" / "summary.json").read_text())
    assert summary["interrupted"] is True and summary["tests"][0]["samples"] == len(rows)
    assert summary["tests"][0]["epsilon"] > 0  # the ε-coverage of the rows that came (scipy)
    assert sorted((pytester.path / "nodes-down.txt").read_text().split()) == ["None", "None", "gw0", "gw1"]
    for pid in map(int, (pytester.path / "worker-pids.txt").read_text().split()):
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)  # ended and reaped before pytest returned


def test_ctrl_c_under_xdist_says_one_line_per_worker_and_keeps_every_row(pytester):
    # #33 item 6: Ctrl-C at a terminal reaches the controller and both workers; before, pytest
    # rendered the whole traceback of the interrupt in every process (the time it took), and
    # nothing said where the workers stopped; the time to the prompt is bench/bench_stop.py's
    out, status = stop_an_xdist_run(pytester, lambda pid: os.killpg(pid, signal.SIGINT))
    assert_stopped_whole(pytester, out, status)


def test_sigterm_to_an_xdist_controller_alone_stops_the_run_as_ctrl_c_does(pytester):
    # `kill PID` (a CI runner's cancel): only the controller is told; it ends its workers
    out, status = stop_an_xdist_run(pytester, lambda pid: os.kill(pid, signal.SIGTERM))
    assert_stopped_whole(pytester, out, status)

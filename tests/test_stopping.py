"""Every item keeps its row, and every run can be stopped: pytest's own exits in a body or a
driver, crashed and killed xdist workers, cases that will not stop at their time limit, and
SIGTERM — with no scenario test, stuck in C, twice, while the report is written, and sent to
an xdist controller."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pytest_avscenario.pytest_plugin.stopping import crash_row
from pytest_avscenario.runner import GRACE_S


def rows_of(path: Path) -> list[dict]:
    table = path / "avs-report" / "errors.jsonl"
    return [json.loads(line) for line in table.read_text().splitlines()] if table.exists() else []


def start(pytester: pytest.Pytester, *args: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", *args], cwd=pytester.path,
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT)


def wait_for_rows(pytester: pytest.Pytester, proc: subprocess.Popen, n: int, limit_s: float = 90) -> None:
    deadline = time.monotonic() + limit_s
    while len(rows_of(pytester.path)) < n:
        assert proc.poll() is None, proc.communicate()[0].decode()
        assert time.monotonic() < deadline, "the run wrote no rows"
        time.sleep(0.1)


def junit_cases(path: Path) -> int:
    return path.read_text().count("<testcase ")


def ctrl_c_as_at_a_terminal() -> None:
    """A child's SIGINT as a terminal's Ctrl-C finds it: a shell starts background jobs with
    SIGINT ignored, and a Python started so never raises KeyboardInterrupt (the test would
    stop nothing and fail in a CI job that runs its tests in the background)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


# -- pytest's own exits in a body or a driver ---------------------------------------------

EXITS = """
import sys
import pytest
from pytest_avscenario import scenario, Uniform

@scenario(x=Uniform(0, 1), samples=5, sampler="halton")
def test_body(case):
    if case.index == 0:
        pytest.fail("judged unsafe by the body")
    if case.index == 1:
        sys.exit(3)
    if case.index == 2:
        pytest.skip("not applicable")

@scenario(x=Uniform(0, 1), samples=2, sampler="halton")
def test_driver(case, world):
    road = world.straight_road(lanes=1, length=200)
    world.ego(road.lane(0), s=20.0, speed=10.0)
    world.run(seconds=1)
"""


def test_pytest_fail_and_sys_exit_in_a_body_or_a_driver_keep_their_rows(pytester):
    pytester.makeconftest("""
import sys
import pytest

@pytest.fixture
def avs_driver(request):
    if "test_driver" not in request.node.name:
        return "idm"
    def policy(observation):
        sys.exit(4)
    return policy
""")
    pytester.makepyfile(test_exits=EXITS)
    result = pytester.runpytest("--avs-db=none", "--avs-shrink-budget=0", "-p", "no:xdist")
    # pytest.fail: a counterexample (failed); sys.exit: an error, in the body and in the driver;
    # pytest.skip: skipped, as pytest skips (a skipped case has no verdict, so no row)
    result.assert_outcomes(failed=1, errors=3, passed=2, skipped=1)
    rows = {r["item"].split("::")[1]: r for r in rows_of(pytester.path)}
    assert len(rows) == 6
    assert rows["test_body[halton-000]"]["verdict"] == "fail"
    assert rows["test_body[halton-000]"]["error"] == "judged unsafe by the body"
    assert rows["test_body[halton-001]"]["verdict"] == "error"
    assert "sys.exit(3)" in rows["test_body[halton-001]"]["error"]
    assert "test_body[halton-002]" not in rows
    for k in (0, 1):
        assert rows[f"test_driver[halton-00{k}]"]["verdict"] == "error"
        assert "sys.exit(4)" in rows[f"test_driver[halton-00{k}]"]["error"]


def test_pytest_exit_in_a_body_still_ends_the_run(pytester):
    pytester.makepyfile("""
import pytest
from pytest_avscenario import scenario, Uniform

@scenario(x=Uniform(0, 1), samples=4, sampler="halton")
def test_x(case):
    if case.index == 1:
        pytest.exit("stop here", returncode=5)
""")
    result = pytester.runpytest("--avs-db=none", "-p", "no:xdist")
    assert result.ret == 5
    assert [r["item"][-11:-1] for r in rows_of(pytester.path)] == ["halton-000"]


# -- crashed xdist workers ------------------------------------------------------------------

def test_items_of_a_crashed_xdist_worker_get_error_rows(pytester):
    pytester.makepyfile("""
import os
from pytest_avscenario import scenario, Uniform

@scenario(x=Uniform(0, 1), samples=3, sampler="halton")
def test_dies(case):
    os._exit(7)

@scenario(x=Uniform(0, 1), samples=3, sampler="halton")
def test_fine(case):
    pass
""")
    result = pytester.runpytest_subprocess("--avs-db=none", "-n", "2", "--junitxml=out.xml")
    result.assert_outcomes(failed=3, passed=3)
    rows = rows_of(pytester.path)
    assert len(rows) == 6 == junit_cases(pytester.path / "out.xml")
    died = [r for r in rows if "test_dies" in r["item"]]
    assert sorted(r["index"] for r in died) == [0, 1, 2]
    assert all(r["verdict"] == "error" and "worker running this case died" in r["error"] for r in died)
    summary = json.loads((pytester.path / "avs-report" / "summary.json").read_text())
    assert {t["test"].split("::")[1]: t["errors"] for t in summary["tests"]} == {"test_dies": 3, "test_fine": 0}


def test_crash_rows_are_made_only_for_case_ids():
    names = {"halton", "mab", "replay", "example"}
    row = crash_row("t.py::test_x[mab-012]", names)
    assert (row.test, row.sampler, row.index, row.origin) == ("t.py::test_x", "mab", 12, "sampled")
    row = crash_row("t.py::test_x[wet-replay-3]", names)
    assert (row.sampler, row.index, row.origin) == ("replay", 3, "replay")
    assert crash_row("t.py::test_plain[1-2]", names) is None
    assert crash_row("t.py::test_plain", names) is None


def test_a_killed_xdist_worker_loses_only_its_running_case_and_that_case_keeps_a_row(pytester):
    # with the replay database on: the worker that replaces the killed one must collect the
    # same items as the others, not replay what this run stored meanwhile
    pytester.makepyfile("""
import time
from pytest_avscenario import scenario, Uniform

@scenario(x=Uniform(0, 1), samples=60, sampler="halton")
def test_slow(case):
    time.sleep(0.1)
    assert case.x < 0.5
""")
    proc = start(pytester, "--avs-shrink-budget=0", "-n", "2", "--junitxml=out.xml")
    wait_for_rows(pytester, proc, 8)
    children = Path(f"/proc/{proc.pid}/task/{proc.pid}/children").read_text().split()
    assert children, "no xdist worker found"
    os.kill(int(children[0]), signal.SIGKILL)
    out = proc.communicate(timeout=120)[0].decode()
    rows = rows_of(pytester.path)
    assert len(rows) == 60 == len({r["item"] for r in rows}) == junit_cases(pytester.path / "out.xml"), out
    assert {r["origin"] for r in rows} == {"sampled"}
    died = [r for r in rows if r["verdict"] == "error"]
    assert len(died) <= 1 and all("worker running this case died" in r["error"] for r in died)
    summary = json.loads((pytester.path / "avs-report" / "summary.json").read_text())
    assert summary["tests"][0]["samples"] == 60


# -- cases that will not stop ---------------------------------------------------------------

STUBBORN = """
import hashlib
from pytest_avscenario import scenario, Uniform

@scenario(x=Uniform(0, 1), samples=3, sampler="halton", case_timeout=1)
def test_swallows(case):
    if case.index == 1:
        while True:
            try:
                sum(range(10**5))
            except:  # noqa: E722 - swallows the time limit too
                pass

@scenario(x=Uniform(0, 1), samples=3, sampler="halton", case_timeout=1)
def test_in_c(case):
    if case.index == 1:
        hashlib.pbkdf2_hmac("sha256", b"p", b"s", 10**9)  # one C call of minutes
"""


def test_a_case_that_will_not_stop_ends_the_run_with_its_row_written(pytester):
    pytester.makepyfile(test_stubborn=STUBBORN)
    proc = start(pytester, "--avs-db=none", "-p", "no:xdist", "test_stubborn.py::test_swallows")
    out = proc.communicate(timeout=60)[0].decode()
    assert proc.returncode == 1, out
    rows = rows_of(pytester.path)
    assert [r["verdict"] for r in rows] == ["pass", "error"]
    assert "ran past its time limit of 1 s and did not stop" in rows[1]["error"]
    ran = float(rows[1]["sim_time_s"])
    assert 1 + GRACE_S - 0.5 <= ran, rows[1]
    assert "would not stop" in out and "ending the test run" in out


def test_under_xdist_a_case_that_will_not_stop_costs_its_worker_and_the_run_goes_on(pytester):
    pytester.makepyfile(test_stubborn=STUBBORN)
    result = pytester.runpytest_subprocess("--avs-db=none", "-n", "2", "--junitxml=out.xml")
    rows = rows_of(pytester.path)
    assert len(rows) == 6 == len({r["item"] for r in rows})
    stuck = {r["item"].split("::")[1]: r for r in rows if r["verdict"] == "error"}
    assert set(stuck) == {"test_swallows[halton-001]", "test_in_c[halton-001]"}
    assert all("did not stop" in r["error"] for r in stuck.values())
    assert sum(r["verdict"] == "pass" for r in rows) == 4
    result.stdout.fnmatch_lines(["*replacing crashed worker*"])


# -- SIGTERM -------------------------------------------------------------------------------

STUCK_IN_C = """
import hashlib
def busy():
    hashlib.pbkdf2_hmac("sha256", b"p", b"s", 10**9)  # one C call of minutes
"""


def test_without_scenario_tests_sigterm_keeps_its_default_action(pytester):
    pytester.makepyfile(helper=STUCK_IN_C, test_plain="""
from helper import busy
def test_plain():
    open("started", "w").close()
    busy()
""")
    proc = start(pytester, "-p", "no:xdist", "test_plain.py")
    deadline = time.monotonic() + 60
    while not (pytester.path / "started").exists():
        assert time.monotonic() < deadline and proc.poll() is None
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    proc.communicate(timeout=30)
    assert proc.returncode == -signal.SIGTERM  # killed by the signal itself: no handler of ours


SCENARIO_STUCK = """
import time
from helper import busy
from pytest_avscenario import scenario, Uniform

@scenario(x=Uniform(0, 1), samples=6, sampler="halton")
def test_stuck(case):
    if case.index == 2:
        busy()
"""


@pytest.mark.parametrize("signals", [1, 2])
def test_sigterm_ends_a_scenario_stuck_in_c_and_the_finished_rows_stay(pytester, signals):
    # one SIGTERM: ended once it went unanswered for a few seconds; two: at once
    pytester.makepyfile(helper=STUCK_IN_C, test_stuck=SCENARIO_STUCK)
    proc = start(pytester, "--avs-db=none", "-p", "no:xdist")
    wait_for_rows(pytester, proc, 2)
    time.sleep(0.5)
    for _ in range(signals):
        proc.send_signal(signal.SIGTERM)
        time.sleep(0.2)
    out = proc.communicate(timeout=60)[0].decode()
    assert proc.returncode == 128 + signal.SIGTERM, out
    assert [r["index"] for r in rows_of(pytester.path)] == [0, 1]
    if signals == 1:
        assert "SIGTERM not answered" in out


def test_sigterm_while_the_report_is_written_waits_for_the_report(pytester):
    pytester.makeconftest("""
import os
import signal
import pytest

@pytest.hookimpl(wrapper=True)
def pytest_sessionfinish(session):
    os.kill(os.getpid(), signal.SIGTERM)  # CI cancels the job as the report is being built
    return (yield)
""")
    pytester.makepyfile("""
from pytest_avscenario import scenario, Uniform

@scenario(x=Uniform(0, 1), samples=4, sampler="halton")
def test_x(case):
    assert case.x < 0.6
""")
    result = pytester.runpytest_subprocess("--avs-db=none", "-p", "no:xdist", "--junitxml=out.xml")
    assert result.ret == pytest.ExitCode.INTERRUPTED
    report = pytester.path / "avs-report"
    assert json.loads((report / "summary.json").read_text())["tests"][0]["samples"] == 4
    assert (report / "index.html").exists() and junit_cases(pytester.path / "out.xml") == 4


# Where issue #34 lost rows, held there by the inner run's conftest rather than hoped for
# with a timed signal. The chosen item is worker gw0's third; its setup report carries its row.
#
# * between-plugins: the controller is stopped by a hook implementation that runs before the
#   error table's (a signal lands between two plugins' handling of one report), while gw0,
#   having sent that setup report, waits before its call report for the SIGTERM the stopped
#   controller sends it (the worker is ended between its two reports);
# * in-process: as between-plugins, in a run without xdist;
# * between-events: the controller is stopped just after it took the setup report from its
#   queue, before any plugin has it, once the item's call report is queued behind it (that
#   call report alone would give JUnit a test case without a row).
STOP_AT_A_REPORT = """
import os
import signal
import time
import pytest
from pytest_avscenario.pytest_plugin.stash import guard_key

SIG = signal.Signals[os.environ["AVS_TEST_SIGNAL"]]
WHERE = os.environ["AVS_TEST_WHERE"]
seen = []


def stop_here(nodeid):
    with open("stopped_at", "w") as f:
        f.write(nodeid)
    os.kill(os.getpid(), SIG)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item, call):
    report = yield
    if getattr(item.config, "workerinput", {}).get("workerid", "gw0") == "gw0" and call.when == "setup":
        seen.append(item.nodeid)
        report.avs_stop_here = len(seen) == 3  # travels to the controller with the report
    return report


class StopController:
    @pytest.hookimpl(tryfirst=True)  # before the error table's implementation
    def pytest_runtest_logreport(self, report):
        if getattr(report, "avs_stop_here", False):
            stop_here(report.nodeid)


class HoldWorker:
    def __init__(self, config):
        self.config = config

    @pytest.hookimpl(wrapper=True)
    def pytest_runtest_logreport(self, report):
        result = yield
        if getattr(report, "avs_stop_here", False):
            # the setup report is sent: before the call report, wait for the controller to end us
            guard = self.config.stash[guard_key]
            deadline = time.monotonic() + 60
            while not (guard.pending or guard.terminated) and time.monotonic() < deadline:
                time.sleep(0.01)
        return result


def pytest_configure(config):
    if WHERE in ("between-plugins", "in-process"):
        worker = hasattr(config, "workerinput")
        config.pluginmanager.register(HoldWorker(config) if worker else StopController())


def pytest_sessionstart(session):
    dsession = session.config.pluginmanager.getplugin("dsession")
    if WHERE != "between-events" or dsession is None:
        return
    handle = dsession.worker_testreport

    def worker_testreport(node, rep):
        if getattr(rep, "avs_stop_here", False):
            def call_report_queued():
                return any(name == "testreport" and kw["rep"].nodeid == rep.nodeid
                           and kw["rep"].when == "call" for name, kw in list(dsession.queue.queue))
            deadline = time.monotonic() + 60
            while not call_report_queued() and time.monotonic() < deadline:
                time.sleep(0.01)
            stop_here(rep.nodeid)
        return handle(node, rep)

    dsession.worker_testreport = worker_testreport
"""


@pytest.mark.parametrize("where", ["between-plugins", "between-events"])
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_stopping_an_xdist_controller_ends_its_workers_and_every_reported_row_is_on_disk(pytester, sig, where):
    pytester.makeconftest(STOP_AT_A_REPORT)
    pytester.makepyfile("""
import time
from pytest_avscenario import scenario, Uniform

@scenario(x=Uniform(0, 1), samples=40, sampler="halton")
def test_many(case):
    time.sleep(0.02)
    assert case.x < 0.3
""")
    proc = subprocess.Popen(
        [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-n", "2", "--avs-shrink-budget=0",
         "--junitxml=out.xml"], cwd=pytester.path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
        env={**os.environ, "AVS_TEST_SIGNAL": sig.name, "AVS_TEST_WHERE": where},
        preexec_fn=ctrl_c_as_at_a_terminal)
    out = proc.communicate(timeout=120)[0].decode()
    assert proc.returncode == pytest.ExitCode.INTERRUPTED, out
    stopped_at = (pytester.path / "stopped_at").read_text()
    time.sleep(1.0)  # a worker that went on would store more meanwhile
    rows = rows_of(pytester.path)
    assert stopped_at in {r["item"] for r in rows}, (stopped_at, out)
    assert len(rows) == junit_cases(pytester.path / "out.xml") < 40, out
    summary = json.loads((pytester.path / "avs-report" / "summary.json").read_text())
    assert summary["tests"][0]["samples"] == len(rows)
    failing = sum(r["verdict"] == "fail" for r in rows)
    stored = len(list((pytester.path / ".avscenario").glob("*.json")))
    # each failure is stored as found (no shrinking); at most the one case each of the two
    # workers was finishing when the controller stopped listening is stored but not reported
    assert failing <= stored <= failing + 2, (failing, stored)
    assert "PluggyTeardownRaisedWarning" not in out


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_stopping_a_run_while_a_report_is_handled_keeps_that_items_row(pytester, sig):
    pytester.makeconftest(STOP_AT_A_REPORT)
    pytester.makepyfile("""
from pytest_avscenario import scenario, Uniform

@scenario(x=Uniform(0, 1), samples=10, sampler="halton")
def test_few(case):
    assert case.x < 0.3
""")
    proc = subprocess.Popen(
        [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:xdist", "--avs-db=none",
         "--junitxml=out.xml"], cwd=pytester.path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
        env={**os.environ, "AVS_TEST_SIGNAL": sig.name, "AVS_TEST_WHERE": "in-process"},
        preexec_fn=ctrl_c_as_at_a_terminal)
    out = proc.communicate(timeout=120)[0].decode()
    assert proc.returncode == pytest.ExitCode.INTERRUPTED, out
    stopped_at = (pytester.path / "stopped_at").read_text()
    rows = rows_of(pytester.path)
    assert [r["item"] for r in rows][-1] == stopped_at and len(rows) == 3, out
    assert junit_cases(pytester.path / "out.xml") == 3, out
    assert "PluggyTeardownRaisedWarning" not in out


def test_an_error_around_the_case_still_gives_the_item_its_row(pytester):
    # a user's active sampler whose tell() raises: the case ran, the plugin failed after it;
    # a user's fixture that raises: the case never ran
    pytester.makeconftest("""
import numpy as np
import pytest
from pytest_avscenario.samplers import Sampler, register

@pytest.fixture
def broken():
    raise RuntimeError("no map server")

@register("clumsy")
class Clumsy(Sampler):
    name = "clumsy"
    active = True

    def ask_unit(self):
        return np.full(self.d, 0.5)

    def tell_unit(self, u, rho):
        raise ValueError("clumsy sampler cannot learn")
""")
    pytester.makepyfile("""
from pytest_avscenario import scenario, Uniform

@scenario(x=Uniform(0, 1), samples=2, sampler="clumsy")
def test_x(case):
    pass

@scenario(x=Uniform(0, 1), samples=2, sampler="halton")
def test_y(case, broken):
    pass
""")
    result = pytester.runpytest("--avs-db=none", "-p", "no:xdist")
    result.assert_outcomes(errors=4)
    rows = rows_of(pytester.path)
    assert [(r["test"][-6:], r["index"], r["verdict"]) for r in rows] == [
        ("test_x", 0, "error"), ("test_x", 1, "error"), ("test_y", 0, "error"), ("test_y", 1, "error")]
    assert all("ValueError: clumsy sampler cannot learn" in r["error"] for r in rows[:2])
    assert all("RuntimeError: no map server" in r["error"] for r in rows[2:])
    assert [r["params"] for r in rows[2:]] == [{"x": 0.5}, {"x": 0.25}]


def test_no_alarm_outlives_a_case_that_ends_as_its_limit_fires():
    # bodies that end right as their limit fires: afterwards no alarm is armed and SIGALRM is
    # what it was (an alarm left behind would raise CaseTimeout in the plugin's own code)
    from pytest_avscenario.runner import CaseTimeout, TimeLimit

    before = signal.getsignal(signal.SIGALRM)
    for _ in range(300):
        limit = TimeLimit(0.002)
        try:
            try:
                limit.start()
                t0 = time.perf_counter()
                while time.perf_counter() - t0 < 0.002:
                    pass
            finally:
                limit.stop()
        except CaseTimeout:
            pass
        assert signal.getitimer(signal.ITIMER_REAL)[0] == 0
        assert signal.getsignal(signal.SIGALRM) is before

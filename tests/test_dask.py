"""The Dask executor: same results as in-process, cases survive dying workers, clear errors.

Plugin-level runs use ``runpytest_subprocess`` (a real process that starts and stops its own
``LocalCluster`` with two workers); the wire format and the worker-side import are tested
in this process without a cluster. Skipped when Dask is not installed.
"""

from __future__ import annotations

import json
import os
import pickle
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("distributed", reason="the Dask executor needs `pip install '.[dask]'`")

from pytest_avscenario.executors import remote  # noqa: E402


@pytest.fixture(scope="module")
def cluster_address():
    """One LocalCluster (two single-threaded worker processes) shared by this file's runs.

    Starting a cluster per run costs seconds of process spawning and imports on a loaded
    machine; a run given ``--avs-dask-address`` only connects. One death per case is
    tolerated (allowed-failures=1): the killed-worker test needs one resubmission, the
    exhausted-retries test needs the second death to end the case.
    """
    import dask
    import distributed

    # the executor's own LocalCluster settings, but one resubmission instead of two
    with dask.config.set({"distributed.scheduler.allowed-failures": 1,
                          "distributed.scheduler.worker-saturation": 1.0}):
        cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                           dashboard_address=None, silence_logs=40,
                                           scheduler_kwargs={"dashboard_address": ":0"})
    try:
        yield cluster.scheduler_address
    finally:
        cluster.close(timeout=20)

def _wait_for_both_workers(address: str) -> None:
    """A worker killed by an earlier test of this file is restarted by its nanny; on a loaded
    machine that takes seconds, and a one-worker cluster asks nothing ahead."""
    import distributed

    with distributed.Client(address, timeout=30) as client:
        client.wait_for_workers(2, timeout=60)


# Passive (halton) and active (mab) cases; with --avs-seed=5 some violate a monitor and some
# fail the body's assert: both kinds of failure must come back with the same properties.
COMPARED = """
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import distance, ttc

def far_enough(gap):
    assert gap < 30

@scenario(gap=Uniform(8.0, 40.0), lead_speed=Uniform(2.0, 8.0), samples=6, sampler=["halton", "mab"],
          monitors=[distance(5.0, kind="centre"), ttc(2.0, kind="centre")])
def test_follow(case, world):
    road = world.straight_road(lanes=1, length=300)
    world.ego(road.lane(0), s=20.0, speed=12.0)
    world.car(road.lane(0), s=20.0 + case.gap, speed=case.lead_speed)
    world.run(seconds=4)
    far_enough(case.gap)
"""


def _junit_props(path: Path) -> list[tuple]:
    import xml.etree.ElementTree as ET

    out = []
    for case in ET.parse(path).getroot().iter("testcase"):
        props = tuple((p.get("name"), p.get("value")) for p in case.iter("property")
                      if p.get("name") != "avs.sim_time_s")
        out.append((case.get("name"), props))
    return sorted(out)


def test_dask_local_cluster_gives_the_same_items_rows_and_properties(pytester, cluster_address,
                                                                     monkeypatch):
    pytester.makepyfile(test_follow=COMPARED)
    stats = pytester.path / "dask-stats.json"
    monkeypatch.setenv("AVS_DASK_STATS", str(stats))
    # no report directory: its plots cost seconds; JUnit holds every case's row
    common = ("-p", "no:cacheprovider", "--avs-seed=5", "--avs-db=none", "--avs-shrink-budget=2",
              "--avs-samples=3", "--avs-report=none", "-rA")
    local = pytester.runpytest(*common, "--junitxml=local.xml")
    remote_run = pytester.runpytest_subprocess(*common, "--avs-executor=dask", "--junitxml=dask.xml",
                                               f"--avs-dask-address={cluster_address}")
    outcomes = local.parseoutcomes()
    assert outcomes.get("failed", 0) >= 2 and outcomes.get("passed", 0) >= 1, local.outlines
    assert remote_run.parseoutcomes() == outcomes
    # every item's parameters, seed, robustness, verdict and error text (asserts rewritten on
    # the worker too), and what shrinking found with its candidates simulated on the cluster
    local_props = _junit_props(pytester.path / "local.xml")
    remote_props = _junit_props(pytester.path / "dask.xml")
    assert [name for name, _ in remote_props] == [name for name, _ in local_props]
    # passive and active cases alike: the bandit asks case k once cases 0 .. k-1 are told,
    # on the cluster as in-process
    assert remote_props == local_props
    assert any(("avs.minimized" in dict(props)) for _, props in local_props)
    # the three passive (halton) cases started at collection and were matched by their
    # items; the active (mab) cases and the shrink candidates were run on demand
    counters = json.loads(stats.read_text())
    assert counters.get("prefetched") == 3 and counters.get("matched", 0) >= 3, (
        f"passive cases were not started ahead: {counters} (does the plugin's prefetch job "
        "carry the built-in driver name when avs_driver is not overridden?)")
    # the body's own traceback still points at the failing line of the test module
    remote_run.stdout.fnmatch_lines(["E * assert 3*.* < 30", "test_follow.py:5: AssertionError"])


KILLED = """
import os
from pathlib import Path
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import distance

LOG = Path({log!r})
MARKER = Path({marker!r})

@scenario(gap=Uniform(20.0, 40.0), samples=16, monitors=[distance(5.0, kind="centre")])
def test_follow(case, world):
    with LOG.open("a") as f:
        f.write(f"{{case.index}} {{os.getpid()}}\\n")
    if case.index == 2 and not MARKER.exists():
        MARKER.write_text(str(os.getpid()))
        os._exit(13)  # the worker process dies in the middle of this case
    road = world.straight_road(lanes=1, length=300)
    world.ego(road.lane(0), s=20.0, speed=10.0)
    world.car(road.lane(0), s=20.0 + case.gap, speed=10.0)
    world.run(seconds=3)
"""


def test_a_worker_killed_mid_case_is_resubmitted_and_every_case_reports(pytester, cluster_address):
    log, marker = pytester.path / "runs.log", pytester.path / "killed.marker"
    pytester.makepyfile(test_killed=KILLED.format(log=str(log), marker=str(marker)))
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider", "--avs-seed=2", "--avs-db=none",
                                           "--avs-executor=dask", "-v",
                                           f"--avs-dask-address={cluster_address}")
    assert marker.exists(), "the scenario never killed its worker"
    result.assert_outcomes(passed=16)
    rows = [json.loads(line) for line in (pytester.path / "avs-report" / "errors.jsonl").read_text().splitlines()]
    assert sorted(r["index"] for r in rows) == list(range(16))
    assert all(r["verdict"] == "pass" and r["rho"]["distance"] > 0 for r in rows)
    runs = [tuple(map(int, line.split())) for line in log.read_text().splitlines()]
    killed_pid = int(marker.read_text())
    second = [pid for index, pid in runs if index == 2 and pid != killed_pid]
    # case 2 ran again (its whole chunk of 16 // (4 x 2 workers) = 2 cases did), in another
    # process, exactly once more
    assert len(second) == 1, runs


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_stopping_a_dask_run_while_a_report_is_handled_keeps_that_items_row(pytester, cluster_address, sig):
    # the item's case came back from the cluster; the run is stopped by a hook implementation
    # that handles its setup report before the error table does (issue #34's moment)
    from test_stopping import STOP_AT_A_REPORT, ctrl_c_as_at_a_terminal

    pytester.makeconftest(STOP_AT_A_REPORT)
    pytester.makepyfile("""
from pytest_avscenario import scenario, Uniform

@scenario(x=Uniform(0, 1), samples=10, sampler="halton")
def test_few(case):
    assert case.x < 0.3
""")
    proc = subprocess.Popen(
        [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:xdist", "--avs-db=none",
         "--avs-executor=dask", f"--avs-dask-address={cluster_address}", "--junitxml=out.xml"],
        cwd=pytester.path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
        env={**os.environ, "AVS_TEST_SIGNAL": sig.name, "AVS_TEST_WHERE": "in-process"},
        preexec_fn=ctrl_c_as_at_a_terminal)
    out = proc.communicate(timeout=120)[0].decode()
    assert proc.returncode == pytest.ExitCode.INTERRUPTED, out
    stopped_at = (pytester.path / "stopped_at").read_text()
    table = pytester.path / "avs-report" / "errors.jsonl"
    rows = [json.loads(line) for line in table.read_text().splitlines()]
    assert [r["item"] for r in rows][-1] == stopped_at and len(rows) == 3, out
    assert (pytester.path / "out.xml").read_text().count("<testcase ") == 3, out


def test_a_conftest_driver_drives_on_the_workers(pytester, cluster_address):
    # the driver exists only when an item runs (no prefetch); its class lives in a
    # conftest.py, which workers cannot import by name: it must travel by value
    pytester.makeconftest("""
import pytest

class StandStill:
    def act(self, observation):
        return (-6.0, 0.0)

@pytest.fixture
def avs_driver():
    return StandStill()
""")
    pytester.makepyfile(test_stand="""
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import progress

@scenario(gap=Uniform(25, 40), samples=3, monitors=[progress(30.0)])
def test_follow(case, world):
    road = world.straight_road(lanes=1, length=400)
    world.ego(road.lane(0), s=20.0, speed=12.0)
    world.car(road.lane(0), s=20.0 + case.gap, speed=12.0)
    world.run(seconds=5)
""")
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider", "--avs-seed=1", "--avs-db=none",
                                           "--avs-shrink-budget=0", "--avs-report=none",
                                           "--avs-executor=dask", f"--avs-dask-address={cluster_address}")
    # braking at 6 m/s^2 from 12 m/s stops the ego after 12 m: never 30 m of progress
    result.assert_outcomes(failed=3)
    result.stdout.fnmatch_lines(["*scenario violated: progress*"])


def test_prefetched_cases_are_chunked_matched_and_a_replay_runs_again(tmp_path, cluster_address):
    from pytest_avscenario.case import Case
    from pytest_avscenario.executors import CaseJob
    from pytest_avscenario.executors.dask import DaskExecutor
    from pytest_avscenario.monitors import MonitorSet, distance

    path = tmp_path / "test_prefetch_avs.py"
    path.write_text(COMPARED.replace("far_enough(case.gap)", "pass"))
    func = remote.import_test_module(str(path), str(tmp_path)).test_follow
    monitors = MonitorSet([distance(5.0, kind="centre")])

    def job(k: int, gap: float) -> CaseJob:
        case = Case({"gap": gap, "lead_speed": 4.0}, k, 100 + k, "halton", test="t")
        return CaseJob(nodeid=f"test_prefetch_avs.py::test_follow[halton-{k:03d}]",
                       module_path=str(path), rootdir=str(tmp_path), function="test_follow",
                       func=func, argnames=("case", "world"), fixtures={}, case=case,
                       monitor_set=monitors, driver="autopilot")

    jobs = [job(k, 10.0 + 5 * k) for k in range(4)]
    executor = DaskExecutor(cluster_address, chunk_size=3)
    try:
        executor.prefetch(jobs)
        outcomes = [executor.run(j) for j in jobs]
        assert executor.stats["matched"] == 4 and executor.stats["on_demand"] == 0
        assert executor.stats["tasks"] == 2  # a chunk of three and one of one
        # a shrink replay of a consumed case is simulated anew, with the same result
        again = [executor.run(j) for j in jobs]
        assert executor.stats["on_demand"] == 4 and executor.stats["tasks"] == 6
        # an active sampler's batch: submitted ahead, one task each, collected by run
        executor.submit(jobs[:2])
        batch = [executor.run(j) for j in jobs[:2]]
        assert executor.stats["submitted_ahead"] == 2 and executor.stats["on_demand"] == 4
        assert executor.stats["tasks"] == 8 and executor.capacity == 2
    finally:
        executor.close()
    assert [o.rho for o in outcomes] == [o.rho for o in again]
    assert [o.rho for o in batch] == [o.rho for o in outcomes[:2]]
    assert [o.verdict for o in outcomes] == ["fail", "pass", "pass", "pass"]


def test_a_case_past_its_time_limit_is_ended_on_the_worker(tmp_path, cluster_address):
    runner = pytest.importorskip("pytest_avscenario.runner")
    if not hasattr(runner, "CaseTimeout"):
        pytest.skip("this runner has no case time limits")
    from pytest_avscenario.case import Case
    from pytest_avscenario.executors import CaseJob
    from pytest_avscenario.executors.dask import DaskExecutor

    path = tmp_path / "test_spins_avs.py"
    path.write_text("def test_spins(case):\n    while True:\n        pass\n")
    func = remote.import_test_module(str(path), str(tmp_path)).test_spins
    job = CaseJob(nodeid="test_spins_avs.py::test_spins[x]", module_path=str(path),
                  rootdir=str(tmp_path), function="test_spins", func=func, argnames=("case",),
                  fixtures={}, case=Case({"x": 1.0}, 0, 7, "halton"), monitor_set=None, driver=None)
    job.timeout_s = 0.5  # set after construction: works whether CaseJob declares it or not
    executor = DaskExecutor(cluster_address)
    try:
        t0 = time.monotonic()
        # three in a row on two workers: the third runs only if a stopped case freed its thread
        outcomes = [executor.run(job) for _ in range(3)]
        assert time.monotonic() - t0 < 20
    finally:
        executor.close()
    for outcome in outcomes:
        assert outcome.verdict == "error" and outcome.error.startswith("CaseTimeout: the case ran longer")
        assert outcome.signature[:3] == ("exception", "CaseTimeout", str(path))  # stopped in the body


def test_exhausted_retries_make_an_error_never_a_pass(tmp_path, cluster_address):
    from pytest_avscenario.case import Case
    from pytest_avscenario.executors import CaseJob
    from pytest_avscenario.executors.dask import DaskExecutor

    path = tmp_path / "test_sometimes_dies.py"
    path.write_text("import os\ndef test_dies(case):\n    if case.x > 1:\n        os._exit(3)\n")
    func = remote.import_test_module(str(path), str(tmp_path)).test_dies

    def job(k: int, x: float) -> CaseJob:
        return CaseJob(nodeid=f"test_sometimes_dies.py::test_dies[halton-{k:03d}]",
                       module_path=str(path), rootdir=str(tmp_path), function="test_dies",
                       func=func, argnames=("case",), fixtures={},
                       case=Case({"x": x}, k, 7 + k, "halton"), monitor_set=None, driver=None)

    # one chunk of three: the middle case kills every worker it runs on
    jobs = [job(0, 0.5), job(1, 2.0), job(2, 0.7)]
    executor = DaskExecutor(cluster_address, chunk_size=3)
    try:
        executor.prefetch(jobs)
        outcomes = [executor.run(j) for j in jobs]
        stats = dict(executor.stats)
    finally:
        executor.close()
    assert [o.verdict for o in outcomes] == ["pass", "error", "pass"], [o.error for o in outcomes]
    assert "died" in outcomes[1].error and "resubmitted" in outcomes[1].error
    assert not outcomes[1].failed
    # the chunk was split after its retries: its other cases were not blamed for the crash
    assert stats["chunks_split"] == 1 and stats["matched"] == 3, stats


def test_an_unreachable_scheduler_is_a_clear_error_within_the_timeout():
    from pytest_avscenario.executors import make_executor
    from pytest_avscenario.executors.dask import DaskExecutor

    t0 = time.monotonic()
    with pytest.raises(ValueError, match=r"cannot reach the Dask scheduler at tcp://127.0.0.1:9 "
                                         r"within 1.5 s.*--avs-dask-address"):
        DaskExecutor("tcp://127.0.0.1:9", connect_timeout_s=1.5)
    assert time.monotonic() - t0 < 15
    # the plugin turns this ValueError into a usage error; the default timeout is bounded too
    with pytest.raises(ValueError, match="AVS_DASK_TIMEOUT must be a number"):
        os.environ["AVS_DASK_TIMEOUT"] = "soon"
        try:
            make_executor("dask", address="tcp://127.0.0.1:9")
        finally:
            del os.environ["AVS_DASK_TIMEOUT"]


def test_other_fixtures_are_refused_at_collection_under_dask(pytester):
    pytester.makepyfile(test_tmp="""
from pytest_avscenario import scenario, Uniform

@scenario(x=Uniform(0, 1), samples=2)
def test_x(case, tmp_path):
    pass
""")
    result = pytester.runpytest("-p", "no:cacheprovider", "--avs-db=none", "--avs-executor=dask")
    result.stdout.fnmatch_lines(["*--avs-executor=dask*only*case*world*avs_driver*tmp_path*"])
    assert result.ret != 0


# --------------------------------------------------------------------------- no cluster
def test_worker_import_mimics_prepend_mode_and_reloads_an_edited_module(tmp_path, monkeypatch):
    pkg = tmp_path / "suite" / "inner"
    pkg.mkdir(parents=True)
    (tmp_path / "suite" / "__init__.py").write_text("")
    (pkg / "__init__.py").write_text("")
    (pkg / "helpers_avs_t.py").write_text("VALUE = 1\n")
    mod_path = pkg / "test_avs_pkgmod.py"
    mod_path.write_text("from .helpers_avs_t import VALUE\ndef test_v(case):\n    return VALUE\n")
    monkeypatch.setattr(sys, "path", list(sys.path))
    try:
        assert remote.module_name_for(mod_path) == (tmp_path, "suite.inner.test_avs_pkgmod")
        mod = remote.import_test_module(str(mod_path), str(tmp_path))
        assert mod.__name__ == "suite.inner.test_avs_pkgmod" and mod.test_v(None) == 1
        assert remote.import_test_module(str(mod_path), str(tmp_path)) is mod  # unchanged: reused
        mod_path.write_text("def test_v(case):\n    return 2  # edited\n")
        os.utime(mod_path, ns=(time.time_ns(), time.time_ns() + 10**9))
        assert remote.import_test_module(str(mod_path), str(tmp_path)).test_v(None) == 2
    finally:
        for name in [n for n in sys.modules if n == "suite" or n.startswith("suite.")]:
            del sys.modules[name]


class Unpicklable(Exception):
    def __init__(self, a, b):  # pickle calls cls(*args) with one arg: it cannot rebuild this
        super().__init__(f"{a}/{b}")


def test_exceptions_cross_the_wire_with_type_text_and_last_frame():
    from pytest_avscenario.outcome import CaseOutcome

    def body():
        assert 1 + 1 == 3, "arithmetic"

    for raise_it, kind in ((body, AssertionError), (lambda: (_ for _ in ()).throw(Unpicklable(1, 2)), Exception)):
        try:
            raise_it()
        except Exception as exc:
            outcome = CaseOutcome(params={"x": 1}, verdict="fail" if kind is AssertionError else "error",
                                  exc=exc, error=str(exc))
        back = pickle.loads(pickle.dumps(outcome))  # as Dask sends it: the same type
        assert back.signature == outcome.signature
        assert isinstance(back.exc, kind) and str(back.exc) == str(outcome.exc)
        assert back.trajectory is None and back.verdict == outcome.verdict


def test_a_conftest_driver_travels_by_value(pytester):
    conftest = pytester.makeconftest("""
class BrakeHard:
    def act(self, observation):
        return (-6.0, 0.0)
""")
    import cloudpickle
    import importlib.util

    spec = importlib.util.spec_from_file_location("conftest", conftest)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    sys.modules["conftest"] = mod
    try:
        data = remote.pack_spec(remote.TestSpec("m.py", "/", "test_x", ("case",), None, mod.BrakeHard()))
    finally:
        del sys.modules["conftest"]
    driver = cloudpickle.loads(data).driver  # no module called conftest exists here now
    assert driver.act(None) == (-6.0, 0.0)


ACTIVE = """
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import distance

@scenario(gap=Uniform(8.0, 40.0), lead_speed=Uniform(2.0, 12.0), samples=8, sampler="mab",
          monitors=[distance(5.0, kind="centre")])
def test_search(case, world):
    road = world.straight_road(lanes=1, length=300)
    world.ego(road.lane(0), s=20.0, speed=12.0)
    world.car(road.lane(0), s=20.0 + case.gap, speed=case.lead_speed)
    world.run(seconds=4)
"""


@pytest.mark.parametrize("unavoidable", ["keep", "discard"])
def test_an_active_campaign_on_the_cluster_is_the_local_campaign_case_by_case(pytester, cluster_address,
                                                                              unavoidable):
    """A bandit on two Dask workers gives every case id the parameters, seed, robustness and
    verdict of the local serial run (it once asked ahead as many cases as the cluster ran at
    once, and learnt of each late: 49 of the example suite's 75 bandit cases differed). With
    ``unavoidable="discard"`` too: a case that starts RSS-unsafe is judged on its worker (its
    trajectory stays there) and the bandit is told nothing of it, as locally."""
    pytester.makepyfile(test_search=ACTIVE)
    _wait_for_both_workers(cluster_address)  # two workers: room to run cases side by side
    common = ("-p", "no:cacheprovider", "--avs-seed=3", "--avs-db=none", "--avs-shrink-budget=0",
              "--avs-report=none", f"--avs-unavoidable={unavoidable}")
    pytester.runpytest_subprocess(*common, "--junitxml=local.xml")
    pytester.runpytest_subprocess(*common, "--avs-executor=dask", f"--avs-dask-address={cluster_address}",
                                  "--junitxml=dask.xml")
    keep = ("avs.params", "avs.seed", "avs.verdict", "avs.rho.distance")
    rows = [[(n, tuple(p for p in ps if p[0] in keep)) for n, ps in _junit_props(pytester.path / f)]
            for f in ("local.xml", "dask.xml")]
    assert len(rows[0]) == 8 and all(len(ps) == len(keep) for _, ps in rows[0]), rows[0]
    assert len({dict(ps)["avs.params"] for _, ps in rows[0]}) > 1  # the bandit moved
    assert rows[1] == rows[0]


def test_a_worker_takes_the_runs_stack_settings_with_the_spec(tmp_path, monkeypatch):
    """--avs-stack-timeout and --avs-stack-spin reach the process that runs the case."""
    from pytest_avscenario.stack import client

    monkeypatch.setattr(client, "_settings", {"timeout_s": 5.0, "spin_s": None})
    module = tmp_path / "test_m.py"
    module.write_text("def test_x(case):\n    pass\n")
    spec = remote.TestSpec(str(module), str(tmp_path), "test_x", ("case",), None, None,
                           stack={"timeout_s": 17.0, "spin_s": 0.0})
    data = remote.pack_spec(spec)
    fields = remote.CaseFields(nodeid="test_m.py::test_x[halton-000]", params={}, index=0, seed=1,
                               sampler="halton", origin="sampled", test="test_m.py::test_x")
    outcome = remote.run_remote(data, remote.spec_digest(data), str(module), str(tmp_path), fields)
    assert outcome.error is None, outcome.error
    assert client._settings == {"timeout_s": 17.0, "spin_s": 0.0}


HANGING_STACK = """
from pytest_avscenario import scenario, Uniform

@scenario(gap=Uniform(30, 50), samples=3, sampler="halton", monitors=[])
def test_drive(case, world):
    road = world.straight_road(lanes=1, length=300)
    world.ego(road.lane(0), s=10.0, speed=8.0)
    world.car(road.lane(0), s=10.0 + case.gap, speed=9.0)
    world.run(seconds=1)
"""


def test_the_stack_timeout_holds_on_the_cluster_s_workers(pytester, cluster_address):
    """--avs-stack-timeout reaches the worker that spawns and asks the stack: a stack that
    hangs at step 3 of one case makes that case an error after 0.5 s, not the default 5."""
    pytest.importorskip("zmq")
    pytest.importorskip("osi3")
    _wait_for_both_workers(cluster_address)
    raw = Path(__file__).resolve().parent / "data" / "osi_raw_stack.py"
    pytester.makepyfile(test_hang=HANGING_STACK)
    driver = (f"osi+spawn:{sys.executable} {raw} {{address}} --answer motion --fault hang "
              "--case-suffix=-001] --at-step 3")
    result = pytester.runpytest("--avs-driver", driver, "--avs-stack-timeout=0.5", "--avs-db=none",
                                "--avs-report=none", "--avs-shrink-budget=0", "--avs-executor=dask",
                                f"--avs-dask-address={cluster_address}", "-p", "no:xdist",
                                "-p", "no:cacheprovider", "-rA")
    outcomes = result.parseoutcomes()
    assert outcomes.get("passed") == 2, result.stdout.str()[-3000:]
    result.stdout.fnmatch_lines(["*step 3 (t=0.30 s): no answer to the SensorView within 0.5 s "
                                 "(--avs-stack-timeout)*"])

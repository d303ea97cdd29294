"""The pytest plugin: options, the ``scenario`` marker, expansion into cases, judging.

Loaded through the ``pytest11`` entry point ``avscenario`` (``-p no:avscenario`` disables it).
Loading it imports only numpy and the plugin's light modules: highway-env, scipy, matplotlib
and the rest are imported when a scenario test is collected or run.

A test marked with ``@scenario`` becomes one item per concrete case (``test_x[halton-007]``).
Passive samplers fix every case at collection, identically on every machine for one seed;
active samplers are asked for item k's parameters when it runs and told its robustness when
it ends. After the body, the declared monitors judge the recorded trajectory; a violation
fails the item with every metric, the parameters and a command that re-runs just that case.
"""

from __future__ import annotations

import time
from typing import Any

import pytest

from .campaign import attach_to_html_report, build_world, executor_of, make_job, run_item
from .case import Case
from .expansion import CaseSlot, active_sampler, plan_of, plan_scenario
from .keys import (
    db_key,
    executor_key,
    pictures_key,
    plans_key,
    row_key,
    seed_key,
    session_key,
    shrink_rows_key,
)
from .reporting import RunState
from .settings import (
    DeclarationError,
    check_executor,
    default_driver,
    executor_name,
    open_db,
    session_seed,
)
from .space import SpaceError


# --------------------------------------------------------------------------- options
def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("avscenario", "scenario-based AV testing (pytest-avscenario)")

    def add(name: str, ini_help: str, ini_type: str = "string", **kw: Any) -> None:
        group.addoption(f"--avs-{name}", dest=f"avs_{name.replace('-', '_')}", **kw)
        parser.addini(f"avs_{name.replace('-', '_')}", ini_help, type=ini_type, default=None)

    add("seed", "seed of the run (an integer); default: a fresh one each run",
        metavar="N|last", default=None,
        help="seed for sampling and simulation; 'last' reuses the previous run's seed "
             "(default: a fresh seed, printed in the header)")
    add("samples", "cases per scenario test when the marker does not say",
        metavar="N", default=None, type=int,
        help="override the number of cases of every scenario test (e.g. 5 for a smoke run)")
    add("sampler", "sampler for scenario tests whose marker does not name one",
        metavar="NAME", default=None,
        help="override the sampler of every scenario test (halton, random, mab, ce, sa, bo)")
    add("driver", "built-in driver of the ego (autopilot or idm) when avs_driver is not overridden",
        metavar="NAME", default=None,
        help="built-in driver of the ego: 'autopilot' (default) or 'idm'; a conftest "
             "`avs_driver` fixture overrides this")
    add("report", "directory of the scenario report (error table, summary, plots); 'none' disables",
        metavar="DIR", default=None,
        help="write the scenario report under DIR (default avs-report; 'none' disables)")
    add("time-budget", "wall-time cap per scenario test and sampler (e.g. 30m, 90s)",
        metavar="DURATION", default=None,
        help="cap each scenario test's campaign per sampler (e.g. 30m, 90s, 1h); remaining "
             "cases are skipped")
    add("db", "replay database directory (default .avscenario at the rootdir; 'none' disables)",
        metavar="PATH", default=None,
        help="replay database of found counterexamples (default .avscenario at the rootdir; "
             "'none' disables)")
    add("shrink-budget", "simulations allowed to minimize each failing case (0 disables)",
        metavar="N", default=None, type=int,
        help="simulations allowed to minimize each failing case toward the nominal scenario "
             "(default 20; 0 disables)")
    add("executor", "where scenario cases are simulated: inprocess (default) or dask",
        metavar="NAME", default=None,
        help="where scenario cases are simulated: 'inprocess' (default) or 'dask'")
    add("dask-workers", "worker processes of the LocalCluster started for --avs-executor=dask",
        metavar="N", default=None, type=int,
        help="worker processes of the LocalCluster the plugin starts (default: one per core)")
    add("dask-timeout", "seconds to wait for the Dask scheduler",
        metavar="SECONDS", default=None, type=float,
        help="seconds to wait for the Dask scheduler before giving up (default 10)")
    add("dask-retries", "resubmissions of a case whose Dask worker died",
        metavar="N", default=None, type=int,
        help="how often a case whose worker died is resubmitted (default 2)")
    add("dask-address", "Dask scheduler address for --avs-executor=dask (default: a LocalCluster)",
        metavar="ADDRESS", default=None,
        help="scheduler of an existing Dask cluster, e.g. tcp://host:8786 (default: start a "
             "LocalCluster with one worker per core)")
    add("gifs", "GIFs rendered per scenario test for minimized counterexamples (0: none)",
        metavar="N", default=None, type=int,
        help="render a GIF of at most N minimized counterexamples per test (default 3; every "
             "one gets a PNG of its worst moment)")
    add("shrink-max", "failures per test and sampler that are minimized and stored (default: all)",
        metavar="N", default=None, type=int,
        help="minimize (and store for replay) only the first N failures of each scenario test "
             "and sampler; the rest are reported as found (default: every failure)")
    add("case-timeout", "seconds one scenario case may run before it is ended as an error",
        metavar="SECONDS", default=None,
        help="end a scenario case that runs longer than SECONDS (reported as an error with "
             "the time it ran)")
    group.addoption(
        "--avs-params", dest="avs_params", metavar="JSON", default=None,
        help="run the selected scenario cases with these parameter values "
             "(a JSON object; missing parameters take their nominal value)",
    )


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "scenario(**parameters, samples=N, sampler='halton', seed=None, monitors=[...]): "
        "an abstract driving scenario expanded into N concrete cases (pytest-avscenario). "
        "Use the @scenario decorator from pytest_avscenario rather than the bare mark.",
    )
    config.stash[plans_key] = {}
    config.stash[seed_key] = session_seed(config)
    _terminate_like_ctrl_c()
    check_executor(config)
    config.stash[db_key] = open_db(config)
    config.stash[session_key] = state = RunState(config)
    config.pluginmanager.register(state, "avscenario-run")
    if config.pluginmanager.hasplugin("xdist"):
        config.pluginmanager.register(_XdistHooks(), "avscenario-xdist")


def _terminate_like_ctrl_c() -> None:
    """Let SIGTERM end a run the way Ctrl-C does: pytest then still finishes the session, so
    the error table is closed and the partial summary and index are written.

    Only when nobody installed a handler of their own, and only in the main thread."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return
    if signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL:
        return

    def terminate(signum: int, frame: Any) -> None:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)  # a second SIGTERM kills at once
        raise KeyboardInterrupt("SIGTERM")

    signal.signal(signal.SIGTERM, terminate)


class _XdistHooks:
    """Registered only when pytest-xdist is installed: ship seed and database to the workers."""

    def pytest_configure_node(self, node: Any) -> None:
        node.workerinput["avs_seed"] = node.config.stash[seed_key]
        db = node.config.stash[db_key]
        if db is not None:
            node.workerinput["avs_db"] = db.snapshot()


def pytest_report_header(config: pytest.Config) -> str:
    seed = config.stash[seed_key]
    return f"avscenario: seed={seed} (replay with --avs-seed={seed})"


# --------------------------------------------------------------------------- expansion
def _fail_collection(test: str, message: str) -> None:
    raise pytest.Collector.CollectError(f"{test}: {message}")


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    marker = metafunc.definition.get_closest_marker("scenario")
    if marker is None:
        return
    test = metafunc.definition.nodeid
    try:
        plan, slots = plan_scenario(metafunc, marker)
    except (DeclarationError, SpaceError, ValueError) as exc:
        _fail_collection(test, str(exc))
    metafunc.config.stash[plans_key][test] = plan
    metafunc.parametrize("case", slots, ids=[s.id for s in slots], indirect=True)


# --------------------------------------------------------------------------- fixtures
@pytest.fixture
def case(request: pytest.FixtureRequest) -> Case:
    """The concrete case of a ``@scenario`` test: ``case.<parameter>``, ``case.seed``, ``case.rng``."""
    slot: CaseSlot | None = getattr(request, "param", None)
    if not isinstance(slot, CaseSlot):
        raise pytest.UsageError(
            f"{request.node.nodeid}: the `case` fixture is only available to tests decorated "
            "with @scenario(...)"
        )
    plan = plan_of(request.node)
    if plan.time_budget_s is not None:
        start = plan.started.setdefault(slot.sampler, time.monotonic())
        if time.monotonic() - start > plan.time_budget_s:
            pytest.skip(
                f"time budget of {plan.time_budget_s:g} s for {slot.sampler} spent after "
                f"{plan.ran.get(slot.sampler, 0)} cases"
            )
    params = slot.params
    if params is None:
        params = plan.asked.pop((slot.sampler, slot.index), None)  # asked ahead for a cluster
    if params is None:
        params = active_sampler(plan, slot.sampler).ask()
    return Case(params, index=slot.index, seed=slot.seed, sampler=slot.sampler,
                origin=slot.origin if request.config.getoption("avs_params") is None else "pinned",
                test=request.node.nodeid)


@pytest.fixture
def avs_driver(request: pytest.FixtureRequest) -> Any:
    """The AV under test driving the ego: override this fixture in conftest.py with your stack.

    Return a callable ``policy(observation) -> (acceleration, steering)``, an object with
    ``act(observation)`` or ``predict(observation)``, or a built-in name (``"autopilot"``,
    ``"idm"``). The default is ``--avs-driver`` / ini ``avs_driver`` or ``"autopilot"``.
    """
    return default_driver(request.config)


@pytest.fixture
def world(request: pytest.FixtureRequest, case: Case, avs_driver: Any) -> Any:
    """A fresh simulated world for this case, seeded from it, with ``avs_driver`` as the ego's."""
    return build_world(case, avs_driver, request.node.nodeid)


# --------------------------------------------------------------------------- running
@pytest.hookimpl(tryfirst=True)
def pytest_pyfunc_call(pyfuncitem: pytest.Function) -> bool | None:
    if pyfuncitem.get_closest_marker("scenario") is None or "case" not in pyfuncitem.funcargs:
        return None
    result = run_item(pyfuncitem)
    if result.outcome.verdict == "pass":
        return True
    if result.reraise:
        # pytest shows the body's own traceback, with our summary as a report section
        pyfuncitem.add_report_section("call", "avscenario", result.message)
        raise result.outcome.exc
    pytest.fail(result.message, pytrace=False)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Any:
    report = yield
    if call.when == "call" and row_key in item.stash:
        # extra report attributes travel to the xdist controller with the report
        report.avs_row = item.stash[row_key]
        report.avs_shrink_rows = item.stash.get(shrink_rows_key, [])
        report.avs_pictures = item.stash.get(pictures_key, {})
        if report.avs_pictures and item.config.pluginmanager.hasplugin("html"):
            attach_to_html_report(report, report.avs_pictures)
        report.avs_test = plan_of(item).info()
    return report


def pytest_collection_finish(session: pytest.Session) -> None:
    """Hand a remote executor the passive cases ahead, so its workers stay busy."""
    config = session.config
    if executor_name(config) == "inprocess" or hasattr(config, "workerinput"):
        return
    scenario_items = [item for item in session.items if isinstance(item, pytest.Function)
                      and item.get_closest_marker("scenario") is not None]
    if not scenario_items:
        return
    executor = executor_of(config)  # connect now: an unreachable cluster stops the run once
    jobs = []
    for item in scenario_items:
        slot = item.callspec.params.get("case") if hasattr(item, "callspec") else None
        if not isinstance(slot, CaseSlot):
            continue
        if slot.params is None:  # an active sampler's case: asked ahead once items run
            plan_of(item).items[(slot.sampler, slot.index)] = item
            continue
        case_obj = Case(slot.params, index=slot.index, seed=slot.seed, sampler=slot.sampler,
                        origin=slot.origin, test=item.nodeid)
        jobs.append(make_job(item, plan_of(item), case_obj, fresh_world=True, prefetch=True))
    if jobs:
        executor.prefetch(jobs)


def pytest_unconfigure(config: pytest.Config) -> None:
    executor = config.stash.get(executor_key, None)
    if executor is not None:
        executor.close()
    state = config.stash.get(session_key, None)
    if state is not None:
        state.close()

"""The pytest plugin's hooks and fixtures, and nothing else.

Loaded through the ``pytest11`` entry point ``avscenario`` (``-p no:avscenario`` disables it).
Loading it imports only the plugin's light modules — options, stash, the controller's and the
stopping's shells, the hookspecs — and neither numpy nor any ``report`` module: a repository
with the plugin installed and no scenario test pays ~no load time (bench/bench_load.py). The
campaign, collection, numpy, highway-env, scipy and matplotlib load when a scenario test is
collected or run.

A test marked with ``@scenario`` becomes one item per concrete case (``test_x[halton-007]``,
:mod:`.collect`); the session object (:mod:`.session`) runs each item's case through the
campaign pipeline (:mod:`pytest_avscenario.campaign.pipeline`); the controller
(:mod:`.controller`) writes the error table and the report. Settings come from
:mod:`.options`, once per session.
"""

from __future__ import annotations

import os
import sys
from typing import TYPE_CHECKING, Any

import pytest

from .astguard import guard_ast_parse
from .controller import RunState, compact_stash
from .options import DeclarationError, add_options, read_settings
from .stopping import ExitGuard, TermGuard, end_workers, shorten_interrupt, unknown_test_info
from .session import ScenarioSession, session_of
from .stash import (
    campaigns_key,
    case_item_key,
    controller_key,
    db_key,
    executor_key,
    guard_key,
    pictures_key,
    plans_key,
    result_key,
    row_key,
    sent_key,
    session_key,
    settings_key,
    shrink_rows_key,
)

guard_ast_parse()  # before pytest formats any failure of this process


if TYPE_CHECKING:
    from ..case import Case


def pytest_addhooks(pluginmanager: pytest.PytestPluginManager) -> None:
    """The plugin's own hooks (:mod:`.newhooks`): a conftest.py adds a sampler, a row sink, a
    card section or an acceptance criterion without private imports."""
    from . import newhooks

    pluginmanager.add_hookspecs(newhooks)


def pytest_addoption(parser: pytest.Parser) -> None:
    add_options(parser)


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "scenario(**parameters, samples=N, sampler='halton', seed=None, monitors=[...]): "
        "an abstract driving scenario expanded into N concrete cases (pytest-avscenario). "
        "Use the @scenario decorator from pytest_avscenario rather than the bare mark.",
    )
    config.stash[settings_key] = settings = read_settings(config)
    config.stash[plans_key] = {}
    config.stash[campaigns_key] = {}
    config.stash[guard_key] = guard = TermGuard()
    config.pluginmanager.register(guard, "avscenario-sigterm")
    config.pluginmanager.register(ExitGuard(config), "avscenario-exit")
    config.stash[db_key] = _open_db(config, settings.db_path)
    config.stash[controller_key] = state = RunState(config)
    config.stash[session_key] = ScenarioSession(config, config.stash[db_key], state)
    config.pluginmanager.register(state, "avscenario-run")
    if not hasattr(config, "workerinput"):  # a worker's reports go to the controller
        config.pluginmanager.register(_QuietReports(config), "avscenario-quiet-reports")
    if config.pluginmanager.hasplugin("xdist"):
        config.pluginmanager.register(_XdistHooks(config), "avscenario-xdist")
        if not hasattr(config, "workerinput") and getattr(config.option, "dist", "no") != "no":
            from .preload import Preload  # the controller's end-of-run imports, made meanwhile

            config.pluginmanager.register(Preload(config), "avscenario-preload")


def _open_db(config: pytest.Config, path: Any) -> Any:
    """The replay database, or None. Workers get the controller's snapshot (same items)."""
    if path is None:
        return None
    workerinput = getattr(config, "workerinput", None)
    if (workerinput is None or "avs_db" not in workerinput) and not os.path.lexists(path):
        return _DeferredDB(path)  # nothing stored yet: nothing to read or check now
    from ..db import DatabaseError, ReplayDB

    try:
        if workerinput is not None and "avs_db" in workerinput:
            return ReplayDB.from_snapshot(path, workerinput["avs_db"])
        db = ReplayDB(path)
        db.entries()  # read once now, so unreadable files are reported once, before collection
    except DatabaseError as exc:
        raise pytest.UsageError(f"avscenario replay database (--avs-db): {exc}") from None
    for message in db.warnings:
        config.issue_config_time_warning(pytest.PytestWarning(f"avscenario replay database: {message}"), 2)
    return db


class _DeferredDB:
    """The replay database of a directory that does not exist yet, made on first use: a
    repository without scenario tests (or with no stored failure) never loads ``db``."""

    def __init__(self, path: Any):
        self._path = path
        self._db: Any = None

    def __getattr__(self, name: str) -> Any:
        if self._db is None:
            from ..db import ReplayDB

            self._db = ReplayDB(self._path)
        return getattr(self._db, name)


class _XdistHooks:
    """Registered only when pytest-xdist is installed: ship seed and database to the workers,
    learn the collection order from them, give the case of a crashed worker its row, end the
    workers of an interrupted run."""

    def __init__(self, config: pytest.Config):
        self.config = config
        self.snapshot: list[dict] | None = None  # the replay database as the run began
        self.lastwords: str | None = None  # where workers' sentinels leave stuck cases' rows

    def pytest_unconfigure(self, config: pytest.Config) -> None:
        if self.lastwords is not None:
            import shutil

            shutil.rmtree(self.lastwords, ignore_errors=True)  # made by this run (mkdtemp)

    def pytest_xdist_node_collection_finished(self, node: Any, ids: Any) -> None:
        state = node.config.stash[controller_key]
        state.note_order(ids)  # the summary lists tests in this order
        state.note_items(ids, getattr(node.config.option, "numprocesses", None) or 1)

    def pytest_handlecrashitem(self, crashitem: str, report: Any, sched: Any) -> None:
        """A worker died running ``crashitem``: a scenario case still gets its (error) row."""
        state = self.config.stash[controller_key]
        if any(row.item == crashitem for row in state.rows):
            return  # its row came before the worker died (a case that would not stop)
        from ..samplers.base import available
        from .lastresort import last_words
        from .stopping import crash_row

        # a case stuck in C left its row with the worker's sentinel; else the generic one
        row = last_words(self.lastwords, crashitem) or crash_row(crashitem, set(available()) | {"replay", "example"})
        if row is not None:
            state.add(row, state.tests.get(row.test) or unknown_test_info(row.sampler))

    @pytest.hookimpl(wrapper=True)
    def pytest_runtest_logreport(self, report: pytest.TestReport) -> Any:
        result = yield
        guard = self.config.stash[guard_key]
        if getattr(report, "avs_row", None) is not None and not hasattr(self.config, "workerinput") \
                and not guard.installed:
            # the controller runs no item itself: its scenario work starts with the first row,
            # once every plugin has handled that row's report
            guard.install()
        return result

    @pytest.hookimpl(wrapper=True, tryfirst=True)
    def pytest_runtestloop(self, session: pytest.Session) -> Any:
        if hasattr(self.config, "workerinput") or not self.config.pluginmanager.hasplugin("dsession"):
            return (yield)
        from .stopping import whole_xdist_events

        with whole_xdist_events(self.config):
            return (yield)

    @pytest.hookimpl(tryfirst=True)
    def pytest_keyboard_interrupt(self, excinfo: Any) -> None:
        # tryfirst: before pytest's terminal renders the interrupt, and at once for the workers
        shorten_interrupt(self.config, excinfo)
        if not hasattr(self.config, "workerinput"):
            end_workers(self.config)

    def pytest_configure_node(self, node: Any) -> None:
        node.workerinput["avs_seed"] = node.config.stash[settings_key].seed
        if self.lastwords is None:
            import tempfile

            self.lastwords = tempfile.mkdtemp(prefix="avs-lastwords-")
        node.workerinput["avs_lastwords"] = self.lastwords
        db = node.config.stash[db_key]
        if db is not None:
            # one snapshot for every worker of the run, those that replace a crashed worker
            # included: all must collect the same items (xdist schedules by item index), and
            # counterexamples stored during this run replay in the next one
            if self.snapshot is None:
                self.snapshot = db.snapshot()
            node.workerinput["avs_db"] = self.snapshot


class _QuietReports:
    """pytest's terminal reporter keeps every report to the end of the run, each item's
    passed setup and teardown too (category ``""``), though it shows nothing of those but a
    teardown's captured teardown output (after the item's entry in the failures or passes
    summary): each such entry scans all of them for it, O(failures x items) with the default
    ``--tb``, and they cost ~1 KB of memory an item. Once every plugin has handled such a
    report of a scenario case, one with no teardown output, the reporter forgets it: its
    output stays the same (issue #35)."""

    def __init__(self, config: pytest.Config):
        self.config = config
        self.stats: dict[str, list[Any]] | None = None

    @pytest.hookimpl(trylast=True)
    def pytest_sessionstart(self, session: pytest.Session) -> None:
        terminal = self.config.pluginmanager.get_plugin("terminalreporter")
        stats = getattr(terminal, "stats", None)
        self.stats = stats if isinstance(stats, dict) else None

    @pytest.hookimpl(wrapper=True)
    def pytest_runtest_logreport(self, report: pytest.TestReport) -> Any:
        try:
            return (yield)
        finally:
            if self.stats is not None and report.when in ("setup", "teardown") and report.passed \
                    and not any("teardown" in name for name, _ in report.sections) \
                    and "scenario" in getattr(report, "keywords", ()):
                kept = self.stats.get("")
                if kept and kept[-1] is report:
                    kept.pop()


def pytest_report_header(config: pytest.Config) -> list[str]:
    from ..codec import identity_text
    from .identity import session_driver

    seed = config.stash[settings_key].seed
    # the driver the options name; a test whose avs_driver fixture is overridden records its
    # own (the report's "driver under test"), which conftests not loaded yet cannot tell here
    driver = session_driver(config)
    return [f"avscenario: seed={seed} (replay with --avs-seed={seed})",
            f"avscenario: driver={identity_text(driver, 'an avs_driver fixture overrides it')}"]


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    marker = metafunc.definition.get_closest_marker("scenario")
    if marker is None:
        if getattr(metafunc.function, "_avs_examples", None):
            # a pinned case of no scenario would otherwise be silently ignored
            raise pytest.Collector.CollectError(
                f"{metafunc.definition.nodeid}: @example pins a case of a @scenario test, but "
                "this test has no @scenario(...); add one (the parameters @example names are "
                "declared there) or remove the @example")
        return
    from ..space import SpaceError
    from .collect import plan_scenario

    test = metafunc.definition.nodeid
    config = metafunc.config
    try:
        plan, slots = plan_scenario(metafunc, marker, config.stash[settings_key], config.stash[db_key])
    except (DeclarationError, SpaceError, ValueError) as exc:
        raise pytest.Collector.CollectError(f"{test}: {exc}") from None
    config.stash[plans_key][test] = plan
    metafunc.parametrize("case", slots, ids=[s.id for s in slots], indirect=True)


@pytest.hookimpl(wrapper=True)
def pytest_make_collect_report(collector: pytest.Collector) -> Any:
    """A test module whose import failed inside a call to this package (a decorator's bad
    argument): a collection error naming the test, not the package's traceback."""
    report = yield
    call = report.__dict__.get("call")  # set by pytest's own implementation for this purpose
    if report.failed and isinstance(collector, pytest.Module) and getattr(call, "excinfo", None) \
            and not collector.config.getoption("fulltrace", False) \
            and collector.config.getoption("verbose", 0) < 2:
        from .collect import import_error_message

        message = import_error_message(collector, call.excinfo)
        if message is not None:
            report.longrepr = message
    return report


@pytest.fixture
def case(request: pytest.FixtureRequest) -> Case:
    """The concrete case of a ``@scenario`` test: ``case.<parameter>``, ``case.seed``, ``case.rng``."""
    from ..campaign.plan import CaseSlot

    slot: CaseSlot | None = getattr(request, "param", None)
    if not isinstance(slot, CaseSlot):
        raise pytest.UsageError(
            f"{request.node.nodeid}: the `case` fixture is only available to tests decorated "
            "with @scenario(...)"
        )
    return session_of(request.config).case_for(request.node, request)


@pytest.fixture
def avs_driver(request: pytest.FixtureRequest) -> Any:
    """The AV under test driving the ego: override this fixture in conftest.py with your stack.

    Return a callable ``policy(observation) -> (acceleration, steering)``, an object with
    ``act(observation)`` or ``predict(observation)`` answering the plugin's ``Observation``,
    a model trained on highway-env wrapped as ``highway_env_agent(model, env=...)``, a
    built-in name (``"autopilot"``, ``"idm"``, ``"careful"``) or a saved stable-baselines3
    model ``"sb3:PATH@ENV"``. The default is ``--avs-driver`` / ini ``avs_driver`` or
    ``"autopilot"``.
    """
    return request.config.stash[settings_key].driver


@pytest.fixture
def world(request: pytest.FixtureRequest, case: Case, avs_driver: Any) -> Any:
    """A fresh simulated world for this case, seeded from it, with ``avs_driver`` as the ego's."""
    return session_of(request.config).world(request.node, case, avs_driver)


def _is_scenario_case(item: pytest.Item) -> bool:
    if not isinstance(item, pytest.Function) or item.get_closest_marker("scenario") is None:
        return False  # before any import: plain tests never load the campaign
    from ..case import Case

    return isinstance(getattr(item, "funcargs", {}).get("case"), Case)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_setup(item: pytest.Item) -> Any:
    """Simulate the case as the last step of the item's setup, once its fixtures exist.

    A case that cannot be judged (the body or the driver raised, a scenario mistake, a time
    limit) is an *error* of the setup, as pytest and JUnit count errors; a counterexample
    fails the call that follows (:func:`pytest_pyfunc_call`).

    Every scenario item that gets this far keeps a row: one whose fixtures failed (a user's
    fixture, an active sampler that raised while its earlier cases were drawn) gets an error
    row naming the cause, as does one where something around its case went wrong."""
    try:
        result = yield
    except pytest.exit.Exception:
        raise
    except (Exception, pytest.fail.Exception) as exc:
        if item.get_closest_marker("scenario") is not None and _slot_of(item) is not None:
            record_error_row(item, f"the item's setup failed before its case ran: "
                                   f"{type(exc).__name__}: {exc}")
        raise
    config = item.config
    if not _is_scenario_case(item) or config.option.setuponly or config.option.setupplan:
        return result
    try:
        outcome = item.stash[result_key] = session_of(config).run_item(item)
    except pytest.exit.Exception:
        raise  # pytest.exit() in the body: the run ends here, this case has no verdict
    except Exception as exc:
        # whatever went wrong around the case (shrinking, storing, drawing), the item keeps
        # its row: an error naming the cause
        record_error_row(item, f"{type(exc).__name__}: {exc}")
        raise
    if outcome.outcome.verdict == "error":
        _raise_for(item, outcome, "setup")
    return result


@pytest.hookimpl(tryfirst=True)
def pytest_pyfunc_call(pyfuncitem: pytest.Function) -> bool | None:
    result = pyfuncitem.stash.get(result_key, None)
    if result is None:
        return None
    if result.outcome.verdict == "pass":
        return True
    if result.accepted is not None and pyfuncitem.config.stash[settings_key].junit_accepted == "passed":
        # --avs-junit-accepted=passed: a passing test case that still says what it found
        pyfuncitem.add_report_section("call", "avscenario", result.message)
        pyfuncitem.user_properties.append(("avs.accepted", result.accepted))
        return True
    _raise_for(pyfuncitem, result, "call")
    return None  # not reached


def _raise_for(item: pytest.Item, result: Any, when: str) -> None:
    if result.accepted is not None:
        # a counterexample the campaign's acceptance criteria accept: an expected failure,
        # still minimized, stored and reported
        item.add_report_section(when, "avscenario", result.message)
        if item.config.stash[settings_key].junit_accepted == "skipped":
            pytest.skip(result.accepted)
        pytest.xfail(result.accepted)
    if result.reraise:
        # pytest shows the body's own traceback, with our summary as a report section
        item.add_report_section(when, "avscenario", result.message)
        raise result.outcome.exc
    pytest.fail(result.message, pytrace=False)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Any:
    report = yield
    if call.when == "teardown":
        _release(item)
        return report
    if row_key not in item.stash:
        return report  # not a scenario case: nothing of the campaign is loaded for it
    pictures = item.stash.get(pictures_key, None)
    shown = call.when == "call" or (call.when == "setup" and not report.passed)
    if item.stash.get(sent_key, False) and not (
            pictures and shown and item.config.pluginmanager.hasplugin("html")):
        return report  # its row left already, and pytest-html shows no pictures on this report
    from .items import report_case

    report_case(item, call, report)
    return report


@pytest.hookimpl(wrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> Any:
    ran = yield
    if item.stash.get(sent_key, False):  # a scenario case, done: its item made small
        from .kept import slim_item

        slim_item(item)
    return ran


def _release(item: pytest.Item) -> None:
    """The item is done: nothing of its case outlives it but its row, which the controller
    holds. Its outcome (the simulated world, the trajectory, the body's exception and its
    frames) and the copy of its row it sent go, so a campaign's memory does not grow with the
    worlds of its cases (issue #35: 0.22 MB per case before)."""
    for key in (result_key, row_key, shrink_rows_key, case_item_key):
        if key in item.stash and (key is result_key or item.stash.get(sent_key, False)):
            del item.stash[key]
    if item.stash.get(sent_key, False):
        # its teardown report has its copy for the JUnit writer (which reads the teardown's)
        _drop_own_properties(item)
    compact_stash(item)


def _drop_own_properties(holder: Any) -> None:
    """The case's JUnit properties (``avs.*``, ~1 KB a case) off an item or a report that
    no longer needs them; a user's own properties stay."""
    props = getattr(holder, "user_properties", None)
    if props and any(str(name).startswith("avs.") for name, _ in props):
        props[:] = [(name, value) for name, value in props if not str(name).startswith("avs.")]


@pytest.hookimpl(wrapper=True, tryfirst=True)
def pytest_runtest_logreport(report: pytest.TestReport) -> Any:
    """Once every plugin has handled a report (tryfirst: around the others' implementations
    and wrappers), the JSON copy of its row that travelled with it goes (the controller keeps
    the row itself), and so do the case's JUnit properties: pytest's terminal reporter keeps
    every report to the end of the run, each made small (:mod:`.kept`). On an xdist worker
    too: its terminal reporter keeps every report of its cases as well (~3.5 KB a case, made
    small here), and xdist has sent the report (serialized while handling it) by now."""
    try:
        return (yield)
    finally:
        if getattr(report, "avs_row", None) is not None:
            for name in ("avs_row", "avs_shrink_rows", "avs_test"):
                report.__dict__.pop(name, None)
        if "scenario" in getattr(report, "keywords", ()):
            # pytest's JUnit writer took them (from the teardown report) as every other
            # plugin did while handling it; the terminal reporter keeps the report
            _drop_own_properties(report)
            if report.when == "call" or not report.passed:
                from .kept import slim_report

                slim_report(report)  # kept by the terminal reporter to the end


def pytest_collection_finish(session: pytest.Session) -> None:
    """Note which cases of active campaigns this run selects; hand a remote executor the
    passive cases ahead, so its workers stay busy."""
    config = session.config
    if not any(item.get_closest_marker("scenario") is not None for item in session.items):
        return  # no scenario case selected (or an xdist controller): nothing to note or send
    session_of(config).collection_finish(session)


def pytest_sessionfinish(session: pytest.Session) -> None:
    if session.config.stash[campaigns_key]:
        from .session import keep_drawn_values

        keep_drawn_values(session.config)


def _slot_of(item: pytest.Item) -> Any:
    from .collect import slot_of

    return slot_of(item)


def record_error_row(item: pytest.Item, error: str) -> None:
    """Give ``item`` an error row, unless it has its row already."""
    from .items import record_error_row as record

    record(item, error)


def pytest_unconfigure(config: pytest.Config) -> None:
    executor = config.stash.get(executor_key, None)
    if executor is not None:
        executor.close()
    stacks = sys.modules.get("pytest_avscenario.stack.client")
    if stacks is not None:  # the run is over: its spawned stacks too (atexit is the backstop)
        stacks.stop_all()
    state = config.stash.get(controller_key, None)
    if state is not None:
        state.close()

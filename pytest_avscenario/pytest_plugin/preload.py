"""An xdist controller's end-of-run imports, made while its workers run the cases.

The controller of a ``-n N`` run runs no case itself: it waits for its workers' reports. At
the end it writes the report — numpy, the report's modules, and scipy's k-d tree and Sobol
points for the ε-coverage of continuous parameters — and pytest's terminal summary calls
every plugin's hook, Hypothesis's among them, which imports Hypothesis whole. Made at the
end, those imports were most of the seconds a Ctrl-C under ``-n 2`` took to reach the shell
prompt (bench/bench_stop.py ``--ctrl-c-xdist``): the user waited for scipy to load so that an
interrupted run's report could be written.

:class:`Preload` makes them in a thread of the controller once its first row has been handled
(while the workers run the cases the controller only waits). Not before: by then the
controller's own thread has made its per-row imports (numpy, the report package), and the
two threads never initialize the same modules at once — a package whose modules import each
other, imported from two threads at the same time, can stop one of them with a deadlock
error. It imports only what the end of this run imports anyway — scipy only once a test with
a continuous parameter has reported, Hypothesis only while its pytest plugin is active — so a
run pays nothing more in all, and pays it before its end: a run that finishes reaches its
prompt sooner too. At the end of the session, before the report, the controller waits for the
thread (it would wait for those imports in any case); an import that fails here is tried
again, and reported, where the end of the run needs it.
"""

from __future__ import annotations

import importlib
import queue
import threading
from typing import Any

import pytest

#: what the report of a run with rows imports (interrupted or not: an interrupted run leaves
#: out the pictures, so matplotlib is not here)
REPORT_MODULES = (
    "numpy",
    "pytest_avscenario.space",
    "pytest_avscenario.acceptance",
    "pytest_avscenario.monitors.score",
    "pytest_avscenario.campaign.message",
    "pytest_avscenario.sim.drivers.identity",
    "pytest_avscenario.report.summary",
    "pytest_avscenario.report.modes",
    "pytest_avscenario.report.drivers",
    "pytest_avscenario.report.junit",
    "pytest_avscenario.report.compare",
    "pytest_avscenario.report.cards",
    "pytest_avscenario.report.html",
    "pytest_avscenario.report.build",
)

#: what the ε-coverage of continuous parameters imports (report/coverage.py)
COVERAGE_MODULES = ("scipy.spatial", "scipy.stats")

#: what Hypothesis's pytest plugin imports in its terminal summary, every run
HYPOTHESIS_MODULES = ("hypothesis.internal.observability",)

_DONE = object()


class Preload:
    """Registered on an xdist controller (see the module's text)."""

    def __init__(self, config: pytest.Config):
        self.config = config
        self.tests: set[str] = set()  # tests whose space was looked at
        self.coverage = False  # scipy is asked for already
        self.jobs: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self.thread: threading.Thread | None = None

    @pytest.hookimpl(wrapper=True)
    def pytest_runtest_logreport(self, report: pytest.TestReport) -> Any:
        result = yield  # the row handled first (its imports made in this thread)
        row = getattr(report, "avs_row", None)
        if row is not None and not self.coverage:
            test = row.get("test") if isinstance(row, dict) else None
            if test not in self.tests:
                self.tests.add(test)
                self._start()
                space = (getattr(report, "avs_test", None) or {}).get("space")
                if space:
                    self.jobs.put(space)
        return result

    def _start(self) -> None:
        if self.thread is not None:
            return
        modules = list(REPORT_MODULES)
        hypothesis = self.config.pluginmanager.get_plugin("hypothesispytest")
        if hypothesis is not None and hasattr(hypothesis, "pytest_terminal_summary"):
            modules += HYPOTHESIS_MODULES
        self.thread = threading.Thread(target=self._run, args=(modules,), name="avscenario-preload",
                                       daemon=True)
        self.thread.start()

    def _run(self, modules: list[str]) -> None:
        _import(modules[:len(REPORT_MODULES)])  # the report's own first: the end needs them first
        hypothesis = modules[len(REPORT_MODULES):]
        while True:
            try:
                job = self.jobs.get_nowait() if hypothesis else self.jobs.get()
            except queue.Empty:
                _import(hypothesis)  # no space waits to be looked at: Hypothesis's turn
                hypothesis = []
                continue
            if job is _DONE:
                _import(hypothesis)
                return
            if not self.coverage and _has_continuous(job):
                self.coverage = True
                _import(COVERAGE_MODULES)

    @pytest.hookimpl(wrapper=True)
    def pytest_sessionfinish(self, session: pytest.Session) -> Any:
        # (a plain wrapper: inside the stop guard's, which holds a SIGTERM or Ctrl-C for the
        # report, and around the report itself)
        self.finish()
        return (yield)

    def finish(self) -> None:
        """Wait for the imports (the end of the run makes them next in any case)."""
        thread, self.thread = self.thread, None
        if thread is not None:
            self.jobs.put(_DONE)
            thread.join()

    def pytest_unconfigure(self, config: pytest.Config) -> None:
        self.finish()  # a session that ended without its sessionfinish: no thread outlives it


def _import(modules: list[str] | tuple[str, ...]) -> None:
    for name in modules:
        try:
            importlib.import_module(name)
        except BaseException:  # noqa: BLE001 - the end of the run imports it again, and says why
            pass


def _has_continuous(description: Any) -> bool:
    try:
        from ..space import FeatureSpace

        return bool(FeatureSpace.from_description(description).continuous)
    except Exception:  # noqa: BLE001 - a space the report will rebuild (and report) itself
        return True

"""The controller: the run's error table as cases finish, the xdist merge, the report at the end.

:class:`RunState` is registered as a plugin object of its config. Rows reach it through
``pytest_runtest_logreport`` — from this process, or from pytest-xdist's workers, whose
reports carry them as JSON (:meth:`~pytest_avscenario.outcome.CaseRow.to_json`) — and are
written to the error table at once. The first row (or the first case picture) claims the
report directory (:func:`~pytest_avscenario.report.folder.claim_report_dir`: a lock, and a
manifest of our files, so another run's or a user's files are never lost; a run that finds
the directory taken writes to a sibling ``DIR-2`` and says so). Workers draw case pictures
in a private temporary folder, and the controller moves them into the directory it claimed.
At the end of the session it builds the report (summary, plots, index page) from the rows it
holds, adds the suite properties to the JUnit file, and prints the paper's table; each of
those parts is guarded on its own, so a failing one is a warning and never changes the
run's exit status.
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Mapping

import pytest

from .. import files
from ..campaign.versions import versions
from .stash import settings_key

if TYPE_CHECKING:  # loaded with the first row: a run without scenario tests never needs it
    from ..outcome import CaseRow

#: where a run that re-runs some cases (``-k``, ``--lf``, a case id) writes its report, inside
#: the report folder, so the campaign's report stays as it was
RERUN_DIR = "rerun"

#: the prefix of a worker's temporary picture folder (the controller moves what is inside)
STAGING_PREFIX = "avs-cases-"

#: a serial run with at least this many rows makes its plots and ε-coverage at its end in a
#: helper process (:mod:`..report.ahead`), as an xdist controller does: the pytest process
#: then never imports matplotlib and scipy (~110 MB, issue #35: a 100,000-case campaign
#: within 500 MB) nor holds the plots' per-case arrays, and the helper draws while this
#: process writes the summary and the cards. Below it, starting a helper (an interpreter
#: and its imports, ~1-2 s of CPU) costs more than drawing here.
SERIAL_AHEAD_MIN_ROWS = 5000


class RunState:
    """The controller's view of the run: the error table and what the summary needs."""

    def __init__(self, config: pytest.Config):
        self.config = config
        self.is_worker = hasattr(config, "workerinput")
        #: the process that runs the session: a child the test body forked and that carried on
        #: into pytest must not write rows (it would give an item two, #32 item 9)
        self.pid = os.getpid()
        self.requested: Path | None = config.stash[settings_key].report_dir
        self.folder: Any = None  # the claimed report.folder.ReportFolder, while it is usable
        self._claimed: Any = None  # the same, kept to release its lock at the end
        self._claim_tried = False
        self._staging: Path | None = None  # a worker's temporary picture folder
        self._staged: set[Path] = set()  # workers' picture folders the controller emptied
        self.table: Any = None
        self.rows: list[CaseRow] = []
        self.tests: dict[str, dict[str, Any]] = {}
        self.summary_rows: list[Any] | None = None
        self.case_files: dict[str, dict[str, str]] = {}  # item id -> {kind: path} (cards)
        self.order: dict[str, None] = {}  # scenario tests in collection order
        #: why this run re-runs some cases rather than whole campaigns (None: it does not);
        #: such a run writes its report to ``DIR/rerun`` and leaves the campaign's report be
        self.partial: str | None = None
        #: why the run ended before every selected case ran (None: it did not); summary.json
        #: then says ``"interrupted": true`` and the exit status is never 0
        self.stopped: str | None = None
        self.hurry = False  # the run was interrupted: no pictures in its report
        #: an xdist controller's helpers making each finished test's plots and ε ahead of the
        #: end (report.ahead.ReportAhead), and the items of each test still to finish
        self.ahead: Any = None
        self._left: dict[str, int] | None = None
        self._workers = 1

    @property
    def directory(self) -> Path | None:
        """Where this process writes report files: on the controller the directory it claims
        (claimed now, on first use); on an xdist worker a temporary folder of its own, whose
        pictures the controller moves into its directory. None: no report."""
        if self.requested is None:
            return None
        if self.is_worker:
            if self._staging is None:
                try:
                    self._staging = Path(tempfile.mkdtemp(prefix=STAGING_PREFIX))
                except OSError:
                    return None  # no temporary folder: no pictures, the cases still run
            return self._staging
        folder = self.claim()
        return None if folder is None else folder.path

    def claim(self) -> Any:
        """The report folder of this run, claimed on first call (None: no report)."""
        if self._claim_tried or self.requested is None or self.is_worker:
            return self.folder
        self._claim_tried = True
        from ..report.folder import claim_report_dir, describe_fallback

        requested = self.requested if not self.partial else self.requested / RERUN_DIR
        try:
            folder, passed_over = claim_report_dir(requested)
        except OSError as exc:
            self.report_failed(exc)
            return None
        self.folder = self._claimed = folder
        if passed_over:
            self.warn(describe_fallback(requested, folder.path, passed_over))
        return folder

    def note_order(self, nodeids: Any) -> None:
        """The collection order (this process's items, or an xdist worker's ids)."""
        for nodeid in nodeids:
            self.order.setdefault(nodeid.partition("[")[0], None)

    def note_items(self, nodeids: Any, workers: int) -> None:
        """An xdist controller learns the items (the first worker's collection; every worker
        collects the same) and how many workers run them: from then on, each test whose
        items have all finished has its plots and ε made ahead by as many helper processes
        (:mod:`..report.ahead`), while the other tests' cases run."""
        if self._left is not None or self.requested is None or self.is_worker:
            return
        left: dict[str, int] = {}
        for nodeid in nodeids:
            test = nodeid.partition("[")[0]
            left[test] = left.get(test, 0) + 1
        self._left = left
        try:
            workers = int(workers or 1)
        except (TypeError, ValueError):  # an xdist that left "auto" unresolved
            workers = os.cpu_count() or 1
        self._workers = max(1, min(workers, os.cpu_count() or 1))

    # -- hooks (this object is registered as a plugin for its config) ---------------------
    def pytest_collection_finish(self, session: pytest.Session) -> None:
        self.note_order(item.nodeid for item in session.items)

    def pytest_runtest_logfinish(self, nodeid: str) -> None:
        left = self._left
        if left is None:  # not an xdist controller: its report is made at the end
            return
        if self.ahead is None:  # the first item: the helpers start (and import) meanwhile
            self.start_ahead()
            if self._left is None:
                return
        test = nodeid.partition("[")[0]
        n = left.get(test)
        if n is None:
            return
        if n > 1:
            left[test] = n - 1
            return
        del left[test]
        self.guarded("the plots and ε-coverage made ahead", test, lambda: self.make_ahead(test))

    def start_ahead(self) -> None:
        """Start the helpers of the report; if they cannot start (a machine without the
        semaphores multiprocessing needs), say so once and make the report at the end."""
        if self.ahead is not None or self.hurry or self.folder is None or os.getpid() != self.pid:
            return
        from ..report.ahead import ReportAhead

        ahead = ReportAhead(self.folder.path, self._workers)
        try:
            ahead.start()
        except Exception as exc:
            self._left = None
            ahead.cancel()
            self.part_failed("the plots and ε-coverage ahead of the end (helper processes)", None, exc)
            return
        self.ahead = ahead

    def make_ahead(self, test: str) -> None:
        """Hand ``test``'s plots and ε-coverage to the helpers, from the rows it has."""
        if self.hurry or self.folder is None or os.getpid() != self.pid:
            return
        info = self.tests.get(test)
        if info is None or info.get("unknown"):
            return
        rows = [r for r in self.rows if r.test == test and r.origin != "shrink"]
        if not rows:
            return
        self.start_ahead()
        if self.ahead is None:
            return
        for path in self.ahead.submit(test, rows, info):
            self.folder.add(path)  # in the manifest before a helper writes it

    def drawn_ahead(self, test: str, rows: list[CaseRow]) -> Any:
        return self.ahead.plots(test, rows, self.tests.get(test)) if self.ahead is not None else None

    def coverage_ahead(self, test: str, sampler: str, sampled: list[CaseRow]) -> Any:
        return self.ahead.coverage(test, sampler, sampled, self.tests.get(test)) if self.ahead is not None else None

    def modes_ahead(self, test: str, sampler: str, main: list[CaseRow], order: tuple[str, ...]) -> Any:
        return self.ahead.modes(test, sampler, main, order, self.tests.get(test)) if self.ahead is not None else None

    def end_ahead(self, cancel: bool = False) -> None:
        """The helpers' end: after the report, or at once (``cancel``: an interrupted run,
        whose report has no pictures — those they drew go too)."""
        ahead, self.ahead = self.ahead, None
        self._left = None
        if ahead is None:
            return
        if not cancel:
            ahead.close()
            return
        paths = ahead.cancel()
        for path in paths:
            try:
                path.unlink()
            except OSError:
                pass
        for folder in {path.parent for path in paths}:
            try:
                folder.rmdir()  # the plots folder a helper made, if it holds nothing else
            except OSError:
                pass

    def pytest_keyboard_interrupt(self, excinfo: Any) -> None:
        # Ctrl-C, SIGTERM (read as Ctrl-C), pytest.exit(), or a session told to stop
        value = getattr(excinfo, "value", None)
        self.stopped = self.stopped or f"{type(value).__name__}: {value}".rstrip(": ")
        # somebody wants the run over: the report keeps what must survive (summary.json,
        # index.html, the error table, the cards, JUnit) and leaves out the pictures, whose
        # drawing grows with the rows and would outlast a CI runner's grace before SIGKILL
        self.hurry = True
        self.guarded("ending the helpers of the report", None, lambda: self.end_ahead(cancel=True))
        # what exists now lives to the end of the run; in the permanent generation, the
        # collections pytest runs at its end (five full ones while unconfiguring), those the
        # report triggers and the interpreter's at exit no longer walk it — seconds per 10,000
        # items of a large campaign, and 0.7 s of an xdist controller's exit with scipy and
        # Hypothesis loaded (bench/bench_stop.py), which a Ctrl-C waits for. (Garbage cycles
        # made before now are not looked at again: an interrupted run does not report
        # unraisable exceptions of theirs.)
        import gc

        gc.freeze()

    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        data = getattr(report, "avs_row", None)
        # only the process that started the run writes rows (a body's forked child does not)
        if data is not None and not self.is_worker and os.getpid() == self.pid:
            if getattr(report, "avs_partial", None) and not self.partial:
                self.partial = report.avs_partial  # an xdist worker's selection
            # the case's shrink rows, then its own row, in one go
            # the test's declaration came with its first report from this process or worker
            self.add_rows([*getattr(report, "avs_shrink_rows", ()), data], getattr(report, "avs_test", None))
            pictures = getattr(report, "avs_pictures", None)
            if pictures:
                self.case_files.setdefault(data["item"], {}).update(self.place_pictures(data["test"], pictures))

    @pytest.hookimpl(tryfirst=True)
    def pytest_sessionfinish(self, session: pytest.Session) -> None:
        # tryfirst: the suite properties must reach pytest's JUnit writer before it writes
        if self.is_worker or os.getpid() != self.pid:
            return
        self.remove_staging()
        if not self.rows:
            return
        self.summary_rows = None
        try:
            verdicts = self.verdicts()
        except Exception as exc:
            # the gate could not be judged: never a pass (a bad count once made every verdict
            # null and the run exit 0); say why, fail the build
            self.part_failed("the acceptance verdicts", None, exc)
            verdicts = None
            if session.exitstatus == pytest.ExitCode.OK:
                session.exitstatus = pytest.ExitCode.TESTS_FAILED
        if verdicts and session.exitstatus == pytest.ExitCode.OK:
            session.exitstatus = pytest.ExitCode.TESTS_FAILED  # a rejected campaign fails the build
        self.stopped = self.stopped or _stopped(session)
        if self.stopped and session.exitstatus == pytest.ExitCode.OK:
            # some cases never ran: whatever the finished ones say, the run is not "passed"
            session.exitstatus = pytest.ExitCode.INTERRUPTED
        infos = self.guarded("the scenario declarations", None, self.test_infos) or {}
        settings = self.config.stash[settings_key]
        if self.folder is not None and self.table is not None:
            self.guarded("the error table (closing it)", None, self.table.close)
            if self._left is None and not self.hurry and self.ahead is None \
                    and len(self.rows) >= SERIAL_AHEAD_MIN_ROWS:
                # a large serial run: its plots and ε made by a helper from the error table
                self._workers = 1
                for test in self.tests:
                    self.guarded("the plots and ε-coverage made ahead", test, lambda test=test: self.make_ahead(test))
            elif self._left is not None and not self.hurry:
                # an xdist controller: the tests not handed to the helpers yet have their plots
                # and ε made there (the workers are done: their cores are free) while this
                # process makes the rest of the summary and the cards
                for test in [t for t in self.tests if self.ahead is None or not self.ahead.submitted(t)]:
                    self.guarded("the plots and ε-coverage made ahead", test, lambda test=test: self.make_ahead(test))

            def report() -> list[Any]:
                from ..report.build import finish_report
                from .identity import session_driver

                return finish_report(self.folder.path, infos, rows=self.rows, folder=self.folder,
                                     on_error=self.part_failed, seed=settings.seed, versions=versions(),
                                     case_files=self.case_files, verdicts=verdicts,
                                     rerun=self.rerun_command, partial=self.partial,
                                     baseline=settings.baseline, driver=session_driver(self.config),
                                     card_sections=self.card_sections, interrupted=self.stopped,
                                     pictures=not self.hurry, drawn=self.drawn_ahead,
                                     known_coverage=self.coverage_ahead, known_modes=self.modes_ahead)

            self.summary_rows = self.guarded("the report", None, report)
        self.guarded("ending the helpers of the report", None, lambda: self.end_ahead(cancel=self.hurry))
        if self.summary_rows is None:
            self.summary_rows = self.guarded("the summary", None, lambda: self.summary(verdicts, infos)) or []
        self.guarded("the JUnit suite properties", None, self.add_suite_properties)

    def drivers(self) -> tuple[Any, dict[str, Any]]:
        """(the run's driver under test, {test: its driver}) from the rows (:mod:`..report.drivers`)."""
        from ..report.drivers import drivers_of
        from .identity import session_driver

        return drivers_of(self.rows, session_driver(self.config))

    def card_sections(self, row: CaseRow) -> list[tuple[str, str]]:
        """The ``(title, html)`` sections conftest.py files add to ``row``'s card (newhooks)."""
        found = self.config.hook.pytest_avscenario_card_sections(config=self.config, row=row)
        return [(str(title), str(body)) for sections in found for title, body in (sections or ())]

    def rerun_command(self, row: CaseRow) -> str:
        """The command that re-runs the case of ``row`` (for its card)."""
        from ..campaign.message import rerun_text

        space = (self.tests.get(row.test) or {}).get("space") or {}
        return rerun_text(self.config.stash[settings_key], row.item, row.params, space)

    def add_suite_properties(self) -> None:
        from _pytest.junitxml import xml_key

        from ..report.drivers import driver_properties
        from ..report.junit import add_suite_properties_to_logxml, case_suite_properties
        from ..report.summary import suite_properties

        settings = self.config.stash[settings_key]
        props = suite_properties(self.summary_rows or [], seed=settings.seed, versions=versions())
        props.update(driver_properties(*self.drivers()))
        if settings.junit == "strict":
            for row in self.rows:
                if row.origin != "shrink":
                    props.update(case_suite_properties(row))
        add_suite_properties_to_logxml(self.config.stash.get(xml_key, None), props)

    def pytest_terminal_summary(self, terminalreporter: Any) -> None:
        if self.is_worker or not self.rows:
            return
        summary = self.summary_rows
        if summary is None:
            summary = self.guarded("the summary", None, lambda: self.summary(self.verdicts())) or []
        terminalreporter.write_sep("=", "avscenario")
        width = shutil.get_terminal_size(fallback=(120, 24)).columns  # COLUMNS, if set

        def table() -> None:
            from ..report.summary import format_rejections, format_table

            for line in format_table(summary, width=width).splitlines():
                terminalreporter.write_line(line)
            for line in format_rejections(summary):
                terminalreporter.write_line(line, red=True, bold=True)

        self.guarded("the terminal table", None, table)
        baseline = self.config.stash[settings_key].baseline
        run_driver = (self.guarded("the driver under test", None, self.drivers) or (None, {}))[0]
        if run_driver is not None:
            from ..sim.drivers.identity import identity_text

            terminalreporter.write_line(f"driver under test: {identity_text(run_driver)}")
        if baseline is not None and summary and not self.partial:  # a few cases have no rates
            def comparison() -> None:
                from ..report.compare import compare, format_comparison
                from ..report.drivers import baseline_driver_warning

                warning = baseline_driver_warning(run_driver, baseline)
                if warning is not None:
                    terminalreporter.write_line(f"WARNING: {warning}", yellow=True, bold=True)

                for line in format_comparison(compare(summary, baseline)):
                    terminalreporter.write_line(line)

            self.guarded("the comparison with the baseline", None, comparison)
        if self.folder is not None:
            from ..report.summary import format_pointer

            terminalreporter.write_line(format_pointer(self.folder.path))

    # -- state ----------------------------------------------------------------------------
    def add(self, row: CaseRow, info: dict[str, Any]) -> None:
        self.add_rows([row], info)

    def add_rows(self, rows: list[CaseRow | dict[str, Any]], info: dict[str, Any] | None) -> None:
        """Keep finished cases' rows (one item's shrink rows and its own row; rows or their
        JSON data), each handed to the ``pytest_avscenario_case_finished`` hooks and written to
        the error table in turn. ``info``: the test's declaration, None when an earlier
        report brought it."""
        from ..outcome import CaseRow

        for given in rows:
            row = CaseRow.coerce(given)
            known = self.tests.get(row.test)
            if info is not None and (known is None or known.get("unknown")):
                # the first row of the test, or the first one to know the test (a crashed
                # worker's row knows nothing of its declaration)
                self.tests[row.test] = info
            elif known is None:
                from .stopping import unknown_test_info

                self.tests[row.test] = unknown_test_info(row.sampler)
            self.rows.append(row)
            try:
                self.config.hook.pytest_avscenario_case_finished(config=self.config, row=row)
            except Exception as exc:
                # a team's row sink (newhooks) that raises costs a warning, not the run's rows
                self.warn(f"avscenario: a pytest_avscenario_case_finished hook raised for {row.item} "
                          f"({type(exc).__name__}: {exc}); the case's row is kept")
            tried = self._claim_tried or self.requested is None or self.is_worker
            folder = self.folder if tried else self.claim()  # claimed once, on the first row
            if folder is None:
                continue
            try:
                if self.table is None:
                    from ..report.table import ErrorTable

                    self.table = ErrorTable(folder.path, folder=folder)
                # JSON data from a worker is the row's to_json(): written as it came
                self.table.append(row, data=given if given is not row else None)
            except OSError as exc:
                # the run goes on (verdicts, the replay database and the terminal summary do not
                # depend on the report); say once what was lost and where
                self.report_failed(exc)

    def table_path(self) -> str | None:
        """The path of this run's ``errors.jsonl``, the table opened now if it was not yet
        (None: no report here, or an xdist worker): where a row written from outside this
        process goes (:mod:`.lastresort`)."""
        if self.is_worker or os.getpid() != self.pid:
            return None
        if self.table is None:
            folder = self.claim()
            if folder is None:
                return None
            try:
                from ..report.table import ErrorTable

                self.table = ErrorTable(folder.path, folder=folder)
            except OSError as exc:
                self.report_failed(exc)
                return None
        return str(self.table.main_path)

    def place_pictures(self, test: str, pictures: Mapping[str, str]) -> dict[str, str]:
        """The case pictures of a report, in this run's directory: recorded in its manifest,
        and moved there from the worker's temporary folder that drew them."""
        folder = self.claim()
        out = {}
        for caption, path in pictures.items():
            p = Path(path)
            staged = p.parent.name == "cases" and p.parent.parent.name.startswith(STAGING_PREFIX)
            try:
                if folder is not None and folder.owns(p):
                    folder.add(p)
                elif staged and folder is not None:
                    target = folder.add(folder.path / "cases" / p.name)
                    files.move_file(p, target)  # never through a link in the folder
                    self._staged.add(p.parent.parent)
                    p = target
                elif staged:
                    p.unlink(missing_ok=True)  # a worker's picture, and no report to put it in
                    self._staged.add(p.parent.parent)
                    continue
            except OSError as exc:
                self.part_failed("a case picture", test, exc)
                continue
            out[caption] = str(p)
        return out

    def remove_staging(self) -> None:
        """Remove the workers' picture folders the controller emptied (and this worker's own,
        if it stayed empty); folders with anything left in them stay."""
        for folder in [*self._staged, *([self._staging] if self._staging else [])]:
            for path in (folder / "cases", folder):
                try:
                    path.rmdir()
                except OSError:
                    pass

    def part_failed(self, part: str, test: str | None, exc: Exception) -> None:
        """One part of the report could not be made: say which and why; the rest goes on."""
        where = f" of {test}" if test else ""
        if isinstance(exc, OSError):  # a full disk, a read-only folder: the machine's, not a bug
            self.warn(f"avscenario: the report could not write {part}{where} under "
                      f"{self.requested} ({exc.strerror or exc}); the other parts of the report "
                      "are still written and the tests' outcomes stand")
            return
        self.warn(f"avscenario: the report could not make {part}{where} ({type(exc).__name__}: {exc}); "
                  "the other parts of the report are still written and the tests' outcomes stand. "
                  "Please report this to pytest-avscenario with the scenario's declaration")

    def guarded(self, part: str, test: str | None, make: Callable[[], Any]) -> Any:
        try:
            return make()
        except Exception as exc:
            self.part_failed(part, test, exc)
            return None

    def warn(self, message: str) -> None:
        try:
            self.config.issue_config_time_warning(pytest.PytestWarning(message), 3)
        except Exception:  # -W error turned it into an exception: the message must still show
            sys.stderr.write(f"{message}\n")

    def report_failed(self, exc: OSError) -> None:
        folder, self.folder = self.folder, None
        directory = folder.path if folder is not None else self.requested
        if self.table is not None:
            try:
                self.table.close()
            except OSError:
                pass
        self.table = None
        self.warn(f"avscenario: cannot write the report under {directory} ({exc}); the rest of "
                  "this run is reported in the terminal only")

    def close(self) -> None:
        """The end of the run: close the error table, fold the manifest, give the lock back.
        Each step on its own: a full disk (ENOSPC while a buffer is flushed) is one line
        naming the folder, never a traceback out of pytest_unconfigure that turns an
        all-passing run into exit status 1 — every row was flushed as it came."""
        if self.ahead is not None:  # the session did not finish: what the helpers drew goes
            self.guarded("ending the helpers of the report", None, lambda: self.end_ahead(cancel=True))
        steps = [("the error table", self.table.close)] if self.table is not None else []
        if self._claimed is not None:
            steps.append(("the report folder's manifest and lock", self._claimed.release))
        for what, step in steps:
            try:
                step()
            except OSError as exc:
                directory = self._claimed.path if self._claimed is not None else self.requested
                _say(f"avscenario: could not finish {what} under {directory} "
                     f"({exc.strerror or exc}); the rows and the report written before stand")
        if self.is_worker:
            self.remove_staging()

    def test_infos(self) -> dict[str, Any]:
        """What the summary knows of each scenario test; a declaration whose space cannot be
        rebuilt is reported and summarized without ε."""
        from ..report.summary import TestInfo

        ordered = sorted(self.tests, key=list(self.order).index) if set(self.tests) <= set(self.order) \
            else list(self.tests)
        infos = {}
        for test in ordered:
            info = self.tests[test]
            space = self.guarded("the ε-coverage (rebuilding the parameter space)", test,
                                 lambda: _space_of(info["space"]))
            infos[test] = TestInfo(metrics=tuple(info["metrics"]), space=space,
                                   priority=tuple(info.get("priority") or ()),
                                   samplers=tuple(info["samplers"]))
        return infos

    def summary(self, verdicts: Mapping[tuple[str, str], list[str]] | None = None,
                infos: Mapping[str, Any] | None = None) -> list[Any]:
        from ..report.summary import summarize

        return summarize(self.rows, self.test_infos() if infos is None else infos, verdicts=verdicts,
                         on_error=self.part_failed)

    def verdicts(self) -> dict[tuple[str, str], list[str]]:
        """The rejected campaigns, (test, sampler) -> reasons, by each test's criteria."""
        from ..acceptance import Criteria, campaign_verdict, case_verdict

        baseline = self.config.stash[settings_key].baseline
        campaigns: dict[tuple[str, str], list[CaseRow]] = {}
        for row in self.rows:
            if row.origin != "shrink":
                campaigns.setdefault((row.test, row.sampler), []).append(row)
        out = {}
        for (test, sampler), rows in campaigns.items():
            info = self.tests[test]
            criteria = Criteria.from_json(info["accept"])
            rejected = []
            for r in rows:
                if r.verdict != "fail":
                    continue
                why = case_verdict(criteria, r, [m for m, v in r.rho.items() if v is not None and v < 0])
                if why is not None:
                    rejected.append((r.item, why))
            reasons = list(campaign_verdict(criteria, rows, rejected, baseline, test, sampler,
                                            info["metrics"]) or [])
            # a team's own criteria (newhooks): every implementation's reasons count
            for extra in self.config.hook.pytest_avscenario_campaign_verdict(
                    config=self.config, test=test, sampler=sampler, rows=list(rows)):
                reasons += [str(r) for r in extra or ()]
            if reasons:
                out[(test, sampler)] = reasons
        return out


def compact_stash(item: Any) -> None:
    """The item's stash, once its case's keys are gone, in a dict of the size it needs now:
    a dict never shrinks, and our keys beside pytest's made it grow to the next size
    (~0.13 KB an item, kept to the end of the run; issue #35). Here, in a module loaded with
    the plugin: it runs for every item, a plain test's too (:mod:`.items` loads numpy)."""
    storage = getattr(item.stash, "_storage", None)
    if type(storage) is dict:
        # key by key: dict(storage) would copy its table, at the size it grew to
        item.stash._storage = {key: value for key, value in storage.items()}


def empty_stash(item: Any) -> None:
    """The item's stash emptied once its protocol has ended (:func:`.kept.slim_item`): what
    pytest's plugins and ours kept there for its run is read by nothing any more. Here,
    beside :func:`compact_stash`: the plugin's reads of pytest's private attributes stay in
    three modules."""
    storage = getattr(item.stash, "_storage", None)
    if type(storage) is dict and storage:
        item.stash._storage = {}


def _space_of(description: Any) -> Any:
    from ..space import FeatureSpace  # numpy: only once there are scenario rows

    return FeatureSpace.from_description(description)


def _say(message: str) -> None:
    """A last word after the terminal reporter is gone (pytest_unconfigure)."""
    try:
        sys.stderr.write(f"{message}\n")
        sys.stderr.flush()
    except Exception:  # noqa: BLE001 - nowhere left to say it
        pass


def _stopped(session: pytest.Session) -> str | None:
    """Why ``session`` ended before its last item (``-x``, ``--maxfail``, a plugin that
    stopped it), or None."""
    for reason in (session.shouldstop, session.shouldfail):
        if reason:
            return str(reason) if not isinstance(reason, bool) else "the session was stopped"
    return None

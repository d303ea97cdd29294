"""The controller: the run's error table as cases finish, the xdist merge, the report at the end.

:class:`RunState` is registered as a plugin object of its config. Rows reach it through
``pytest_runtest_logreport`` — from this process, or from pytest-xdist's workers, whose
reports carry them as JSON (:meth:`~pytest_avscenario.outcome.CaseRow.to_json`) — and are
written to the error table at once. At the end of the session
it builds the report (summary, plots, index page), adds the suite properties to the JUnit
file, and prints the paper's table.
"""

from __future__ import annotations

import shutil
import time
from typing import Any, Mapping

import pytest

from ..outcome import CaseRow
from ..space import FeatureSpace
from .stash import settings_key


class RunState:
    """The controller's view of the run: the error table and what the summary needs."""

    def __init__(self, config: pytest.Config):
        self.config = config
        self.is_worker = hasattr(config, "workerinput")
        self.directory = config.stash[settings_key].report_dir
        self.table: Any = None
        self.rows: list[CaseRow] = []
        self.tests: dict[str, dict[str, Any]] = {}
        self.summary_rows: list[Any] | None = None
        self.pictures: dict[str, dict[str, str]] = {}
        self.started = time.time()
        self.order: dict[str, None] = {}  # scenario tests in collection order

    def note_order(self, nodeids: Any) -> None:
        """The collection order (this process's items, or an xdist worker's ids)."""
        for nodeid in nodeids:
            self.order.setdefault(nodeid.partition("[")[0], None)

    # -- hooks (this object is registered as a plugin for its config) ---------------------
    def pytest_collection_finish(self, session: pytest.Session) -> None:
        self.note_order(item.nodeid for item in session.items)

    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        data = getattr(report, "avs_row", None)
        if data is not None and not self.is_worker:
            for shrink_row in getattr(report, "avs_shrink_rows", ()):
                self.add(CaseRow.from_json(shrink_row), report.avs_test)
            row = CaseRow.from_json(data)
            self.add(row, report.avs_test)
            pictures = getattr(report, "avs_pictures", None)
            if pictures:
                self.pictures.setdefault(row.test, {}).update(pictures)

    @pytest.hookimpl(tryfirst=True)
    def pytest_sessionfinish(self, session: pytest.Session) -> None:
        # tryfirst: the suite properties must reach pytest's JUnit writer before it writes
        if self.is_worker or not self.rows:
            return
        from _pytest.junitxml import xml_key

        from ..report.junit import add_suite_properties_to_logxml
        from ..report.summary import suite_properties

        self.summary_rows = None
        verdicts = self.verdicts()
        if verdicts and session.exitstatus == pytest.ExitCode.OK:
            session.exitstatus = pytest.ExitCode.TESTS_FAILED  # a rejected campaign fails the build
        if self.directory is not None and self.table is not None:
            from ..report.build import finish_report

            try:
                self.table.close()  # every row is on disk; the report is built from the files
                self.summary_rows = finish_report(
                    self.directory, self.test_infos(), seed=self.config.stash[settings_key].seed,
                    versions=versions(), case_images=self.pictures, verdicts=verdicts)
            except OSError as exc:
                self.report_failed(exc)
        if self.summary_rows is None:
            self.summary_rows = self.summary(verdicts)
        settings = self.config.stash[settings_key]
        props = suite_properties(self.summary_rows, seed=settings.seed, versions=versions())
        if settings.junit == "strict":
            from ..report.junit import case_suite_properties

            for row in self.rows:
                if row.origin != "shrink":
                    props.update(case_suite_properties(row))
        add_suite_properties_to_logxml(self.config.stash.get(xml_key, None), props)

    def pytest_terminal_summary(self, terminalreporter: Any) -> None:
        if self.is_worker or not self.rows:
            return
        from ..report.summary import format_pointer, format_rejections, format_table

        summary = self.summary_rows if self.summary_rows is not None else self.summary(self.verdicts())
        terminalreporter.write_sep("=", "avscenario")
        width = shutil.get_terminal_size(fallback=(120, 24)).columns  # COLUMNS, if set
        for line in format_table(summary, width=width).splitlines():
            terminalreporter.write_line(line)
        for line in format_rejections(summary):
            terminalreporter.write_line(line, red=True, bold=True)
        if self.directory is not None:
            terminalreporter.write_line(format_pointer(self.directory))

    # -- state ----------------------------------------------------------------------------
    def add(self, row: CaseRow, info: dict[str, Any]) -> None:
        self.tests.setdefault(row.test, info)
        self.rows.append(row)
        if self.directory is None:
            return
        try:
            if self.table is None:
                from ..report.table import ErrorTable, prepare_report_dir

                prepare_report_dir(self.directory)
                remove_stale_pictures(self.directory / "cases", self.started)
                self.table = ErrorTable(self.directory)
            self.table.append(row)
        except OSError as exc:
            # the run goes on (verdicts, the replay database and the terminal summary do not
            # depend on the report); say once what was lost and where
            self.report_failed(exc)

    def report_failed(self, exc: OSError) -> None:
        directory, self.directory = self.directory, None
        if self.table is not None:
            try:
                self.table.close()
            except OSError:
                pass
        self.table = None
        self.config.issue_config_time_warning(pytest.PytestWarning(
            f"avscenario: cannot write the report under {directory} ({exc}); the rest of "
            "this run is reported in the terminal only"), 2)

    def close(self) -> None:
        if self.table is not None:
            self.table.close()

    def test_infos(self) -> dict[str, Any]:
        from ..report.summary import TestInfo

        ordered = sorted(self.tests, key=list(self.order).index) if set(self.tests) <= set(self.order) \
            else list(self.tests)
        return {
            test: TestInfo(metrics=tuple(self.tests[test]["metrics"]),
                           space=FeatureSpace.from_description(self.tests[test]["space"]),
                           samplers=tuple(self.tests[test]["samplers"]))
            for test in ordered
        }

    def summary(self, verdicts: Mapping[tuple[str, str], list[str]] | None = None) -> list[Any]:
        from ..report.summary import summarize

        return summarize(self.rows, self.test_infos(), verdicts=verdicts)

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
            reasons = campaign_verdict(criteria, rows, rejected, baseline, test, sampler,
                                       info["metrics"])
            if reasons:
                out[(test, sampler)] = reasons
        return out


def remove_stale_pictures(folder: Any, since: float) -> None:
    """Delete our case pictures left by earlier runs (workers may have drawn this run's already)."""
    if not folder.is_dir():
        return
    for f in folder.iterdir():
        if f.suffix in (".png", ".gif") and f.is_file() and f.stat().st_mtime < since - 1.0:
            f.unlink()


def versions() -> dict[str, str]:
    from importlib.metadata import PackageNotFoundError, version

    out = {}
    for dist in ("pytest-avscenario", "highway-env"):
        try:
            out[dist] = version(dist)
        except PackageNotFoundError:
            out[dist] = "not installed"
    return out

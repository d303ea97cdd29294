"""The run's report: error table, ε-coverage, the paper's summary table, JUnit, plots, HTML.

Everything here takes plain data (:class:`~pytest_avscenario.outcome.CaseRow` s, numpy arrays, summary rows) and produces files
or strings; nothing imports pytest, and importing this package pulls in neither matplotlib
nor scipy (they load inside the functions that draw or search). The plugin wires it into
pytest's hooks: :mod:`.folder` claims the report directory (a lock, and a manifest of the
files we wrote there), :mod:`.table` writes rows as cases finish, :mod:`.summary` computes the
terminal table and JUnit suite properties, :mod:`.junit` adds properties to the XML,
:mod:`.plots` and :mod:`.html` draw the pictures and the static ``index.html``; :mod:`.cards`
writes a page per counterexample, with its :mod:`.recording` played by :mod:`.player`; :mod:`.modes`
groups each campaign's counterexamples into failure modes and :mod:`.compare` sets a run
against an earlier one (``python -m pytest_avscenario.report compare OLD NEW``).
"""

from .build import finish_report
from .folder import ReportFolder, claim_report_dir
from .coverage import covering_radius, covering_radius_bounds, epsilon_coverage, fraction_within
from .summary import SummaryRow, TestInfo, format_pointer, format_table, suite_properties, summarize
from .table import (
    ErrorTable,
    atomic_write_bytes,
    atomic_write_text,
    file_slug,
    prepare_report_dir,
    read_rows,
)

__all__ = [
    "finish_report",
    "epsilon_coverage",
    "covering_radius",
    "covering_radius_bounds",
    "fraction_within",
    "ErrorTable",
    "read_rows",
    "atomic_write_text",
    "atomic_write_bytes",
    "prepare_report_dir",
    "claim_report_dir",
    "ReportFolder",
    "file_slug",
    "TestInfo",
    "SummaryRow",
    "summarize",
    "format_table",
    "format_pointer",
    "suite_properties",
]

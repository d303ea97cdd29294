"""The end-of-run step in one call: from the error table on disk to the finished report.

On the controller, once every case has ended (``pytest_sessionfinish``), the plugin calls
:func:`finish_report` with the report directory and what it knows of each scenario test.
It reads the rows back from the JSONL files the :class:`~.table.ErrorTable` wrote during
the run (so under xdist it sees the merged table), computes the paper's summary, writes
``summary.json``, the pictures and ``index.html``, and returns the summary rows for the
terminal table and the JUnit suite properties.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Mapping

from .coverage import DEFAULT_TOL
from .summary import SummaryRow, TestInfo, summarize, summary_to_json
from .table import MAIN_JSONL, SHRINK_JSONL, TABLES_DIR, atomic_write_text, file_slug, read_rows

__all__ = ["finish_report", "SUMMARY_JSON"]

SUMMARY_JSON = "summary.json"


def finish_report(
    directory: str | os.PathLike,
    tests: Mapping[str, TestInfo] | None = None,
    *,
    seed: Any = None,
    versions: Mapping[str, Any] | None = None,
    pictures: bool = True,
    case_images: Mapping[str, Mapping[str, Any]] | None = None,
    tol: float = DEFAULT_TOL,
    within_radius: float | None = 0.1,
    verdicts: Mapping[tuple[str, str], Any] | None = None,
) -> list[SummaryRow]:
    """Summarize the run's tables under ``directory`` and write the rest of the report.

    ``tests``: ``{test nodeid: TestInfo(metrics, space)}`` in collection order. ``pictures``
    False skips the PNGs (and matplotlib's import) but still writes ``index.html``.
    ``case_images``: ``{test: {caption: path}}`` pictures of single cases (e.g. the GIF and
    worst-moment PNG of each minimized counterexample), listed after the test's plots.
    ``verdicts``: the campaigns' rejection reasons (see :func:`.summary.summarize`).
    Returns the summary rows (possibly empty).
    """
    root = Path(directory)
    main = read_rows(root)
    shrink = read_rows(root, shrink=True)
    summary = summarize(main + shrink, tests, tol=tol, within_radius=within_radius, verdicts=verdicts)
    atomic_write_text(
        root / SUMMARY_JSON,
        json.dumps({"seed": seed, "versions": dict(versions or {}), "tests": summary_to_json(summary)},
                   indent=2, allow_nan=False, default=str) + "\n",
    )
    images: dict[str, Any] = {}
    tables: dict[str, list[Path]] = {"": [p for p in (root / MAIN_JSONL, root / SHRINK_JSONL, root / SUMMARY_JSON) if p.exists()]}
    by_test: dict[str, list[Any]] = {}
    for r in main:
        by_test.setdefault(r.test, []).append(r)
    for test in dict.fromkeys([s.test for s in summary] + list(by_test)):
        slug = file_slug(test)
        tables[test] = [p for p in (root / TABLES_DIR / f"{slug}.csv", root / TABLES_DIR / f"{slug}.shrink.csv") if p.exists()]
        if pictures and by_test.get(test):
            from .plots import plot_test

            info = (tests or {}).get(test)
            images[test] = plot_test(root, test, by_test[test], metrics=(info.metrics or None) if info else None)
    for test, extra in (case_images or {}).items():
        merged = dict(images.get(test) or {})
        merged.update({caption: path for caption, path in extra.items() if Path(path).exists()})
        images[test] = merged
    from .html import write_index

    meta = {}
    if seed is not None:
        meta["seed"] = seed
    meta.update({k: v for k, v in (versions or {}).items()})
    write_index(root, summary, images, tables, meta=meta)
    return summary

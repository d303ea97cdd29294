"""Commands on finished reports: ``python -m pytest_avscenario.report compare OLD NEW``.

``compare`` prints what changed between two runs — per test, sampler and metric the
violation rate then and now, and the failure modes that are new or gone — from their
``summary.json`` files (or report directories), and with ``--html PATH`` writes the same as a
page. Exit status 0, or 2 when a file cannot be read.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Sequence


def _summary_path(arg: str) -> Path:
    path = Path(arg)
    return path / "summary.json" if path.is_dir() else path


def _page(body: str, title: str) -> str:
    from .cards import PAGE_CSS, e

    return (f"<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'><title>{e(title)}</title>"
            f"<style>{PAGE_CSS}</style></head><body>\n<h1>{e(title)}</h1>\n{body}\n</body></html>\n")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m pytest_avscenario.report",
                                     description="Commands on finished pytest-avscenario reports.")
    commands = parser.add_subparsers(dest="command", required=True)
    cmp = commands.add_parser("compare", help="what changed between two runs: violation rates and failure modes",
                              description="Compare two runs' summary.json files (or report directories).")
    cmp.add_argument("old", help="the earlier run's summary.json (or its report directory)")
    cmp.add_argument("new", help="the later run's summary.json (or its report directory)")
    cmp.add_argument("--html", metavar="PATH", help="also write the comparison as an HTML page here")
    args = parser.parse_args(argv)

    from ..acceptance import load_baseline
    from .compare import compare, comparison_html, format_comparison

    try:
        # a look by hand may compare an interrupted run (its rates cover the finished cases)
        old = load_baseline(_summary_path(args.old), partial_ok=True)
        new = load_baseline(_summary_path(args.new), partial_ok=True)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for run in (old, new):
        if run.interrupted:
            print(f"note: {run.path} is the summary of an interrupted run: its rates count only "
                  "the cases that finished", file=sys.stderr)
    comparison = compare(new, old)
    for line in format_comparison(comparison, now=new.path):
        print(line)
    if args.html:
        from .table import atomic_write_text

        path = Path(args.html)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            atomic_write_text(path, _page(comparison_html(comparison), f"avscenario: {new.path} against {old.path}"))
        except OSError as exc:  # a folder at that name, no permission, a full disk
            print(f"error: cannot write --html {path}: {exc.strerror or exc}", file=sys.stderr)
            return 2
        print(f"written: {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

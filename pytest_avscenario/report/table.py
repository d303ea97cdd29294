"""The error table: one row per simulated case, on disk the moment the case ends.

An AV engineer opens the error table after (or during) a falsification run to see which
parameter combinations violated which metric and by how much. :class:`ErrorTable` appends
each row to JSON Lines and CSV files and flushes them (fsync on request) before returning,
so a run killed half-way leaves every finished case readable.

Layout under the report directory (``--avs-report``, default ``avs-report/``)::

    errors.jsonl            every sampled / replay / example case of every test (lossless)
    shrink.jsonl            shrinking candidates, kept apart so errors.jsonl counts samples
    tables/<slug>.csv       the same rows for one test, one column per parameter and metric
    tables/<slug>.shrink.csv
    .avs-manifest.json      every file a run of ours wrote here (see :mod:`.folder`)
    .avs-lock               held by the run writing here

Why one CSV per test plus a combined JSONL: tests have different parameters and metrics,
and a CSV has one header. A CSV per test gives real columns (``param.gap``,
``rho.distance``) that a spreadsheet or ``csv.DictReader`` reads without decoding JSON
cells; the combined JSONL keeps exact types (±inf, ints, strings) for programs, and is what
:func:`read_rows` loads back. If a later row of a test brings a column the CSV header lacks,
the CSV is rewritten atomically with the wider header (rare: all cases of a test share their
parameters and metrics).

A row is a :class:`~pytest_avscenario.outcome.CaseRow` (frozen); a JSONL line is its
:meth:`~pytest_avscenario.outcome.CaseRow.to_json`, and :func:`read_rows` gives rows back.
Robustness values may be ±inf (a metric that holds trivially); they are written as the
strings ``"inf"`` / ``"-inf"`` (and ``"nan"``) in JSON and CSV and read back as floats, with
the one codec every file uses (:mod:`pytest_avscenario.codec`).
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import os
import re
import threading
import warnings
from pathlib import Path
from typing import Any, Iterable, Iterator, Mapping

from .. import files
from ..codec import jsonable, rho_from_json, rho_to_str
from ..outcome import CaseRow
from .folder import MAIN_JSONL, SHRINK_JSONL, TABLES_DIR, ReportFolder, atomic_write_bytes, atomic_write_text

__all__ = [
    "ErrorTable",
    "read_rows",
    "read_csv_rows",
    "atomic_write_text",
    "atomic_write_bytes",
    "prepare_report_dir",
    "file_slug",
    "MAIN_JSONL",
    "SHRINK_JSONL",
    "TABLES_DIR",
]


# Fixed leading CSV columns, in the order an engineer scans them.
_CSV_FIXED = ("test", "item", "sampler", "index", "seed", "origin", "verdict", "sim_time_s", "error")


# --------------------------------------------------------------------------- files


def file_slug(test: str, max_len: int = 80) -> str:
    """A file-name-safe, unique, readable name for a test node id.

    ``tests/test_x.py::test_follow[halton]`` → ``test_x.py-test_follow-halton-1a2b3c4d``:
    the readable part is truncated, the hash of the full id keeps two tests apart.
    """
    tail = test.split("/")[-1]
    readable = re.sub(r"[^A-Za-z0-9._-]+", "-", tail).strip("-.") or "test"
    digest = hashlib.sha1(test.encode("utf-8")).hexdigest()[:8]
    return f"{readable[:max_len]}-{digest}"


def prepare_report_dir(directory: str | os.PathLike) -> Path:
    """Create the report directory and remove what a previous run of ours left in it.

    Only the files listed in the directory's manifest (:mod:`.folder`: the files an earlier
    run wrote there) are deleted, and ``tables/`` / ``plots/`` / ``cases/`` only when that
    leaves them empty: pointing ``--avs-report`` at a directory that holds other things (even
    the project root) never deletes them. The plugin itself claims the directory with
    :func:`.folder.claim_report_dir`, which also locks it and checks nothing is in the way.
    """
    root = Path(directory)
    root.mkdir(parents=True, exist_ok=True)
    ReportFolder(root).clear()
    return root


def _csv_cell(value: Any) -> Any:
    if value is None:
        return ""
    if isinstance(value, float):
        # repr keeps every digit, so a CSV value round-trips to the exact simulated float.
        return repr(value) if math.isfinite(value) else rho_to_str(value)
    if isinstance(value, (str, int)):
        return value
    return json.dumps(value, sort_keys=True)


class _CsvFile:
    """One per-test CSV: header fixed at the first row, widened by an atomic rewrite."""

    def __init__(self, path: Path, columns: list[str], fsync: bool):
        self.path = path
        self.columns = columns
        self.fsync = fsync
        self.fh = files.open_regular(path, "w", newline="")
        try:
            self.writer = csv.DictWriter(self.fh, fieldnames=columns, extrasaction="raise")
            self.writer.writeheader()
            self._sync()
        except BaseException:  # e.g. a full disk: don't leak the handle of a table never kept
            self.fh.close()
            raise

    def _sync(self) -> None:
        self.fh.flush()
        if self.fsync:
            os.fsync(self.fh.fileno())

    def write(self, cells: dict[str, Any]) -> None:
        new = [c for c in cells if c not in self.columns]
        if new:
            self._widen(new)
        self.writer.writerow(cells)
        self._sync()

    def _widen(self, new: list[str]) -> None:
        self.fh.close()
        with files.open_regular(self.path, "r", newline="") as fh:
            old = list(csv.DictReader(fh))
        # Parameters before metrics keeps the "inputs, then outputs" reading order.
        self.columns = _order_columns(self.columns + new)
        buf = io.StringIO()
        w = csv.DictWriter(buf, fieldnames=self.columns, restval="")
        w.writeheader()
        w.writerows(old)
        atomic_write_text(self.path, buf.getvalue())
        self.fh = files.open_regular(self.path, "a", newline="")
        self.writer = csv.DictWriter(self.fh, fieldnames=self.columns, restval="")

    def close(self) -> None:
        if not self.fh.closed:
            self.fh.close()


def _order_columns(columns: Iterable[str]) -> list[str]:
    seen = list(dict.fromkeys(columns))
    fixed = [c for c in _CSV_FIXED if c in seen]
    params = [c for c in seen if c.startswith("param.")]
    rhos = [c for c in seen if c.startswith("rho.")]
    rest = [c for c in seen if c not in fixed and c not in params and c not in rhos]
    return fixed + params + rhos + rest


def _csv_cells(row: CaseRow) -> dict[str, Any]:
    cells = {k: _csv_cell(getattr(row, k)) for k in _CSV_FIXED}
    for name, value in row.params.items():
        cells[f"param.{name}"] = _csv_cell(jsonable(value))
    for name, value in row.rho.items():
        cells[f"rho.{name}"] = _csv_cell(value)
    if row.score is not None:  # the Leaderboard's driving score of the run, after the rho
        cells["driving_score"] = _csv_cell(row.driving_score)
    return cells


class ErrorTable:
    """Incremental writer of the error table under one report directory.

    ``append(row)`` validates the row, writes it to the JSONL and the test's CSV and flushes
    both to the operating system before returning, so a killed or crashed pytest process
    leaves every finished row readable. ``fsync=True`` also forces each row to the disk,
    which survives a power cut or kernel crash too, but costs 0.1–5 ms per row (two
    fsyncs; measured in bench/README.md) against ~20 ms per simulated case, so it is opt-in.
    Rows with ``origin == "shrink"`` go to the shrink table. Thread-safe; meant for one
    writing process (under xdist: the controller, fed by the workers' reports). Opening
    truncates the tables of a previous run (use :func:`prepare_report_dir` to clear plots and
    pages too). Every file is recorded in ``folder``'s manifest before it is written (default:
    the directory's own, see :mod:`.folder`). Use as a context manager or call :meth:`close`.
    """

    def __init__(self, directory: str | os.PathLike, *, fsync: bool = False, folder: ReportFolder | None = None):
        self.directory = Path(directory)
        self.fsync = fsync
        self.folder = folder if folder is not None else ReportFolder(self.directory)
        self._own_folder = folder is None  # then closing the table ends the folder's run
        files.make_dirs(self.directory / TABLES_DIR)
        self._lock = threading.Lock()
        self._jsonl: dict[bool, Any] = {}
        try:
            for shrink, name in ((False, MAIN_JSONL), (True, SHRINK_JSONL)):
                self._jsonl[shrink] = files.open_regular(self.folder.add(self.directory / name), "w")
        except BaseException:  # the first file's handle must not outlive a failed second open
            for fh in self._jsonl.values():
                fh.close()
            if self._own_folder:
                self.folder.close()
            raise
        self._csv: dict[tuple[str, bool], _CsvFile] = {}
        self.counts = {"main": 0, "shrink": 0}

    @property
    def main_path(self) -> Path:
        return self.directory / MAIN_JSONL

    @property
    def shrink_path(self) -> Path:
        return self.directory / SHRINK_JSONL

    def csv_path(self, test: str, shrink: bool = False) -> Path:
        """Where the CSV of ``test`` (or its shrink candidates) lives."""
        suffix = ".shrink.csv" if shrink else ".csv"
        return self.directory / TABLES_DIR / f"{file_slug(test)}{suffix}"

    def tables(self) -> dict[str, list[Path]]:
        """``{test: [csv paths]}`` of every CSV written so far (for the index page)."""
        out: dict[str, list[Path]] = {}
        for (test, _), f in self._csv.items():
            out.setdefault(test, []).append(f.path)
        return out

    def append(self, row: CaseRow | Mapping[str, Any], data: Mapping[str, Any] | None = None) -> CaseRow:
        """Write one finished case (a row, or its JSON data); on disk when this returns.
        ``data``: the row's :meth:`~CaseRow.to_json` made already (an xdist worker's), written
        as it is rather than made again."""
        row = CaseRow.coerce(row)
        line = json.dumps(row.to_json() if data is None else data, allow_nan=False, ensure_ascii=False) + "\n"
        shrink = row.origin == "shrink"
        cells = _csv_cells(row)
        with self._lock:
            fh = self._jsonl[shrink]
            fh.write(line)
            fh.flush()
            if self.fsync:
                os.fsync(fh.fileno())
            key = (row.test, shrink)
            f = self._csv.get(key)
            if f is None:
                f = self._csv[key] = _CsvFile(
                    self.folder.add(self.csv_path(row.test, shrink)), _order_columns(cells), self.fsync
                )
            f.write(cells)
            self.counts["shrink" if shrink else "main"] += 1
        return row

    def close(self) -> None:
        with self._lock:
            for fh in self._jsonl.values():
                if not fh.closed:
                    fh.close()
            for f in self._csv.values():
                f.close()
            if self._own_folder:
                self.folder.close()

    def __enter__(self) -> "ErrorTable":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


# --------------------------------------------------------------------------- reading


def _iter_jsonl(path: Path) -> Iterator[CaseRow]:
    with open(path, encoding="utf-8") as fh:
        lines = fh.readlines()
    for n, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            yield CaseRow.from_json(json.loads(line))
        except json.JSONDecodeError:
            # Only the very last line can be torn (a process killed mid-write); anything
            # earlier is real corruption and must not be skipped silently.
            if n == len(lines) and not line.endswith("\n"):
                warnings.warn(f"{path}: ignoring a truncated last line (interrupted write)")
                return
            raise ValueError(f"{path}:{n}: not a JSON row: {line[:80]!r}") from None


def read_rows(source: str | os.PathLike, *, shrink: bool = False) -> list[CaseRow]:
    """Load rows back: from a report directory (its ``errors.jsonl``, or ``shrink.jsonl``
    with ``shrink=True``) or from a ``.jsonl`` file. rho values come back as floats."""
    path = Path(source)
    if path.is_dir():
        path = path / (SHRINK_JSONL if shrink else MAIN_JSONL)
    if not path.exists():
        return []
    return list(_iter_jsonl(path))


def read_csv_rows(path: str | os.PathLike) -> list[dict[str, Any]]:
    """Load a per-test CSV back into row dicts (``params`` values stay strings, except
    numbers; ``rho`` values become floats)."""
    rows = []
    with open(path, newline="", encoding="utf-8") as fh:
        for rec in csv.DictReader(fh):
            row: dict[str, Any] = {"params": {}, "rho": {}}
            for col, cell in rec.items():
                if col.startswith("param."):
                    row["params"][col[6:]] = _parse_number(cell)
                elif col.startswith("rho."):
                    row["rho"][col[4:]] = rho_from_json(cell)
                else:
                    row[col] = cell if cell != "" else None
            for col in ("index", "seed"):
                if row.get(col) is not None:
                    row[col] = int(row[col])
            row["sim_time_s"] = float(row.get("sim_time_s") or 0.0)
            rows.append(row)
    return rows


def _parse_number(cell: str) -> Any:
    if cell == "":
        return None
    try:
        return int(cell)
    except ValueError:
        pass
    try:
        return float(cell)
    except ValueError:
        return cell

"""The parts of the report that one test's rows decide, made ahead: as soon as the test's last
case has ended, in helper processes, while the cases of other tests still run.

A test's two plots (:mod:`.plots`), its campaigns' ε-coverage (:func:`.summary.
campaign_coverage`) and their failure modes (:func:`.modes.failure_modes`) depend on its own
rows and declaration only. Built after the last case
they were most of the end of the run (the example suite: 19 tests, ~30 s of the ~34 s after
the last case, in a serial run and under ``-n 2`` alike), which no number of xdist workers
shortened. An xdist controller runs no case itself; it hands each finished test's parts to
a pool of spawned processes (as many as the run has workers) and at the end takes what they
made. A part is taken only when it was made from the very rows (same items, same order) and
the same declaration that the end of the run holds, and only if it was made without error;
anything else is made again at the end, as a run without helpers makes it. The pictures and
numbers are the same either way: the same functions on the same data.

Rows do not cross to the helpers: a helper reads the test's rows back from the run's error
table (``errors.jsonl``, written and flushed row by row as cases end), as their JSON data
(:meth:`~pytest_avscenario.outcome.CaseRow.to_json`) — a copy of 100,000 rows handed over as
data was ~100 MB more in the controller at the end of the run. Each helper's result names
the rows it used (a digest of their items, in order), and it is taken only if those are the
rows the end of the run holds. The helpers ignore SIGINT (a Ctrl-C reaches the whole process
group): the controller ends them itself (:meth:`ReportAhead.cancel`).

A serial run of many cases makes its plots and ε at its end the same way
(:data:`~pytest_avscenario.pytest_plugin.controller.SERIAL_AHEAD_MIN_ROWS`): the pytest
process then never imports matplotlib or scipy (~110 MB) nor holds the plots' per-case
arrays, and the helper draws while it writes the summary and the cards.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
from pathlib import Path
from typing import Any, Iterable, Iterator, Mapping, Sequence

from ..outcome import CaseRow
from .coverage import DEFAULT_TOL
from .plots import PLOT_KINDS, plot_paths
from .table import MAIN_JSONL

__all__ = ["ReportAhead", "items_digest", "table_rows"]


class _Submitted:
    __slots__ = ("items", "info", "coverage", "plots")

    def __init__(self, items: tuple[str, ...], info: Mapping[str, Any], coverage: Any, plots: dict[str, Any]):
        self.items, self.info, self.coverage, self.plots = items, info, coverage, plots


class ReportAhead:
    """A pool of ``processes`` helper processes (started with the first test handed to it)
    making tests' plots under ``directory`` and their campaigns' ε-coverage (with ``tol`` and
    ``within_radius``, as :func:`.build.finish_report` computes them)."""

    def __init__(self, directory: str | os.PathLike, processes: int, *, tol: float = DEFAULT_TOL,
                 within_radius: float | None = 0.1):
        self.directory = Path(directory)
        self.processes = max(1, int(processes))
        self.tol, self.within_radius = tol, within_radius
        self._pool: Any = None
        self._jobs: dict[str, _Submitted] = {}

    def submitted(self, test: str) -> bool:
        return test in self._jobs

    def start(self) -> None:
        """Start the helpers now, each importing what it draws and computes with (~1-2 s of
        CPU per process) while cases still run, not once the first test — for a one-test
        campaign, the last case — is done. Raises when no helper can be started."""
        if self._pool is not None:
            return
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        # spawned, not forked: the controller has execnet's threads, which a fork copies in
        # whatever state (a lock held) they are in
        self._pool = ProcessPoolExecutor(max_workers=self.processes, initializer=_helper_start,
                                         mp_context=multiprocessing.get_context("spawn"))
        with _sigint_blocked():
            for _ in range(self.processes):  # one process is started per job while none is idle
                self._pool.submit(os.getpid)

    def submit(self, test: str, rows: Sequence[CaseRow], info: Mapping[str, Any]) -> list[Path]:
        """Start making ``test``'s campaigns' ε-coverage, then its plots, from its main-table
        rows in the report's order and its declaration (the JSON data of its plan's
        ``info()``). Returns the paths the plots may be written to (for the report folder's
        manifest, before they are written). Raises when no helper can be started."""
        self.start()
        table = str(self.directory / MAIN_JSONL)
        with _sigint_blocked():  # a submit may start a helper
            # first: the end of the run waits for it before the summary, for the plots after the cards
            cover = self._pool.submit(_coverage_job, info, table, test, self.tol, self.within_radius)
            plots = {kind: self._pool.submit(_plot_job, str(self.directory), test, table, kind, info)
                     for kind in PLOT_KINDS}
        self._jobs[test] = _Submitted(items_digest(row.item for row in rows), info, cover, plots)
        return list(plot_paths(self.directory, test).values())

    def plots(self, test: str, rows: Sequence[CaseRow], info: Mapping[str, Any] | None) -> dict[str, Path] | None:
        """``{kind: path}`` of ``test``'s plots made ahead from these ``rows`` and ``info``
        (waiting for them), or None: to be drawn here."""
        job = self._jobs.get(test)
        if job is None or job.info is not info or job.items != items_digest(row.item for row in rows):
            return None
        out = {}
        for kind, future in job.plots.items():
            try:
                used, path = future.result()
            except Exception:  # noqa: BLE001 - drawn again here, where its error is reported
                return None
            if used != job.items:  # the table held other rows than this process (a row lost)
                return None
            if path is not None:
                out[kind] = Path(path)
        return out

    def _made_ahead(self, test: str, info: Mapping[str, Any] | None, part: int, sampler: str) -> Any:
        """What the helper's ε-and-modes job of ``test`` made for ``sampler`` (part 0: the
        ε-coverage, 1: the failure modes; waiting for it), or None: not handed this
        declaration, failed (made again here, where its error is reported), or no such campaign."""
        job = self._jobs.get(test)
        if job is None or job.info is not info:
            return None
        try:
            return job.coverage.result()[part].get(sampler)
        except Exception:  # noqa: BLE001 - made again here, where its error is reported
            return None

    def coverage(self, test: str, sampler: str, sampled: Sequence[CaseRow],
                 info: Mapping[str, Any] | None) -> tuple | None:
        """(ε, covering radius, fraction within) of the campaign ``(test, sampler)`` made
        ahead from these ``sampled`` rows and ``info`` (waiting for it), or None."""
        found = self._made_ahead(test, info, 0, sampler)
        if found is None or found[0] != items_digest(row.item for row in sampled):
            return None
        return tuple(found[1])

    def modes(self, test: str, sampler: str, main: Sequence[CaseRow], order: Sequence[str],
              info: Mapping[str, Any] | None) -> tuple | None:
        """The failure modes (:func:`.modes.failure_modes`) of the campaign ``(test, sampler)``
        made ahead from these ``main`` rows, ``info`` and metric ``order`` (waiting for
        them), or None."""
        found = self._made_ahead(test, info, 1, sampler)
        if found is None or tuple(found[1]) != tuple(order) or found[0] != items_digest(row.item for row in main):
            return None
        return tuple(found[2])

    def cancel(self) -> list[Path]:
        """The run was interrupted: end the helpers now, whatever they were making. Returns
        the paths of the plots handed to them (some may be written)."""
        pool, self._pool = self._pool, None
        paths = [p for test in self._jobs for p in plot_paths(self.directory, test).values()]
        self._jobs.clear()
        if pool is not None:
            processes = list((getattr(pool, "_processes", None) or {}).values())
            pool.shutdown(wait=False, cancel_futures=True)
            for process in processes:
                try:
                    process.terminate()
                except Exception:  # noqa: BLE001 - already gone
                    pass
            _ended(processes, _CANCEL_WAIT_S)
        return paths

    def close(self) -> None:
        """The report is made: let the helpers finish and end."""
        pool, self._pool = self._pool, None
        self._jobs.clear()
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)


#: how long :meth:`ReportAhead.cancel` waits for terminated helpers before it kills them
_CANCEL_WAIT_S = 2.0


def _ended(processes: Sequence[Any], wait: float) -> None:
    """Wait until each terminated process is known to have ended, killing the ones still there
    after ``wait`` seconds. Known, not only reaped: the pool's own thread reaps its workers
    too, and a process it reaped a moment before this thread looked reads as alive here until
    that thread records its exit code, so the exit code is what is waited for."""
    import time

    deadline = time.monotonic() + wait
    for process in processes:
        process.join(timeout=max(0.0, deadline - time.monotonic()))
        while process.exitcode is None and time.monotonic() < deadline:
            time.sleep(0.005)
    for process in processes:
        if process.exitcode is None:
            try:
                process.kill()
            except Exception:  # noqa: BLE001 - gone meanwhile
                pass
            process.join(timeout=1.0)
            end = time.monotonic() + 1.0
            while process.exitcode is None and time.monotonic() < end:
                time.sleep(0.005)


@contextlib.contextmanager
def _sigint_blocked() -> Iterator[None]:
    """SIGINT blocked in this thread while helpers are started: a helper inherits the mask,
    so a Ctrl-C at the terminal (sent to the whole process group) never reaches one, not even
    while the interpreter starts, before it could ignore it; this process gets a Ctrl-C that
    came meanwhile once it is unblocked."""
    import signal

    block = getattr(signal, "pthread_sigmask", None)
    if block is None:  # pragma: no cover - no POSIX signal masks: the helpers ignore it once started
        yield
        return
    before = block(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        block(signal.SIG_SETMASK, before)


def _helper_start() -> None:
    """A helper's start: Ctrl-C is the controller's to answer (it ends the helpers); the
    modules of the plots and of ε imported now."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        import matplotlib.backends.backend_agg  # noqa: F401
        import matplotlib.figure  # noqa: F401
        import PIL.PngImagePlugin  # noqa: F401
        import scipy.spatial  # noqa: F401
        import scipy.stats.qmc  # noqa: F401

        from . import cards, plots, summary  # noqa: F401
    except Exception:  # noqa: BLE001 - a job that needs one says so (and is made at the end)
        pass


def _space(info: Mapping[str, Any]) -> Any:
    from ..space import FeatureSpace

    try:
        return FeatureSpace.from_description(info["space"])
    except Exception:  # noqa: BLE001 - the end of the run reports it (and plots without units)
        return None


def items_digest(items: Iterable[str]) -> bytes:
    """Which rows, in which order: a digest of their item ids (what a helper used and what
    the end of the run holds are compared by it, not by 100,000 ids sent back)."""
    h = hashlib.blake2b(digest_size=16)
    for item in items:
        h.update(item.encode("utf-8", "surrogatepass"))
        h.update(b"\0")
    return h.digest()


#: the rows a helper read last, ``((table, test), rows)``: a test's ε and failure modes and
#: each of its plots are jobs of their own, and a serial run's one helper makes them one
#: after the other from the same rows (read once, not once a job: 100,000 rows are ~3 s of
#: parsing). A test's rows are all in the table when it is handed over, and it is handed
#: over once. Rows, not their JSON data: the plots and ε take rows, and a line's data is
#: let go as soon as its row is made (100,000 rows' data held beside them was ~150 MB).
_READ: list[Any] = []


def _rows_of(table: str, test: str) -> list[CaseRow]:
    key = (str(table), test)
    if not _READ or _READ[0][0] != key:
        _READ.clear()  # the rows of the test before are not held beside these
        _READ.append((key, [CaseRow.from_json(d) for d in _table_data(table, test)]))
    return _READ[0][1]


def table_rows(table: str | os.PathLike, test: str) -> list[dict[str, Any]]:
    """The JSON data of ``test``'s rows in the error table ``table``, in its order. A line
    still being written (no newline yet) is not read: it is a later case's, of another test
    (a test is handed over once all of its cases have ended)."""
    return list(_table_data(table, test))


def _table_data(table: str | os.PathLike, test: str) -> Iterator[dict[str, Any]]:
    needle = json.dumps(test, ensure_ascii=False)  # the test's id as each of its lines holds it
    with open(table, encoding="utf-8") as fh:
        for line in fh:
            if needle in line and line.endswith("\n"):
                data = json.loads(line)
                if data.get("test") == test and data.get("origin") != "shrink":
                    yield data


def _plot_job(directory: str, test: str, table: str, kind: str,
              info: Mapping[str, Any]) -> tuple[bytes, str | None]:
    """One plot of a test, drawn as :func:`.build.finish_report` draws it; with the digest
    of the rows it was drawn from."""
    from .cards import unit_of
    from .plots import plot_kind

    rows = _rows_of(table, test)
    space = _space(info)
    units = {n: unit_of(space, n) for n in getattr(space, "parameters", {}) or {}}
    metrics = tuple(info.get("metrics") or ())
    path = plot_kind(directory, test, rows, kind, metrics=metrics or None,
                     units={n: u for n, u in units.items() if u})
    return items_digest(r.item for r in rows), None if path is None else str(path)


def _coverage_job(info: Mapping[str, Any], table: str, test: str, tol: float,
                  within_radius: float | None) -> tuple[dict[str, tuple[bytes, tuple]], dict[str, tuple]]:
    """({sampler: (the digest of its sampled items, (ε, covering radius, fraction within))},
    {sampler: (the digest of its main-table items, the metric order, its failure modes)})
    of a test: its campaigns' ε-coverage and failure modes, as :func:`.summary.summarize`
    makes them. A campaign whose failure modes fail here is left out (made again at the
    end, where the error is reported)."""
    from .modes import failure_modes
    from .summary import campaign_coverage

    space = _space(info)
    campaigns: dict[str, list[CaseRow]] = {}
    for row in _rows_of(table, test):
        campaigns.setdefault(row.sampler, []).append(row)
    coverage: dict[str, tuple[bytes, tuple]] = {}
    modes: dict[str, tuple] = {}
    for sampler, main in campaigns.items():
        sampled = [r for r in main if r.origin == "sampled"]
        if sampled:
            coverage[sampler] = (items_digest(r.item for r in sampled),
                                 campaign_coverage(sampled, space, tol=tol, within_radius=within_radius))
        if space is None or not any(r.verdict == "fail" for r in main):
            continue
        # the metric order summarize uses: the declared ones, then those the rows add
        metrics = list(info.get("metrics") or ())
        for r in main:
            for m in r.rho:
                if m not in metrics:
                    metrics.append(m)
        order = tuple(info.get("priority") or ()) or tuple(metrics)
        try:
            found = tuple(failure_modes(main, space, list(order)))
        except Exception:  # noqa: BLE001 - made again at the end, where its error is reported
            continue
        modes[sampler] = (items_digest(r.item for r in main), order, found)
    return coverage, modes

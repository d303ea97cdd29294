"""The parts of the report that one test's rows decide, made ahead: as soon as the test's last
case has ended, in helper processes, while the cases of other tests still run.

A test's two plots (:mod:`.plots`) and its campaigns' ε-coverage (:func:`.summary.
campaign_coverage`) depend on its own rows and declaration only. Built after the last case
they were most of the end of the run (the example suite: 19 tests, ~30 s of the ~34 s after
the last case, in a serial run and under ``-n 2`` alike), which no number of xdist workers
shortened. An xdist controller runs no case itself; it hands each finished test's parts to
a pool of spawned processes (as many as the run has workers) and at the end takes what they
made. A part is taken only when it was made from the very rows (same items, same order) and
the same declaration that the end of the run holds, and only if it was made without error;
anything else is made again at the end, as a run without helpers makes it. The pictures and
numbers are the same either way: the same functions on the same data.

Rows cross to the helpers as their JSON data (:meth:`~pytest_avscenario.outcome.CaseRow.
to_json`), as they crossed from the xdist workers. The helpers ignore SIGINT (a Ctrl-C
reaches the whole process group): the controller ends them itself (:meth:`ReportAhead.
cancel`).
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import Any, Iterator, Mapping, Sequence

from ..outcome import CaseRow
from .coverage import DEFAULT_TOL
from .plots import PLOT_KINDS, plot_paths

__all__ = ["ReportAhead"]


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
        data = [row.to_json() for row in rows]
        with _sigint_blocked():  # a submit may start a helper
            # first: the end of the run waits for it before the summary, for the plots after the cards
            cover = self._pool.submit(_coverage_job, info, data, self.tol, self.within_radius)
            plots = {kind: self._pool.submit(_plot_job, str(self.directory), test, data, kind, info)
                     for kind in PLOT_KINDS}
        self._jobs[test] = _Submitted(tuple(row.item for row in rows), info, cover, plots)
        return list(plot_paths(self.directory, test).values())

    def plots(self, test: str, rows: Sequence[CaseRow], info: Mapping[str, Any] | None) -> dict[str, Path] | None:
        """``{kind: path}`` of ``test``'s plots made ahead from these ``rows`` and ``info``
        (waiting for them), or None: to be drawn here."""
        job = self._jobs.get(test)
        if job is None or job.info is not info or job.items != tuple(row.item for row in rows):
            return None
        out = {}
        for kind, future in job.plots.items():
            try:
                path = future.result()
            except Exception:  # noqa: BLE001 - drawn again here, where its error is reported
                return None
            if path is not None:
                out[kind] = Path(path)
        return out

    def coverage(self, test: str, sampler: str, sampled: Sequence[CaseRow],
                 info: Mapping[str, Any] | None) -> tuple | None:
        """(ε, covering radius, fraction within) of the campaign ``(test, sampler)`` made
        ahead from these ``sampled`` rows and ``info`` (waiting for it), or None."""
        job = self._jobs.get(test)
        if job is None or job.info is not info:
            return None
        try:
            found = job.coverage.result().get(sampler)
        except Exception:  # noqa: BLE001 - computed again here, where its error is reported
            return None
        if found is None or found[0] != tuple(row.item for row in sampled):
            return None
        return tuple(found[1])

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


def _plot_job(directory: str, test: str, data: list[dict[str, Any]], kind: str,
              info: Mapping[str, Any]) -> str | None:
    """One plot of a test, drawn as :func:`.build.finish_report` draws it."""
    from .cards import unit_of
    from .plots import plot_kind

    space = _space(info)
    units = {n: unit_of(space, n) for n in getattr(space, "parameters", {}) or {}}
    metrics = tuple(info.get("metrics") or ())
    path = plot_kind(directory, test, data, kind, metrics=metrics or None,
                     units={n: u for n, u in units.items() if u})
    return None if path is None else str(path)


def _coverage_job(info: Mapping[str, Any], data: list[dict[str, Any]], tol: float,
                  within_radius: float | None) -> dict[str, tuple[tuple[str, ...], tuple]]:
    """{sampler: (its sampled items, (ε, covering radius, fraction within))} of a test."""
    from .summary import campaign_coverage

    space = _space(info)
    campaigns: dict[str, list[CaseRow]] = {}
    for row in map(CaseRow.from_json, data):
        if row.origin == "sampled":
            campaigns.setdefault(row.sampler, []).append(row)
    return {sampler: (tuple(r.item for r in rows),
                      campaign_coverage(rows, space, tol=tol, within_radius=within_radius))
            for sampler, rows in campaigns.items()}

"""The Dask executor: scenario cases simulated on a Dask cluster, judged the same way.

``--avs-executor=dask`` sends each case to a Dask worker, which imports the test module,
builds the case and a fresh world and runs :func:`~pytest_avscenario.runner.run_case` there
(see :mod:`.remote` for what crosses the wire). pytest still runs one item per case, in its
own order; the executor makes that cheap by starting cases *ahead*:

* ``prefetch`` submits every passive case at collection, in pytest's order (earlier items get
  a higher Dask priority), so all workers stay busy while pytest walks the items; consecutive
  cases of one test travel in chunks (one task, one round trip), since a case can cost
  little more than Dask's own per-task overhead. ``run`` matches a job to its prefetched
  task by ``(node id, parameters, seed)``; a job that was not prefetched (an active
  sampler's case, a shrink candidate) is submitted at once, alone, with a priority above
  every prefetched case, so the item pytest is waiting for never queues behind hundreds of
  later ones.
* Finished results are pulled to the client as they complete (one ``gather`` for all that
  are ready), so a worker that dies afterwards loses nothing already computed.
* A worker that dies mid-case: the scheduler resubmits the task to another worker, at most
  ``max_retries`` times on a cluster this executor starts (``distributed.scheduler.allowed-
  failures``; an existing cluster uses its own setting, Dask's default is 3). A chunk that
  exhausts that is split, each case resubmitted alone, so only the case that kills its
  worker ends as an *error* naming the cause — never as a pass, never lost.
* A scheduler that cannot be reached fails within ``connect_timeout_s`` with a message that
  says what to check; a scheduler lost during the run (or one left without workers) fails
  the waiting item, and every later one at once, after the same timeout.

Without an address the executor starts a ``LocalCluster`` with one single-threaded worker
process per core (simulations are pure Python: threads would share the GIL) and closes it
in :meth:`close`. Dask is imported only when this module is, i.e. when the executor is made.
"""

from __future__ import annotations

import collections
import itertools
import json
import logging
import os
import sys
import time
from concurrent.futures import CancelledError
from dataclasses import dataclass
from typing import Any, Sequence

import dask
import distributed

from ..outcome import CaseOutcome
from .base import CaseJob, Executor
from .remote import CaseFields, TestSpec, pack_spec, run_remote_many, spec_digest, warm_up

#: seconds to reach a scheduler (and to find a worker on it) before giving up
DEFAULT_CONNECT_TIMEOUT_S = 10.0
#: environment variable that overrides the default above (no command-line option exists yet)
TIMEOUT_ENV = "AVS_DASK_TIMEOUT"
#: environment variable naming a file for the executor's counters at the end (diagnostics)
STATS_ENV = "AVS_DASK_STATS"

# Dask priorities: higher runs first. Prefetched cases get 0, -1, -2, ... (pytest's order);
# a case someone is already waiting for outranks all of them.
_URGENT = 1


class DaskExecutorError(RuntimeError):
    """The cluster cannot run cases any more (scheduler lost, no workers)."""


class DaskExecutor(Executor):
    """Runs case jobs on a Dask cluster.

    ``address``: scheduler of an existing cluster (``tcp://host:8786``); None starts a
    ``LocalCluster`` with ``n_workers`` (default: the cores this process may use) single-
    threaded worker processes. ``max_retries``: how often a case is resubmitted after the
    worker running it died (local cluster only). ``connect_timeout_s``: how long to try to
    reach the scheduler (default 10 s, or ``$AVS_DASK_TIMEOUT``). ``chunk_size``: prefetched
    cases per Dask task (default: automatic, see :meth:`prefetch`).

    Raises ValueError (which the plugin shows as a usage error) when the scheduler cannot be
    reached or has no workers.
    """

    name = "dask"

    def __init__(self, address: str | None = None, *, n_workers: int | None = None,
                 max_retries: int = 2, connect_timeout_s: float | None = None,
                 chunk_size: int | None = None) -> None:
        if connect_timeout_s is None:
            raw = os.environ.get(TIMEOUT_ENV, "")
            try:
                connect_timeout_s = float(raw) if raw else DEFAULT_CONNECT_TIMEOUT_S
            except ValueError:
                raise ValueError(
                    f"${TIMEOUT_ENV} must be a number of seconds, got {raw!r}") from None
        if max_retries < 0:
            raise ValueError(f"max_retries must be >= 0, got {max_retries}")
        if chunk_size is not None and chunk_size < 1:
            raise ValueError(f"chunk_size must be >= 1, got {chunk_size}")
        if n_workers is not None and n_workers < 1:
            raise ValueError(f"n_workers must be >= 1, got {n_workers}")
        self.address = address
        self.n_workers = n_workers
        self.chunk_size = chunk_size
        self.max_retries = int(max_retries)
        self.connect_timeout_s = float(connect_timeout_s)
        self._cluster: Any = None
        self._client: Any = None
        self._ahead: dict[tuple, _Task] = {}  # match key -> its task (submitted, not collected)
        self._results: dict[tuple, CaseOutcome] = {}  # match key -> outcome already pulled here
        self._ready: collections.deque = collections.deque()  # tasks whose future finished
        self._specs: dict[tuple, tuple[bytes, str]] = {}
        self._counter = itertools.count()
        self._broken: str | None = None
        self._warm: list[Any] = []
        self.stats = collections.Counter()  # prefetched, matched, on_demand, tasks, ...
        self._start()

    # -- connecting ---------------------------------------------------------------------
    def _start(self) -> None:
        timeout = self.connect_timeout_s
        if self.address is None:
            workers = self.n_workers or self._cores()
            # Read by the local scheduler when it starts: allowed-failures bounds the
            # resubmissions of a case whose worker died; with a worker-saturation of 1.0 a
            # worker holds only the task it runs, so a worker killed by one case does not
            # count as a failure of the cases queued behind it.
            settings = {"distributed.scheduler.allowed-failures": self.max_retries,
                        "distributed.scheduler.worker-saturation": 1.0}
            try:
                with dask.config.set(settings):
                    self._cluster = distributed.LocalCluster(
                        n_workers=workers, threads_per_worker=1, processes=True,
                        silence_logs=logging.ERROR, dashboard_address=None,
                        # the scheduler's HTTP endpoint on a free port: 8787 may be taken
                        # by another user's cluster on a shared machine
                        scheduler_kwargs={"dashboard_address": ":0"},
                    )
            except Exception as exc:
                raise ValueError(
                    f"--avs-executor=dask: could not start a local Dask cluster with {workers} "
                    f"worker process(es): {type(exc).__name__}: {exc}"
                ) from exc
            address = self._cluster
        else:
            address = self.address
        try:
            self._client = distributed.Client(address, timeout=timeout, set_as_default=False)
        except (OSError, TimeoutError) as exc:
            self._close_cluster()
            raise ValueError(
                f"--avs-executor=dask: cannot reach the Dask scheduler at {self.address} within "
                f"{timeout:g} s ({type(exc).__name__}: {exc}). Check the address (tcp://host:port) "
                "and that `dask scheduler` runs there, or leave out --avs-dask-address to start "
                f"a local cluster (timeout: ${TIMEOUT_ENV})"
            ) from None
        try:
            self._client.wait_for_workers(1, timeout=timeout)
        except (OSError, TimeoutError):
            self.close()
            raise ValueError(
                f"--avs-executor=dask: the Dask scheduler at {self.address} has no workers after "
                f"{timeout:g} s; start some (`dask worker {self.address}`) and run again"
            ) from None
        self._warm_up()

    def _warm_up(self) -> None:
        # one import-heavy tiny scene per worker, ahead of every case and not waited for
        # (the futures are kept: Dask forgets a task nobody holds a future of)
        try:
            for worker in self._client.scheduler_info(n_workers=-1)["workers"]:
                self._warm.append(self._client.submit(
                    warm_up, key=f"avs-warm-up-{next(self._counter)}", pure=False,
                    workers=[worker], allow_other_workers=False, priority=_URGENT + 1))
        except Exception:  # only a head start: cases import what they need anyway
            pass

    def _stack_settings(self) -> dict | None:
        """The stack settings the workers take (``--avs-stack-timeout``, ``--avs-stack-spin``)
        when a stack out of process is in use here (its client module loaded: a driver spec
        resolved at start-up, or an ``OSIStack`` made by the test or its conftest)."""
        client = sys.modules.get("pytest_avscenario.stack.client")
        if client is None:
            return None
        # a local cluster's workers share this machine; a remote one's are not known
        return client.settings_for(None if self.address is not None
                                   else (self.n_workers or self._cores()))

    @staticmethod
    def _cores() -> int:
        try:
            return max(1, len(os.sched_getaffinity(0)))
        except AttributeError:  # not on Linux
            return max(1, os.cpu_count() or 1)

    @property
    def capacity(self) -> int:
        """Worker threads in the cluster now: how many cases run at once (a batch's size)."""
        try:
            workers = self._client.scheduler_info(n_workers=-1)["workers"]
        except Exception:
            return 1
        return max(1, sum(int(w.get("nthreads", 1)) for w in workers.values()))

    @property
    def dashboard_link(self) -> str | None:
        return getattr(self._client, "dashboard_link", None)

    # -- the executor interface ---------------------------------------------------------
    def prefetch(self, jobs: Sequence[CaseJob]) -> None:
        """Submit these cases now, in this order; :meth:`run` collects each later.

        Consecutive cases of one test go in chunks of up to ``chunk_size`` per Dask task (auto:
        at least four tasks per worker thread, at most 16 cases each): a vehicle-following case
        costs ~7 ms, while every task costs the scheduler, client and worker ~2 ms on its own.
        Jobs without a driver (a conftest overrides ``avs_driver``: its value exists only when
        the item runs) cannot start ahead and are left to :meth:`run`.
        """
        self._start_ahead(jobs, urgent=False)

    def submit(self, jobs: Sequence[CaseJob]) -> None:
        """Start these cases now, one task each, ahead of every prefetched one; :meth:`run`
        collects each.

        For active samplers asking in batches: submit the batch, then ``run`` each job when
        its item runs (feedback then arrives while later cases of the batch still run).
        """
        self._start_ahead(jobs, urgent=True)

    def run(self, job: CaseJob) -> CaseOutcome:
        """The outcome of ``job``: its prefetched result if any, else simulated now."""
        if self._broken is not None:
            raise DaskExecutorError(self._broken)
        self._harvest()
        key = self._match_key(job)
        outcome = self._results.pop(key, None)
        if outcome is not None:
            self.stats["matched"] += 1
        else:
            task = self._ahead.pop(key, None)
            if task is not None:
                self.stats["matched"] += 1
            else:
                self.stats["on_demand"] += 1
                task = self._submit([job], [key], _URGENT)
            outcome = self._collect(task, key, job)
        return outcome

    def close(self) -> None:
        """Cancel what is still queued, disconnect, and stop a cluster this executor started.

        With ``$AVS_DASK_STATS`` naming a file, the counters (cases prefetched, matched, run
        on demand, tasks, chunks split) are written there as JSON: benchmarks and tests use
        it to see that cases really started ahead.
        """
        stats_path = os.environ.get(STATS_ENV)
        if stats_path:
            try:
                with open(stats_path, "w") as f:
                    json.dump(dict(self.stats), f)
            except OSError:
                pass
        client, self._client = self._client, None
        if client is not None:
            try:
                pending = {id(t): t.future for t in self._ahead.values()}
                if pending:
                    client.cancel(list(pending.values()))
            except Exception:  # closing must not fail the session
                pass
            self._ahead.clear()
            try:
                client.close(timeout=5)
            except Exception:
                pass
        self._close_cluster()

    def _close_cluster(self) -> None:
        cluster, self._cluster = self._cluster, None
        if cluster is not None:
            try:
                cluster.close(timeout=10)
            except Exception:
                pass

    # -- submitting ---------------------------------------------------------------------
    def _start_ahead(self, jobs: Sequence[CaseJob], urgent: bool) -> None:
        if self._broken is not None:
            return
        runnable = []
        for job in jobs:
            if job.driver is None and ("world" in job.argnames or "avs_driver" in job.argnames):
                continue
            key = self._match_key(job)
            if key not in self._ahead and key not in self._results:
                runnable.append((job, key))
        if not runnable:
            return
        if urgent:
            size = 1
        else:  # >= 4 tasks per worker thread keeps the tail balanced; <= 16 cases per task
            size = self.chunk_size or max(1, min(16, len(runnable) // (4 * self.capacity)))
        pieces: list[list[tuple[CaseJob, tuple]]] = []
        for job, key in runnable:  # consecutive jobs of one test share a chunk
            last = pieces[-1] if pieces else None
            if last and len(last) < size and self._spec_key(last[0][0]) == self._spec_key(job):
                last.append((job, key))
            else:
                pieces.append([(job, key)])
        for i, piece in enumerate(pieces):
            keys = [k for _, k in piece]
            task = self._submit([j for j, _ in piece], keys, _URGENT if urgent else -i)
            for key in keys:
                self._ahead[key] = task
        self.stats["submitted_ahead" if urgent else "prefetched"] += len(runnable)

    @staticmethod
    def _match_key(job: CaseJob) -> tuple:
        case = job.case
        return (job.nodeid, json.dumps(dict(case.params), sort_keys=True, default=repr), case.seed)

    @staticmethod
    def _spec_key(job: CaseJob) -> tuple:
        driver_id = job.driver if isinstance(job.driver, (str, type(None))) else id(job.driver)
        return (job.module_path, job.function, tuple(job.argnames), id(job.monitor_set), driver_id)

    def _spec(self, job: CaseJob) -> tuple[bytes, str]:
        cache_key = self._spec_key(job)
        hit = self._specs.get(cache_key)
        if hit is None:
            spec = TestSpec(module_path=job.module_path, rootdir=job.rootdir, function=job.function,
                            argnames=tuple(job.argnames), monitor_set=job.monitor_set,
                            driver=job.driver, dt=job.world_dt, dt_from=job.world_dt_from,
                            stack=self._stack_settings())
            data = pack_spec(spec)
            hit = (data, spec_digest(data))
            if isinstance(cache_key[-1], (str, type(None))):  # objects may die and reuse their id
                self._specs[cache_key] = hit
        return hit

    def _submit(self, jobs: list[CaseJob], keys: list[tuple], priority: int) -> "_Task":
        """One Dask task for ``jobs`` (cases of one test), in order."""
        first = jobs[0]
        data, digest = self._spec(first)
        fields = [CaseFields(nodeid=j.nodeid, params=dict(j.case.params), index=j.case.index,
                             seed=j.case.seed, sampler=j.case.sampler, origin=j.case.origin,
                             test=j.case.test, timeout_s=getattr(j, "timeout_s", None),
                             judge_start=getattr(j, "judge_start", False))
                  for j in jobs]
        name = f"avs-{first.function}-{first.case.sampler}-{first.case.index}-{next(self._counter)}"
        self.stats["tasks"] += 1
        # fifo_timeout=0: every submission is its own generation, so equal priorities keep
        # submission order; pure=False: a shrink replay of the same case must really rerun
        future = self._client.submit(run_remote_many, data, digest, first.module_path,
                                     first.rootdir, fields, key=name, pure=False,
                                     priority=priority, fifo_timeout=0)
        task = _Task(future, list(jobs), list(keys))
        # runs on the client's event-loop thread: only note the task (deque is thread-safe)
        future.add_done_callback(lambda _f, t=task: self._ready.append(t))
        return task

    def _harvest(self) -> None:
        """Pull every finished prefetched task's outcomes in one round trip."""
        done: list[_Task] = []
        while self._ready:
            task = self._ready.popleft()
            wanted = any(self._ahead.get(k) is task for k in task.keys)
            if wanted and task.future.status == "finished":
                done.append(task)
        if not done:
            return
        try:
            values = self._client.gather([t.future for t in done], errors="skip")
        except Exception:  # leave them to _wait, which reports per case
            return
        if len(values) != len(done):  # errors="skip" dropped some: each is collected on its own
            return
        for task, outs in zip(done, values):
            self._store(task, outs, skip=None)

    def _store(self, task: "_Task", outs: list[CaseOutcome], skip: tuple | None) -> None:
        for key, outcome in zip(task.keys, outs):
            if key != skip and self._ahead.get(key) is task:
                self._results[key] = outcome
                del self._ahead[key]

    # -- waiting ------------------------------------------------------------------------
    def _collect(self, task: "_Task", key: tuple, job: CaseJob) -> CaseOutcome:
        """``job``'s outcome from ``task``; the task's other outcomes are kept for later."""
        outs = self._wait(task)
        if outs is None:
            # A chunk whose worker kept dying: run each of its cases as its own task, so the
            # case that crashes the process fails alone and the others get their retries.
            self.stats["chunks_split"] += 1
            for other_job, other_key in zip(task.jobs, task.keys):
                if other_key != key and self._ahead.get(other_key) is task:
                    self._ahead[other_key] = self._submit([other_job], [other_key], 0)
            return self._collect(self._submit([job], [key], _URGENT), key, job)
        self._store(task, outs, skip=key)
        return outs[task.keys.index(key)]

    def _wait(self, task: "_Task") -> list[CaseOutcome] | None:
        """The task's outcomes, in order; errors become error outcomes (never passes).

        None means a chunk of several cases lost its worker too often: the caller splits it.
        """
        lost_since: float | None = None
        attempts = 0
        limits = [getattr(j, "timeout_s", None) for j in task.jobs]
        # The worker ends a body that overruns its limit itself; this deadline is for a case
        # stuck where that cannot reach (inside one C call). Counted from when pytest waits,
        # with a grace for queueing behind cases that started just before.
        budget = None if None in limits else sum(limits) + max(10.0, max(limits))
        deadline = None if budget is None else time.monotonic() + budget
        while True:
            try:
                return task.future.result(timeout=1.0)
            except TimeoutError:
                if deadline is not None and time.monotonic() > deadline:
                    task.future.cancel()
                    return self._errors(task, (
                        f"CaseTimeout: the case did not come back from its Dask worker within "
                        f"{budget:g} s (its time limit plus grace; stuck in native code?); the "
                        "worker may stay busy until that call returns"))
                lost_since = self._check_cluster(lost_since)
            except distributed.KilledWorker as exc:
                if len(task.jobs) > 1:
                    return None
                retries = f"{self.max_retries} time(s)" if self._cluster is not None else \
                    "as often as the scheduler allows (distributed.scheduler.allowed-failures)"
                return self._errors(task, (
                    f"the Dask worker running this case died, and so did the workers it was "
                    f"resubmitted to ({retries}): {exc}. The case (or the worker's environment) "
                    "crashes the process: a segfault, os._exit, running out of memory"))
            except CancelledError:
                # the scheduler forgot the task (it restarted, or the client reconnected)
                if self._client is None or attempts >= self.max_retries:
                    return self._errors(task, "the case was cancelled on the Dask cluster "
                                              f"{attempts + 1} time(s)")
                attempts += 1
                fresh = self._submit(task.jobs, task.keys, _URGENT)
                for key in task.keys:
                    if self._ahead.get(key) is task:
                        self._ahead[key] = fresh
                task = fresh
            except Exception as exc:  # the task itself failed (e.g. it did not unpickle there)
                return self._errors(task, (
                    f"the Dask worker could not run the case: {type(exc).__name__}: {exc} — is "
                    "pytest-avscenario (and everything the test module imports) installed on "
                    "every worker, and the test file at the same path?"))

    def _check_cluster(self, lost_since: float | None) -> float | None:
        """None while the cluster looks usable; raises once it has not been for the timeout."""
        client = self._client
        ok = client is not None and client.status == "running"
        why = "lost the connection to the Dask scheduler"
        if ok:
            try:
                ok = bool(client.scheduler_info(n_workers=1)["workers"])
                why = "the Dask cluster has no workers"
            except Exception:
                ok = False
        if ok:
            return None
        now = time.monotonic()
        if lost_since is None:
            return now
        if now - lost_since > self.connect_timeout_s:
            self._broken = (f"{why} for more than {self.connect_timeout_s:g} s "
                            f"(address {self.address or 'local cluster'}); the remaining cases "
                            "cannot run")
            raise DaskExecutorError(self._broken)
        return lost_since

    @staticmethod
    def _errors(task: "_Task", message: str) -> list[CaseOutcome]:
        return [CaseOutcome(params=dict(j.case.params), verdict="error", error=message)
                for j in task.jobs]


@dataclass(eq=False)
class _Task:
    """One Dask task: a case, or a chunk of consecutive prefetched cases of one test."""

    future: Any
    jobs: list[CaseJob]
    keys: list[tuple]

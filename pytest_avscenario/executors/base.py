"""The executor interface and the in-process executor.

A :class:`CaseJob` is everything needed to simulate one case of one scenario test away from
pytest: the test function (and where it lives, so a remote worker can import it), the values
of its other fixtures, the case, the monitors and the ego's driver. ``run`` returns the
:class:`~pytest_avscenario.outcome.CaseOutcome`. ``prefetch`` lets an executor start cases
before pytest reaches their items (a cluster stays busy); the in-process one ignores it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

from ..case import Case
from ..outcome import CaseOutcome
from ..runner import run_case


@dataclass
class CaseJob:
    """One case of one scenario test, ready to run anywhere the test module imports."""

    nodeid: str  # the pytest item id (the function's id for shrink candidates)
    module_path: str  # absolute path of the test module
    rootdir: str  # pytest's rootdir (import base for remote workers)
    function: str  # the test function's name in its module (``Class.method`` not supported)
    func: Callable[..., Any]  # the function object itself (used in-process)
    argnames: tuple[str, ...]
    fixtures: Mapping[str, Any]  # values of the test's other fixtures (in-process only)
    case: Case
    monitor_set: Any
    driver: Any  # the ego's driver (avs_driver's value)
    fresh_world: bool = True  # build a new world for the case (False: use fixtures["world"])
    timeout_s: float | None = None  # wall-time limit of the body (None: none)
    make_world: Callable[[Case], Any] | None = field(default=None, repr=False)
    world_dt: float | None = None  # [s] the world's step setting (None: the driver's own)
    world_dt_from: str = ""  # where it was set (quoted by warnings)
    #: in-process: called from a watchdog thread when the case passed its time limit and
    #: does not stop (see :func:`pytest_avscenario.runner.time_limit`)
    on_stuck: Callable[[float], None] | None = field(default=None, repr=False)
    #: judge ``CaseOutcome.start_unsafe`` where the case runs (``unavoidable="discard"``: a
    #: remote outcome leaves a passing case's trajectory behind)
    judge_start: bool = False


class Executor:
    """Runs case jobs. Subclasses override :meth:`run`; the others are optional."""

    name = "?"

    def prefetch(self, jobs: Sequence[CaseJob]) -> None:
        """Cases pytest will ask for later, in order (passive samplers' cases)."""

    def run(self, job: CaseJob) -> CaseOutcome:  # pragma: no cover - abstract
        raise NotImplementedError

    def close(self) -> None:
        """Release workers and connections (called once at the end of the session)."""


class InProcessExecutor(Executor):
    """The default: simulate in the pytest process, when pytest reaches the item."""

    name = "inprocess"

    def run(self, job: CaseJob) -> CaseOutcome:
        return run_case(job.func, job.argnames, job.fixtures, job.case, job.monitor_set,
                        make_world=job.make_world if job.fresh_world else None,
                        timeout_s=job.timeout_s, on_stuck=job.on_stuck)

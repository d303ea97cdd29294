"""What a campaign runs with, and what it knows of one case.

:class:`CampaignContext` carries the session's parts — the executor (made on first use), the
replay database, the report folder, the settings, the hook caller that may make a sampler —
and the campaigns of the session by test. :class:`CaseItem` is one case as the pipeline runs
it: its test, its slot, its function and how to reach its fixtures' values; the pytest side
makes one per item (:mod:`pytest_avscenario.pytest_plugin.items`), a script one per slot
(:mod:`.script`). Neither knows pytest.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..case import Case
from .plan import CaseSlot, SamplerHook, ScenarioPlan
from .state import Campaign


def _warn(message: str) -> None:
    warnings.warn(message, stacklevel=2)


def default_executor(settings: Any) -> Any:
    """The executor the settings name (``inprocess``, or ``dask`` with its options);
    ValueError says what is wrong with them."""
    from ..executors import make_executor

    options: dict[str, Any] = {}
    if settings.executor == "dask":
        options["address"] = settings.dask_address
        for key, value in (("n_workers", settings.dask_workers),
                           ("connect_timeout_s", settings.dask_timeout_s),
                           ("max_retries", settings.dask_retries)):
            if value is not None:
                options[key] = value
    return make_executor(settings.executor, **options)


@dataclass(eq=False)
class CampaignContext:
    """The parts every case of a session's campaigns uses."""

    settings: Any  # settings.Settings
    db: Any = None  # the db.ReplayDB, or None
    #: the report folder, asked when a case has something to draw (None: no report)
    folder: Callable[[], Path | None] = lambda: None
    #: makes the executor on first use (default: the settings' executor)
    make_executor: Callable[[], Any] | None = None
    make_sampler: SamplerHook | None = None  # the hook caller for a sampler of one's own
    warn: Callable[[str], None] = _warn  # a warning about one case (drawing, storing)
    #: asked when a failure is minimized: the writer of a live line in verbose runs (with
    #: an ``every`` attribute), or None
    progress: Callable[[], Any] = lambda: None
    verbosity: int = 0  # failure texts: 0 compact, 1 or more every metric side by side
    worker: bool = False  # this process runs a share of the cases (an xdist worker)
    campaigns: dict[str, Campaign] = field(default_factory=dict)  # test id -> its campaign
    said: set = field(default_factory=set)  # (test, warning key) a world said already
    _executor: Any = None

    @property
    def executor(self) -> Any:
        """The executor, made on first use (a Dask cluster only when a case runs)."""
        if self._executor is None:
            self._executor = (self.make_executor or (lambda: default_executor(self.settings)))()
        return self._executor

    def campaign(self, plan: ScenarioPlan) -> Campaign:
        """The campaign of ``plan``'s test, made on first use."""
        found = self.campaigns.get(plan.test)
        if found is None:
            found = self.campaigns[plan.test] = Campaign(plan, make_sampler=self.make_sampler)
        return found

    def world_warner(self, test: str) -> Callable[[Warning, str], None]:
        """``World.warn`` for the worlds of ``test``: each kind of warning once per test
        function and process, not once per case, shrink candidate or replay."""
        said = self.said

        def warn(warning: Warning, key: str) -> None:
            if (test, key or str(warning)) in said:
                return
            said.add((test, key or str(warning)))
            warnings.warn(warning, stacklevel=2)

        return warn

    def close(self) -> None:
        if self._executor is not None:
            self._executor.close()


def _nothing() -> dict[str, Any]:
    return {}


@dataclass(eq=False)
class CaseItem:
    """One case of a campaign as the pipeline runs it (under pytest: one item)."""

    nodeid: str  # "tests/test_x.py::test_x[halton-003]"
    test: str  # the test function's id: "tests/test_x.py::test_x"
    name: str  # "test_x[halton-003]": the title of its pictures
    slot: CaseSlot
    plan: ScenarioPlan
    func: Callable[..., Any]  # the test function
    function: str  # its name in its module
    module_path: str
    rootdir: str
    argnames: tuple[str, ...]  # the fixtures the function takes
    #: the values of its fixtures, once they are set up (they may fill while set up)
    fixtures: Callable[[], Mapping[str, Any]] = _nothing
    #: the values of its fixtures other than ``case`` and ``world``, while its own ``case``
    #: is being made (an active sampler simulates the cases before it with them)
    other_fixtures: Callable[[], dict[str, Any]] = _nothing
    #: the ego's driver (the ``avs_driver`` fixture's value), when no fixture value has it
    driver: Callable[[], Any] = lambda: None
    driver_ahead: Any = None  # the driver known before its fixtures exist (None: unknown)
    identity: Callable[[], Any] = lambda: None  # who drives the ego, for its row
    #: ``on_stuck(limit_s, make_row, info, during)``: the handler of a simulation that would
    #: not stop (None: the runner's own)
    on_stuck: Callable[..., Any] | None = None
    user_properties: list = field(default_factory=list)  # (name, value) for the JUnit file
    # what the case gave, kept as soon as known (a failure after the row keeps the row)
    row: Any = None
    shrink_rows: list = field(default_factory=list)
    pictures: dict = field(default_factory=dict)

    def keep_row(self, row: Any, shrink_rows: list) -> None:
        self.row, self.shrink_rows = row, shrink_rows

    def keep_pictures(self, pictures: dict) -> None:
        self.pictures = pictures

    def own_case(self) -> Case:
        """Its own case: the ``case`` fixture's value, or, before its fixtures exist (or when
        they failed), its slot's (the values an active sampler has not asked yet are {})."""
        own = self.fixtures().get("case")
        if isinstance(own, Case):
            return own
        slot = self.slot
        return slot.case(self.nodeid, slot.params if slot.params is not None else {})

"""The plugin's one session object: the campaigns, the executor and the report sink.

:class:`ScenarioSession` is made in ``pytest_configure`` and kept in the config's stash. It
owns the :class:`~pytest_avscenario.campaign.context.CampaignContext` of the run (made on
first use, so a run without scenario tests loads no campaign code): the settings, the replay
database, the report folder of the controller (:class:`~.controller.RunState`, the sink of
every row), the executor and the campaigns by test. The hooks hand it items; it hands the
pipeline their :class:`~.items.PytestCase`. It also keeps what pytest's cache holds of active
campaigns between runs (a re-run of one case id replays the values that were drawn).
"""

from __future__ import annotations

import warnings
from typing import Any

import pytest

from .stash import (
    campaigns_key,
    case_item_key,
    controller_key,
    executor_key,
    session_key,
    settings_key,
)


class ScenarioSession:
    """The scenario side of one pytest session (one per config)."""

    def __init__(self, config: pytest.Config, db: Any, report: Any):
        self.config = config
        self.settings = config.stash[settings_key]
        self.db = db
        self.report = report  # the controller's RunState: the rows' sink and the report folder
        self.campaigns: dict[str, Any] = config.stash.setdefault(campaigns_key, {})
        self._context: Any = None

    @property
    def context(self) -> Any:
        """The campaigns' context, made on first use."""
        if self._context is None:
            from ..campaign.context import CampaignContext
            from .collect import sampler_hook

            config = self.config
            self._context = CampaignContext(
                self.settings, self.db, folder=lambda: self.report.directory,
                make_executor=self._make_executor, make_sampler=sampler_hook(config),
                warn=_warn, progress=lambda: progress_writer(config),
                verbosity=config.get_verbosity(), worker=hasattr(config, "workerinput"),
                campaigns=self.campaigns)
        return self._context

    def _make_executor(self) -> Any:
        from ..campaign.context import default_executor

        try:
            executor = default_executor(self.settings)
        except ValueError as exc:
            raise pytest.UsageError(str(exc)) from None
        self.config.stash[executor_key] = executor
        return executor

    @property
    def executor(self) -> Any:
        """The session's executor, made on first use (a Dask cluster only when a case runs)."""
        return self.context.executor

    def campaign_of(self, item: pytest.Item) -> Any:
        from .collect import plan_of

        return self.context.campaign(plan_of(item))

    # -- the items' cases ------------------------------------------------------------------
    def case_for(self, item: pytest.Item, request: pytest.FixtureRequest) -> Any:
        """The ``case`` fixture's value of ``item``; skipped once its campaign's time budget
        is spent."""
        ctx = self._context or self.context
        from .items import case_item

        ci = case_item(item, request)
        from ..campaign.pipeline import OutOfTime, case_for  # loaded before the clock starts

        try:
            return case_for(ctx, ci)
        except OutOfTime as exc:
            why = str(exc)
        pytest.skip(why)

    def world(self, item: pytest.Item, case: Any, driver: Any) -> Any:
        """The ``world`` fixture's value of ``item``."""
        from ..campaign.jobs import world_for

        return world_for(self._context or self.context, _case_of(item), case, driver)

    def run_item(self, item: pytest.Item) -> Any:
        """Run ``item``'s case through the pipeline (its row lands in the item's stash)."""
        from ..campaign.pipeline import run_item

        return run_item(self._context or self.context, _case_of(item))

    # -- the whole selection ---------------------------------------------------------------
    def collection_finish(self, session: pytest.Session) -> None:
        """Note which cases of active campaigns this run selects; hand a remote executor the
        passive cases ahead, so its workers stay busy."""
        config = self.config
        note_selection(session)
        config.stash[controller_key].partial = left_out(session)
        if self.settings.executor == "inprocess" or hasattr(config, "workerinput"):
            return
        self.executor  # connect now: an unreachable cluster stops the run once  # noqa: B018
        prefetch_passive_cases(session)

    def close(self) -> None:
        if self._context is not None:
            self._context.close()


def _case_of(item: pytest.Item) -> Any:
    """The item's campaign case (:func:`.items.case_item`), made once."""
    found = item.stash.get(case_item_key, None)
    if found is None:
        from .items import case_item

        found = case_item(item)
    return found


def session_of(config: pytest.Config) -> ScenarioSession:
    return config.stash[session_key]


def _warn(message: str) -> None:
    warnings.warn(pytest.PytestWarning(message), stacklevel=2)


def campaign_of(item: pytest.Item) -> Any:
    return session_of(item.config).campaign_of(item)


def executor_of(config: pytest.Config) -> Any:
    """The session's executor, made on first use (a Dask cluster only when a case runs)."""
    return session_of(config).executor


def progress_writer(config: pytest.Config) -> Any:
    """A function printing a live line in verbose runs (None when quiet or on an xdist worker)."""
    if config.get_verbosity() < 1 or hasattr(config, "workerinput"):
        return None
    reporter = config.pluginmanager.get_plugin("terminalreporter")
    capman = config.pluginmanager.get_plugin("capturemanager")
    if reporter is None or capman is None:
        return None

    def write(text: str) -> None:
        with capman.global_and_fixture_disabled():
            reporter.write_line(f"  avscenario: {text}")

    write.every = 1 if config.get_verbosity() >= 2 else 5  # type: ignore[attr-defined]
    return write


def note_selection(session: pytest.Session) -> None:
    """Where this run selects only part of an active campaign (``-k``, ``--lf``), load the
    values pytest's cache kept from the run that drew them, to replay them exactly."""
    from .collect import function_id, slot_of

    cache = getattr(session.config, "cache", None)
    if cache is None:
        return
    chosen: dict[tuple[str, str], set[int]] = {}
    for item in session.items:
        slot = slot_of(item)
        if slot is not None and slot.params is None and slot.origin == "sampled":
            chosen.setdefault((function_id(item), slot.sampler), set()).add(slot.index)
    for (test, name), indexes in chosen.items():
        campaign = campaign_of(next(i for i in session.items if function_id(i) == test))
        if len(indexes) == campaign.plan.samples:
            continue  # the whole campaign runs: draw it afresh
        kept = cache.get(campaign.cache_key(name), None)
        if isinstance(kept, list):
            campaign.run_of(name).cached = {j: p for j, p in enumerate(kept) if isinstance(p, dict)}


def left_out(session: pytest.Session) -> str | None:
    """Why this run re-runs some cases of a campaign (one scenario test with one sampler)
    rather than whole campaigns, or None: it runs some but not all of a campaign's sampled
    cases (``-k halton-003``, ``--lf``, a case id on the command line). Leaving out whole
    tests or samplers is not a re-run."""
    from .collect import function_id, plan_of, slot_of

    counts: dict[tuple[str, str], int] = {}
    plans: dict[str, Any] = {}
    for item in session.items:
        slot = slot_of(item)
        if slot is None or slot.origin != "sampled":
            continue
        test = function_id(item)
        plans.setdefault(test, plan_of(item))
        counts[(test, slot.sampler)] = counts.get((test, slot.sampler), 0) + 1
    for (test, name), n in counts.items():
        if n < plans[test].samples:
            return f"it runs {n} of the {plans[test].samples} {name} cases of {test}"
    return None


def keep_drawn_values(config: pytest.Config) -> None:
    """Put the values each active campaign drew into pytest's cache, for re-runs of single ids."""
    cache = getattr(config, "cache", None)
    if cache is None:
        return
    from ..codec import jsonable

    for campaign in config.stash[campaigns_key].values():
        for name, run in campaign.active.items():
            if not run.params or run.from_cache:
                continue
            key = campaign.cache_key(name)
            kept = cache.get(key, None)
            if not isinstance(kept, list) or len(kept) <= len(run.params):
                cache.set(key, [jsonable(p) for p in run.params])


def prefetch_passive_cases(session: pytest.Session) -> None:
    """Hand a remote executor the passive cases ahead, so its workers stay busy; remember the
    items of active samplers, whose cases are asked ahead once items run."""
    from ..campaign.pipeline import prefetch_jobs
    from .collect import slot_of
    from .items import case_item

    own = session_of(session.config)
    items = [case_item(item) for item in session.items
             if slot_of(item) is not None and item.get_closest_marker("scenario") is not None]
    jobs = prefetch_jobs(own.context, items)
    if jobs:
        own.executor.prefetch(jobs)

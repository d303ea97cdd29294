"""One scenario test's campaign while it runs.

:class:`Campaign` is the running state of a test's campaign — its live active samplers, how
many failures were minimized, when each sampler's campaign started — kept apart from the
read-only :class:`~.plan.ScenarioPlan`. :class:`ActiveRun` keeps an active sampler's cases in
case-index order whatever order the cases run in.
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import dataclass, field
from typing import Any

from ..outcome import CaseOutcome
from .plan import SamplerHook, ScenarioPlan


@dataclass
class ActiveRun:
    """One active sampler's campaign, drawn in case-index order whatever order pytest runs
    its items in: case k is asked only once cases 0 .. k-1 are told. An item reached before
    the items of earlier cases (a reversed or shuffled order, ``-k``, ``--lf``, an xdist
    worker given a share) simulates those cases first, with its own fixtures, and keeps their
    outcomes for their items. So ``test_x[mab-007]`` names the same values in every order
    and process for one seed. When this run selects only part of the campaign, values that
    pytest's cache kept from the run that drew them are replayed instead."""

    sampler: Any
    params: list[dict[str, Any]] = field(default_factory=list)  # asked, by case index
    told: int = 0  # cases 0 .. told-1 are told
    ahead: dict[int, CaseOutcome] = field(default_factory=dict)  # simulated before their item
    cached: dict[int, dict[str, Any]] = field(default_factory=dict)  # from pytest's cache
    from_cache: set[int] = field(default_factory=set)  # items that replayed cached values


@dataclass
class Campaign:
    """The running state of one scenario test's campaign (all its samplers)."""

    plan: ScenarioPlan
    make_sampler: SamplerHook | None = None  # a sampler of one's own (pytest: the conftests' hook)
    active: dict[str, ActiveRun] = field(default_factory=dict)  # active sampler name -> its run
    shrunk: dict[str, int] = field(default_factory=dict)  # sampler -> failures minimized so far
    gifs: int = 0  # GIFs rendered so far for this test
    pictured: dict[str, int] = field(default_factory=dict)  # sampler -> cases drawn as PNGs
    exported: dict[str, int] = field(default_factory=dict)  # sampler -> cases exported, not minimized
    started: dict[str, float] = field(default_factory=dict)  # sampler -> campaign start
    ran: dict[str, int] = field(default_factory=dict)  # sampler -> cases run
    judged: dict[str, int] = field(default_factory=dict)  # sampler -> avoidability checks run
    # (sampler, index) -> its avoidability, judged before its item ran (to tell a sampler)
    judgements: dict[tuple[str, int], Any] = field(default_factory=dict)

    def run_of(self, name: str) -> ActiveRun:
        """The run of active sampler ``name``, made on first use."""
        if name not in self.active:
            self.active[name] = ActiveRun(self.plan.make_sampler(name, self.make_sampler))
        return self.active[name]

    def cache_key(self, name: str) -> str:
        """pytest's cache key of the values active sampler ``name`` draws in this campaign:
        the same declaration and seed, the same key."""
        p = self.plan
        what = [p.test, name, p.seed, p.space.fingerprint(), p.samples,
                sorted(p.sampler_options.items()), list(p.metrics),
                list(p.monitor_set.priority_edges) if p.monitor_set is not None else []]
        digest = hashlib.sha256(json.dumps(what, default=repr).encode()).hexdigest()[:24]
        return f"avscenario/active/{digest}"

    def out_of_time(self, sampler: str) -> str | None:
        """Why the next case of ``sampler`` is skipped (its time budget is spent), or None."""
        budget = self.plan.time_budget_s
        if budget is None:
            return None
        start = self.started.setdefault(sampler, time.monotonic())
        if time.monotonic() - start <= budget:
            return None
        return f"time budget of {budget:g} s for {sampler} spent after {self.ran.get(sampler, 0)} cases"

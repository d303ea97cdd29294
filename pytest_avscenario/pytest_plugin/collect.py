"""Collection: one ``@scenario`` test becomes one pytest item per concrete case.

:func:`plan_scenario` validates the declaration, resolves its settings (:mod:`.options`) into
a frozen :class:`ScenarioPlan` — what the declaration says, nothing that changes while the
campaign runs (that is :class:`~.campaign.Campaign`) — and lists the :class:`CaseSlot` of
every item in order: pinned ``@example``s, stored counterexamples to replay, then the sampled
cases. Passive samplers fix each slot's values here, identically in every process for one
seed; an active sampler's slots stay empty until the item runs.
"""

from __future__ import annotations

import types
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import pytest

from ..case import RESERVED, Case, stable_seed
from ..markers.spec import ScenarioSpec
from ..space import FeatureSpace, SpaceError
from .options import DeclarationError, Settings
from .stash import plans_key


@dataclass(frozen=True)
class CaseSlot:
    """What collection fixes about one item: its index, origin and (if passive) its values."""

    sampler: str
    index: int
    seed: int
    origin: str = "sampled"
    params: Mapping[str, Any] | None = None  # None: asked from an active sampler at run time

    @property
    def id(self) -> str:
        return f"{self.sampler}-{self.index:03d}" if self.origin == "sampled" else f"{self.origin}-{self.index}"

    def case(self, test: str, params: Mapping[str, Any] | None = None, origin: str | None = None) -> Case:
        """The :class:`Case` of this slot (``params`` for an active sampler's slot, or a
        shrinking candidate; ``origin`` to say so)."""
        values = self.params if params is None else params
        return Case(values, index=self.index, seed=self.seed, sampler=self.sampler,
                    origin=origin or self.origin, test=test)


@dataclass(frozen=True)
class ScenarioPlan:
    """A scenario test's resolved declaration (one per test function), read-only."""

    test: str
    space: FeatureSpace
    samplers: tuple[str, ...]
    samples: int
    seed: int
    monitor_set: Any
    sampler_options: Mapping[str, Any]
    time_budget_s: float | None
    shrink_budget: int
    shrink_max: int | None  # failures per sampler minimized and stored (None: all)
    case_timeout_s: float | None
    replays: Mapping[int, Any]  # replay index -> db entry
    accept: Any  # acceptance.Criteria

    @property
    def metrics(self) -> tuple[str, ...]:
        return tuple(self.monitor_set.names) if self.monitor_set is not None else ()

    def info(self) -> dict[str, Any]:
        """What the controller needs to summarize this test (plain JSON)."""
        return {"metrics": list(self.metrics), "space": self.space.describe(),
                "accept": self.accept.to_json(), "samplers": list(self.samplers)}

    def make_sampler(self, name: str) -> Any:
        from .. import samplers

        opts = dict(self.sampler_options)
        if samplers.base.is_active(name) and self.monitor_set is not None:
            opts.setdefault("metrics", list(self.monitor_set.names))
            if self.monitor_set.priority_edges:
                opts.setdefault("priority", [list(e) for e in self.monitor_set.priority_edges])
        return samplers.make(name, self.space, seed=stable_seed(self.seed, name), **opts)


def plan_scenario(metafunc: pytest.Metafunc, marker: pytest.Mark, settings: Settings,
                  db: Any) -> tuple[ScenarioPlan, list[CaseSlot]]:
    """The plan of ``metafunc``'s test and its items' slots; DeclarationError, SpaceError
    or ValueError say what is wrong with the declaration."""
    test = metafunc.definition.nodeid
    if len(marker.args) != 1 or not isinstance(marker.args[0], ScenarioSpec) or marker.kwargs:
        raise DeclarationError(
            "use the @scenario(...) decorator from pytest_avscenario, not a bare "
            "@pytest.mark.scenario"
        )
    spec: ScenarioSpec = marker.args[0]
    if "case" not in metafunc.fixturenames:
        raise DeclarationError(
            "a @scenario test must request the `case` fixture (add `case` to its arguments) "
            "to read the concrete parameter values"
        )
    space = _space(metafunc, spec)
    if settings.executor != "inprocess":
        _check_remote_fixtures(metafunc, settings.executor)
    own = settings.for_test(spec)

    if spec.seed is not None:
        if isinstance(spec.seed, bool) or not isinstance(spec.seed, int) or spec.seed < 0:
            raise DeclarationError(f"seed must be a non-negative int, got {spec.seed!r}")
        seed = stable_seed("marker", spec.seed)
    else:
        seed = stable_seed(settings.seed, test)

    monitor_set = None
    if spec.monitors:
        from ..monitors import MonitorSet

        try:
            monitor_set = MonitorSet(list(spec.monitors), priority=spec.priority)
        except ValueError as exc:
            raise DeclarationError(f"monitors: {exc}") from None
    elif spec.priority:
        raise DeclarationError("priority= is given but no monitors= to order")
    opts = spec.sampler_options or {}
    if not isinstance(opts, dict):
        raise DeclarationError(f"sampler_options must be a dict, got {opts!r}")

    pinned = None
    if settings.params is not None:
        pinned = {**space.nominal(), **settings.params}
        space.validate(pinned)

    if getattr(metafunc.function, "hypothesis_explicit_examples", None):
        raise DeclarationError(
            "@example here is Hypothesis's, which does not pin scenario cases: use "
            "`from pytest_avscenario import example`")
    slots: list[CaseSlot] = []
    for k, pin in enumerate(getattr(metafunc.function, "_avs_examples", ())):
        params = space.complete(pin)
        try:
            space.validate(params)
        except SpaceError as exc:
            raise DeclarationError(f"@example #{k} ({call_text('example', pin)}): {exc}") from None
        slots.append(CaseSlot("example", k, stable_seed(seed, "example", k), "example", params))
    replays: dict[int, Any] = {}
    if db is not None and pinned is None:
        from ..db import replay_params, space_changes

        for entry in db.entries(test):
            if entry.fingerprint != space.fingerprint():
                changed = ", ".join(repr(n) for n in space_changes(entry.space, space)) or "its space"
                warnings.warn(pytest.PytestWarning(
                    f"{test}: stored counterexample {entry.path.name} skipped: parameter "
                    f"{changed} changed since it was found"))
                continue
            try:
                # the file is data anyone may have edited: only declared values reach the body
                params = replay_params(space, entry.params)
            except ValueError as exc:
                warnings.warn(pytest.PytestWarning(
                    f"{test}: stored counterexample {entry.path} skipped: {exc}; not replayed, "
                    "left on disk for you to fix or delete"))
                continue
            k = len(replays)
            replays[k] = entry
            slots.append(CaseSlot("replay", k, entry.seed, "replay", params))

    plan = ScenarioPlan(
        test=test, space=space, samplers=own.samplers, samples=own.samples, seed=seed,
        monitor_set=monitor_set, sampler_options=types.MappingProxyType(dict(opts)),
        time_budget_s=own.time_budget_s, shrink_budget=own.shrink_budget,
        shrink_max=own.shrink_max, case_timeout_s=own.case_timeout_s,
        replays=types.MappingProxyType(replays), accept=own.accept)
    from ..samplers import base as sampler_base

    for name in plan.samplers:
        try:
            own.accept.check(plan.metrics, active=sampler_base.is_active(name))
        except ValueError as exc:
            raise DeclarationError(f"accept: {exc} (sampler {name!r})") from None

    from ..samplers import SamplerError

    for name in plan.samplers:
        try:
            sampler = plan.make_sampler(name)
        except SamplerError as exc:
            raise DeclarationError(str(exc)) from None
        if pinned is not None:
            values: list[Mapping[str, Any] | None] = [dict(pinned)] * plan.samples
        elif sampler.active:
            values = [None] * plan.samples
        else:
            values = [space.from_unit(p) for p in sampler.sample_unit(plan.samples)]
        for k, params in enumerate(values):
            slots.append(sampled_slot(plan, name, k, params))
    return plan, slots


def sampled_slot(plan: ScenarioPlan, sampler: str, index: int,
                 params: Mapping[str, Any] | None = None) -> CaseSlot:
    """The slot of sampled case ``index`` of ``sampler``'s campaign (its seed is fixed by the
    plan's seed, the sampler and the index alone)."""
    return CaseSlot(sampler, index, stable_seed(plan.seed, sampler, index), origin="sampled", params=params)


def _space(metafunc: pytest.Metafunc, spec: ScenarioSpec) -> FeatureSpace:
    """The test's feature space, refusing parameter names that would shadow something."""
    if not spec.parameters:
        raise DeclarationError("@scenario declares no parameters; give at least one, e.g. gap=Uniform(10, 40)")
    fm = metafunc.definition.session._fixturemanager
    for name in spec.parameters:
        if name in RESERVED:
            raise DeclarationError(
                f"parameter {name!r} clashes with the case attribute of the same name; rename it"
            )
        if fm.getfixturedefs(name, metafunc.definition):
            raise DeclarationError(
                f"parameter {name!r} clashes with the fixture {name!r}; rename the parameter "
                "(read values as case.<name>, fixtures stay available as arguments)"
            )
    return FeatureSpace(spec.parameters)


def _check_remote_fixtures(metafunc: pytest.Metafunc, executor: str) -> None:
    fm = metafunc.definition.session._fixturemanager
    autouse = set(fm._getautousenames(metafunc.definition))
    own = set(metafunc.definition._fixtureinfo.argnames)
    # `request` is in every closure (our fixtures use it); refused only when the test asks
    others = sorted((set(metafunc.fixturenames) - {"case", "world", "avs_driver", "request"} - autouse)
                    | (own & {"request"}))
    if others:
        raise DeclarationError(
            f"under --avs-executor={executor} a scenario test gets only `case`, `world` and "
            f"`avs_driver` on the remote workers; it also requests {', '.join(others)} — run "
            "it with the in-process executor or drop them"
        )


def call_text(name: str, params: Mapping[str, Any]) -> str:
    return f"@{name}(" + ", ".join(f"{k}={v!r}" for k, v in params.items()) + ")"


def function_id(item: pytest.Item) -> str:
    nodeid = item.nodeid
    return nodeid[: nodeid.index("[")] if "[" in nodeid else nodeid


def plan_of(item: pytest.Item) -> ScenarioPlan:
    return item.config.stash[plans_key][function_id(item)]


def slot_of(item: pytest.Item) -> CaseSlot | None:
    """The item's slot, or None for an item that is not a scenario case."""
    slot = item.callspec.params.get("case") if hasattr(item, "callspec") else None
    return slot if isinstance(slot, CaseSlot) else None

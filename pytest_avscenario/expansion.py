"""Expansion: one ``@scenario`` test becomes one pytest item per concrete case.

:func:`plan_scenario` validates the declaration and resolves its settings into a
:class:`ScenarioPlan` (one per test function), and lists the :class:`CaseSlot` of every item
in order: pinned ``@example``s, stored counterexamples to replay, then the sampled cases.
Passive samplers fix each slot's values here, identically in every process for one seed;
an active sampler's slots stay empty until the item runs (:func:`active_sampler`).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import pytest

from .case import RESERVED, stable_seed
from .keys import db_key, plans_key, seed_key
from .markers.spec import ScenarioSpec
from .settings import (
    DEFAULT_SHRINK_BUDGET,
    DeclarationError,
    executor_name,
    pinned_params,
    resolve_case_timeout,
    resolve_samplers,
    resolve_samples,
    resolve_shrink_budget,
    resolve_shrink_max,
    resolve_time_budget,
)
from .space import FeatureSpace, SpaceError


@dataclass
class CaseSlot:
    """What collection fixes about one item: its index, origin and (if passive) its values."""

    sampler: str
    index: int
    seed: int
    origin: str = "sampled"
    params: dict[str, Any] | None = None  # None: asked from an active sampler at run time

    @property
    def id(self) -> str:
        return f"{self.sampler}-{self.index:03d}" if self.origin == "sampled" else f"{self.origin}-{self.index}"


@dataclass
class ScenarioPlan:
    """A scenario test's resolved declaration (one per test function)."""

    test: str
    space: FeatureSpace
    samplers: list[str]
    samples: int
    seed: int
    monitor_set: Any
    sampler_options: dict[str, Any]
    time_budget_s: float | None = None
    shrink_budget: int = DEFAULT_SHRINK_BUDGET
    shrink_max: int | None = None  # failures per sampler minimized and stored (None: all)
    shrunk: dict[str, int] = field(default_factory=dict)  # sampler -> failures minimized so far
    replays: dict[int, Any] = field(default_factory=dict)  # replay index -> db entry
    gifs: int = 0  # GIFs rendered so far for this test
    case_timeout_s: float | None = None
    active: dict[str, Any] = field(default_factory=dict)  # sampler name -> live sampler
    started: dict[str, float] = field(default_factory=dict)  # sampler -> campaign start
    ran: dict[str, int] = field(default_factory=dict)  # sampler -> cases run
    # asking ahead on a cluster: (sampler, index) -> the item, values asked, last index asked
    items: dict[tuple[str, int], Any] = field(default_factory=dict)
    asked: dict[tuple[str, int], dict[str, Any]] = field(default_factory=dict)
    asked_upto: dict[str, int] = field(default_factory=dict)

    @property
    def metrics(self) -> tuple[str, ...]:
        return tuple(self.monitor_set.names) if self.monitor_set is not None else ()

    def info(self) -> dict[str, Any]:
        """What the controller needs to summarize this test (plain JSON)."""
        return {"metrics": list(self.metrics), "space": self.space.describe()}

    def make_sampler(self, name: str) -> Any:
        from . import samplers

        opts = dict(self.sampler_options)
        if samplers.base.is_active(name) and self.monitor_set is not None:
            opts.setdefault("metrics", list(self.monitor_set.names))
            if self.monitor_set.priority_edges:
                opts.setdefault("priority", [list(e) for e in self.monitor_set.priority_edges])
        return samplers.make(name, self.space, seed=stable_seed(self.seed, name), **opts)


def plan_scenario(metafunc: pytest.Metafunc, marker: pytest.Mark) -> tuple[ScenarioPlan, list[CaseSlot]]:
    config = metafunc.config
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

    # parameters: their distributions, and names that would shadow something
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
    space = FeatureSpace(spec.parameters)
    if executor_name(config) != "inprocess":
        own = set(metafunc.definition._fixtureinfo.argnames)
        # `request` is in every closure (our fixtures use it); refused only when the test asks
        others = sorted((set(metafunc.fixturenames) - {"case", "world", "avs_driver", "request"}
                         - set(autouse_names(metafunc))) | (own & {"request"}))
        if others:
            raise DeclarationError(
                f"under --avs-executor={executor_name(config)} a scenario test gets only "
                f"`case`, `world` and `avs_driver` on the remote workers; it also requests "
                f"{', '.join(others)} — run it with the in-process executor or drop them"
            )

    samples = resolve_samples(config, spec)
    sampler_names = resolve_samplers(config, spec)

    if spec.seed is not None:
        if isinstance(spec.seed, bool) or not isinstance(spec.seed, int) or spec.seed < 0:
            raise DeclarationError(f"seed must be a non-negative int, got {spec.seed!r}")
        seed = stable_seed("marker", spec.seed)
    else:
        seed = stable_seed(config.stash[seed_key], test)

    monitor_set = None
    if spec.monitors:
        from .monitors import MonitorSet

        try:
            monitor_set = MonitorSet(list(spec.monitors), priority=spec.priority)
        except ValueError as exc:
            raise DeclarationError(f"monitors: {exc}") from None
    elif spec.priority:
        raise DeclarationError("priority= is given but no monitors= to order")

    opts = spec.sampler_options or {}
    if not isinstance(opts, dict):
        raise DeclarationError(f"sampler_options must be a dict, got {opts!r}")
    plan = ScenarioPlan(test=test, space=space, samplers=sampler_names, samples=samples,
                        seed=seed, monitor_set=monitor_set, sampler_options=dict(opts),
                        time_budget_s=resolve_time_budget(config, spec),
                        shrink_budget=resolve_shrink_budget(config, spec),
                        shrink_max=resolve_shrink_max(config, spec),
                        case_timeout_s=resolve_case_timeout(config, spec))

    pinned = pinned_params(config, space)
    slots: list[CaseSlot] = []
    for k, pin in enumerate(getattr(metafunc.function, "_avs_examples", ())):
        params = space.complete(pin)
        try:
            space.validate(params)
        except SpaceError as exc:
            raise DeclarationError(f"@example #{k} ({call_text('example', pin)}): {exc}") from None
        slots.append(CaseSlot("example", k, stable_seed(seed, "example", k), "example", params))
    db = config.stash[db_key]
    if db is not None and pinned is None:
        from .db import space_changes

        for entry in db.entries(test):
            if entry.fingerprint != space.fingerprint():
                changed = ", ".join(repr(n) for n in space_changes(entry.space, space)) or "its space"
                warnings.warn(pytest.PytestWarning(
                    f"{test}: stored counterexample {entry.path.name} skipped: parameter "
                    f"{changed} changed since it was found"))
                continue
            k = len(plan.replays)
            plan.replays[k] = entry
            slots.append(CaseSlot("replay", k, entry.seed, "replay", space.complete(entry.params)))
    from .samplers import SamplerError

    for name in sampler_names:
        try:
            sampler = plan.make_sampler(name)
        except SamplerError as exc:
            raise DeclarationError(str(exc)) from None
        if pinned is not None:
            values: list[dict[str, Any] | None] = [dict(pinned)] * samples
        elif sampler.active:
            values = [None] * samples
        else:
            pts = sampler.sample_unit(samples)
            values = [space.from_unit(p) for p in pts]
        for k, params in enumerate(values):
            slots.append(CaseSlot(name, k, stable_seed(seed, name, k),
                                  origin="sampled", params=params))
    return plan, slots


def autouse_names(metafunc: pytest.Metafunc) -> list[str]:
    fm = metafunc.definition.session._fixturemanager
    return list(fm._getautousenames(metafunc.definition))


def call_text(name: str, params: Mapping[str, Any]) -> str:
    return f"@{name}(" + ", ".join(f"{k}={v!r}" for k, v in params.items()) + ")"


def plan_of(item: pytest.Item) -> ScenarioPlan:
    return item.config.stash[plans_key][function_id(item)]


def function_id(item: pytest.Item) -> str:
    nodeid = item.nodeid
    return nodeid[: nodeid.index("[")] if "[" in nodeid else nodeid


def active_sampler(plan: ScenarioPlan, name: str) -> Any:
    if name not in plan.active:
        plan.active[name] = plan.make_sampler(name)
    return plan.active[name]

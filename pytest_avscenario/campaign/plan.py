"""A scenario test's plan: its resolved declaration and the slot of every case.

:func:`build_plan` validates a ``@scenario`` declaration, resolves its settings
(:mod:`.settings`) into a frozen :class:`ScenarioPlan` — what the declaration says, nothing
that changes while the campaign runs (that is :class:`~.state.Campaign`) — and lists the
:class:`CaseSlot` of every case in order: pinned ``@example``s, stored counterexamples to
replay, then the sampled cases. Passive samplers fix each slot's values here, identically in
every process for one seed; an active sampler's slots stay empty until the case runs. The
pytest side (:mod:`pytest_avscenario.pytest_plugin.collect`) adds the checks that need the
pytest collection (the marker's form, fixtures) and makes one item per slot.
"""

from __future__ import annotations

import keyword
import types
import warnings
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any, Callable

from ..case import RESERVED, Case, stable_seed
from ..frozen import CompactMapping
from ..markers.spec import SPEC_KEYWORDS, BadExample, ScenarioSpec
from ..space import Distribution, FeatureSpace, SpaceError, _show
from .settings import DeclarationError, Settings

#: ``hook(name=, space=, seed=, options=)``: a sampler of one's own, or None for the registry's
SamplerHook = Callable[..., Any]


@dataclass(frozen=True, slots=True)
class CaseSlot:
    """What collection fixes about one item: its index, origin and (if passive) its values.
    One per item, alive for the whole run: slots, no ``__dict__`` (a 100,000-case campaign)."""

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
    reference_driver: str | None = None  # judges avoidability of counterexamples (None: off)
    reference_max: int | None = None  # counterexamples per sampler judged (None: all)
    discard_unavoidable: bool = False  # active samplers learn nothing of unfair cases
    dt: float | None = None  # [s] world.run()'s step when it gives none (None: the driver's)
    dt_from: str = ""  # where dt was set, for the warnings that quote it
    #: metric -> margin of the avoidability judgement in the metric's unit (absent: the
    #: default of monitors.conflict: 0.2 m for a collision, 0 otherwise)
    reference_margin: Mapping[str, float] = field(default_factory=dict)

    @property
    def metrics(self) -> tuple[str, ...]:
        return tuple(self.monitor_set.names) if self.monitor_set is not None else ()

    def info(self) -> dict[str, Any]:
        """What the controller needs to summarize this test (plain JSON)."""
        return {"metrics": list(self.metrics), "space": self.space.describe(),
                "priority": list(self.monitor_set.priority_order) if self.monitor_set is not None else [],
                "accept": self.accept.to_json(), "samplers": list(self.samplers)}

    def make_sampler(self, name: str, hook: SamplerHook | None = None) -> Any:
        """Sampler ``name`` of this test: what ``hook(name=, space=, seed=, options=)`` makes
        (under pytest, a conftest's ``pytest_avscenario_make_sampler``) when it answers, else
        the registry's."""
        from .. import samplers

        seed = stable_seed(self.seed, name)
        if hook is not None:
            made = hook(name=name, space=self.space, seed=seed, options=dict(self.sampler_options))
            if made is not None:
                return made
        opts = dict(self.sampler_options)
        if samplers.base.is_active(name) and self.monitor_set is not None:
            opts.setdefault("metrics", list(self.monitor_set.names))
            if self.monitor_set.priority_edges:
                opts.setdefault("priority", [list(e) for e in self.monitor_set.priority_edges])
        return samplers.make(name, self.space, seed=seed, **opts)


def build_plan(test: str, spec: ScenarioSpec, function: Any, settings: Settings, db: Any, *,
               has_world: bool, is_fixture: Callable[[str], bool] = lambda name: False,
               check_fixtures: Callable[[], None] | None = None,
               make_sampler: SamplerHook | None = None,
               warn: Callable[[str], None] | None = None) -> tuple[ScenarioPlan, list[CaseSlot]]:
    """The plan of test ``test`` (its id) declared by ``spec`` on ``function``, and its cases'
    slots; DeclarationError, SpaceError or ValueError say what is wrong with the declaration.

    ``has_world``: the test uses the ``world`` (a reference driver can replay its cases);
    ``is_fixture(name)``: a parameter of that name would shadow a fixture; ``check_fixtures``
    runs once the space is checked (the pytest side's check of remote fixtures);
    ``make_sampler``: the :data:`SamplerHook`; ``warn(message)``: a stored counterexample
    that is skipped (default: a ``UserWarning``)."""
    if spec.problem is not None:
        raise DeclarationError(spec.problem)
    say = warn if warn is not None else (lambda message: warnings.warn(message, stacklevel=2))
    space = _space(spec, is_fixture)
    if check_fixtures is not None:
        check_fixtures()
    own = settings.for_test(spec)

    if spec.seed is not None:
        if isinstance(spec.seed, bool) or not isinstance(spec.seed, int) or spec.seed < 0:
            raise DeclarationError(f"seed must be a non-negative int, got {_show(spec.seed)}")
        seed = stable_seed("marker", spec.seed)
    else:
        seed = stable_seed(settings.seed, test)

    monitor_set = _monitor_set(spec)
    opts = {} if spec.sampler_options is None else spec.sampler_options
    if not isinstance(opts, dict) or not all(isinstance(k, str) for k in opts):
        raise DeclarationError(
            f"sampler_options must be a dict of keyword options, e.g. sampler_options={{'scramble': True}}, "
            f"got {_show(opts)}")

    pinned = None
    if settings.params is not None:
        pinned = {**space.nominal(), **settings.params}
        space.validate(pinned)

    if getattr(function, "hypothesis_explicit_examples", None):
        raise DeclarationError(
            "@example here is Hypothesis's, which does not pin scenario cases: use "
            "`from pytest_avscenario import example`")
    slots: list[CaseSlot] = []
    for k, pin in enumerate(getattr(function, "_avs_examples", ())):
        if isinstance(pin, BadExample):
            raise DeclarationError(f"@example #{k}: {pin.problem}")
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
                say(f"{test}: stored counterexample {entry.path.name} skipped: parameter "
                    f"{changed} changed since it was found")
                continue
            try:
                # the file is data anyone may have edited: only declared values reach the body
                params = replay_params(space, entry.params)
            except ValueError as exc:
                say(f"{test}: stored counterexample {entry.path} skipped: {exc}; not replayed, "
                    "left on disk for you to fix or delete")
                continue
            k = len(replays)
            replays[k] = entry
            slots.append(CaseSlot("replay", k, entry.seed, "replay", params))

    plan = ScenarioPlan(
        test=test, space=space, samplers=own.samplers, samples=own.samples, seed=seed,
        monitor_set=monitor_set, sampler_options=types.MappingProxyType(dict(opts)),
        time_budget_s=own.time_budget_s, shrink_budget=own.shrink_budget,
        shrink_max=own.shrink_max, case_timeout_s=own.case_timeout_s,
        replays=types.MappingProxyType(replays), accept=own.accept,
        reference_driver=own.reference_driver if has_world else None,
        reference_max=own.reference_max, discard_unavoidable=own.unavoidable == "discard",
        dt=own.dt, dt_from=own.dt_from,
        reference_margin=types.MappingProxyType(dict(own.reference_margin or {})))
    # a marker's margins must name this test's metrics (a typo would silently keep the
    # default); the command line's apply to whichever tests monitor the metrics it names
    unknown = sorted(set(plan.reference_margin) - set(plan.metrics))
    if unknown and "reference_margin" in spec.given:
        raise DeclarationError(
            f"reference_margin names {', '.join(repr(m) for m in unknown)}, which this test does "
            f"not monitor; its metrics: {', '.join(plan.metrics) or '(none)'}")
    if own.accept.avoidable and plan.reference_driver is None:
        raise DeclarationError(
            "accept='avoidable' counts only counterexamples a reference driver avoids, but this "
            "test has none: it must use the `world` fixture (the reference drives its ego), "
            "with reference_driver= not 'none'")
    from ..samplers import base as sampler_base

    for name in plan.samplers:
        try:
            own.accept.check(plan.metrics, active=sampler_base.is_active(name))
        except ValueError as exc:
            raise DeclarationError(f"accept: {exc} (sampler {name!r})") from None

    from ..samplers import SamplerError

    for name in plan.samplers:
        try:
            sampler = plan.make_sampler(name, make_sampler)
        except SamplerError as exc:
            raise DeclarationError(str(exc)) from None
        except (TypeError, ValueError, ArithmeticError) as exc:
            # an unknown or ill-typed option reaches the sampler's constructor
            raise DeclarationError(
                f"sampler {name!r} cannot be made with sampler_options={_show(opts)}: "
                f"{type(exc).__name__}: {exc}") from None
        if pinned is not None:
            values: list[Mapping[str, Any] | None] = [dict(pinned)] * plan.samples
        elif sampler.active:
            values = [None] * plan.samples
        else:
            try:
                points = sampler.sample_unit(plan.samples)
            except (TypeError, ValueError, ArithmeticError) as exc:  # e.g. a huge skip=
                raise DeclarationError(
                    f"sampler {name!r} could not draw {plan.samples} cases with "
                    f"sampler_options={_show(opts)}: {type(exc).__name__}: {exc}") from None
            # one per item, alive for the whole run: compact (frozen.CompactMapping)
            values = [CompactMapping(space.from_unit(p)) for p in points]
        for k, params in enumerate(values):
            slots.append(sampled_slot(plan, name, k, params))
    return plan, slots


def sampled_slot(plan: ScenarioPlan, sampler: str, index: int,
                 params: Mapping[str, Any] | None = None) -> CaseSlot:
    """The slot of sampled case ``index`` of ``sampler``'s campaign (its seed is fixed by the
    plan's seed, the sampler and the index alone)."""
    return CaseSlot(sampler, index, stable_seed(plan.seed, sampler, index), origin="sampled", params=params)


#: attributes a Case finds on its class before falling back to its parameters
_CASE_ATTRIBUTES = frozenset(name for klass in Case.__mro__ for name in vars(klass)) | RESERVED


def _space(spec: ScenarioSpec, is_fixture: Callable[[str], bool]) -> FeatureSpace:
    """The test's feature space, refusing parameter names that would shadow something or
    that look like a misspelt setting."""
    if not spec.parameters:
        raise DeclarationError("@scenario declares no parameters; give at least one, e.g. gap=Uniform(10, 40)")
    for name, value in spec.parameters.items():
        if not isinstance(name, str) or not name.isidentifier() or keyword.iskeyword(name):
            raise DeclarationError(
                f"parameter {_show(name)} is not a valid Python name, so case.<name> cannot read "
                "it; rename it (letters, digits and underscores, not a keyword)")
        if name.startswith("__") and name.endswith("__"):
            raise DeclarationError(
                f"parameter {name!r}: names of the form __name__ are Python's own (case.{name} "
                "would not read the parameter); rename it")
        if name in _CASE_ATTRIBUTES:
            raise DeclarationError(
                f"parameter {name!r} clashes with the case attribute of the same name; rename it"
            )
        setting = likely_setting(name)
        if setting is not None and not isinstance(value, Distribution):
            raise DeclarationError(
                f"parameter {name!r}={_show(value)}: did you mean {setting}=? A plain value "
                f"under a name this close to the setting {setting!r} is taken for a misspelling; "
                f"write {name}=Constant({_show(value)}) if it really is a constant parameter")
        if is_fixture(name):
            raise DeclarationError(
                f"parameter {name!r} clashes with the fixture {name!r}; rename the parameter "
                "(read values as case.<name>, fixtures stay available as arguments)"
            )
    space = FeatureSpace(spec.parameters)
    space.check_description()
    return space


def _normal_name(name: str) -> str:
    return name.lower().replace("_", "")


def _edits(a: str, b: str) -> int:
    """Edit distance with swaps of neighbours (optimal string alignment)."""
    prev2: list[int] = []
    prev = list(range(len(b) + 1))
    for i, ca in enumerate(a, 1):
        cur = [i] + [0] * len(b)
        for j, cb in enumerate(b, 1):
            cur[j] = min(prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (ca != cb))
            if i > 1 and j > 1 and ca == b[j - 2] and a[i - 2] == cb:
                cur[j] = min(cur[j], prev2[j - 2] + 1)
        prev2, prev = prev, cur
    return prev[-1]


def likely_setting(name: str) -> str | None:
    """The @scenario setting that ``name`` probably misspells, or None.

    Compared ignoring case and underscores: the setting's name itself, or with a trailing
    ``s`` added or removed (``sample``, ``samplers``, ``case_time_out``); one edit (insert,
    delete, replace, swap of neighbours) from a setting of 5 to 7 letters (``sampels``,
    ``acept``); two edits from a longer one (``monitrs``, ``shrink_budjet``). ``seed`` only
    by the first rule, so that ``speed`` stays a parameter.
    """
    n = _normal_name(name)
    best: tuple[int, str] | None = None
    for key in SPEC_KEYWORDS:
        k = _normal_name(key)
        if n in (k, k + "s") or (k.endswith("s") and n == k[:-1]):
            return key
        allowed = 0 if len(k) < 5 else 1 if len(k) <= 7 else 2
        if abs(len(n) - len(k)) > allowed:
            continue
        d = _edits(n, k)
        if d <= allowed and (best is None or d < best[0]):
            best = (d, key)
    return None if best is None else best[1]


def _monitor_set(spec: ScenarioSpec) -> Any:
    """The declared monitors as a MonitorSet (None when there are none)."""
    monitors, priority = spec.monitors, spec.priority
    if monitors is None or (isinstance(monitors, (list, tuple)) and not monitors):
        if priority is not None and not (isinstance(priority, (list, tuple)) and not priority):
            raise DeclarationError("priority= is given but no monitors= to order")
        return None
    from ..monitors import Monitor, MonitorSet

    if isinstance(monitors, (str, bytes, Mapping)) or not (
            isinstance(monitors, Monitor) or callable(monitors) or isinstance(monitors, Iterable)):
        raise DeclarationError(
            f"monitors must be a list of monitors, e.g. monitors=[distance(5.0), ttc(2.0)], "
            f"got {_show(monitors)}")
    try:
        members = [monitors] if isinstance(monitors, Monitor) or callable(monitors) else list(monitors)
        return MonitorSet(members, priority=priority)
    except (ValueError, TypeError) as exc:
        raise DeclarationError(f"monitors: {exc}") from None


def call_text(name: str, params: Mapping[str, Any]) -> str:
    return f"@{name}(" + ", ".join(f"{k}={v!r}" for k, v in params.items()) + ")"

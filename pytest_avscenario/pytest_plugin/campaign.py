"""One scenario test's campaign while it runs, and one item's run within it.

:class:`Campaign` is the running state of a test's campaign — its live active samplers, how
many failures were minimized, when each sampler's campaign started — kept apart from the
read-only :class:`~.collect.ScenarioPlan`. :func:`run_item` is what ``pytest_pyfunc_call``
does for a scenario item: have the executor simulate the case, tell an active sampler, and
for a failure replay it once (flaky?), minimize it with Hypothesis under the simulation
budget, store it in the replay database and draw its worst moment. The item's
:class:`~pytest_avscenario.outcome.CaseRow`, its shrink rows and its pictures go into the
item's stash, from where the hooks hand them to the controller with the report.
"""

from __future__ import annotations

import hashlib
import json
import time
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import pytest

from ..acceptance import accepted_reason, case_verdict
from ..case import Case
from ..outcome import CaseOutcome, CaseRow, all_unavoidable, violations_of
from ..report.junit import case_properties
from .collect import CaseSlot, ScenarioPlan, function_id, plan_of, sampled_slot, slot_of
from ..codec import fmt_rho
from .failure import failure_message
from .identity import driver_identity
from .stopping import stuck_case_handler
from .stash import (
    campaigns_key,
    controller_key,
    db_key,
    executor_key,
    pictures_key,
    row_key,
    settings_key,
    shrink_rows_key,
)


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
    config: Any = None  # the pytest config, whose hooks may make the samplers
    active: dict[str, ActiveRun] = field(default_factory=dict)  # active sampler name -> its run
    shrunk: dict[str, int] = field(default_factory=dict)  # sampler -> failures minimized so far
    gifs: int = 0  # GIFs rendered so far for this test
    pictured: dict[str, int] = field(default_factory=dict)  # sampler -> cases drawn as PNGs
    started: dict[str, float] = field(default_factory=dict)  # sampler -> campaign start
    ran: dict[str, int] = field(default_factory=dict)  # sampler -> cases run
    judged: dict[str, int] = field(default_factory=dict)  # sampler -> avoidability checks run
    # (sampler, index) -> its avoidability, judged before its item ran (to tell a sampler)
    judgements: dict[tuple[str, int], Any] = field(default_factory=dict)
    # asking ahead on a cluster: (sampler, index) -> the item
    items: dict[tuple[str, int], Any] = field(default_factory=dict)

    def run_of(self, name: str) -> ActiveRun:
        """The run of active sampler ``name``, made on first use."""
        if name not in self.active:
            self.active[name] = ActiveRun(self.plan.make_sampler(name, self.config))
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


def campaign_of(item: pytest.Item) -> Campaign:
    campaigns = item.config.stash[campaigns_key]
    test = function_id(item)
    if test not in campaigns:
        campaigns[test] = Campaign(plan_of(item), config=item.config)
    return campaigns[test]


def case_for(item: pytest.Function, slot: CaseSlot, request: pytest.FixtureRequest) -> Case:
    """The case of ``item``: the slot's values, or its active sampler's (see :class:`ActiveRun`)."""
    params = slot.params if slot.params is not None else active_params(item, slot, request)
    pinned = item.config.stash[settings_key].pinned
    return slot.case(item.nodeid, params, origin="pinned" if pinned else None)


def active_params(item: pytest.Function, slot: CaseSlot, request: pytest.FixtureRequest) -> dict[str, Any]:
    """Case ``slot.index`` of an active campaign, after simulating the cases before it that
    no item has run yet (with this item's fixtures; their outcomes wait for their items)."""
    campaign = campaign_of(item)
    run = campaign.run_of(slot.sampler)
    k = slot.index
    if k < len(run.params):  # asked already: by an item after it, or ahead for a cluster
        return run.params[k]
    if k in run.cached:
        run.from_cache.add(k)
        return run.cached[k]
    fixtures = None
    executor = executor_of(item.config)
    while run.told < k:
        j = run.told
        if j == len(run.params):
            run.params.append(run.sampler.ask())
        if fixtures is None:
            fixtures = {name: request.getfixturevalue(name) for name in item._fixtureinfo.argnames
                        if name not in ("case", "world")}
        earlier = sampled_slot(campaign.plan, slot.sampler, j).case(
            f"{function_id(item)}[{slot.sampler}-{j:03d}]", run.params[j])
        outcome = executor.run(make_job(item, campaign.plan, earlier, fresh_world=True, fixtures=fixtures))
        run.ahead[j] = outcome
        tell(run, outcome, unfair(item, campaign, earlier, outcome, fixtures))
    run.params.append(run.sampler.ask())
    return run.params[k]


def tell(run: ActiveRun, outcome: CaseOutcome, discard: bool = False) -> None:
    """Tell the next case's outcome to its sampler (errors, and with ``discard`` unfair cases,
    as invalid: no evidence)."""
    run.sampler.tell(outcome.params, None if outcome.verdict == "error" or discard
                     else (dict(outcome.rho) or body_rho(outcome)))
    run.told += 1


def unfair(item: pytest.Function, campaign: Campaign, case: Case, outcome: CaseOutcome,
           fixtures: Mapping[str, Any] | None = None) -> bool:
    """With ``unavoidable="discard"``: whether the sampler should learn nothing of this case —
    it starts RSS-unsafe, or it is a counterexample the reference driver cannot avoid either
    (judged now, and kept for the case's row)."""
    if not campaign.plan.discard_unavoidable:
        return False
    if starts_unsafe(outcome):
        return True
    if not (outcome.failed and outcome.violated):
        return False
    judged = judge_avoidability(item, campaign, case, outcome, fixtures)
    campaign.judgements[(case.sampler, case.index)] = judged
    return judged is not None and judged.error is None and judged.all_unavoidable


def starts_unsafe(outcome: CaseOutcome) -> bool:
    """The ego and another agent are in an RSS-dangerous situation at t = 0 (both distances
    unsafe): nobody entered it, no driver is to blame. False without a trajectory (a remote
    outcome carries none)."""
    traj = outcome.trajectory
    if traj is None or traj.n_agents < 2 or traj.n_steps < 1:
        return False
    from ..monitors import MonitorError
    from ..monitors.rss import rss_margins

    try:
        lon, lat = rss_margins(traj)
    except (MonitorError, ValueError, FloatingPointError):
        return False
    return bool(((lon[:, 0] < 0) & (lat[:, 0] < 0)).any())


def note_selection(session: pytest.Session) -> None:
    """Where this run selects only part of an active campaign (``-k``, ``--lf``), load the
    values pytest's cache kept from the run that drew them, to replay them exactly."""
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


@dataclass
class ShrinkReport:
    """What minimizing one failing case gave (for the message, the rows and the database)."""

    flaky: bool
    sims: int
    budget: int
    minimized: dict[str, Any] | None = None
    outcome: CaseOutcome | None = None  # the minimized case's outcome
    exhausted: bool = False
    rows: list[CaseRow] = field(default_factory=list)


@dataclass
class ItemResult:
    """What running one scenario item gave the plugin's hook: the outcome and, when it did not
    pass, the message to show and whether to re-raise the body's own exception."""

    outcome: CaseOutcome
    message: str | None = None
    reraise: bool = False
    accepted: str | None = None  # an accepted counterexample: the xfail reason


def run_item(item: pytest.Function) -> ItemResult:
    """Run the item's case; tell an active sampler; shrink, store and draw a failure; record
    its row and properties for the reports."""
    campaign = campaign_of(item)
    plan = campaign.plan
    case_obj: Case = item.funcargs["case"]
    slot = slot_of(item)
    run = campaign.run_of(slot.sampler) if slot.params is None and case_obj.origin == "sampled" else None
    if run is not None and slot.index in run.ahead:  # simulated before its item, in index order
        outcome = run.ahead.pop(slot.index)
    else:
        if run is not None:
            ask_ahead(item, campaign, slot)
        outcome = executor_of(item.config).run(make_job(item, plan, case_obj, fresh_world=False))
        if run is not None and slot.index not in run.from_cache:
            tell(run, outcome, unfair(item, campaign, case_obj, outcome))
    campaign.ran[slot.sampler] = campaign.ran.get(slot.sampler, 0) + 1

    shrink = None
    capped = False
    if outcome.failed and case_obj.origin == "sampled" and plan.shrink_budget > 0:
        done = campaign.shrunk.get(slot.sampler, 0)
        capped = plan.shrink_max is not None and done >= plan.shrink_max
        if not capped:
            campaign.shrunk[slot.sampler] = done + 1
            shrink = shrink_case(item, plan, case_obj, outcome)
    minimized = shrink is not None and shrink.minimized is not None
    key = (case_obj.sampler, case_obj.index)
    known = case_obj.origin == "sampled" and key in campaign.judgements  # judged to tell a sampler
    judged = campaign.judgements.pop(key) if known else None
    if shrink is not None and shrink.flaky:
        judged = None  # not a counterexample of the scenario: nothing to judge
    elif not known:
        judged = judge_avoidability(item, campaign, case_obj, outcome)
    min_judged = judge_minimized(item, campaign, case_obj, shrink, judged) if minimized else None
    min_outcome = shrink.outcome if minimized else None
    row = make_row(item, case_obj, outcome,
                   minimized=shrink.minimized if minimized else None,
                   shrink_sims=shrink.sims if minimized else None,
                   flaky=shrink is not None and shrink.flaky,
                   avoidable=judged.avoidable if judged else None,
                   unsafe_first=judged.unsafe_first if judged else None,
                   conflicts=judged.conflicts_json() if judged else None,
                   minimized_violations=violations_of(min_outcome.results, min_outcome.first)
                   if min_outcome is not None else None,
                   minimized_avoidable=min_judged.avoidable if min_judged else None,
                   minimized_conflicts=min_judged.conflicts_json() if min_judged else None)
    if min_judged is not None:
        shrink.rows = judged_shrink_rows(shrink.rows, shrink.minimized, min_judged)
    item.stash[row_key] = row
    item.stash[shrink_rows_key] = shrink.rows if shrink is not None else []
    if item.config.stash[settings_key].junit == "properties":
        # user_properties (not record_property): the same XML without xunit2's warning;
        # under --avs-junit=strict the controller writes them at suite level instead
        item.user_properties.extend(case_properties(row))
    if capped:
        n = plan.shrink_max
        first = "the first failure" if n == 1 else f"the first {n} failures"
        note = (f"not minimized nor stored: {first} of this test's {slot.sampler} campaign "
                f"{'was' if n == 1 else 'were'} minimized already (--avs-shrink-max {n})")
    else:
        note = update_db(item, plan, slot, case_obj, outcome, shrink)
    if outcome.failed:
        item.stash[pictures_key] = render_case(item, campaign, outcome, shrink)
    if outcome.verdict == "pass":
        return ItemResult(outcome)
    judgements = [j.text(case) for j, case in ((judged, "found" if min_judged else ""),
                                                (min_judged, "minimized")) if j is not None]
    message = failure_message(item, case_obj, outcome, shrink, note,
                              avoidability="\n".join(judgements) or None)
    # the body's own exception keeps its traceback; monitor errors are our message alone
    reraise = outcome.exc is not None and not isinstance(outcome.exc, monitor_error_type())
    accepted = None
    if outcome.failed and case_verdict(plan.accept, row, outcome.violated) is None:
        accepted = accepted_reason(plan.accept, outcome.violated, row)
    return ItemResult(outcome, message, reraise, accepted)


def ask_ahead(item: pytest.Function, campaign: Campaign, slot: CaseSlot) -> None:
    """Keep a cluster busy with an active sampler: while case k runs, cases k+1 .. k+B-1 (B the
    cluster's capacity) are asked and started too, so the sampler learns of each case up to B-1
    cases late — as a parallel falsifier does. Nothing happens in-process or on an xdist
    worker (whose items are not consecutive), nor with a conftest driver, which cannot be sent
    before its item's fixtures exist."""
    executor = executor_of(item.config)
    submit = getattr(executor, "submit", None)
    if submit is None or hasattr(item.config, "workerinput") or driver_ahead(item) is None:
        return
    run = campaign.run_of(slot.sampler)
    jobs = []
    for j in range(len(run.params), slot.index + executor.capacity):
        ahead = campaign.items.get((slot.sampler, j))
        if ahead is None:
            break
        run.params.append(run.sampler.ask())
        case_j = slot_of(ahead).case(ahead.nodeid, run.params[j])
        jobs.append(make_job(ahead, campaign.plan, case_j, fresh_world=True, prefetch=True))
    if jobs:
        submit(jobs)


def prefetch_passive_cases(session: pytest.Session) -> None:
    """Hand a remote executor the passive cases ahead, so its workers stay busy; remember the
    items of active samplers, whose cases are asked ahead once items run."""
    jobs = []
    for item in session.items:
        slot = slot_of(item)
        if slot is None or item.get_closest_marker("scenario") is None:
            continue
        campaign = campaign_of(item)
        if slot.params is None:
            campaign.items[(slot.sampler, slot.index)] = item
            continue
        jobs.append(make_job(item, campaign.plan, slot.case(item.nodeid), fresh_world=True,
                             prefetch=True))
    if jobs:
        executor_of(session.config).prefetch(jobs)


def monitor_error_type() -> type:
    from ..monitors import MonitorError

    return MonitorError


def shrink_case(item: pytest.Function, plan: ScenarioPlan, case: Case, outcome: CaseOutcome) -> ShrinkReport:
    """Replay the failure once (flakiness), then minimize it toward the nominal scenario."""
    from ..shrink import minimize

    report = ShrinkReport(flaky=False, sims=0, budget=plan.shrink_budget)
    outcomes: dict[str, CaseOutcome] = {}
    executor = executor_of(item.config)
    slot = slot_of(item)
    progress = progress_writer(item.config)

    def simulate(params: dict[str, Any]) -> CaseOutcome:
        candidate = slot.case(item.nodeid, params, origin="shrink")
        result = executor.run(make_job(item, plan, candidate, fresh_world=True))
        report.rows.append(make_row(item, candidate, result))
        done = len(report.rows) - 1  # the first row is the flakiness replay
        if progress is not None and done > 0 and (done % progress.every == 0 or done == plan.shrink_budget):
            progress(f"shrinking {item.nodeid}: {done}/{plan.shrink_budget} simulations")
        return result

    signature = outcome.signature
    again = simulate(dict(case.params))
    if not (again.failed and again.signature == signature):
        report.flaky = True
        return report

    def still_fails(params: dict[str, Any]) -> bool:
        result = simulate(dict(params))
        outcomes[json.dumps(params, sort_keys=True, default=repr)] = result
        return result.failed and result.signature == signature

    result = minimize(plan.space, dict(case.params), still_fails, budget=plan.shrink_budget,
                      seed=case.seed % (2**32))
    report.sims = result.sims
    report.exhausted = result.exhausted
    report.minimized = dict(result.minimized)
    report.outcome = outcomes.get(json.dumps(result.minimized, sort_keys=True, default=repr), outcome)
    return report


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


def render_case(item: pytest.Function, campaign: Campaign, outcome: CaseOutcome,
                shrink: ShrinkReport | None) -> dict[str, str]:
    """The recording of a failing case and its pictures: ``{kind: path}``.

    Every failing case gets its recording (``recording``: the clip the card page's player plays);
    within the per-test caps the annotated still of its first violation (``moment``), its time
    series (``timeseries``) and a GIF (``gif``). Drawn from the minimized case when there is
    one (that is the one an engineer studies), else from the case as found. Only in-process
    outcomes keep their world; a test that returns a Trajectory of its own gets a recording
    without the road and no pictures.
    """
    directory = item.config.stash[controller_key].directory
    shown = shrink.outcome if shrink is not None and shrink.outcome is not None else outcome
    world = shown.world
    if world is not None and getattr(world, "trajectory", None) is None:
        world = None
    traj = world.trajectory if world is not None else shown.trajectory
    if directory is None or traj is None:
        return {}
    from ..files import atomic_write_text
    from ..report.recording import recording_data
    from ..report.table import file_slug
    from ..sim.clip import dumps

    base = directory / "cases" / f"{file_slug(item.nodeid)}"
    pictures: dict[str, str] = {}
    violations = violations_of(shown.results, shown.first) or {}
    for metric, where in violations.items():
        where["rho"] = shown.rho.get(metric)
    worst = min(shown.results.values(), key=lambda r: r.rho, default=None)
    monitors = list(campaign.plan.monitor_set or ())
    data = None
    try:
        base.parent.mkdir(parents=True, exist_ok=True)
        data = recording_data(world if world is not None else traj, violations=violations, monitors=monitors,
                              title=item.name, fallback_t=worst.t if worst is not None else None)
        # the file keeps its earlier name (".replay.json"): reports and tools read it
        atomic_write_text(f"{base}.replay.json", dumps(data), durable=False)  # one of many
        pictures["recording"] = f"{base}.replay.json"
    except Exception as exc:  # the recording is a convenience: never fail the case over it
        warnings.warn(pytest.PytestWarning(f"{item.nodeid}: could not record the case's replay: {exc}"))
    if world is None or data is None:
        return pictures
    settings = item.config.stash[settings_key]
    drawn = campaign.pictured.get(outcome_sampler(item), 0)
    pngs = shown is not outcome or drawn < settings.case_pictures
    try:
        if pngs:
            if shown is outcome:
                campaign.pictured[outcome_sampler(item)] = drawn + 1
            from ..sim.render import render_moment

            pictures["moment"] = render_moment(world, f"{base}.moment.png", data)["path"]
            from ..report.casefigs import plot_case_timeseries

            first_t = data["first_t"] if data["first_kind"] != "moment" or worst is not None else None
            pictures["timeseries"] = str(plot_case_timeseries(
                f"{base}.timeseries.png", traj, agent=data["critical"], first_t=first_t,
                monitors=monitors, title=item.name))
        if campaign.gifs < settings.gifs:
            pictures["gif"] = world.render_gif(f"{base}.gif", every=2)
            campaign.gifs += 1
    except Exception as exc:  # a picture is a convenience: never fail the case over it
        warnings.warn(pytest.PytestWarning(f"{item.nodeid}: could not render the case: {exc}"))
    return pictures


def outcome_sampler(item: pytest.Item) -> str:
    slot = slot_of(item)
    return slot.sampler if slot is not None else ""


def build_world(case: Case, driver: Any, name: str, ego_driver: Any = None, *,
                plan: ScenarioPlan | None = None, item: pytest.Item | None = None) -> Any:
    """The case's world: its step setting from the plan, its warnings said once per test."""
    from ..sim import World

    return World(seed=case.seed, rng=case.rng, driver=driver, name=name, ego_driver=ego_driver,
                 dt=plan.dt if plan is not None else None,
                 dt_from=plan.dt_from if plan is not None else "",
                 warn=None if item is None else world_warner(item))


#: (test function id, warning key) already said in this process
_warned_key = pytest.StashKey[set]()


def world_warner(item: pytest.Item) -> Any:
    """``World.warn`` for the worlds of ``item``'s test: each kind of warning once per test
    function and process, not once per case, shrink candidate or replay."""
    said = item.config.stash.setdefault(_warned_key, set())
    test = function_id(item)

    def warn(warning: Warning, key: str) -> None:
        if (test, key or str(warning)) in said:
            return
        said.add((test, key or str(warning)))
        warnings.warn(warning, stacklevel=2)

    return warn


def executor_of(config: pytest.Config) -> Any:
    """The session's executor, made on first use (a Dask cluster only when a case runs)."""
    executor = config.stash.get(executor_key, None)
    if executor is None:
        from ..executors import make_executor

        settings = config.stash[settings_key]
        options: dict[str, Any] = {}
        if settings.executor == "dask":
            options["address"] = settings.dask_address
            for key, value in (("n_workers", settings.dask_workers),
                               ("connect_timeout_s", settings.dask_timeout_s),
                               ("max_retries", settings.dask_retries)):
                if value is not None:
                    options[key] = value
        try:
            executor = make_executor(settings.executor, **options)
        except ValueError as exc:
            raise pytest.UsageError(str(exc)) from None
        config.stash[executor_key] = executor
    return executor


#: the module whose ``avs_driver`` fixture is the plugin's own (any other is a user's)
_OWN_FIXTURES = f"{__package__}.hooks"


def driver_ahead(item: pytest.Function) -> Any:
    """The ego's driver of ``item`` before its fixtures exist: the built-in one named by the
    options when ``avs_driver`` is the plugin's own fixture, else None (a user's fixture)."""
    defs = item._fixtureinfo.name2fixturedefs.get("avs_driver", ())
    overridden = bool(defs) and getattr(defs[-1].func, "__module__", None) != _OWN_FIXTURES
    return None if overridden else item.config.stash[settings_key].driver


def make_job(item: pytest.Function, plan: ScenarioPlan, case: Case, fresh_world: bool,
             prefetch: bool = False, fixtures: Mapping[str, Any] | None = None,
             reference: str | None = None) -> Any:
    """The executor's description of one case of ``item``'s test.

    With ``prefetch`` (before the item's fixtures exist) there are no fixture values, and the
    driver is known only when ``avs_driver`` is the plugin's own (then it is the built-in
    name); otherwise ``driver`` is None and the job cannot be started ahead. ``fixtures``
    gives the values of the test's other fixtures while the item's own are being set up.
    ``reference`` names a driver that drives the ego whatever the scenario says (the
    avoidability check); on a cluster it replaces the world's default driver.
    """
    from ..executors import CaseJob

    argnames = tuple(item._fixtureinfo.argnames)
    if prefetch:
        fixtures = {}
        driver = driver_ahead(item)
    else:
        fixtures = item.funcargs if fixtures is None else fixtures
        driver = fixtures.get("avs_driver")
        if driver is None and "world" in argnames:
            driver = item._request.getfixturevalue("avs_driver")
    during = ("" if case.origin != "shrink" else "while it was being minimized") if reference is None \
        else f"while the {reference} reference driver replayed it"
    if reference is None and case.origin == "sampled" and case.index != getattr(slot_of(item), "index", case.index):
        during = f"while case {case.index} of its active campaign was simulated first"
    return CaseJob(
        nodeid=item.nodeid, module_path=str(item.path), rootdir=str(item.config.rootpath),
        function=item.originalname, func=item.obj, argnames=argnames, fixtures=fixtures,
        case=case, monitor_set=plan.monitor_set, driver=driver if reference is None else reference,
        fresh_world=fresh_world or reference is not None, timeout_s=plan.case_timeout_s,
        make_world=lambda c: build_world(c, driver, item.nodeid, ego_driver=reference,
                                         plan=plan, item=item),
        **_remote_step(plan, driver, reference),
        on_stuck=None if prefetch else stuck_case_handler(
            item, plan.case_timeout_s, lambda o: make_row(item, item_case(item), o), plan.info, during),
    )


def _remote_step(plan: ScenarioPlan, driver: Any, reference: str | None) -> dict[str, Any]:
    """The world's step setting for a job run away from this process. A reference replay
    there has only the reference as its driver, so the scenario's driver's own step goes
    with it (in-process the world finds it itself): the other agents move as in the case."""
    if plan.dt is not None or reference is None:
        return {"world_dt": plan.dt, "world_dt_from": plan.dt_from}
    from ..sim.drivers import declared_step

    try:
        step = declared_step(driver)
    except Exception:  # the replay reports a driver that cannot be made; only its step is wanted
        step = None
    if not isinstance(step, (int, float)) or isinstance(step, bool):
        return {"world_dt": None, "world_dt_from": ""}
    return {"world_dt": float(step), "world_dt_from": f"the scenario's driver's step ({driver!r})"}


def item_case(item: pytest.Item) -> Case:
    """The item's own case: its ``case`` fixture's value, or, before its fixtures exist (or
    when they failed), its slot's (the values an active sampler has not asked yet are {})."""
    own = getattr(item, "funcargs", {}).get("case")
    if isinstance(own, Case):
        return own
    slot = slot_of(item)
    return slot.case(item.nodeid, slot.params if slot.params is not None else {})


def attach_to_html_report(report: pytest.TestReport, pictures: Mapping[str, str]) -> None:
    """Show a failing case's pictures in its pytest-html row (embedded, so the page travels);
    ``pictures``: ``{kind: path}`` as :func:`render_case` gives them."""
    import base64

    from pytest_html import extras

    attached = list(getattr(report, "extras", []))
    from ..report.cards import FILE_CAPTIONS

    for kind, path in pictures.items():
        if not str(path).endswith((".png", ".gif")):
            continue
        caption = FILE_CAPTIONS.get(kind, kind)
        try:
            with open(path, "rb") as f:
                data = base64.b64encode(f.read()).decode()
        except OSError:
            continue
        kind = "gif" if str(path).endswith(".gif") else "png"
        attached.append(extras.image(data, caption, mime_type=f"image/{kind}", extension=kind))
    report.extras = attached


def update_db(item: pytest.Item, plan: ScenarioPlan, slot: CaseSlot, case: Case,
              outcome: CaseOutcome, shrink: ShrinkReport | None) -> str | None:
    """Keep failures for the next run; forget replayed ones that pass now (fix confirmed)."""
    db = item.config.stash[db_key]
    if db is None:
        return None
    from ..db import DatabaseError

    def trouble(what: str, exc: DatabaseError) -> None:
        # a database that cannot be written (read-only, disk full) must not hide the failure
        # itself: the item keeps its message and says it was not stored; the run warns once
        db.write_failures += 1
        if db.write_failures == 1:
            warnings.warn(pytest.PytestWarning(
                f"avscenario replay database: {item.nodeid}: {what}: {exc} (warned once; "
                "the run goes on, and each failure says whether it was stored)"))

    if case.origin == "replay":
        if outcome.verdict == "pass":
            entry = plan.replays[slot.index]
            try:
                db.delete(entry)
            except DatabaseError as exc:
                trouble(f"the fixed counterexample {entry.path.name} passes now but could not be "
                        "removed", exc)
                return f"fixed, but not removed from the database: {exc}"
            return "fixed: this stored counterexample passes now and was removed from the database"
        return None
    if case.origin != "sampled" or not outcome.failed or (shrink is not None and shrink.flaky):
        return None
    minimized = shrink is not None and shrink.minimized is not None and shrink.minimized != case.params
    params = shrink.minimized if minimized else case.params
    rho = shrink.outcome.rho if minimized and shrink.outcome is not None else outcome.rho
    from .controller import versions

    try:
        entry = db.save(plan.test, params, rho, case.seed, plan.space, minimized=minimized,
                        versions=versions())
    except DatabaseError as exc:
        trouble("could not store a counterexample for replay", exc)
        return f"could not store for replay: {exc}"
    return f"stored for replay in {entry.path}"


@dataclass
class Avoidability:
    """What the reference driver made of one counterexample: per violated metric, whether it
    avoids the same conflict (:mod:`pytest_avscenario.monitors.conflict`)."""

    driver: str
    avoidable: dict[str, bool | None]  # violated metric -> avoided by the reference?
    reference_rho: dict[str, float]  # the reference run's own rho (every agent, whole run)
    unsafe_first: dict[str, Any] | None = None  # {"agent": ..., "t": ...}
    error: str | None = None  # the reference run could not be judged
    conflicts: dict[str, Any] = field(default_factory=dict)  # metric -> ConflictVerdict

    @property
    def all_unavoidable(self) -> bool:
        return all_unavoidable(self.avoidable)

    def conflicts_json(self) -> dict[str, dict[str, Any]] | None:
        return {m: c.to_json() for m, c in self.conflicts.items()} or None

    def text(self, case: str = "") -> str:
        """The failure text's lines; ``case`` names which case was judged (e.g. "minimized")."""
        lines = []
        of = f" ({case} case)" if case else ""
        if self.error is not None:
            lines.append(f"avoidability unknown{of}: the {self.driver} reference run failed ({self.error})")
        else:
            for m, ok in self.avoidable.items():
                word = {True: "avoidable", False: "UNAVOIDABLE", None: "avoidability unknown"}[ok]
                verb = {True: "keeps it", False: "violates it too", None: "was not judged on it"}[ok]
                c = self.conflicts.get(m)
                if c is not None:
                    where = f" with {c.agent}" if c.agent and not c.ego_alone else ""
                    when = f" at t = {c.t:.1f} s" if c.t is not None else ""
                    verb = {True: "keeps it", False: "violates it too", None: "cannot tell"}[ok]
                    lines.append(f"{m}{where}{when}{of}: {word} — the {self.driver} reference driver "
                                 f"{verb}: {c.why}")
                    continue
                rho = self.reference_rho.get(m)
                how = "" if rho is None else f" (reference rho {fmt_rho(rho)})"
                lines.append(f"{m}{of}: {word} — the {self.driver} reference driver {verb}{how}")
        if self.unsafe_first is not None and not case:
            who = self.unsafe_first["agent"]
            subject = "both cars" if who == "both" else who
            lines.append(f"RSS: {subject} entered an unsafe state first, at "
                         f"t = {self.unsafe_first['t']:.1f} s")
        return "\n".join(lines)


def judge_avoidability(item: pytest.Function, campaign: Campaign, case: Case,
                       outcome: CaseOutcome, fixtures: Mapping[str, Any] | None = None,
                       *, extra: bool = False) -> Avoidability | None:
    """Simulate a counterexample again with the plan's reference driver as the ego (same seed,
    same other agents and behaviours) and judge each violated metric on the same conflict
    (the same other agent, around the same time, with a margin); name who entered an
    RSS-unsafe state first. None when not judged (no reference, no violated monitor, budget
    spent). ``extra``: the minimized case of a counterexample judged already (not counted
    against ``reference_max``: it is part of judging that counterexample).

    The reference runs in this process whatever the executor: the judgement needs its
    recording, which a remote outcome leaves behind."""
    plan = campaign.plan
    reference = plan.reference_driver
    if reference is None or not outcome.failed or not outcome.violated:
        return None
    if not extra:
        done = campaign.judged.get(case.sampler, 0)
        if plan.reference_max is not None and done >= plan.reference_max:
            return None
        campaign.judged[case.sampler] = done + 1
    from ..executors import InProcessExecutor

    ref = InProcessExecutor().run(make_job(item, plan, case, fresh_world=True, reference=reference,
                                           fixtures=fixtures))
    judged = Avoidability(reference, {}, {k: float(v) for k, v in ref.rho.items()},
                          unsafe_first=unsafe_first(outcome))
    traj = ref.trajectory
    if ref.verdict == "error" or traj is None:  # a run that went wrong is no evidence either way
        judged.error = ref.error or "it recorded no trajectory"
        judged.avoidable = {m: None for m in outcome.violated}
        return judged
    from ..monitors.conflict import crash_partner, judge_conflict
    from ..monitors.evidence import reads_crash_flags

    monitors = {m.name: m for m in (plan.monitor_set or ())}
    where = violations_of(outcome.results, outcome.first) or {}
    for m in outcome.violated:
        monitor = monitors.get(m)
        if monitor is None:
            judged.avoidable[m] = None
            continue
        agent, t = where.get(m, {}).get("agent"), where.get(m, {}).get("t")
        if agent is None and reads_crash_flags(monitor) and outcome.trajectory is not None:
            # a crash flag without a visible overlap (a crash between two samples): the
            # simulator flagged the other car of it at the same step
            partner = crash_partner(outcome.trajectory)
            if partner is not None:
                agent, t = partner[0], partner[1] if t is None else t
        verdict = judge_conflict(monitor, traj, agent, t, margin=plan.reference_margin.get(m))
        judged.conflicts[m] = verdict
        judged.avoidable[m] = verdict.avoided
    return judged


def judge_minimized(item: pytest.Function, campaign: Campaign, case: Case, shrink: ShrinkReport,
                    found: Avoidability | None) -> Avoidability | None:
    """The minimized case's own judgement: the reference driven on the minimized parameters
    (it may meet another agent than the case as found did). Only for a counterexample whose
    found case was judged — one more reference simulation for it, beyond ``reference_max``'s
    count of counterexamples — and the found case's judgement when minimizing changed nothing."""
    if found is None or shrink.minimized is None or shrink.outcome is None:
        return None
    if dict(shrink.minimized) == dict(case.params):
        return found
    small = slot_of(item).case(item.nodeid, dict(shrink.minimized), origin="shrink")
    return judge_avoidability(item, campaign, small, shrink.outcome, extra=True)


def judged_shrink_rows(rows: list[CaseRow], params: Mapping[str, Any], judged: Avoidability) -> list[CaseRow]:
    """The shrink rows with the minimized candidate's row carrying its judgement."""
    from dataclasses import replace

    out = list(rows)
    for k in range(len(out) - 1, -1, -1):
        if dict(out[k].params) == dict(params) and out[k].verdict == "fail":
            out[k] = replace(out[k], avoidable=judged.avoidable, unsafe_first=judged.unsafe_first,
                             conflicts=judged.conflicts_json())
            break
    return out


def unsafe_first(outcome: CaseOutcome) -> dict[str, Any] | None:
    """Who entered an RSS-unsafe state first by their own responsibility, between the ego and
    the agent of the worst violated metric (or, if none is named, the earliest of all)."""
    traj = outcome.trajectory
    if traj is None:
        return None
    from ..monitors import MonitorError
    from ..monitors.rss import rss_blame

    try:
        blames = rss_blame(traj)
    except (MonitorError, ValueError, FloatingPointError):
        return None
    worst = min((r for r in outcome.results.values() if r.rho < 0), key=lambda r: r.rho, default=None)
    pairs = [b for b in blames if worst is not None and b.other == worst.agent] or list(blames)
    found = []
    for b in pairs:
        who = b.first
        if who is not None:
            t = min(x for x in (b.ego_unsafe_at, b.other_unsafe_at) if x is not None)
            found.append((t, who))
    if not found:
        return None
    t, who = min(found)
    return {"agent": who, "t": float(t)}


def body_rho(outcome: CaseOutcome) -> float:
    # no monitors: a failing assertion is a violation, a pass is neutral
    return -1.0 if outcome.verdict == "fail" else 0.0


def make_row(item: pytest.Item, case: Case, outcome: CaseOutcome, *,
             minimized: Mapping[str, Any] | None = None, shrink_sims: int | None = None,
             flaky: bool = False, avoidable: Mapping[str, bool | None] | None = None,
             unsafe_first: Mapping[str, Any] | None = None,
             conflicts: Mapping[str, Mapping[str, Any]] | None = None,
             minimized_violations: Mapping[str, Mapping[str, Any]] | None = None,
             minimized_avoidable: Mapping[str, bool | None] | None = None,
             minimized_conflicts: Mapping[str, Mapping[str, Any]] | None = None) -> CaseRow:
    """The error-table row of one finished case."""
    return CaseRow(
        test=function_id(item), item=item.nodeid, sampler=case.sampler, index=case.index,
        seed=case.seed, origin=case.origin, params=case.params, rho=outcome.rho,
        verdict=outcome.verdict, sim_time_s=outcome.sim_time_s, error=outcome.error,
        minimized=minimized, shrink_sims=shrink_sims, flaky=flaky, avoidable=avoidable,
        unsafe_first=unsafe_first, violations=violations_of(outcome.results, outcome.first), drawn=outcome.drawn,
        conflicts=conflicts, minimized_violations=minimized_violations,
        minimized_avoidable=minimized_avoidable, minimized_conflicts=minimized_conflicts,
        driver=driver_identity(item))

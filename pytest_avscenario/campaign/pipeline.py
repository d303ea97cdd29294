"""One case of a campaign, from its values to its verdict.

:func:`case_for` gives a case its values (an active sampler's in case-index order, see
:class:`~.state.ActiveRun`); :func:`run_item` runs it: the executor simulates it, an active
sampler is told, and a failure is replayed once (flaky?), minimized with Hypothesis under
the simulation budget, judged by the reference driver (:mod:`.avoidability`), stored in the
replay database and drawn. The case's :class:`~pytest_avscenario.outcome.CaseRow`, its shrink
rows and its pictures are kept on its :class:`~.context.CaseItem`; the returned
:class:`ItemResult` says the verdict and the text to show.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from ..acceptance import accepted_reason, case_verdict
from ..case import Case
from ..outcome import CaseOutcome, CaseRow, violations_of
from ..report.junit import case_properties
from .avoidability import judge_avoidability, judge_minimized, judged_shrink_rows
from .context import CampaignContext, CaseItem
from .jobs import body_rho, make_job, make_row
from .message import failure_message
from .plan import CaseSlot, ScenarioPlan, sampled_slot
from .state import ActiveRun, Campaign
from .versions import versions


class OutOfTime(Exception):
    """The campaign's time budget for this case's sampler is spent: the case is skipped."""


def case_for(ctx: CampaignContext, ci: CaseItem) -> Case:
    """The case of ``ci``: the slot's values, or its active sampler's (see :class:`ActiveRun`).
    :class:`OutOfTime` once its sampler's time budget is spent (the budget's clock starts
    with the first case asked)."""
    slot = ci.slot
    why = ctx.campaign(ci.plan).out_of_time(slot.sampler)
    if why is not None:
        raise OutOfTime(why)
    params = slot.params if slot.params is not None else active_params(ctx, ci)
    pinned = ctx.settings.pinned
    return slot.case(ci.nodeid, params, origin="pinned" if pinned else None)


def active_params(ctx: CampaignContext, ci: CaseItem) -> dict[str, Any]:
    """Case ``slot.index`` of an active campaign, after simulating the cases before it that
    no item has run yet (with this item's fixtures; their outcomes wait for their items)."""
    slot = ci.slot
    campaign = ctx.campaign(ci.plan)
    run = campaign.run_of(slot.sampler)
    k = slot.index
    if k < len(run.params):  # asked already, by an item after it
        return run.params[k]
    if k in run.cached:
        run.from_cache.add(k)
        return run.cached[k]
    fixtures = None
    executor = ctx.executor
    while run.told < k:
        j = run.told
        if j == len(run.params):
            run.params.append(run.sampler.ask())
        if fixtures is None:
            fixtures = ci.other_fixtures()
        earlier = sampled_slot(campaign.plan, slot.sampler, j).case(
            f"{ci.test}[{slot.sampler}-{j:03d}]", run.params[j])
        outcome = executor.run(make_job(ctx, ci, campaign.plan, earlier, fresh_world=True, fixtures=fixtures))
        tell(run, outcome, unfair(ctx, ci, campaign, earlier, outcome, fixtures))
        if outcome.verdict != "fail":  # only a failure's item draws from its world
            outcome.world = outcome.trajectory = None  # its item may run elsewhere, or never
        run.ahead[j] = outcome
    run.params.append(run.sampler.ask())
    return run.params[k]


def tell(run: ActiveRun, outcome: CaseOutcome, discard: bool = False) -> None:
    """Tell the next case's outcome to its sampler (errors, and with ``discard`` unfair cases,
    as invalid: no evidence)."""
    run.sampler.tell(outcome.params, None if outcome.verdict == "error" or discard
                     else (dict(outcome.rho) or body_rho(outcome)))
    run.told += 1


def unfair(ctx: CampaignContext, ci: CaseItem, campaign: Campaign, case: Case, outcome: CaseOutcome,
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
    judged = judge_avoidability(ctx, ci, campaign, case, outcome, fixtures)
    campaign.judgements[(case.sampler, case.index)] = judged
    return judged is not None and judged.error is None and judged.all_unavoidable


def starts_unsafe(outcome: CaseOutcome) -> bool:
    """The ego and another agent are in an RSS-dangerous situation at t = 0 (both distances
    unsafe): nobody entered it, no driver is to blame. A remote outcome without its trajectory
    answers with what its worker judged (``CaseOutcome.start_unsafe``)."""
    if outcome.trajectory is None:
        return bool(outcome.start_unsafe)
    from ..monitors.rss import starts_unsafe as unsafe_at_start

    return unsafe_at_start(outcome.trajectory)


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
    row: CaseRow | None = None  # the case's row (also kept on its CaseItem)


def run_item(ctx: CampaignContext, ci: CaseItem) -> ItemResult:
    """Run the item's case; tell an active sampler; shrink, store and draw a failure; record
    its row and properties for the reports."""
    campaign = ctx.campaign(ci.plan)
    plan = campaign.plan
    case_obj: Case = ci.fixtures()["case"]
    slot = ci.slot
    run = campaign.run_of(slot.sampler) if slot.params is None and case_obj.origin == "sampled" else None
    if run is not None and slot.index in run.ahead:  # simulated before its item, in index order
        outcome = run.ahead.pop(slot.index)
    else:
        outcome = ctx.executor.run(make_job(ctx, ci, plan, case_obj, fresh_world=False))
        if run is not None and slot.index not in run.from_cache:
            tell(run, outcome, unfair(ctx, ci, campaign, case_obj, outcome))
    campaign.ran[slot.sampler] = campaign.ran.get(slot.sampler, 0) + 1

    shrink = None
    capped = False
    if outcome.failed and case_obj.origin == "sampled" and plan.shrink_budget > 0:
        done = campaign.shrunk.get(slot.sampler, 0)
        capped = plan.shrink_max is not None and done >= plan.shrink_max
        if not capped:
            campaign.shrunk[slot.sampler] = done + 1
            shrink = shrink_case(ctx, ci, plan, case_obj, outcome)
    minimized = shrink is not None and shrink.minimized is not None
    key = (case_obj.sampler, case_obj.index)
    known = case_obj.origin == "sampled" and key in campaign.judgements  # judged to tell a sampler
    judged = campaign.judgements.pop(key) if known else None
    if shrink is not None and shrink.flaky:
        judged = None  # not a counterexample of the scenario: nothing to judge
    elif not known:
        judged = judge_avoidability(ctx, ci, campaign, case_obj, outcome)
    min_judged = judge_minimized(ctx, ci, campaign, case_obj, shrink, judged) if minimized else None
    min_outcome = shrink.outcome if minimized else None
    row = make_row(ci, case_obj, outcome,
                   minimized=shrink.minimized if minimized else None,
                   shrink_sims=shrink.sims if minimized else None,
                   flaky=shrink is not None and shrink.flaky,
                   avoidable=judged.avoidable if judged else None,
                   unsafe_first=judged.unsafe_first if judged else None,
                   conflicts=judged.conflicts_json() if judged else None,
                   minimized_violations=violations_of(min_outcome.results, min_outcome.first)
                   if min_outcome is not None else None,
                   minimized_avoidable=min_judged.avoidable if min_judged else None,
                   minimized_conflicts=min_judged.conflicts_json() if min_judged else None,
                   minimized_rho=min_outcome.rho if min_outcome is not None else None)
    if min_judged is not None:
        shrink.rows = judged_shrink_rows(shrink.rows, shrink.minimized, min_judged)
    ci.keep_row(row, shrink.rows if shrink is not None else [])
    if ctx.settings.junit == "properties":
        # user_properties (not record_property): the same XML without xunit2's warning;
        # under --avs-junit=strict the controller writes them at suite level instead
        ci.user_properties.extend(case_properties(row))
    if capped:
        n = plan.shrink_max
        first = "the first failure" if n == 1 else f"the first {n} failures"
        note = (f"not minimized nor stored: {first} of this test's {slot.sampler} campaign "
                f"{'was' if n == 1 else 'were'} minimized already (--avs-shrink-max {n})")
    else:
        note = update_db(ctx, ci, plan, slot, case_obj, outcome, shrink)
    if outcome.failed:
        pictures = render_case(ctx, ci, campaign, outcome, shrink)
        ci.keep_pictures(pictures)
        from .export import export_counterexample  # --avs-export: .xosc/.xodr/.osi by the card
        export_counterexample(ctx, ci, campaign, outcome, shrink, pictures)
    if outcome.verdict == "pass":
        return ItemResult(outcome, row=row)
    judgements = [j.text(case) for j, case in ((judged, "found" if min_judged else ""),
                                                (min_judged, "minimized")) if j is not None]
    message = failure_message(ctx, ci, case_obj, outcome, shrink, note,
                              avoidability="\n".join(judgements) or None)
    # the body's own exception keeps its traceback; monitor errors are our message alone
    reraise = outcome.exc is not None and not isinstance(outcome.exc, monitor_error_type())
    accepted = None
    if outcome.failed and case_verdict(plan.accept, row, outcome.violated) is None:
        accepted = accepted_reason(plan.accept, outcome.violated, row)
    return ItemResult(outcome, message, reraise, accepted, row=row)


def prefetch_jobs(ctx: CampaignContext, items: list[CaseItem]) -> list[Any]:
    """The jobs of the passive cases among ``items``, to hand a remote executor ahead so its
    workers stay busy. An active sampler's cases are not asked ahead: case k is asked once
    cases 0 .. k-1 are told, on a cluster as in-process, so each case id names the same values
    and verdict as a local run."""
    jobs = []
    for ci in items:
        slot = ci.slot
        if slot.params is None:
            continue
        campaign = ctx.campaign(ci.plan)
        jobs.append(make_job(ctx, ci, campaign.plan, slot.case(ci.nodeid), fresh_world=True,
                             prefetch=True))
    return jobs


def monitor_error_type() -> type:
    from ..monitors import MonitorError

    return MonitorError


def shrink_case(ctx: CampaignContext, ci: CaseItem, plan: ScenarioPlan, case: Case,
                outcome: CaseOutcome) -> ShrinkReport:
    """Replay the failure once (flakiness), then minimize it toward the nominal scenario."""
    from ..shrink import minimize

    report = ShrinkReport(flaky=False, sims=0, budget=plan.shrink_budget)
    outcomes: dict[str, CaseOutcome] = {}
    executor = ctx.executor
    slot = ci.slot
    progress = ctx.progress()

    def simulate(params: dict[str, Any]) -> CaseOutcome:
        candidate = slot.case(ci.nodeid, params, origin="shrink")
        result = executor.run(make_job(ctx, ci, plan, candidate, fresh_world=True))
        report.rows.append(make_row(ci, candidate, result))
        done = len(report.rows) - 1  # the first row is the flakiness replay
        if progress is not None and done > 0 and (done % progress.every == 0 or done == plan.shrink_budget):
            progress(f"shrinking {ci.nodeid}: {done}/{plan.shrink_budget} simulations")
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


def render_case(ctx: CampaignContext, ci: CaseItem, campaign: Campaign, outcome: CaseOutcome,
                shrink: ShrinkReport | None) -> dict[str, str]:
    """The recording of a failing case and its pictures: ``{kind: path}``.

    Every failing case gets its recording (``recording``: the clip the card page's player plays);
    within the per-test caps the annotated still of its first violation (``moment``), its time
    series (``timeseries``) and a GIF (``gif``). Drawn from the minimized case when there is
    one (that is the one an engineer studies), else from the case as found. Only in-process
    outcomes keep their world; a test that returns a Trajectory of its own gets a recording
    without the road and no pictures.
    """
    directory = ctx.folder()
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

    base = directory / "cases" / f"{file_slug(ci.nodeid)}"
    pictures: dict[str, str] = {}
    violations = violations_of(shown.results, shown.first) or {}
    for metric, where in violations.items():
        where["rho"] = shown.rho.get(metric)
    worst = min(shown.results.values(), key=lambda r: r.rho, default=None)
    monitors = list(campaign.plan.monitor_set or ())
    title = ci.name if shown is outcome else f"{ci.name}, minimized case"  # the item id is the found case's
    data = None
    try:
        base.parent.mkdir(parents=True, exist_ok=True)
        data = recording_data(world if world is not None else traj, violations=violations, monitors=monitors,
                              title=title, fallback_t=worst.t if worst is not None else None,
                              case="minimized" if shown is not outcome else None)
        # the file keeps its earlier name (".replay.json"): reports and tools read it
        atomic_write_text(f"{base}.replay.json", dumps(data), durable=False)  # one of many
        pictures["recording"] = f"{base}.replay.json"
    except Exception as exc:  # the recording is a convenience: never fail the case over it
        ctx.warn(f"{ci.nodeid}: could not record the case's replay: {exc}")
    if world is None or data is None:
        return pictures
    settings = ctx.settings
    drawn = campaign.pictured.get(outcome_sampler(ci), 0)
    pngs = shown is not outcome or drawn < settings.case_pictures
    try:
        if pngs:
            if shown is outcome:
                campaign.pictured[outcome_sampler(ci)] = drawn + 1
            from ..sim.render import render_moment

            pictures["moment"] = render_moment(world, f"{base}.moment.png", data)["path"]
            from ..report.casefigs import plot_case_timeseries

            first_t = data["first_t"] if data["first_kind"] != "moment" or worst is not None else None
            pictures["timeseries"] = str(plot_case_timeseries(
                f"{base}.timeseries.png", traj, agent=data["critical"], first_t=first_t,
                monitors=monitors, title=title))
        if campaign.gifs < settings.gifs:
            pictures["gif"] = world.render_gif(f"{base}.gif", every=2)
            campaign.gifs += 1
    except Exception as exc:  # a picture is a convenience: never fail the case over it
        ctx.warn(f"{ci.nodeid}: could not render the case: {exc}")
    return pictures


def outcome_sampler(ci: CaseItem) -> str:
    return ci.slot.sampler


def update_db(ctx: CampaignContext, ci: CaseItem, plan: ScenarioPlan, slot: CaseSlot, case: Case,
              outcome: CaseOutcome, shrink: ShrinkReport | None) -> str | None:
    """Keep failures for the next run; forget replayed ones that pass now (fix confirmed)."""
    db = ctx.db
    if db is None:
        return None
    from ..db import DatabaseError

    def trouble(what: str, exc: DatabaseError) -> None:
        # a database that cannot be written (read-only, disk full) must not hide the failure
        # itself: the item keeps its message and says it was not stored; the run warns once
        db.write_failures += 1
        if db.write_failures == 1:
            ctx.warn(f"avscenario replay database: {ci.nodeid}: {what}: {exc} (warned once; "
                     "the run goes on, and each failure says whether it was stored)")

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
        if outcome.failed:  # still a counterexample: is another entry the same one?
            entry = plan.replays[slot.index]
            try:
                kept = db.redundant(entry, plan.space)
                if kept is not None:
                    db.delete(entry)
            except DatabaseError as exc:
                trouble(f"the near-duplicate {entry.path.name} could not be removed", exc)
                return None
            if kept is not None:
                return (f"removed from the replay database: {kept.path.name} holds the same "
                        "counterexample, at least as close to the nominal scenario")
        return None
    if case.origin != "sampled" or not outcome.failed or (shrink is not None and shrink.flaky):
        return None
    minimized = shrink is not None and shrink.minimized is not None and shrink.minimized != case.params
    params = shrink.minimized if minimized else case.params
    rho = shrink.outcome.rho if minimized and shrink.outcome is not None else outcome.rho
    found = {"case": ci.nodeid.partition("[")[2].rstrip("]") or ci.nodeid, "params": dict(case.params)}
    try:
        # one file per counterexample: not again when it is stored already, nor beside a
        # near-duplicate of it (the same failure found from another sample, another run)
        stored = db.store(plan.test, params, rho, case.seed, plan.space, minimized=minimized,
                          versions=versions(), found=found)
    except DatabaseError as exc:
        trouble("could not store a counterexample for replay", exc)
        return f"could not store for replay: {exc}"
    if not stored.written:
        return (f"not stored again: the replay database holds the same counterexample, at least as "
                f"close to the nominal scenario, in {stored.entry.path}")
    text = f"stored for replay in {stored.entry.path}"
    if stored.replaced:
        text += f", replacing {', '.join(p.name for p in stored.replaced)} (the same counterexample, farther from nominal)"
    for problem in stored.problems:
        text += f"; {problem}"
    return text

"""One scenario item's run, from the case to everything the reports need.

:func:`run_item` is what the plugin's ``pytest_pyfunc_call`` does for a scenario item: have the
executor simulate the case, tell an active sampler, and for a failure replay it once (flaky?),
minimize it with Hypothesis under the simulation budget, store it in the replay database and
draw its worst moment. The error-table row, the shrink rows and the pictures go into the
item's stash, from where the plugin hands them to the controller with the report.
"""

from __future__ import annotations

import json
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import pytest

from .case import Case
from .expansion import CaseSlot, ScenarioPlan, active_sampler, function_id, plan_of
from .keys import db_key, executor_key, pictures_key, row_key, session_key, shrink_rows_key
from .messages import failure_message
from .reporting import versions
from .runner import CaseOutcome
from .settings import dask_address, default_driver, executor_name, gif_cap


@dataclass
class ShrinkReport:
    """What minimizing one failing case gave (for the message, the rows and the database)."""

    flaky: bool
    sims: int
    budget: int
    minimized: dict[str, Any] | None = None
    outcome: CaseOutcome | None = None  # the minimized case's outcome
    exhausted: bool = False
    rows: list[dict[str, Any]] = field(default_factory=list)


@dataclass
class ItemResult:
    """What running one scenario item gave the plugin's hook: the outcome and, when it did not
    pass, the message to show and whether to re-raise the body's own exception."""

    outcome: CaseOutcome
    message: str | None = None
    reraise: bool = False


def run_item(item: pytest.Function) -> ItemResult:
    """Run the item's case; tell an active sampler; shrink, store and draw a failure; record
    its row and properties for the reports."""
    plan = plan_of(item)
    case_obj: Case = item.funcargs["case"]
    slot: CaseSlot = item.callspec.params["case"]
    if slot.params is None and case_obj.origin == "sampled":
        ask_ahead(item, plan, slot)
    outcome = executor_of(item.config).run(make_job(item, plan, case_obj, fresh_world=False))
    if slot.params is None and case_obj.origin == "sampled":
        active_sampler(plan, slot.sampler).tell(
            outcome.params,
            None if outcome.verdict == "error" else (dict(outcome.rho) or body_rho(outcome)),
        )
    plan.ran[slot.sampler] = plan.ran.get(slot.sampler, 0) + 1

    shrink = None
    capped = False
    if outcome.failed and case_obj.origin == "sampled" and plan.shrink_budget > 0:
        done = plan.shrunk.get(slot.sampler, 0)
        capped = plan.shrink_max is not None and done >= plan.shrink_max
        if not capped:
            plan.shrunk[slot.sampler] = done + 1
            shrink = shrink_case(item, plan, case_obj, outcome)
    row = make_row(item, case_obj, outcome)
    if shrink is not None and shrink.minimized is not None:
        row["minimized"] = shrink.minimized
        row["shrink_sims"] = shrink.sims
    item.stash[row_key] = row
    item.stash[shrink_rows_key] = shrink.rows if shrink is not None else []
    record_properties(item, row, shrink)
    if capped:
        note = (f"not minimized nor stored: {plan.shrink_max} failures of this test's "
                f"{slot.sampler} campaign were already (--avs-shrink-max)")
    else:
        note = update_db(item, plan, slot, case_obj, outcome, shrink)
    if outcome.failed:
        item.stash[pictures_key] = render_case(item, plan, outcome, shrink)
    if outcome.verdict == "pass":
        return ItemResult(outcome)
    message = failure_message(item, case_obj, outcome, shrink, note)
    # the body's own exception keeps its traceback; monitor errors are our message alone
    reraise = outcome.exc is not None and not isinstance(outcome.exc, monitor_error_type())
    return ItemResult(outcome, message, reraise)


def ask_ahead(item: pytest.Function, plan: ScenarioPlan, slot: CaseSlot) -> None:
    """Keep a cluster busy with an active sampler: while case k runs, cases k+1 .. k+B-1 (B the
    cluster's capacity) are asked and started too, so the sampler learns of each case up to B-1
    cases late — as a parallel falsifier does. Nothing happens in-process or on an xdist
    worker (whose items are not consecutive), nor with a conftest driver, which cannot be sent
    before its item's fixtures exist."""
    executor = executor_of(item.config)
    submit = getattr(executor, "submit", None)
    if submit is None or hasattr(item.config, "workerinput") or driver_ahead(item) is None:
        return
    sampler = active_sampler(plan, slot.sampler)
    start = max(slot.index, plan.asked_upto.get(slot.sampler, -1)) + 1
    jobs = []
    for j in range(start, slot.index + executor.capacity):
        ahead = plan.items.get((slot.sampler, j))
        if ahead is None:
            break
        params = sampler.ask()
        plan.asked[(slot.sampler, j)] = params
        plan.asked_upto[slot.sampler] = j
        case_j = Case(params, index=j, seed=ahead.callspec.params["case"].seed,
                      sampler=slot.sampler, origin="sampled", test=ahead.nodeid)
        jobs.append(make_job(ahead, plan, case_j, fresh_world=True, prefetch=True))
    if jobs:
        submit(jobs)


def monitor_error_type() -> type:
    from .monitors import MonitorError

    return MonitorError


def shrink_case(item: pytest.Function, plan: ScenarioPlan, case: Case, outcome: CaseOutcome) -> ShrinkReport:
    """Replay the failure once (flakiness), then minimize it toward the nominal scenario."""
    from .shrink import minimize

    report = ShrinkReport(flaky=False, sims=0, budget=plan.shrink_budget)
    outcomes: dict[str, CaseOutcome] = {}
    executor = executor_of(item.config)

    progress = progress_writer(item.config)

    def simulate(params: dict[str, Any]) -> CaseOutcome:
        candidate = Case(params, index=case.index, seed=case.seed, sampler=case.sampler,
                         origin="shrink", test=item.nodeid)
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


def render_case(item: pytest.Function, plan: ScenarioPlan, outcome: CaseOutcome,
                 shrink: ShrinkReport | None) -> dict[str, str]:
    """PNG of the worst moment (and, within the per-test cap, a GIF) of a failing case.

    Drawn from the minimized case when there is one (that is the one an engineer studies),
    else from the case as found. Only in-process outcomes keep their world; nothing to draw
    for tests that return a Trajectory of their own.
    """
    state = item.config.stash[session_key]
    shown = shrink.outcome if shrink is not None and shrink.outcome is not None else outcome
    world = shown.world
    if state.directory is None or world is None or getattr(world, "trajectory", None) is None:
        return {}
    from .report.table import file_slug

    base = state.directory / "cases" / f"{file_slug(item.nodeid)}"
    pictures: dict[str, str] = {}
    traj = world.trajectory
    step = traj.n_steps - 1
    worst = min(shown.results.values(), key=lambda r: r.rho, default=None)
    if worst is not None and worst.t is not None:
        import numpy as np

        step = int(np.argmin(np.abs(traj.t - worst.t)))
    what = "minimized" if shown is not outcome else "as found"
    try:
        base.parent.mkdir(parents=True, exist_ok=True)
        pictures[f"{item.name}: worst moment ({what})"] = world.render_png(f"{base}.png", step=step)
        if plan.gifs < gif_cap(item.config):
            pictures[f"{item.name}: the run ({what})"] = world.render_gif(f"{base}.gif", every=2)
            plan.gifs += 1
    except Exception as exc:  # a picture is a convenience: never fail the case over it
        warnings.warn(pytest.PytestWarning(f"{item.nodeid}: could not render the case: {exc}"))
    return pictures


def build_world(case: Case, driver: Any, name: str) -> Any:
    from .sim import World

    return World(seed=case.seed, rng=case.rng, driver=driver, name=name)


def executor_of(config: pytest.Config) -> Any:
    """The session's executor, made on first use (a Dask cluster only when a case runs)."""
    executor = config.stash.get(executor_key, None)
    if executor is None:
        from .executors import make_executor

        name = executor_name(config)
        options = {}
        if name == "dask":
            options["address"] = dask_address(config)
            for key, option in (("n_workers", "avs_dask_workers"), ("connect_timeout_s", "avs_dask_timeout"),
                                ("max_retries", "avs_dask_retries")):
                value = config.getoption(option)
                if value is None and config.getini(option) not in (None, ""):
                    value = config.getini(option)
                if value is not None:
                    options[key] = int(value) if key != "connect_timeout_s" else float(value)
        try:
            executor = make_executor(name, **options)
        except ValueError as exc:
            raise pytest.UsageError(str(exc)) from None
        config.stash[executor_key] = executor
    return executor


def driver_ahead(item: pytest.Function) -> Any:
    """The ego's driver of ``item`` before its fixtures exist: the built-in one named by the
    options when ``avs_driver`` is the plugin's own fixture, else None (a user's fixture)."""
    defs = item._fixtureinfo.name2fixturedefs.get("avs_driver", ())
    # the plugin's own avs_driver fixture lives in plugin.py; any other is a user's
    overridden = bool(defs) and getattr(defs[-1].func, "__module__", None) != "pytest_avscenario.plugin"
    return None if overridden else default_driver(item.config)


def make_job(item: pytest.Function, plan: ScenarioPlan, case: Case, fresh_world: bool,
         prefetch: bool = False) -> Any:
    """The executor's description of one case of ``item``'s test.

    With ``prefetch`` (before the item's fixtures exist) there are no fixture values, and the
    driver is known only when ``avs_driver`` is the plugin's own (then it is the built-in
    name); otherwise ``driver`` is None and the job cannot be started ahead.
    """
    from .executors import CaseJob

    argnames = tuple(item._fixtureinfo.argnames)
    if prefetch:
        fixtures: Mapping[str, Any] = {}
        driver = driver_ahead(item)
    else:
        fixtures = item.funcargs
        driver = item.funcargs.get("avs_driver")
        if driver is None and "world" in argnames:
            driver = item._request.getfixturevalue("avs_driver")
    return CaseJob(
        nodeid=item.nodeid, module_path=str(item.path), rootdir=str(item.config.rootpath),
        function=item.originalname, func=item.obj, argnames=argnames, fixtures=fixtures,
        case=case, monitor_set=plan.monitor_set, driver=driver, fresh_world=fresh_world,
        timeout_s=plan.case_timeout_s, make_world=lambda c: build_world(c, driver, item.nodeid),
    )


def attach_to_html_report(report: pytest.TestReport, pictures: Mapping[str, str]) -> None:
    """Show a failing case's pictures in its pytest-html row (embedded, so the page travels)."""
    import base64

    from pytest_html import extras

    attached = list(getattr(report, "extras", []))
    for caption, path in pictures.items():
        try:
            data = base64.b64encode(open(path, "rb").read()).decode()
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
    if case.origin == "replay":
        if outcome.verdict == "pass":
            db.delete(plan.replays[slot.index])
            return "fixed: this stored counterexample passes now and was removed from the database"
        return None
    if case.origin != "sampled" or not outcome.failed or (shrink is not None and shrink.flaky):
        return None
    minimized = shrink is not None and shrink.minimized is not None and shrink.minimized != case.params
    params = shrink.minimized if minimized else case.params
    rho = shrink.outcome.rho if minimized and shrink.outcome is not None else outcome.rho
    entry = db.save(plan.test, params, rho, case.seed, plan.space, minimized=minimized,
                    versions=versions())
    return f"stored for replay in {entry.path}"


def body_rho(outcome: CaseOutcome) -> float:
    # no monitors: a failing assertion is a violation, a pass is neutral
    return -1.0 if outcome.verdict == "fail" else 0.0


def make_row(item: pytest.Item, case: Case, outcome: CaseOutcome) -> dict[str, Any]:
    """The error-table row of one finished case (plain JSON-able data)."""
    from .report.table import row_to_json

    return row_to_json({
        "test": function_id(item), "item": item.nodeid, "sampler": case.sampler,
        "index": case.index, "seed": case.seed, "origin": case.origin,
        "params": dict(case.params), "rho": dict(outcome.rho), "verdict": outcome.verdict,
        "sim_time_s": outcome.sim_time_s, "error": outcome.error,
    })


def record_properties(item: pytest.Item, row: dict[str, Any], shrink: ShrinkReport | None) -> None:
    from .report.junit import case_properties
    from .report.table import row_from_json

    minimized = shrink.minimized if shrink is not None else None
    sims = shrink.sims if shrink is not None and shrink.minimized is not None else None
    # user_properties (not record_property) gives the same XML without xunit2's warning
    item.user_properties.extend(case_properties(row_from_json(row), minimized=minimized, shrink_sims=sims))
    if shrink is not None and shrink.flaky:
        item.user_properties.append(("avs.flaky", "true"))

"""What the executor is handed for one case, and the row a finished case gives.

:func:`make_job` describes one simulation of a case of a :class:`~.context.CaseItem` (the
case as found, a shrinking candidate, an earlier case of an active campaign, the reference
driver's replay); :func:`build_world` makes its world; :func:`make_row` is the error-table
row of an outcome.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..case import Case
from ..outcome import CaseOutcome, CaseRow, violations_of
from .plan import ScenarioPlan


def build_world(case: Case, driver: Any, name: str, ego_driver: Any = None, *,
                plan: ScenarioPlan | None = None, warn: Any = None) -> Any:
    """The case's world: its step setting from the plan, its warnings said once per test
    (``warn``: :meth:`~.context.CampaignContext.world_warner`)."""
    from ..sim import World

    return World(seed=case.seed, rng=case.rng, driver=driver, name=name, ego_driver=ego_driver,
                 dt=plan.dt if plan is not None else None,
                 dt_from=plan.dt_from if plan is not None else "",
                 warn=warn)


def world_for(ctx: Any, ci: Any, case: Case, driver: Any) -> Any:
    """The world of ``ci``'s own case (the ``world`` fixture's value), ``driver`` driving."""
    return build_world(case, driver, ci.nodeid, plan=ci.plan, warn=ctx.world_warner(ci.test))


def make_job(ctx: Any, ci: Any, plan: ScenarioPlan, case: Case, fresh_world: bool,
             prefetch: bool = False, fixtures: Mapping[str, Any] | None = None,
             reference: str | None = None) -> Any:
    """The executor's description of one case of ``ci``'s test.

    With ``prefetch`` (before the item's fixtures exist) there are no fixture values, and the
    driver is known only when ``avs_driver`` is the plugin's own (then it is the built-in
    name); otherwise ``driver`` is None and the job cannot be started ahead. ``fixtures``
    gives the values of the test's other fixtures while the item's own are being set up.
    ``reference`` names a driver that drives the ego whatever the scenario says (the
    avoidability check); on a cluster it replaces the world's default driver.
    """
    from ..executors import CaseJob

    argnames = tuple(ci.argnames)
    if prefetch:
        fixtures = {}
        driver = ci.driver_ahead
    else:
        fixtures = ci.fixtures() if fixtures is None else fixtures
        driver = fixtures.get("avs_driver")
        if driver is None and "world" in argnames:
            driver = ci.driver()
    during = ("" if case.origin != "shrink" else "while it was being minimized") if reference is None \
        else f"while the {reference} reference driver replayed it"
    if reference is None and case.origin == "sampled" and case.index != ci.slot.index:
        during = f"while case {case.index} of its active campaign was simulated first"
    warn = ctx.world_warner(ci.test)
    return CaseJob(
        nodeid=ci.nodeid, module_path=ci.module_path, rootdir=ci.rootdir,
        function=ci.function, func=ci.func, argnames=argnames, fixtures=fixtures,
        case=case, monitor_set=plan.monitor_set, driver=driver if reference is None else reference,
        fresh_world=fresh_world or reference is not None, timeout_s=plan.case_timeout_s,
        make_world=lambda c: build_world(c, driver, ci.nodeid, ego_driver=reference,
                                         plan=plan, warn=warn),
        **_remote_step(plan, driver, reference),
        judge_start=plan.discard_unavoidable and reference is None,
        on_stuck=None if prefetch or ci.on_stuck is None else ci.on_stuck(
            plan.case_timeout_s, lambda o: make_row(ci, ci.own_case(), o), plan.info, during),
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


def item_case(ci: Any) -> Case:
    """The item's own case (:meth:`~.context.CaseItem.own_case`)."""
    return ci.own_case()


def body_rho(outcome: CaseOutcome) -> float:
    # no monitors: a failing assertion is a violation, a pass is neutral
    return -1.0 if outcome.verdict == "fail" else 0.0


def make_row(ci: Any, case: Case, outcome: CaseOutcome, *,
             minimized: Mapping[str, Any] | None = None, shrink_sims: int | None = None,
             flaky: bool = False, avoidable: Mapping[str, bool | None] | None = None,
             unsafe_first: Mapping[str, Any] | None = None,
             conflicts: Mapping[str, Mapping[str, Any]] | None = None,
             minimized_violations: Mapping[str, Mapping[str, Any]] | None = None,
             minimized_avoidable: Mapping[str, bool | None] | None = None,
             minimized_conflicts: Mapping[str, Mapping[str, Any]] | None = None,
             minimized_rho: Mapping[str, float] | None = None) -> CaseRow:
    """The error-table row of one finished case."""
    return CaseRow(
        test=ci.test, item=ci.nodeid, sampler=case.sampler, index=case.index,
        seed=case.seed, origin=case.origin, params=case.params, rho=outcome.rho,
        verdict=outcome.verdict, sim_time_s=outcome.sim_time_s, error=outcome.error,
        minimized=minimized, shrink_sims=shrink_sims, flaky=flaky, avoidable=avoidable,
        unsafe_first=unsafe_first, violations=violations_of(outcome.results, outcome.first), drawn=outcome.drawn,
        conflicts=conflicts, minimized_violations=minimized_violations,
        minimized_avoidable=minimized_avoidable, minimized_conflicts=minimized_conflicts,
        minimized_rho=minimized_rho, driver=ci.identity(), score=outcome.score)

"""A scenario campaign run from a plain script, without pytest collecting anything.

:func:`run_campaign` takes a ``@scenario`` test function and runs every case of its campaign
through the same pipeline as the plugin (:mod:`.pipeline`): the same plan, the same seeds, the
same case ids, values, verdicts and rho as ``pytest --avs-seed=SEED`` gives for that test.
The function may take ``case``, ``world`` and ``avs_driver`` (the script provides them as the
plugin's fixtures do); any other argument is an error naming it::

    from pytest_avscenario.campaign import run_campaign
    from tests_av.test_following import test_following

    rows = run_campaign(test_following, seed=0, rootdir=".")
    for row in rows:
        print(row.item, row.verdict, row.rho)
"""

from __future__ import annotations

import inspect
import os
from pathlib import Path
from typing import Any

from ..outcome import CaseOutcome, CaseRow
from .context import CampaignContext, CaseItem
from .jobs import make_row, world_for
from .plan import build_plan
from .settings import DeclarationError, Settings, script_settings

#: what a script provides a test function, as the plugin's fixtures of the same names do
PROVIDED = ("case", "world", "avs_driver")


def scenario_spec(func: Any) -> Any:
    """The :class:`~pytest_avscenario.markers.spec.ScenarioSpec` a ``@scenario`` decorator put
    on ``func`` (ValueError if there is none)."""
    from ..markers.spec import ScenarioSpec

    marks = [m for m in getattr(func, "pytestmark", ()) if getattr(m, "name", None) == "scenario"]
    specs = [m.args[0] for m in marks if len(m.args) == 1 and isinstance(m.args[0], ScenarioSpec)]
    if len(specs) != 1:
        raise ValueError(f"{getattr(func, '__qualname__', func)!r}: run_campaign needs a function "
                         f"with one @scenario(...) declaration, found {len(specs)}")
    return specs[0]


def node_id_of(func: Any, rootdir: str | os.PathLike[str]) -> str:
    """The id pytest gives ``func`` when run from ``rootdir``: ``path/to/test_x.py::test_x``
    (the seeds of a campaign depend on it)."""
    path = Path(inspect.getsourcefile(func) or "").resolve()
    rel = os.path.relpath(path, Path(rootdir).resolve()).replace(os.sep, "/")
    return f"{rel}::{func.__name__}"


def run_campaign(func: Any, settings: Settings | None = None, *, seed: int = 0,
                 rootdir: str | os.PathLike[str] = ".", db: Any = None,
                 context: CampaignContext | None = None, **options: Any) -> list[CaseRow]:
    """Run every case of ``func``'s campaign; its rows, in case order.

    ``settings``: the session's (default: :func:`~.settings.script_settings` of ``seed`` and
    ``options``, e.g. ``samples=5``, ``shrink_budget=0``); ``rootdir``: where pytest would run
    from (the test's id, hence its seeds, depends on it); ``db``: a
    :class:`~pytest_avscenario.db.ReplayDB` (default: the settings' ``db_path``, or none);
    ``context``: one shared by several campaigns (default: a fresh one, closed at the end).
    DeclarationError names a mistake in the declaration."""
    if settings is None:
        settings = script_settings(seed, **options)
    elif options:
        raise ValueError("run_campaign: give either settings= or per-test options, not both")
    if db is None and settings.db_path is not None:
        from ..db import ReplayDB

        db = ReplayDB(settings.db_path)
    spec = scenario_spec(func)
    test = node_id_of(func, rootdir)
    argnames = tuple(inspect.signature(func).parameters)
    others = [name for name in argnames if name not in PROVIDED]
    if "case" not in argnames:
        raise DeclarationError(f"{test}: a @scenario test must take the `case` argument")
    if others:
        raise DeclarationError(f"{test}: run_campaign provides only {', '.join(PROVIDED)}; the "
                               f"function also takes {', '.join(others)}")
    plan, slots = build_plan(test, spec, func, settings, db, has_world="world" in argnames,
                             is_fixture=lambda name: name in PROVIDED)
    own = context is None
    if context is None:
        report = None if settings.report_dir is None else Path(settings.report_dir)
        context = CampaignContext(settings, db, folder=lambda: report)
    drives = "world" in argnames or "avs_driver" in argnames
    rows: list[CaseRow] = []
    try:
        for slot in slots:
            row = _run_slot(context, func, test, plan, slot, argnames, drives, rootdir)
            if row is not None:
                rows.append(row)
    finally:
        if own:
            context.close()
    return rows


def _run_slot(ctx: CampaignContext, func: Any, test: str, plan: Any, slot: Any,
              argnames: tuple[str, ...], drives: bool, rootdir: Any) -> CaseRow | None:
    """One case: what the plugin's fixtures, setup hook and pipeline do for one item."""
    from .pipeline import OutOfTime, case_for, run_item

    driver = ctx.settings.driver
    values: dict[str, Any] = {}
    ci = CaseItem(
        nodeid=f"{test}[{slot.id}]", test=test, name=f"{func.__name__}[{slot.id}]", slot=slot,
        plan=plan, func=func, function=func.__name__,
        module_path=str(Path(inspect.getsourcefile(func) or "").resolve()),
        rootdir=str(Path(rootdir).resolve()), argnames=argnames, fixtures=lambda: values,
        other_fixtures=lambda: {"avs_driver": driver} if "avs_driver" in argnames else {},
        driver=lambda: driver, driver_ahead=driver,
        identity=lambda: _identity(driver) if drives else None)
    try:
        values["case"] = case = case_for(ctx, ci)
    except OutOfTime:
        return None  # skipped, as the plugin skips it: no row
    except Exception as exc:
        return _error_row(ci, f"the item's setup failed before its case ran: {type(exc).__name__}: {exc}")
    try:
        if "avs_driver" in argnames:
            values["avs_driver"] = driver
        if "world" in argnames:
            values["world"] = world_for(ctx, ci, case, driver)
    except Exception as exc:
        return _error_row(ci, f"the item's setup failed before its case ran: {type(exc).__name__}: {exc}")
    try:
        run_item(ctx, ci)
    except Exception as exc:
        if ci.row is None:
            return _error_row(ci, f"{type(exc).__name__}: {exc}")
    return ci.row


def _error_row(ci: CaseItem, error: str) -> CaseRow:
    case = ci.own_case()
    ci.row = make_row(ci, case, CaseOutcome(params=dict(case.params), verdict="error", error=error))
    return ci.row


def _identity(driver: Any) -> dict[str, Any]:
    if driver is None or (isinstance(driver, str) and ":" not in driver):
        found = {"name": (driver or "autopilot").strip(), "kind": "builtin"}
    else:
        from ..sim.drivers.identity import describe

        found = describe(driver)
    found["from"] = "script"
    return found

"""A pytest item as a campaign case: :func:`case_item` makes the
:class:`~pytest_avscenario.campaign.context.CaseItem` the pipeline runs from a scenario
item — its test, slot, function, and how to reach its fixtures and its driver — and keeps
what the case gives (row, shrink rows, pictures) in the item's stash for the report hooks.

With :mod:`.collect` and :mod:`.controller`, the only module that reads pytest's private
attributes (``item._fixtureinfo``, ``item._request``).
"""

from __future__ import annotations

import inspect
import os
from collections.abc import Mapping
from typing import Any

import pytest

from ..campaign.context import CaseItem
from .collect import function_id, plan_of, slot_of
from .identity import session_driver
from .stash import case_item_key, controller_key, pictures_key, row_key, sent_key, settings_key, shrink_rows_key, told_key
from .stopping import stuck_case_handler

#: the module whose ``avs_driver`` fixture is the plugin's own (any other is a user's)
_OWN_FIXTURES = f"{__package__}.hooks"


class PytestCase(CaseItem):
    """A :class:`CaseItem` of a pytest item: what the case gives goes to the item's stash too."""

    def keep_row(self, row: Any, shrink_rows: list) -> None:
        super().keep_row(row, shrink_rows)
        self.item.stash[row_key] = row
        self.item.stash[shrink_rows_key] = shrink_rows

    def keep_pictures(self, pictures: dict) -> None:
        super().keep_pictures(pictures)
        self.item.stash[pictures_key] = pictures


def case_item(item: pytest.Item, request: pytest.FixtureRequest | None = None) -> PytestCase:
    """The campaign case of scenario item ``item``, made once. ``request``: the ``case``
    fixture's request, through which an active sampler's earlier cases get their fixtures."""
    found = item.stash.get(case_item_key, None)
    if found is None:
        found = PytestCase(
            nodeid=item.nodeid, test=function_id(item), name=item.name, slot=slot_of(item),
            plan=plan_of(item), func=item.obj, function=item.originalname,
            module_path=str(item.path), rootdir=str(item.config.rootpath),
            argnames=tuple(item._fixtureinfo.argnames),
            fixtures=lambda: getattr(item, "funcargs", {}),
            driver=lambda: item._request.getfixturevalue("avs_driver"),
            driver_ahead=driver_ahead(item),
            identity=lambda: driver_identity(item),
            on_stuck=lambda limit, make_row, info, during: stuck_case_handler(
                item, limit, make_row, info, during),
            user_properties=item.user_properties)
        found.item = item
        item.stash[case_item_key] = found
    if request is not None:
        found.other_fixtures = lambda: {name: request.getfixturevalue(name)
                                        for name in item._fixtureinfo.argnames
                                        if name not in ("case", "world")}
    return found


def driver_ahead(item: pytest.Item) -> Any:
    """The ego's driver of ``item`` before its fixtures exist: the built-in one named by the
    options when ``avs_driver`` is the plugin's own fixture, else None (a user's fixture)."""
    defs = item._fixtureinfo.name2fixturedefs.get("avs_driver", ())
    overridden = bool(defs) and getattr(defs[-1].func, "__module__", None) != _OWN_FIXTURES
    return None if overridden else item.config.stash[settings_key].driver


def driver_identity(item: pytest.Item) -> dict[str, Any] | None:
    """Who drives the ego of ``item``'s case: the options' driver, or the value of the
    ``avs_driver`` fixture a conftest or module overrides (its class, or what its
    ``describe()`` says), with the fixture's file. None for a test without a driver."""
    if "avs_driver" not in getattr(item, "fixturenames", ()):
        return None  # no `world` nor `avs_driver`: no ego under test
    defs = item._fixtureinfo.name2fixturedefs.get("avs_driver", ())
    if not defs or getattr(defs[-1].func, "__module__", None) == _OWN_FIXTURES:
        return session_driver(item.config)
    funcargs = getattr(item, "funcargs", {})
    if "avs_driver" not in funcargs:
        return None  # its fixture did not run (an earlier one failed): unknown, not guessed
    from ..sim.drivers.identity import describe

    out = describe(funcargs["avs_driver"])
    try:
        where = os.path.relpath(inspect.getsourcefile(defs[-1].func) or "", item.config.rootpath)
    except (TypeError, ValueError):
        where = ""
    out["from"] = f"avs_driver fixture ({where})" if where else "avs_driver fixture"
    return out


def record_error_row(item: pytest.Item, error: str) -> None:
    """Give ``item`` an error row, unless it has its row already."""
    from ..campaign.jobs import make_row
    from ..outcome import CaseOutcome

    if row_key in item.stash:
        return
    ci = case_item(item)
    case_obj = ci.own_case()
    item.stash[row_key] = make_row(ci, case_obj, CaseOutcome(params=dict(case_obj.params),
                                                             verdict="error", error=error))


def report_case(item: pytest.Item, call: pytest.CallInfo[None], report: pytest.TestReport) -> None:
    """Put the case's row on the first report made after it ran, and its pictures on the
    report pytest-html shows."""
    if not item.stash.get(sent_key, False):
        # The row leaves with the first report after the case ran: the setup's, since the case
        # runs as the last step of the setup. pytest's JUnit writer counts an item from its
        # first report on (the setup's duration opens its <testcase>), so a run stopped between
        # an item's setup and call reports (a SIGTERM to an xdist worker lands there) still has
        # the item's row, as it has its JUnit test case (issue #34). Extra attributes travel to
        # the xdist controller too.
        item.stash[sent_key] = True
        plan = case_item(item).plan
        row = item.stash[row_key]
        report.avs_row = row.to_json()
        report.avs_shrink_rows = list(map(type(row).to_json, item.stash.get(shrink_rows_key, [])))
        report.avs_pictures = item.stash.get(pictures_key, {})
        # the test's declaration (the space, criteria: larger than the row) goes with the first
        # report of each test this process sends; the controller keeps it by test, so later
        # reports carry the row only (an xdist controller unpacks every report it is sent)
        told = item.config.stash.setdefault(told_key, set())
        if row.test not in told:
            told.add(row.test)
            report.avs_test = plan.info()
        report.avs_partial = item.config.stash[controller_key].partial
    pictures = item.stash.get(pictures_key, None)
    shown = call.when == "call" or (call.when == "setup" and not report.passed)
    if pictures and shown and item.config.pluginmanager.hasplugin("html"):
        # pytest-html shows the report that decides the outcome, and a passed setup's not at all
        attach_to_html_report(report, pictures)


def attach_to_html_report(report: pytest.TestReport, pictures: Mapping[str, str]) -> None:
    """Show a failing case's pictures in its pytest-html row (embedded, so the page travels);
    ``pictures``: ``{kind: path}`` as the pipeline's ``render_case`` gives them."""
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

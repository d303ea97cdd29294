"""``--avs-export``: a failing case written for other simulators beside its card.

Which cases: the minimized counterexamples and the first N more per test and sampler (N:
``--avs-export N``; by default every pictured one, N = ``--avs-case-pictures``), every one
with ``all``, none with ``none``; without the option, only when scenariogeneration is
installed. The files
(:func:`pytest_avscenario.export.export_case`) join the case's pictures, so the report places
them beside the card and the card links them; the row's ``exports`` names them. An export
that fails is said in the row (``exports.errors``) and never fails or loses the case.
"""

from __future__ import annotations

import dataclasses
import importlib.util
from typing import Any

from .context import CampaignContext, CaseItem

__all__ = ["export_counterexample"]


def _limit(settings: Any) -> int | str | None:
    """N, "all", or None (no export)."""
    chosen = getattr(settings, "export", None)
    if chosen is None:
        if importlib.util.find_spec("scenariogeneration") is None:
            return None
        # every pictured counterexample: the cases a reader sees on their cards can be
        # replayed elsewhere (~0.2 MB each: two .xosc with the recorded trajectories, the trace)
        return settings.case_pictures
    return None if chosen == "none" else chosen


def export_counterexample(ctx: CampaignContext, ci: CaseItem, campaign: Any, outcome: Any,
                          shrink: Any, pictures: dict[str, str]) -> None:
    """Export ``ci``'s failing case when ``--avs-export`` selects it: the files go into
    ``pictures`` (``xosc``, ``xodr``, ``osi``) and the row's ``exports`` says what was written."""
    limit = _limit(ctx.settings)
    if limit is None or ci.row is None:
        return
    directory = ctx.folder()
    if directory is None:
        return
    minimized = shrink is not None and shrink.outcome is not None
    if not minimized and limit != "all":
        counts = campaign.exported
        sampler = ci.slot.sampler
        if counts.get(sampler, 0) >= limit:
            return
        counts[sampler] = counts.get(sampler, 0) + 1
    shown = shrink.outcome if minimized else outcome
    world = shown.world
    row = ci.row
    if world is None or getattr(world, "trajectory", None) is None:
        exports: dict[str, Any] = {"errors": {"xosc": "not exported: the case ran in another "
                                              "process (its world is not here) or returned "
                                              "a trajectory of its own"}}
    else:
        from ..export import export_case
        from ..report.table import file_slug

        params = dict(shown.params)
        space = campaign.plan.space
        units = {k: getattr(space.parameters.get(k), "unit", None) or ""
                 for k in params if hasattr(space, "parameters")}
        base = directory / "cases" / file_slug(ci.nodeid)
        res = export_case(world, params, base.parent, base.name, units=units,
                          title=ci.nodeid + (" (minimized)" if minimized else ""),
                          osi=importlib.util.find_spec("osi3") is not None)
        pictures.update(res.files)
        exports = res.to_json()
    ci.keep_row(dataclasses.replace(row, exports=exports), ci.shrink_rows)

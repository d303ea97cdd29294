"""The campaign engine, free of pytest: a scenario test's plan, its running state and the
pipeline of one case.

* :mod:`.settings` — the option table, its parsers and the frozen session :class:`Settings`
  (:func:`~.settings.script_settings` for a script).
* :mod:`.plan` — a declaration becomes a frozen :class:`~.plan.ScenarioPlan` and the
  :class:`~.plan.CaseSlot` of every case.
* :mod:`.state` — a campaign while it runs (:class:`~.state.Campaign`) and each active
  sampler's case-index order (:class:`~.state.ActiveRun`).
* :mod:`.context` — what a campaign runs with (:class:`~.context.CampaignContext`: executor,
  replay database, report folder, settings, hook caller) and what it knows of one case
  (:class:`~.context.CaseItem`).
* :mod:`.pipeline` — one case: simulate, tell the sampler, shrink, judge avoidability
  (:mod:`.avoidability`), row, store, evidence, verdict (:mod:`.message` words it).
* :mod:`.script` — a campaign run from a plain script: :func:`~.script.run_campaign`.

The pytest side (:mod:`pytest_avscenario.pytest_plugin`) turns items into :class:`CaseItem`
objects and the pipeline's results into pytest outcomes. Importing this package loads no
pytest, and (so the plugin's load stays light) nothing until a submodule is used.
"""

from __future__ import annotations

from typing import Any

__all__ = ["run_campaign", "script_settings", "CampaignContext"]


def __getattr__(name: str) -> Any:
    if name == "run_campaign":
        from .script import run_campaign

        return run_campaign
    if name == "script_settings":
        from .settings import script_settings

        return script_settings
    if name == "CampaignContext":
        from .context import CampaignContext

        return CampaignContext
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

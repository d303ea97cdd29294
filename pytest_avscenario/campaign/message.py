"""The failure text of a scenario case: every metric, the parameters as found and minimized,
and how to re-run just that case or pin it as a regression."""

from __future__ import annotations

import json
import shlex
from typing import Any, Mapping

from ..case import Case
from ..codec import fmt_rho, fmt_value
from ..outcome import CaseOutcome, violations_of
from .plan import ScenarioPlan, call_text


def failure_message(ctx: Any, ci: Any, case: Case, outcome: CaseOutcome,
                    shrink: Any = None, note: str | None = None,
                    avoidability: str | None = None) -> str:
    """The text a failing case shows: by default the violated metrics, the parameters (found
    and minimized), the line to pin it and the command to re-run it; with ``-v`` every
    metric and found / minimized / nominal side by side, as the report has them."""
    lines = []
    if outcome.verdict == "fail" and outcome.violated:
        lines.append(f"scenario violated: {', '.join(outcome.violated)}")
    elif outcome.verdict == "fail":
        lines.append(f"scenario failed: {outcome.error}")
    else:
        lines.append(f"scenario case could not be judged: {outcome.error}")
    shrunk = shrink is not None and shrink.minimized is not None and shrink.outcome is not None
    verbose = ctx.verbosity >= 1
    if verbose:
        lines += _full_tables(ci.plan, case, outcome, shrink if shrunk else None)
    else:
        # compact: the violated metrics, the parameters, what to paste and what to run; with a
        # minimized case each number says which case it is about, as the card does
        found = " (as found)" if shrunk else ""
        first = violations_of(outcome.results, outcome.first) or {}
        for name, res in outcome.results.items():
            if res.rho < 0:
                thr = "" if res.threshold is None else f", threshold {res.threshold:g}"
                # the detail names the worst moment; the card's column, the first violation
                lines.append(f"  {name}: rho {fmt_rho(res.rho)}{thr} — {res.detail}"
                             f"{first_text(first.get(name), '; ')}{found}")
        lines.append("  parameters: " + ", ".join(f"{k}={fmt_value(v)}" for k, v in case.params.items())
                     + found)
        if shrunk:
            lines.append(f"  minimized ({shrink.sims} simulations): "
                         + ", ".join(f"{k}={fmt_value(v)}" for k, v in shrink.minimized.items()))
            small = shrink.outcome
            there = violations_of(small.results, small.first) or {}
            said = [f"{name} rho {fmt_rho(res.rho)}{first_text(there.get(name))}"
                    for name, res in small.results.items() if res.rho < 0]
            if said:
                lines.append("  minimized case: " + "; ".join(said))
    if shrunk:
        lines.append(f"  pin it as a regression above the test: {call_text('example', shrink.minimized)}")
        lines.append("      (with: from pytest_avscenario import example)")
    if shrink is not None and shrink.flaky:
        lines.append("  FLAKY: a replay of this case with the same seed did not fail the same way; "
                     "it was not shrunk (is the scene or the driver nondeterministic?)")
    if verbose:
        lines.append(f"  case: {case.sampler} #{case.index}, origin {case.origin}, seed {case.seed}, "
                     f"simulated in {outcome.sim_time_s:.3f} s")
    drawn = draws_text(outcome.drawn, 3 if not verbose else 10)
    if drawn:
        lines.append(f"  {drawn}")
    if avoidability:
        lines += [f"  {line}" for line in avoidability.splitlines()]
    if note:
        lines.append(f"  {note}")
    lines.append(f"  re-run only this case: {rerun_command(ctx, ci, case)}")
    return "\n".join(lines)


def first_text(where: Mapping[str, Any] | None, sep: str = ", ") -> str:
    """"first violated at t=… s" after ``sep``: the moment the card's "first violation"
    column gives; "" when unknown."""
    t = (where or {}).get("t")
    return "" if t is None else f"{sep}first violated at t={float(t):.2f} s"


def _first_cell(where: Mapping[str, Any] | None) -> str:
    t = (where or {}).get("t")
    return "—" if t is None else f"{float(t):.2f}"


def _full_tables(plan: ScenarioPlan, case: Case, outcome: CaseOutcome, shrink: Any) -> list[str]:
    """Every metric (and, for a minimized case, found / minimized / nominal side by side)."""
    lines = []
    if outcome.results:
        first = violations_of(outcome.results, outcome.first) or {}
        there = violations_of(shrink.outcome.results, shrink.outcome.first) or {} if shrink else {}
        head = ("  metric       rho (found)" + ("   minimized" if shrink else "")
                + "  threshold  verdict   first [s] (found" + (" / minimized)" if shrink else ")")
                + "  worst (as found)")
        lines.append(head)
        for name, res in outcome.results.items():
            thr = "" if res.threshold is None else f"{res.threshold:g}"
            mid = f"  {fmt_rho(shrink.outcome.rho.get(name)):>10}" if shrink else ""
            verdict = "VIOLATED" if res.rho < 0 else "ok"
            when = _first_cell(first.get(name)) if res.rho < 0 else ""
            if shrink and name in there:
                when += " / " + _first_cell(there.get(name))
            width = 29 if shrink else 17
            lines.append(f"  {name:<12} {fmt_rho(res.rho):>11}{mid}  {thr:>9}  {verdict:<8}  "
                         f"{when:<{width}}  {res.detail}")
    if shrink:
        nominal = plan.space.nominal()
        lines.append("  parameter          found      minimized        nominal")
        for k, v in case.params.items():
            lines.append(f"  {k:<12} {fmt_value(v):>11}  {fmt_value(shrink.minimized[k]):>13}  "
                         f"{fmt_value(nominal.get(k)):>13}")
        how = "budget spent" if shrink.exhausted else "done"
        lines.append(f"  shrinking: {shrink.sims} of {shrink.budget} simulations ({how})")
    else:
        lines.append("  parameters: " + ", ".join(f"{k}={fmt_value(v)}" for k, v in case.params.items()))
    return lines


def draws_text(drawn: Any, shown: int = 3) -> str | None:
    """One line of what the run drew from ``case.rng`` (its first ``shown`` draws)."""
    if not drawn or not drawn.get("count"):
        return None
    parts = []
    for d in list(drawn.get("draws") or ())[:shown]:
        at = "" if d.get("t") is None else f" at {d['t']:g} s"
        parts.append(f"{d.get('call')} -> {fmt_value(d.get('value'))}{at}")
    n = int(drawn["count"])
    more = f", … ({n - len(parts)} more; all in the report)" if n > len(parts) else ""
    return f"drawn from case.rng ({n}): " + "; ".join(parts) + more


def rerun_command(ctx: Any, ci: Any, case: Case) -> str:
    """A command that re-runs just this case, with the same values."""
    return rerun_text(ctx.settings, ci.nodeid, case.params, ci.plan.space.parameters)


def rerun_text(settings: Any, nodeid: str, params: Mapping[str, Any], names: Any) -> str:
    """The re-run command of case ``nodeid`` with ``params`` under the run's ``settings``;
    ``names``: the test's parameter names (what ``--avs-params`` pins).

    A user pastes this into a shell, so every word that comes from the user's files (the node
    id holds directory, file and test names; pinned values are the user's strings) is
    ``shlex.quote``d: a folder named ``d'$(touch x)'`` must be a name, never a command."""
    words = ["pytest", nodeid, f"--avs-seed={settings.seed}"]
    if settings.pinned:
        words += ["--avs-params", json.dumps({k: v for k, v in params.items() if k in names})]
    for name in ("samples", "sampler", "driver"):  # they change which case an id names
        if name in settings.command_line:
            words.append(f"--avs-{name}={settings.command_line[name]}")
    return " ".join(shlex.quote(w) for w in words)

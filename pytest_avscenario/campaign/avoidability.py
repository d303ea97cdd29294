"""Was a counterexample avoidable? The reference driver replays it as the ego, and each
violated metric is judged on the same conflict (:mod:`pytest_avscenario.monitors.conflict`);
RSS names who entered an unsafe state first."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from ..case import Case
from ..codec import fmt_rho
from ..outcome import CaseOutcome, CaseRow, all_unavoidable, violations_of
from .jobs import make_job
from .state import Campaign


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
                    when = f" at t = {c.t:.2f} s" if c.t is not None else ""
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


def judge_avoidability(ctx: Any, ci: Any, campaign: Campaign, case: Case,
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

    ref = InProcessExecutor().run(make_job(ctx, ci, plan, case, fresh_world=True, reference=reference,
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


def judge_minimized(ctx: Any, ci: Any, campaign: Campaign, case: Case, shrink: Any,
                    found: Avoidability | None) -> Avoidability | None:
    """The minimized case's own judgement: the reference driven on the minimized parameters
    (it may meet another agent than the case as found did). Only for a counterexample whose
    found case was judged — one more reference simulation for it, beyond ``reference_max``'s
    count of counterexamples — and the found case's judgement when minimizing changed nothing."""
    if found is None or shrink.minimized is None or shrink.outcome is None:
        return None
    if dict(shrink.minimized) == dict(case.params):
        return found
    small = ci.slot.case(ci.nodeid, dict(shrink.minimized), origin="shrink")
    return judge_avoidability(ctx, ci, campaign, small, shrink.outcome, extra=True)


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

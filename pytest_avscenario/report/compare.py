"""Run-to-run comparison: what changed since an earlier run of the same scenarios.

A team that changed its driving stack wants to see, per scenario test, sampler and metric,
the violation rate now and before, and which failure modes (:mod:`.modes`) are new and which
are gone. :func:`compare` computes that from this run's summary rows (or a second
``summary.json``) and an earlier run's ``summary.json``, read by
:func:`pytest_avscenario.acceptance.load_baseline` (the file ``--avs-baseline`` names): modes
are matched by their content key (metrics, critical agent and the rule's parameters with
their directions), so ``M1`` of one run may be ``M2`` of the other and still be the same.
:func:`format_comparison` gives the terminal lines, :func:`comparison_html` the table at the
top of ``index.html``; ``python -m pytest_avscenario.report compare OLD NEW`` prints it for
two finished runs. Rates compare sampled cases only, as the summary counts them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

__all__ = ["Comparison", "RateChange", "ModeChange", "compare", "format_comparison", "comparison_html"]

DASH = "—"


@dataclass(frozen=True)
class RateChange:
    """One metric of one campaign: violations ``k`` of ``n`` sampled cases now and before
    (None: the campaign is not in that run)."""

    test: str
    sampler: str
    metric: str
    now: tuple[int, int] | None
    before: tuple[int, int] | None

    @staticmethod
    def _rate(kn: tuple[int, int] | None) -> float | None:
        return None if kn is None or kn[1] <= 0 else kn[0] / kn[1]

    @property
    def rate_now(self) -> float | None:
        return self._rate(self.now)

    @property
    def rate_before(self) -> float | None:
        return self._rate(self.before)

    @property
    def change(self) -> float | None:
        """The rate now minus before (None when either is unknown)."""
        if self.rate_now is None or self.rate_before is None:
            return None
        return self.rate_now - self.rate_before

    def to_json(self) -> dict[str, Any]:
        return {"test": self.test, "sampler": self.sampler, "metric": self.metric,
                "now": None if self.now is None else {"violations": self.now[0], "samples": self.now[1]},
                "before": None if self.before is None else {"violations": self.before[0], "samples": self.before[1]},
                "rate_now": self.rate_now, "rate_before": self.rate_before}


@dataclass(frozen=True)
class ModeChange:
    """A failure mode that is ``new`` (only now), ``gone`` (only before) or ``kept`` (both),
    with its id and count in each run."""

    test: str
    sampler: str
    status: str
    key: str
    metrics: tuple[str, ...]
    agent: str | None
    rule: str
    now_id: str | None = None
    now_count: int = 0
    before_id: str | None = None
    before_count: int = 0

    @property
    def what(self) -> str:
        metrics = ", ".join(self.metrics) or "assertion"
        return f"{metrics} with {self.agent}" if self.agent else metrics

    def to_json(self) -> dict[str, Any]:
        return {"test": self.test, "sampler": self.sampler, "status": self.status, "key": self.key,
                "metrics": list(self.metrics), "agent": self.agent, "rule": self.rule,
                "now": None if self.now_id is None else {"id": self.now_id, "count": self.now_count},
                "before": None if self.before_id is None else {"id": self.before_id, "count": self.before_count}}


@dataclass(frozen=True)
class Comparison:
    """This run against ``baseline`` (the earlier summary's path)."""

    baseline: str
    rates: tuple[RateChange, ...]
    modes: tuple[ModeChange, ...]
    #: campaigns of both runs whose modes cannot be compared (a run that did not record them)
    modes_unknown: tuple[tuple[str, str], ...] = ()
    only_now: tuple[tuple[str, str], ...] = ()
    only_before: tuple[tuple[str, str], ...] = ()

    @property
    def new_modes(self) -> list[ModeChange]:
        return [m for m in self.modes if m.status == "new"]

    @property
    def gone_modes(self) -> list[ModeChange]:
        return [m for m in self.modes if m.status == "gone"]

    def to_json(self) -> dict[str, Any]:
        """For ``summary.json``'s ``"comparison"``."""
        return {"baseline": self.baseline, "rates": [r.to_json() for r in self.rates],
                "modes": [m.to_json() for m in self.modes],
                "modes_unknown": [list(c) for c in self.modes_unknown],
                "only_now": [list(c) for c in self.only_now], "only_before": [list(c) for c in self.only_before]}


@dataclass(frozen=True)
class _Campaign:
    samples: int
    violations: Mapping[str, int]
    modes: tuple[Mapping[str, Any], ...] | None  # None: not recorded


def _campaigns(run: Any) -> dict[tuple[str, str], _Campaign]:
    """Campaigns of a run: summary rows (this run) or a :class:`~..acceptance.Baseline`."""
    from ..acceptance import Baseline

    if isinstance(run, Baseline):
        return {c: _Campaign(n, dict(v), run.modes.get(c)) for c, (n, v) in run.campaigns.items()}
    out = {}
    for s in run:
        modes = tuple({"id": m.id, "key": m.key, "metrics": list(m.metrics), "agent": m.agent,
                       "count": m.count, "rule": m.rule} for m in s.modes)
        out[(s.test, s.sampler)] = _Campaign(s.samples, {m: s.violations.get(m, 0) for m in s.metrics}, modes)
    return out


def compare(summary_rows: Any, baseline: Any) -> Comparison:
    """This run (its :class:`~.summary.SummaryRow` s, or a ``Baseline`` read from a later
    ``summary.json``) against ``baseline`` (:func:`~pytest_avscenario.acceptance.load_baseline`
    of the earlier one). Campaigns in this run's order, then those only the baseline has."""
    now, before = _campaigns(summary_rows), _campaigns(baseline)
    rates: list[RateChange] = []
    modes: list[ModeChange] = []
    unknown = []
    for campaign in list(now) + [c for c in before if c not in now]:
        test, sampler = campaign
        a, b = now.get(campaign), before.get(campaign)
        metrics = list(dict.fromkeys([*(a.violations if a else {}), *(b.violations if b else {})]))
        for m in metrics:
            rates.append(RateChange(
                test, sampler, m,
                None if a is None or m not in a.violations else (a.violations[m], a.samples),
                None if b is None or m not in b.violations else (b.violations[m], b.samples)))
        if a is None or b is None:
            continue
        if a.modes is None or b.modes is None:
            unknown.append(campaign)
            continue
        earlier = {m["key"]: m for m in b.modes}
        later = {m["key"]: m for m in a.modes}
        for m in a.modes:
            old = earlier.get(m["key"])
            modes.append(ModeChange(test, sampler, "kept" if old else "new", m["key"], tuple(m["metrics"]),
                                    m["agent"], m["rule"], m["id"], m["count"],
                                    old["id"] if old else None, old["count"] if old else 0))
        for m in b.modes:
            if m["key"] not in later:
                modes.append(ModeChange(test, sampler, "gone", m["key"], tuple(m["metrics"]), m["agent"],
                                        m["rule"], before_id=m["id"], before_count=m["count"]))
    path = getattr(baseline, "path", "")
    return Comparison(str(path), tuple(rates), tuple(modes), tuple(unknown),
                      tuple(c for c in now if c not in before), tuple(c for c in before if c not in now))


# --------------------------------------------------------------------------- text


def _kn(kn: tuple[int, int] | None) -> str:
    if kn is None:
        return DASH
    k, n = kn
    return f"{k}/{n} ({100 * k / n:.1f}%)" if n else f"{k}/{n}"


def _change(r: RateChange) -> str:
    c = r.change
    if c is None:
        return "new campaign" if r.before is None else "not run now" if r.now is None else DASH
    if abs(c) < 1e-12:
        return "="
    return f"{'↑' if c > 0 else '↓'} {100 * c:+.1f} pts"


def format_comparison(comparison: Comparison, now: str = "this run") -> list[str]:
    """The terminal lines: the rates that are not zero in both runs (aligned), then the new
    and gone failure modes. ``now`` names the later run in the first line."""
    from .summary import short_names

    tests = list(dict.fromkeys([r.test for r in comparison.rates] + [m.test for m in comparison.modes]))
    names = short_names(tests)
    lines = [f"{now} compared with {comparison.baseline}:"]
    shown = [r for r in comparison.rates if r.now is not None
             and ((r.now and r.now[0]) or (r.before and r.before[0]))]
    table = [["test", "sampler", "metric", "now", "before", "change"]]
    table += [[names[r.test], r.sampler, r.metric, _kn(r.now), _kn(r.before), _change(r)] for r in shown]
    if shown:
        widths = [max(len(row[i]) for row in table) for i in range(len(table[0]))]
        for row in table:
            cells = [c.rjust(w) if i in (3, 4) else c.ljust(w) for i, (c, w) in enumerate(zip(row, widths))]
            lines.append("  " + "  ".join(cells).rstrip())
    quiet = sum(r.now is not None for r in comparison.rates) - len(shown)
    if quiet:
        lines.append(f"  ({quiet} more metric{'s' if quiet != 1 else ''}: no violation in either run)")
    if comparison.only_before:  # a run of some tests: the others are one line, not a table
        lines.append(f"  {_not_run(comparison.only_before, short_names([t for t, _ in comparison.only_before]))}")
    for m in comparison.modes:
        if m.status == "new":
            lines.append(f"  new mode {names[m.test]} [{m.sampler}] {m.now_id}: {m.what}, {m.rule} "
                         f"({m.now_count} case{'s' if m.now_count != 1 else ''})")
        elif m.status == "gone":
            lines.append(f"  gone mode {names[m.test]} [{m.sampler}] (was {m.before_id}): {m.what}, {m.rule} "
                         f"({m.before_count} case{'s' if m.before_count != 1 else ''} before)")
    if comparison.modes and not comparison.new_modes and not comparison.gone_modes:
        lines.append("  failure modes: the same as before")
    for test, sampler in comparison.modes_unknown:
        lines.append(f"  {names[test]} [{sampler}]: failure modes not recorded in one of the runs")
    return lines


def _not_run(campaigns: Sequence[tuple[str, str]], names: Mapping[str, str]) -> str:
    tests = list(dict.fromkeys(t for t, _ in campaigns))
    shown = ", ".join(names.get(t, t) for t in tests[:6]) + (f" and {len(tests) - 6} more" if len(tests) > 6 else "")
    return (f"not run now: {len(campaigns)} campaign{'s' if len(campaigns) != 1 else ''} of the baseline "
            f"({len(tests)} test{'s' if len(tests) != 1 else ''}: {shown})")


def comparison_html(comparison: Comparison, *, link: Any = None) -> str:
    """The comparison as an HTML section (for the top of the index). ``link(test, sampler,
    mode_id)``: where a mode of this run is shown (an ``#anchor``), or None."""
    from .cards import e
    from .summary import short_names

    tests = list(dict.fromkeys([r.test for r in comparison.rates] + [m.test for m in comparison.modes]))
    names = short_names(tests)
    out = ["<section id='comparison'><h2>Compared with an earlier run</h2>",
           f"<p class='meta'>baseline: <code>{e(comparison.baseline)}</code> · rates count violations "
           "among sampled cases</p>"]
    head = ("<div class='wide'><table class='comparison{}'><thead><tr><th>test</th><th>sampler</th>"
            "<th>metric</th><th>now</th><th>before</th><th>change</th></tr></thead><tbody>")
    changed_rows, same_rows = [], []
    for r in comparison.rates:
        if r.now is None:
            continue  # a campaign of the baseline this run did not run: one line below
        if r.now[1] == 0 and not (r.before and r.before[1]):
            continue  # no sampled case in either run (e.g. the replays of stored failures)
        c = r.change
        cls = " bad" if c is not None and c > 1e-12 else " good" if c is not None and c < -1e-12 else ""
        row = (f"<tr><td title='{e(r.test)}'>{e(names[r.test])}</td><td>{e(r.sampler)}</td>"
               f"<td>{e(r.metric)}</td><td class='num'>{e(_kn(r.now))}</td>"
               f"<td class='num'>{e(_kn(r.before))}</td><td class='num{cls}'>{e(_change(r))}</td></tr>")
        (same_rows if c is not None and abs(c) < 1e-12 else changed_rows).append(row)
    # only what changed is open; the unchanged rates are one click away
    if changed_rows:
        out += [head.format(" changed"), *changed_rows, "</tbody></table></div>"]
    else:
        out.append("<p id='no-rate-change'>No violation rate changed.</p>")
    if same_rows:
        out += [f"<details class='unchanged'><summary>{len(same_rows)} unchanged rate"
                f"{'s' if len(same_rows) != 1 else ''}</summary>", head.format(" unchanged"), *same_rows,
                "</tbody></table></div></details>"]
    if comparison.only_before:
        out.append(f"<p class='meta'>{e(_not_run(comparison.only_before, names))}</p>")
    order = {"new": 0, "gone": 1, "kept": 2}
    kept = sum(m.status == "kept" for m in comparison.modes)
    mode_head = ("<table class='mode-changes'><thead><tr><th></th><th>test</th><th>sampler</th><th>mode</th>"
                 "<th>violated</th><th>where</th><th>cases</th></tr></thead><tbody>")
    for group in ([m for m in comparison.modes if m.status != "kept"],
                  [m for m in comparison.modes if m.status == "kept"]):
        if not group:
            continue
        if group[0].status == "kept":
            out.append(f"<details class='unchanged'><summary>{len(group)} kept failure mode"
                       f"{'s' if len(group) != 1 else ''}</summary>")
        out.append(mode_head)
        for m in sorted(group, key=lambda m: order[m.status]):  # stable: run order within
            if m.status == "gone":
                ident, count = f"was {e(m.before_id)}", f"{m.before_count} before"
            else:
                target = link(m.test, m.sampler, m.now_id) if link else None
                ident = f"<a href='{e(target)}'>{e(m.now_id)}</a>" if target else e(m.now_id)
                count = f"{m.now_count}" if m.status == "new" else f"{m.now_count} ({m.before_count} before)"
                if m.status == "kept" and m.before_id != m.now_id:
                    ident += f" (was {e(m.before_id)})"
            cls = {"new": "bad", "gone": "good", "kept": "meta"}[m.status]
            out.append(f"<tr><td class='{cls}'>{e(m.status)}</td><td title='{e(m.test)}'>{e(names[m.test])}</td>"
                       f"<td>{e(m.sampler)}</td><td>{ident}</td><td>{e(m.what)}</td>"
                       f"<td><code>{e(m.rule)}</code></td><td class='num'>{e(count)}</td></tr>")
        out.append("</tbody></table>")
        if group[0].status == "kept":
            out.append("</details>")
    if comparison.modes:
        out.append(f"<p class='meta'>{len(comparison.new_modes)} new, {len(comparison.gone_modes)} gone, "
                   f"{kept} kept failure mode{'s' if kept != 1 else ''} (matched by metric, agent and the "
                   "rule's parameters)</p>")
    if comparison.modes_unknown:
        out.append(f"<p class='meta'>Failure modes of {len(comparison.modes_unknown)} campaign(s) cannot be "
                   "compared: one of the runs did not record them.</p>")
    out.append("</section>")
    return "\n".join(out)

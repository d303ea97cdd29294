"""One page per counterexample: what failed, where, with which values, and how to see it again.

The index lists each scenario test's counterexamples in a short table; each links to its
card, ``cases/<test>-<hash>.<case>.html``, a page of its own that holds

* the violated metrics with ρ, threshold, the time of the first violation and the agent
  involved, and whether the reference driver avoids it;
* the parameters as found, minimized and nominal, with the units the declaration gives;
* the values the run drew from ``case.rng``;
* the ``@example(...)`` line with its import, and the exact command that re-runs the case;
* the case's pictures (time series, the annotated moment of the first violation, the GIF)
  and, when its recording is at hand, a player with a time slider.

Pages are static, self-contained HTML (inline CSS and script, relative links), every text
HTML-escaped. Nothing here imports pytest or the simulator.
"""

from __future__ import annotations

import hashlib
import html
import json
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence
from urllib.parse import quote

from ..codec import fmt_rho, fmt_value  # the terminal's formatters: one convention
from ..outcome import CaseRow

__all__ = ["CaseFiles", "card_name", "card_rows", "render_card", "counterexample_table",
           "example_line", "PAGE_CSS", "e", "href", "fmt_value", "unit_of"]

DASH = "—"

#: kinds of case file a card shows, in the order it shows them, with their captions
FILE_CAPTIONS = {
    "timeseries": "speeds, gaps and TTC over time",
    "moment": "the first violation, from above",
    "gif": "the run",
}

#: counts the page's script errors into ``<html data-script-errors>`` (and says so on the page),
#: so a broken player shows instead of silently doing nothing; automated checks read it too
ERROR_PROBE = """
(function () {
  var root = document.documentElement, n = 0;
  root.setAttribute("data-script-errors", "0");
  window.addEventListener("error", function (ev) {
    n += 1;
    root.setAttribute("data-script-errors", String(n));
    root.setAttribute("data-last-error", String(ev.message || ev));
  });
  window.addEventListener("load", function () { root.setAttribute("data-loaded", "yes"); });
})();
"""

PAGE_CSS = """
body { font: 14px/1.45 system-ui, -apple-system, "Segoe UI", sans-serif; margin: 1.2em 2em; color: #222; max-width: 1300px; }
h1 { font-size: 1.3em; margin-bottom: .2em; word-break: break-all; }
h2 { font-size: 1.1em; margin-top: 1.6em; border-bottom: 1px solid #ddd; word-break: break-all; }
h3 { font-size: 1em; margin: 1.2em 0 .3em; }
table { border-collapse: collapse; margin: .5em 0; }
th, td { border: 1px solid #ccc; padding: .2em .55em; vertical-align: top; }
th { background: #f3f3f3; text-align: left; white-space: nowrap; }
th.group { text-align: center; background: #e9eef5; }
td.num { text-align: right; white-space: nowrap; font-variant-numeric: tabular-nums; }
.bad { color: #b33c00; font-weight: 600; }
.good { color: #2a7a2a; font-weight: 600; }
.meta { color: #666; }
.wide { overflow-x: auto; max-width: 100%; }
pre { background: #f6f6f6; border: 1px solid #e2e2e2; padding: .5em .8em; overflow-x: auto; white-space: pre-wrap; word-break: break-all; }
figure { display: inline-block; margin: .5em 1em .5em 0; vertical-align: top; }
figure img { max-width: 760px; width: 100%; border: 1px solid #eee; }
figcaption { color: #666; font-size: .9em; }
details > summary { cursor: pointer; font-weight: 600; margin: .4em 0; }
dl.legend { display: grid; grid-template-columns: max-content auto; gap: .1em 1em; color: #444; font-size: .92em; }
dl.legend dt { font-weight: 600; }
dl.legend dd { margin: 0; }
.banner { background: #fff6e0; border: 1px solid #f0c36d; padding: .5em .8em; }
#image-status.broken { color: #b33c00; font-weight: 600; }
.run-verdict { font-size: 1.1em; padding: .4em .8em; border: 1px solid #ccc; margin: .5em 0; }
.run-verdict.bad { background: #fdecea; border-color: #e0a39a; color: #222; font-weight: 400; }
.run-verdict.good { background: #eaf6ea; border-color: #9ccc9c; color: #222; font-weight: 400; }
.run-verdict .head { font-weight: 700; }
td.verdict { white-space: nowrap; }
"""


def e(value: Any) -> str:
    """HTML-escaped text."""
    return html.escape(str(value), quote=True)


def href(directory: Path, path: str | os.PathLike) -> str:
    """A link to ``path`` from a page in ``directory``: relative, forward slashes, quoted."""
    p = Path(path)
    rel = os.path.relpath(p if p.is_absolute() else directory / p, directory)
    return quote(Path(rel).as_posix(), safe="/#")


def unit_of(space: Any, name: str) -> str:
    """The unit the declaration gives parameter ``name`` (``Uniform(0, 30, unit="m")``), or ""."""
    dist = getattr(space, "parameters", {}).get(name) if space is not None else None
    return getattr(dist, "unit", None) or ""


def example_line(params: Mapping[str, Any]) -> str:
    """The line that pins a case above its test."""
    return "@example(" + ", ".join(f"{k}={v!r}" for k, v in params.items()) + ")"


def card_name(row: CaseRow) -> str:
    """The card page's file name (under ``cases/``): readable, and unique per item id."""
    test, _, case = row.item.partition("[")
    stem = re.sub(r"[^A-Za-z0-9_.-]+", "_", test.rpartition("::")[2])[:60]
    case = re.sub(r"[^A-Za-z0-9_.-]+", "_", case.rstrip("]"))[:40] or "case"
    digest = hashlib.sha256(row.item.encode()).hexdigest()[:8]
    return f"{stem}-{digest}.{case}.html"


@dataclass(frozen=True)
class CaseFiles:
    """What a case left on disk beside its row: ``{kind: path}`` with kinds ``timeseries``,
    ``moment``, ``gif`` (pictures) and ``recording`` (its clip as JSON, for the player; the
    card embeds it, and the report keeps that copy only)."""

    files: Mapping[str, str] = field(default_factory=dict)

    def get(self, kind: str) -> str | None:
        path = self.files.get(kind)
        return path if path and Path(path).exists() else None


def card_rows(rows: Sequence[CaseRow]) -> list[CaseRow]:
    """The rows that get a card: failing cases of the campaign and of its regressions
    (sampled, replay, example, pinned), in the order they ran."""
    return [r for r in rows if r.origin != "shrink" and r.verdict == "fail"]


def _worst(row: CaseRow) -> tuple[str | None, float | None]:
    vals = [(m, v) for m, v in row.rho.items() if v is not None and not math.isnan(v)]
    if not vals:
        return None, None
    m, v = min(vals, key=lambda mv: mv[1])
    return m, v


def _first(row: CaseRow) -> tuple[float | None, str | None]:
    """The earliest violation of the row, and its agent."""
    best: tuple[float | None, str | None] = (None, None)
    for where in (row.violations or {}).values():
        t = where.get("t")
        if t is not None and (best[0] is None or t < best[0]):
            best = (float(t), where.get("agent"))
    if best[0] is None and row.violations:
        where = next(iter(row.violations.values()))
        best = (None, where.get("agent"))
    return best


def counterexample_table(directory: Path, rows: Sequence[CaseRow], *, modes: Mapping[str, str] | None = None) -> str:
    """The index's list of a test's counterexamples: one line each, linked to its card."""
    out = ["<div class='wide'><table class='cex'>",
           "<thead><tr><th>case</th><th>violated</th><th>worst ρ (as found)</th>"
           "<th>first violation [s] (as found)</th><th>agent (as found)</th><th>minimized</th>" + ("<th>mode</th>" if modes else "") + "</tr></thead><tbody>"]
    for r in rows:
        metric, worst = _worst(r)
        t, agent = _first(r)
        violated = ", ".join(m for m, v in r.rho.items() if v is not None and v < 0) or (r.error or DASH)
        link = href(directory, Path("cases") / card_name(r))
        name = r.item.partition("[")[2].rstrip("]") or r.item
        tags = []
        if r.unavoidable:
            tags.append("unavoidable")
        if r.flaky:
            tags.append("flaky")
        out.append(
            "<tr>"
            f"<td><a href='{link}'>{e(name)}</a>{' <span class=meta>(' + e(', '.join(tags)) + ')</span>' if tags else ''}</td>"
            f"<td>{e(violated)}</td>"
            f"<td class='num'>{e(fmt_rho(worst))}{' ' + e(metric) if metric else ''}</td>"
            f"<td class='num'>{DASH if t is None else f'{t:.2f}'}</td>"
            f"<td>{e(agent or DASH)}</td>"
            f"<td>{'yes' if r.minimized is not None else ''}</td>"
            + (f"<td>{e(modes.get(r.item, ''))}</td>" if modes else "")
            + "</tr>")
    out.append("</tbody></table></div>")
    return "\n".join(out)


def _parameter_table(row: CaseRow, space: Any) -> str:
    names = list(dict.fromkeys([*(getattr(space, "parameters", {}) or {}), *row.params]))
    shown_min = row.minimized is not None
    head = "<tr><th>parameter</th><th>unit</th><th>found</th>" + ("<th>minimized</th>" if shown_min else "") \
        + "<th>nominal</th></tr>"
    out = ["<table class='params'>", f"<thead>{head}</thead><tbody>"]
    for n in names:
        dist = getattr(space, "parameters", {}).get(n) if space is not None else None
        nominal = DASH
        if dist is not None:
            try:
                nominal = fmt_value(dist.nominal)
            except Exception:
                nominal = DASH
        found = fmt_value(row.params[n]) if n in row.params else DASH
        cells = [f"<td>{e(n)}</td>", f"<td>{e(unit_of(space, n))}</td>", f"<td class='num'>{e(found)}</td>"]
        if shown_min:
            mval = row.minimized.get(n, DASH) if row.minimized is not None else DASH
            changed = n in row.params and mval != DASH and mval != row.params[n]
            cells.append(f"<td class='num{' bad' if changed else ''}'>{e(fmt_value(mval) if mval != DASH else DASH)}</td>")
        cells.append(f"<td class='num'>{e(nominal)}</td>")
        out.append("<tr>" + "".join(cells) + "</tr>")
    out.append("</tbody></table>")
    return "\n".join(out)


#: a judgement's words on the card (True: the reference avoids the conflict)
_JUDGEMENT = {True: "avoids it", False: "violates it too (unavoidable)", None: "unknown"}


def _judgement_cell(avoidable: Mapping[str, Any] | None, conflicts: Mapping[str, Any] | None,
                    metric: str, bad: bool) -> str:
    if not bad:
        return "<td></td>"
    if avoidable is None or metric not in avoidable:
        return f"<td>{DASH}</td>"
    text = _JUDGEMENT.get(avoidable[metric], "unknown")
    why = ((conflicts or {}).get(metric) or {}).get("why")
    return f"<td>{e(text)}" + (f"<br><span class='meta'>{e(why)}</span>" if why else "") + "</td>"


def _when_cell(where: Mapping[str, Any]) -> str:
    """The first violation's time and, when the worst value came later, that moment (the one
    the monitor's own text, as the terminal prints it, names)."""
    t, worst = where.get("t"), where.get("worst_t")
    if t is None:
        return f"<td class='num'>{DASH}</td>"
    text = f"{float(t):.2f}"
    if worst is not None and abs(float(worst) - float(t)) >= 0.005:
        text += f"<br><span class='meta'>worst at {float(worst):.2f}</span>"
    return f"<td class='num'>{text}</td>"


def _metric_table(row: CaseRow, metrics: Sequence[str]) -> str:
    """Each metric's threshold, then the case as found — ρ, where it violated first, with whom
    and, when judged, what the reference driver did there — and, for a minimized case, the
    same of the minimized case: a header over each group says which case it is about."""
    names = list(dict.fromkeys([*metrics, *row.rho]))
    judged = row.avoidable is not None
    small = row.minimized is not None and (row.minimized_violations is not None
                                           or row.minimized_rho is not None)
    small_judged = small and row.minimized_avoidable is not None
    found_head = ["ρ", "first violation [s]", "agent"] + (["reference driver"] if judged else [])
    small_head = ["ρ", "first violation [s]", "agent"] + (["reference driver"] if small_judged else [])
    groups = (f"<th colspan='{len(found_head)}' class='group'>case as found</th>"
              + (f"<th colspan='{len(small_head)}' class='group'>minimized case</th>" if small else ""))
    sub = [*found_head, *(small_head if small else ())]
    out = ["<div class='wide'><table class='metrics'>",
           "<thead><tr><th rowspan='2'>metric</th><th rowspan='2'>threshold</th>" + groups + "</tr>",
           "<tr>" + "".join(f"<th>{e(h)}</th>" for h in sub) + "</tr></thead><tbody>"]
    for m in names:
        rho = row.rho.get(m)
        where = (row.violations or {}).get(m) or {}
        bad = rho is not None and rho < 0
        thr = where.get("threshold")
        if thr is None and small:
            thr = ((row.minimized_violations or {}).get(m) or {}).get("threshold")
        thr_text = DASH if thr is None else fmt_value(float(thr)) if not isinstance(thr, str) else thr
        cells = [f"<td>{e(m)}</td>", f"<td class='num'>{e(thr_text)}</td>",
                 f"<td class='num{' bad' if bad else ''}'>{e(fmt_rho(rho))}</td>", _when_cell(where),
                 f"<td>{e(where.get('agent') or DASH)}</td>"]
        if judged:
            cells.append(_judgement_cell(row.avoidable, row.conflicts, m, bad))
        if small:
            mrho = (row.minimized_rho or {}).get(m)
            mbad = mrho is not None and mrho < 0
            there = (row.minimized_violations or {}).get(m) or {}
            cells += [f"<td class='num{' bad' if mbad else ''}'>{e(fmt_rho(mrho))}</td>", _when_cell(there),
                      f"<td>{e(there.get('agent') or DASH)}</td>"]
            if small_judged:
                cells.append(_judgement_cell(row.minimized_avoidable, row.minimized_conflicts, m,
                                             mbad or bad))
        out.append("<tr>" + "".join(cells) + "</tr>")
    out.append("</tbody></table></div>")
    return "\n".join(out)


#: the files a case is exported as (``--avs-export``), in the order the card lists them
EXPORT_CAPTIONS = {
    "xosc": "OpenSCENARIO 1.3 scenario (esmini and most tools)",
    "xosc_1_0": "the same in OpenSCENARIO 1.0 (CARLA ScenarioRunner)",
    "xodr": "OpenDRIVE road (the built road in 1.7, or a copy of the map the case ran on)",
    "osi": "OSI SensorView trace",
}


def _exports_html(directory: Path, row: CaseRow, files: CaseFiles) -> str:
    """The card's links to the case as exported for other simulators, and what was not."""
    exports = row.exports or {}
    links = [(k, files.get(k)) for k in EXPORT_CAPTIONS]
    links = [(k, p) for k, p in links if p]
    errors = exports.get("errors") or {}
    if not links and not errors:
        return ""
    which = "minimized case" if row.minimized is not None else "case as found"
    out = [f"<h2>For other simulators ({e(which)})</h2>"]
    if links:
        out.append("<ul class='exports'>" + "".join(
            f"<li><a href='{href(directory, p)}' download>{e(Path(p).name)}</a> "
            f"<span class='meta'>{e(EXPORT_CAPTIONS[k])}</span></li>" for k, p in links) + "</ul>")
        out.append("<p class='meta'>Replay with <code>esmini --headless --osc FILE.xosc</code> or "
                   "CARLA ScenarioRunner's <code>--openscenario FILE.v1_0.xosc</code>; the ego follows its "
                   "recorded trajectory: replace that action with your own controller.</p>")
    following = exports.get("trajectories") or {}
    others = {k: v for k, v in following.items() if k != "ego"}
    if others:
        out.append("<p class='meta'>Following their recorded trajectories (no one-to-one "
                   "OpenSCENARIO action): " + e("; ".join(f"{k}: {v}" for k, v in others.items()))
                   + "</p>")
    for note in exports.get("notes") or ():
        out.append(f"<p class='meta'>{e(note)}</p>")
    for part, why in errors.items():
        out.append(f"<p class='bad'>Not exported ({e(part)}): {e(why)}</p>")
    return "\n".join(out)


def _draws_table(drawn: Mapping[str, Any] | None) -> str:
    if not drawn or not drawn.get("count"):
        return "<p class='meta'>The run drew nothing from <code>case.rng</code>.</p>"
    draws = list(drawn.get("draws") or ())
    n = int(drawn["count"])
    out = [f"<p class='meta'>{n} draw{'s' if n != 1 else ''} from <code>case.rng</code>"
           + (f"; the first {len(draws)} are listed" if len(draws) < n else "") + ".</p>",
           "<div class='wide'><table class='draws'><thead><tr><th>#</th><th>t [s]</th><th>call</th><th>value</th>"
           "</tr></thead><tbody>"]
    for d in draws:
        t = d.get("t")
        out.append(f"<tr><td class='num'>{e(d.get('n', ''))}</td>"
                   f"<td class='num'>{DASH if t is None else e(f'{float(t):g}')}</td>"
                   f"<td><code>{e(d.get('call', ''))}</code></td><td class='num'>{e(fmt_value(d.get('value')))}</td></tr>")
    out.append("</tbody></table></div>")
    return "\n".join(out)


def _score_block(score: Mapping[str, Any]) -> str:
    """The run's driving score with its route completion and each infraction's factor."""
    inf = list(score.get("infractions") or ())
    lines = [f"<h2>Driving score {float(score['score']):.2f}</h2>",
             f"<p class='meta'>CARLA Leaderboard: route completion {float(score['route_completion']):.2f} "
             f"× infraction penalty {float(score['penalty']):.3g}"
             + ("" if inf else " (no infraction)") + ".</p>"]
    if inf:
        lines.append("<table><thead><tr><th>infraction</th><th>factor</th><th>t [s]</th>"
                     "<th>agent</th><th>detail</th></tr></thead><tbody>")
        for i in inf:
            t = i.get("t")
            lines.append(f"<tr><td>{e(i.get('kind'))}</td><td class='num'>{float(i.get('factor', 1)):.3g}</td>"
                         f"<td class='num'>{'' if t is None else f'{float(t):.2f}'}</td>"
                         f"<td>{e(i.get('agent') or '')}</td><td>{e(i.get('detail') or '')}</td></tr>")
        lines.append("</tbody></table>")
    return "\n".join(lines)


def render_card(
    directory: Path,
    row: CaseRow,
    *,
    metrics: Sequence[str] = (),
    space: Any = None,
    files: CaseFiles | None = None,
    rerun: str | None = None,
    index_href: str = "../index.html",
    mode: str | None = None,
    player: Callable[[Mapping[str, Any], CaseRow], str] | None = None,
    sections: Sequence[tuple[str, str]] = (),
) -> str:
    """The HTML text of ``row``'s card page, written in ``directory`` (the report's
    ``cases/``). ``files``: the case's pictures and recording; ``rerun``: the command that
    re-runs it; ``player(data, row)``: the player's HTML for the recording's JSON data;
    ``sections``: ``(title, html)`` a team adds at the end (the title escaped, the HTML as given)."""
    files = files or CaseFiles()
    violated = [m for m, v in row.rho.items() if v is not None and v < 0]
    t, agent = _first(row)
    title = row.item
    parts = ["<!DOCTYPE html>", "<html lang='en'><head><meta charset='utf-8'>",
             f"<title>{e(title)}</title>", f"<style>{PAGE_CSS}</style>",
             f"<script>{ERROR_PROBE}</script>", "</head><body>",
             f"<p class='meta'><a href='{e(index_href)}'>← the report</a> · {e(row.test)}</p>",
             f"<h1>{e(title)}</h1>"]
    what = f"violated {', '.join(violated)}" if violated else f"failed: {row.error or 'the test body failed'}"
    if t is not None:
        what += f", first at t = {t:.2f} s" + (f" with {agent}" if agent else "")
    if row.minimized is not None:
        mt = min((float(w["t"]) for w in (row.minimized_violations or {}).values()
                  if w.get("t") is not None), default=None)
        what += " (case as found" + (f"; minimized case first at t = {mt:.2f} s)" if mt is not None else ")")
    facts = [f"{row.sampler} case {row.index}", f"origin {row.origin}", f"seed {row.seed}",
             f"simulated in {row.sim_time_s:.2f} s"]
    if row.driver:
        from ..sim.drivers.identity import identity_text

        facts.append(f"driver {identity_text(row.driver)}")
    if mode:
        facts.append(f"failure mode {mode}")
    if row.flaky:
        facts.append("FLAKY: a replay with the same seed did not fail the same way")
    if row.unavoidable:
        facts.append("unavoidable: the reference driver violates it too (case as found)")
    if row.minimized_avoidable and all(v is False for v in row.minimized_avoidable.values()):
        facts.append("minimized case unavoidable: the reference driver violates it too")
    parts.append(f"<p class='bad'>{e(what)}</p><p class='meta'>{e(' · '.join(facts))}</p>")
    if row.error and violated:
        parts.append(f"<p class='meta'>The body said: {e(row.error)}</p>")
    parts.append("<h2>Metrics</h2>")
    parts.append(_metric_table(row, metrics))
    parts.append("<p class='meta'>ρ: robustness in the metric's unit (≥ 0 holds, &lt; 0 violated by that much); "
                 "first violation: the first moment the requirement was already violated (worst at: the "
                 "moment of its worst value, when later); agent: the other road user involved.</p>")
    if row.score is not None:
        parts.append(_score_block(row.score))
    parts.append("<h2>Parameters</h2>")
    parts.append(_parameter_table(row, space))
    if row.minimized is not None:
        parts.append(f"<p class='meta'>Minimized in {row.shrink_sims or 0} simulations: the smallest "
                     "departure from the nominal scenario that still fails the same way (changed values in colour).</p>")
    parts.append("<h2>Pin it, run it again</h2>")
    pinned = row.minimized if row.minimized is not None else row.params
    parts.append("<p>Above the test, to run it first in every run:</p>")
    parts.append(f"<pre class='example'>from pytest_avscenario import example\n\n{e(example_line(pinned))}</pre>")
    if rerun:
        parts.append("<p>Re-run just this case:</p>")
        parts.append(f"<pre class='rerun'>{e(rerun)}</pre>")
    parts.append("<h2>Drawn during the run</h2>")
    parts.append(_draws_table(row.drawn))
    pictures = [(kind, files.get(kind)) for kind in FILE_CAPTIONS]
    pictures = [(k, p) for k, p in pictures if p]
    recording = None
    if files.get("recording") and player is not None:
        try:
            recording = json.loads(Path(files.get("recording")).read_text())
        except (OSError, ValueError):
            recording = None
    if pictures or recording is not None:
        parts.append("<h2>What happened</h2>")
        # the pictures and the recording are drawn from the minimized case when there is one
        # (the one an engineer studies), which may meet another agent than the case as found
        which = "minimized case" if row.minimized is not None else "case as found"
        if row.minimized is not None:
            parts.append("<p class='meta'>The replay and the pictures show the <b>minimized case</b> "
                         f"({e(', '.join(f'{k}={fmt_value(v)}' for k, v in row.minimized.items()))}), "
                         "not the case as found; the metrics table says where each violated first.</p>")
        if recording is not None:
            parts.append(f"<h3>Replay ({e(which)})</h3>")  # the page's word for the player
            parts.append(player(recording, row))
        for kind, path in pictures:
            link = href(directory, path)
            caption = f"{FILE_CAPTIONS[kind]} ({which})"
            parts.append(f"<figure><a href='{link}'><img src='{link}' alt='{e(caption)}: {e(row.item)}'></a>"
                         f"<figcaption>{e(caption)}</figcaption></figure>")
    parts.append(_exports_html(directory, row, files))
    for title, body in sections:
        parts.append(f"<h2>{e(title)}</h2>")
        parts.append(f"<div class='team-section'>{body}</div>")
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"

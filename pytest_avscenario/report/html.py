"""``index.html``: the report directory's front page, opened straight from the file system.

After a run an engineer (or a CI artifact viewer) opens ``avs-report/index.html``: the paper's
table with a legend for every column, then per test its plots, its failure modes and a short
table of its counterexamples, each linked to a card page of its own (:mod:`.cards`). The
page is one static file with inline CSS and relative links — no server, no network, no
external fonts or scripts — so it works from a zip of the artifact too. A few lines of inline
script only report, on the page, whether every picture loaded (a broken link shows instead
of silently missing). Every piece of text — test ids, parameter values, file names — is
HTML-escaped, and link targets are URL-quoted: node ids routinely contain ``<``, ``&``, ``"``.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Mapping, Sequence

from .cards import PAGE_CSS as _CSS, e as _e, href as _href
from .summary import DASH, SummaryRow, metric_columns, short_names, table_cells
from .table import atomic_write_text

__all__ = ["write_index", "render_index", "mode_table", "mode_labels", "INDEX"]

INDEX = "index.html"

# Reports on the page (and in the DOM, for automated checks) whether every picture decoded.
_SCRIPT = """
window.addEventListener("load", function () {
  var imgs = document.querySelectorAll("img"), ok = 0;
  imgs.forEach(function (img) {
    var good = img.complete && img.naturalWidth > 0;
    img.setAttribute("data-loaded", good ? "yes" : "no");
    if (good) { ok += 1; }
  });
  var status = document.getElementById("image-status");
  status.textContent = ok + " of " + imgs.length + " pictures loaded";
  status.setAttribute("data-loaded", ok + "/" + imgs.length);
  if (ok !== imgs.length) { status.className = "broken"; }
});
"""


#: what each column of the summary table means (metric columns are explained in one line)
COLUMN_LEGEND = {
    "test": "the scenario test (its function name; the full node id heads its section below)",
    "sampler": "how its cases were chosen: halton (space-filling), or an active sampler that hunts failures "
               "(mab, ce, sa, bo, random); replay / example / pinned: regression cases run first",
    "samples": "cases of the campaign that were simulated and judged",
    "ε": "ε-coverage of the continuous parameters scaled to [0, 1] (unit-cube distance; smaller: "
         "the samples leave no big hole): the smallest ε such that every point of a mesh lies within ε of a sample",
    "cex": "counterexamples: cases that violated a metric or failed the test body",
    "min": "counterexamples minimized (shrunk to the smallest departure from the nominal scenario)",
    "unavoid": "counterexamples the reference driver fails too, in the same conflict (unavoidable for a driver of its standard)",
    "modes": "failure modes: groups of counterexamples with the same first violated metric and agent, "
             "near each other in parameter space (each test's section lists them with their rules)",
    "errors": "cases that could not be judged (an exception, a timeout, no trajectory)",
    "sim s": "simulation time of the campaign's cases [s] (CPU time in the processes that ran them)",
    "verdict": "the campaign against its acceptance criteria (accepted / REJECTED; — : not judged)",
    "mesh r": "the mesh's covering radius: the largest distance from a mesh point to its nearest sample "
              "(a cross-check of ε)",
    "covered": "the share of the unit cube within the given radius of a sample",
}


def _summary_table(summary: Sequence[SummaryRow]) -> str:
    if not summary:
        return "<p class='meta'>No scenario cases ran.</p>"
    header, body = table_cells(summary)
    header = header + ["mesh r", "covered"]
    metrics = metric_columns(summary)
    n_metrics = len(metrics)
    first_metric = 3
    if "verdict" in header:
        # the verdict right after test and sampler: on screen without scrolling sideways
        v = header.index("verdict")
        header.insert(2, header.pop(v))
        body = [[*cells[:2], cells[v], *cells[2:v], *cells[v + 1:]] for cells in body]
        first_metric = 4
    out = ["<div class='wide'><table id='summary'>",
           "<thead><tr>" + "".join(f"<th>{_e(h)}</th>" for h in header) + "</tr></thead>", "<tbody>"]
    names = short_names([s.test for s in summary])
    for s, cells in zip(summary, body):
        cover = DASH if s.covering_radius is None else f"{s.covering_radius:.3f}"
        frac = DASH if s.fraction_within is None else f"{100 * s.fraction_within:.1f}% within {s.within_radius:g}"
        tds = []
        for i, cell in enumerate(cells + [cover, frac]):
            h = header[i]
            cls = "num" if i >= 2 and h != "verdict" else ""
            if first_metric <= i < first_metric + n_metrics and cell not in ("0", DASH):
                cls += " bad"  # a violated metric should catch the eye
            if h == "verdict":
                cls = "verdict bad" if cell == "REJECTED" else "verdict good" if cell == "accepted" else "verdict"
            if i == 0:
                cell_html = f"<a href='#{_anchor(s.test)}' title='{_e(s.test)}'>{_e(names[s.test])}</a>"
            else:
                cell_html = _e(cell)
            tds.append(f"<td class='{cls.strip()}'>{cell_html}</td>" if cls else f"<td>{cell_html}</td>")
        out.append("<tr>" + "".join(tds) + "</tr>")
    out.append("</tbody></table></div>")
    legend = ["<dl class='legend' id='legend'>"]
    for h in header:
        if h in COLUMN_LEGEND:
            legend.append(f"<dt>{_e(h)}</dt><dd>{_e(COLUMN_LEGEND[h])}</dd>")
    if metrics:
        legend.append(f"<dt>{_e(', '.join(header[first_metric:first_metric + n_metrics]))}</dt><dd>cases of the campaign that "
                      "violated that metric (its robustness ρ &lt; 0)</dd>")
    legend.append("</dl>")
    out.append("\n".join(legend))
    return "\n".join(out)


def mode_labels(campaigns: Sequence[SummaryRow]) -> dict[str, str]:
    """``{item id: mode label}`` of one test's counterexamples: ``M1``, or ``halton M1`` when
    more than one of the test's campaigns has modes (each campaign numbers its own)."""
    with_modes = [s for s in campaigns if s.modes]
    qualify = len(with_modes) > 1
    return {item: f"{s.sampler} {m.id}" if qualify else m.id
            for s in with_modes for m in s.modes for item in m.items}


def mode_anchor(test: str, sampler: str, mode_id: str) -> str:
    """The id of a mode's row in the index (``m-<test slug>-<sampler>-M1``)."""
    import re

    return f"m-{_anchor(test)[2:]}-{re.sub(r'[^A-Za-z0-9_-]+', '_', sampler)}-{mode_id}"


def mode_table(directory: Path, campaigns: Sequence[SummaryRow], rows: Sequence[Any]) -> str:
    """A test's failure modes: per mode its metrics, agent, count and share, rule, how well the
    rule separates it (precision), and a representative counterexample linked to its card."""
    from .cards import card_name

    with_modes = [s for s in campaigns if s.modes]
    if not with_modes:
        return ""
    by_item = {r.item: r for r in rows if r.origin != "shrink"}
    labels = mode_labels(campaigns)
    n = sum(len(s.modes) for s in with_modes)
    out = [f"<h3>{n} failure mode{'s' if n != 1 else ''}</h3>",
           "<div class='wide'><table class='modes'><thead><tr><th>mode</th><th>violated</th><th>agent</th>"
           "<th>cases</th><th>where (rule over the parameters)</th><th>precision</th>"
           "<th>representative</th></tr></thead><tbody>"]
    for s in with_modes:
        for m in s.modes:
            label = labels.get(m.items[0], m.id) if m.items else m.id
            rep = by_item.get(m.representative)
            name = m.representative.partition("[")[2].rstrip("]") or m.representative
            link = (f"<a href='{_href(directory, Path('cases') / card_name(rep))}'>{_e(name)}</a>"
                    if rep is not None else _e(name))
            how = "the cases' bounding box" if m.kind == "box" else "a rule separating them from the passing cases"
            precision = f"{100 * m.precision:.0f}%" if m.bounds else DASH
            outside = f" ({m.count - m.inside} outside the rule)" if m.bounds and m.inside < m.count else ""
            also = ""
            if m.also:
                also = " <span class='meta'>(also " + _e(", ".join(f"{k} in {v}" for k, v in m.also.items())) + ")</span>"
            out.append(
                f"<tr id='{mode_anchor(s.test, s.sampler, m.id)}'><td>{_e(label)}</td>"
                f"<td>{_e(', '.join(m.metrics) or 'assertion')}{also}</td><td>{_e(m.agent or DASH)}</td>"
                f"<td class='num'>{m.count} ({100 * m.share:.0f}%)</td>"
                f"<td title='{_e(how)}'><code>{_e(m.rule)}</code>{_e(outside)}</td>"
                f"<td class='num'>{precision}</td><td>{link}</td></tr>")
    out.append("</tbody></table></div>")
    out.append("<p class='meta'>violated: the metric that groups the mode's cases (the first one they violate, "
               "in priority order) and any others all of them violate · cases: the mode's counterexamples "
               "(share of the campaign's) · precision: of the campaign's cases inside the rule, the share "
               "violating that metric · representative: the counterexample nearest the centre of the "
               "mode's cases</p>")
    return "\n".join(out)


def run_verdict(summary: Sequence[SummaryRow]) -> str:
    """The run's verdict at the top of the page: accepted or rejected, how many campaigns, and
    each rejected campaign with its reasons, linked to its test's section."""
    if not summary:
        return ""
    judged = [s for s in summary if s.verdict is not None]
    rejected = [s for s in judged if s.verdict == "rejected"]
    errors = sum(s.errors for s in summary)
    names = short_names([s.test for s in summary])
    n = len(summary)
    if not judged:
        head, cls = "NOT JUDGED", "meta"
        text = f"no acceptance criteria were judged for the {n} campaign{'s' if n != 1 else ''}"
    elif rejected or errors:
        head, cls = "REJECTED", "bad"
        text = f"{len(rejected)} of {n} campaign{'s' if n != 1 else ''} rejected"
    else:
        head, cls = "ACCEPTED", "good"
        text = f"all {n} campaign{'s' if n != 1 else ''} accepted"
    if errors:
        text += f"; {errors} case{'s' if errors != 1 else ''} could not be judged (errors)"
    out = [f"<div id='run-verdict' class='run-verdict {cls}' data-verdict='{head.lower()}'>"
           f"<span class='head'>Verdict: {head}</span> — {_e(text)}</div>"]
    if rejected:
        items = [f"<li><a href='#{_anchor(s.test)}' title='{_e(s.test)}'>{_e(names[s.test])}</a> "
                 f"[{_e(s.sampler)}]: {_e('; '.join(s.reasons or ()))}</li>" for s in rejected]
        shown, rest = items[:10], items[10:]
        out.append("<ul id='rejected'>" + "".join(shown) + "</ul>")
        if rest:
            out.append(f"<details><summary>{len(rest)} more rejected campaign{'s' if len(rest) != 1 else ''}"
                       f"</summary><ul>{''.join(rest)}</ul></details>")
    return "\n".join(out)


def _anchor(test: str) -> str:
    from .table import file_slug

    return "t-" + file_slug(test)


def render_index(
    directory: str | os.PathLike,
    summary_rows: Sequence[SummaryRow],
    images: Mapping[str, Mapping[str, str | os.PathLike] | Sequence[str | os.PathLike]],
    tables: Mapping[str, Sequence[str | os.PathLike]],
    *,
    title: str = "avscenario report",
    meta: Mapping[str, Any] | None = None,
    sections: Mapping[str, Sequence[str]] | None = None,
    banner: str | None = None,
    preamble: Sequence[str] = (),
) -> str:
    """The page's HTML text (see :func:`write_index` for the arguments)."""
    directory = Path(directory)
    parts = [
        "<!DOCTYPE html>",
        "<html lang='en'><head><meta charset='utf-8'>",
        f"<title>{_e(title)}</title>",
        f"<style>{_CSS}</style>",
        f"<script>{_SCRIPT}</script>",
        "</head><body>",
        f"<h1>{_e(title)}</h1>",
    ]
    if meta:
        parts.append("<p class='meta'>" + " · ".join(f"{_e(k)}: {_e(v)}" for k, v in meta.items()) + "</p>")
    if banner:
        parts.append(f"<p class='banner'>{banner}</p>")
    parts.append(run_verdict(summary_rows))
    parts.append("<p id='image-status' class='meta'></p>")
    parts.extend(preamble)
    if preamble:  # the table is this run's, not part of what came before it
        parts.append("<h2>This run</h2>")
    parts.append(_summary_table(summary_rows))
    general = tables.get("", ())
    if general:
        parts.append("<p>Tables: " + ", ".join(
            f"<a href='{_href(directory, p)}'>{_e(Path(p).name)}</a>" for p in general) + "</p>")
    sections = sections or {}
    tests = list(dict.fromkeys([*(s.test for s in summary_rows), *images, *(t for t in tables if t), *sections]))
    for test in tests:
        parts.append(f"<section id='{_anchor(test)}'><h2>{_e(test)}</h2>")
        links = tables.get(test, ())
        if links:
            parts.append("<p>Error table: " + ", ".join(
                f"<a href='{_href(directory, p)}'>{_e(Path(p).name)}</a>" for p in links) + "</p>")
        pics = images.get(test, {})
        items = pics.items() if isinstance(pics, Mapping) else ((Path(p).stem, p) for p in pics)
        for caption, path in items:
            href = _href(directory, path)
            parts.append(
                f"<figure><a href='{href}'><img src='{href}' alt='{_e(caption)}: {_e(test)}'></a>"
                f"<figcaption>{_e(caption)}</figcaption></figure>"
            )
        parts.extend(sections.get(test, ()))
        parts.append("</section>")
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"


def write_index(
    directory: str | os.PathLike,
    summary_rows: Sequence[SummaryRow],
    images: Mapping[str, Mapping[str, str | os.PathLike] | Sequence[str | os.PathLike]],
    tables: Mapping[str, Sequence[str | os.PathLike]],
    *,
    title: str = "avscenario report",
    meta: Mapping[str, Any] | None = None,
    sections: Mapping[str, Sequence[str]] | None = None,
    banner: str | None = None,
    preamble: Sequence[str] = (),
) -> Path:
    """Write ``<directory>/index.html`` atomically and return its path.

    ``summary_rows``: from :func:`.summary.summarize`. ``images``: ``{test: {caption: png}}``
    (e.g. the dict :func:`.plots.plot_test` returns) or ``{test: [png, …]}``. ``tables``:
    ``{test: [csv, …]}`` (e.g. :meth:`.table.ErrorTable.tables`), with key ``""`` for files
    of the whole run (``errors.jsonl``, ``shrink.jsonl``, ``summary.json``). Paths may be
    absolute or relative to ``directory``; links are written relative, so the directory can
    be moved or zipped. ``meta``: a line of run facts (seed, versions, date). ``sections``:
    more HTML per test (failure modes, the counterexamples), after its pictures; ``banner``
    an HTML line at the top (a re-run's); ``preamble`` HTML before the table.
    """
    directory = Path(directory)
    text = render_index(directory, summary_rows, images, tables, title=title, meta=meta,
                        sections=sections, banner=banner, preamble=preamble)
    path = directory / INDEX
    atomic_write_text(path, text)
    return path

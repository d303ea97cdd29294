"""``index.html``: the report directory's front page, opened straight from the file system.

After a run an engineer (or a CI artifact viewer) opens ``avs-report/index.html``: the paper's
table with ε and its cross-checks, then per test its pictures and links to its tables. The
page is one static file with inline CSS and relative links — no server, no network, no
external fonts or scripts — so it works from a zip of the artifact too. A few lines of inline
script only report, on the page, whether every picture loaded (a broken link shows instead
of silently missing). Every piece of text — test ids, parameter values, file names — is
HTML-escaped, and link targets are URL-quoted: node ids routinely contain ``<``, ``&``, ``"``.
"""

from __future__ import annotations

import html
import os
from pathlib import Path
from typing import Any, Mapping, Sequence
from urllib.parse import quote

from .summary import DASH, SummaryRow, metric_columns, table_cells
from .table import atomic_write_text

__all__ = ["write_index", "render_index", "INDEX"]

INDEX = "index.html"

_CSS = """
body { font: 14px/1.45 system-ui, -apple-system, "Segoe UI", sans-serif; margin: 1.5em 2em; color: #222; }
h1 { font-size: 1.4em; margin-bottom: .2em; }
h2 { font-size: 1.15em; margin-top: 2em; border-bottom: 1px solid #ddd; word-break: break-all; }
table { border-collapse: collapse; margin: .8em 0; }
th, td { border: 1px solid #ccc; padding: .25em .6em; }
th { background: #f3f3f3; white-space: nowrap; }
td.num { text-align: right; white-space: nowrap; font-variant-numeric: tabular-nums; }
td.bad { color: #b33c00; font-weight: 600; }
.meta { color: #666; }
figure { display: inline-block; margin: .5em 1em .5em 0; vertical-align: top; }
figure img { max-width: 720px; width: 100%; border: 1px solid #eee; }
figcaption { color: #666; font-size: .9em; }
#image-status.broken { color: #b33c00; font-weight: 600; }
"""

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


def _e(value: Any) -> str:
    return html.escape(str(value), quote=True)


def _href(directory: Path, path: str | os.PathLike) -> str:
    p = Path(path)
    rel = os.path.relpath(p if p.is_absolute() else directory / p, directory)
    # Forward slashes and percent-quoting give a link that works from file:// on any OS.
    return quote(Path(rel).as_posix(), safe="/")


def _summary_table(summary: Sequence[SummaryRow]) -> str:
    if not summary:
        return "<p class='meta'>No scenario cases ran.</p>"
    header, body = table_cells(summary)
    header = header + ["mesh r", "covered"]
    out = ["<table id='summary'>", "<thead><tr>" + "".join(f"<th>{_e(h)}</th>" for h in header) + "</tr></thead>", "<tbody>"]
    n_metrics = len(metric_columns(summary))
    for s, cells in zip(summary, body):
        cover = DASH if s.covering_radius is None else f"{s.covering_radius:.3f}"
        frac = DASH if s.fraction_within is None else f"{100 * s.fraction_within:.1f}% within {s.within_radius:g}"
        tds = []
        for i, cell in enumerate(cells + [cover, frac]):
            cls = "num" if i >= 2 else ""
            if 3 <= i < 3 + n_metrics and cell not in ("0", DASH):
                cls += " bad"  # a violated metric should catch the eye
            tds.append(f"<td class='{cls.strip()}'>{_e(cell)}</td>" if cls else f"<td>{_e(cell)}</td>")
        out.append("<tr>" + "".join(tds) + "</tr>")
    out.append("</tbody></table>")
    return "\n".join(out)


def render_index(
    directory: str | os.PathLike,
    summary_rows: Sequence[SummaryRow],
    images: Mapping[str, Mapping[str, str | os.PathLike] | Sequence[str | os.PathLike]],
    tables: Mapping[str, Sequence[str | os.PathLike]],
    *,
    title: str = "avscenario report",
    meta: Mapping[str, Any] | None = None,
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
    parts.append("<p id='image-status' class='meta'></p>")
    parts.append(_summary_table(summary_rows))
    general = tables.get("", ())
    if general:
        parts.append("<p>Tables: " + ", ".join(
            f"<a href='{_href(directory, p)}'>{_e(Path(p).name)}</a>" for p in general) + "</p>")
    tests = list(dict.fromkeys([*(s.test for s in summary_rows), *images, *(t for t in tables if t)]))
    for test in tests:
        parts.append(f"<section><h2>{_e(test)}</h2>")
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
) -> Path:
    """Write ``<directory>/index.html`` atomically and return its path.

    ``summary_rows``: from :func:`.summary.summarize`. ``images``: ``{test: {caption: png}}``
    (e.g. the dict :func:`.plots.plot_test` returns) or ``{test: [png, …]}``. ``tables``:
    ``{test: [csv, …]}`` (e.g. :meth:`.table.ErrorTable.tables`), with key ``""`` for files
    of the whole run (``errors.jsonl``, ``shrink.jsonl``, ``summary.json``). Paths may be
    absolute or relative to ``directory``; links are written relative, so the directory can
    be moved or zipped. ``meta``: a line of run facts (seed, versions, date).
    """
    directory = Path(directory)
    text = render_index(directory, summary_rows, images, tables, title=title, meta=meta)
    path = directory / INDEX
    atomic_write_text(path, text)
    return path

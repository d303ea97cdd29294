"""Pictures of a falsification run: where the failures are, and how robustness evolved.

Two PNGs per scenario test, drawn from its error-table rows:

* the sampled feature space as pairwise 2-D projections of its parameters (a scatter
  matrix) — the paper's point plots, showing at a glance which region of (gap, speed, brake
  time) breaks the AV: passing cases light blue, failing ones coloured by the metric they
  violated first, errored grey; one marker shape per sampler; a minimized counterexample is
  a black star joined to the case it was found at; axes carry the parameters' units;
* ρ per metric over the sample index, one panel per metric with the ρ = 0 boundary, so one
  sees an active sampler closing in on failures (ρ falling) or a passive one spreading out.

matplotlib is imported inside the functions and only through its object-oriented API with
the Agg canvas (no pyplot, no global backend switch), so loading the plugin never pays for
it and a user's own matplotlib state is untouched. Files are written atomically.
"""

from __future__ import annotations

import io
import math
import os
from pathlib import Path
from typing import Any, Mapping, Sequence

from ..outcome import CaseRow

from .table import atomic_write_bytes, file_slug

__all__ = ["plot_feature_space", "plot_rho_over_index", "plot_test", "plot_kind", "plot_paths", "PLOTS_DIR",
           "PLOT_KINDS"]

PLOTS_DIR = "plots"

# Colour-blind-safe pair (blue / vermillion) plus grey for cases that did not simulate.
_COLOURS = {"pass": "#0072B2", "fail": "#D55E00", "error": "#999999"}
# failing cases by the metric violated first (Okabe-Ito's colours after blue, then more)
_METRIC_COLOURS = ("#D55E00", "#E69F00", "#CC79A7", "#009E73", "#F0E442", "#56B4E9", "#8C1515",
                   "#6A3D9A", "#B15928", "#000000")
_PASS_SPACE = "#9ec5e8"
_SAMPLER_MARKERS = {"halton": "o", "mab": "^", "ce": "s", "sa": "D", "bo": "P", "random": "X",
                    "replay": "*", "example": "*", "pinned": "*"}
_OTHER_MARKERS = ("v", "<", ">", "h", "p", "8")
_MAX_PARAMS = 6  # 15 panels; more would make each panel too small to read


def _figure(width_in: float, height_in: float):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    # No layout engine: constrained/tight layout measure every tick label and cost seconds
    # on a scatter matrix; fixed margins (set by each plot) cost nothing.
    fig = Figure(figsize=(width_in, height_in), dpi=100)
    FigureCanvasAgg(fig)
    return fig


def _save(fig, path: str | os.PathLike, colors: int = 128, durable: bool = True) -> Path:
    """Write ``fig`` as a palette PNG of ``colors`` colours, atomically (``durable``: see
    :func:`.folder.atomic_write_bytes`)."""
    from PIL import Image

    # the canvas's own RGBA pixels, as savefig would write them (the figure's facecolour, its
    # dpi): not encoded to a PNG and decoded again, which cost ~15 % of drawing a plot
    canvas = fig.canvas
    canvas.draw()
    width, height = canvas.get_width_height(physical=True)
    pixels = Image.frombuffer("RGBA", (width, height), canvas.buffer_rgba(), "raw", "RGBA", 0, 1)
    # a plot has few colours: a 128-colour palette keeps them and makes the file ~3x smaller
    # (the report of the example suite has a few dozen such plots)
    small = io.BytesIO()
    pixels.convert("RGB").quantize(colors=colors, method=Image.Quantize.MEDIANCUT).save(
        small, format="PNG", optimize=True)
    atomic_write_bytes(path, small.getvalue(), durable=durable)
    return Path(path)


def _is_number(v: Any) -> bool:
    if not isinstance(v, (int, float)) or isinstance(v, bool):
        return False
    try:
        return math.isfinite(float(v))
    except OverflowError:  # an int beyond float range (Choice([10**400, 1])): not drawable as a number
        return False


def _label(v: Any, max_len: int = 24) -> str:
    text = str(v)
    if len(text) <= max_len:
        return text
    if isinstance(v, int) and not isinstance(v, bool):
        digits = text.lstrip("-")
        return f"{text[:len(text) - len(digits)]}{digits[0]}.{digits[1:4]}e+{len(digits) - 1}"
    return text[:max_len - 1] + "…"


def _axis_values(rows: Sequence[Mapping[str, Any]], name: str):
    """Numbers to plot for one parameter, and tick labels when it is categorical."""
    values = [r.params.get(name) for r in rows]
    if all(_is_number(v) for v in values):
        numbers = [float(v) for v in values]
        scale = _axis_scale(numbers)  # once: per value it made the plot O(n²) (#32 item 6)
        return [x / scale for x in numbers], None
    # Categorical (or mixed): position by first appearance, label with the value itself.
    first: dict[str, Any] = {}
    for v in values:
        first.setdefault(str(v), v)
    position = {k: i for i, k in enumerate(first)}
    labels = [_label(v) for v in first.values()]
    # A small deterministic jitter keeps cases with the same category from hiding each other.
    jitter = [((i * 0.6180339887) % 1.0 - 0.5) * 0.3 for i in range(len(values))]
    return [position[str(v)] + j for v, j in zip(values, jitter)], labels


#: beyond this magnitude matplotlib cannot lay out ticks (their spacing overflows)
_AXIS_MAX = 1e150


def _axis_scale(numbers: Sequence[float]) -> float:
    """1, or the power of ten the axis is divided by when its numbers are too large to draw."""
    import math

    finite = [abs(x) for x in numbers if math.isfinite(x)]
    top = max(finite, default=0.0)
    return 1.0 if top <= _AXIS_MAX else 10.0 ** math.floor(math.log10(top))


def _axis_name(rows: Sequence[Mapping[str, Any]], name: str, unit: str | None = None) -> str:
    values = [r.params.get(name) for r in rows]
    if not all(_is_number(v) for v in values):
        return name
    scale = _axis_scale([float(v) for v in values])
    label = name if scale == 1.0 else f"{name} (×{scale:.0e})"
    return f"{label} [{unit}]" if unit else label


def first_violated(row: CaseRow, metrics: Sequence[str] | None = None) -> str | None:
    """The metric ``row`` violated first: the earliest by its violation time, else the first
    violated in ``metrics`` order (else in the row's)."""
    violated = [m for m, v in row.rho.items() if v is not None and v < 0]
    if not violated:
        return None
    times = {m: (row.violations or {}).get(m, {}).get("t") for m in violated}
    order = list(metrics or ()) + [m for m in row.rho if m not in (metrics or ())]
    return min(violated, key=lambda m: (times[m] is None, times[m] or 0.0, order.index(m) if m in order else 0))


def _point_groups(rows: Sequence[CaseRow], metrics: Sequence[str] | None):
    """(label, marker, colour, indexes, failing) per sampler and outcome, passing first."""
    samplers = list(dict.fromkeys(r.sampler if r.origin == "sampled" else r.origin for r in rows))
    extra = iter(_OTHER_MARKERS * 4)
    markers = {s: _SAMPLER_MARKERS.get(s) or next(extra, "o") for s in samplers}
    firsts = [first_violated(r, metrics) if r.verdict == "fail" else None for r in rows]
    named = list(dict.fromkeys([*(metrics or ()), *(f for f in firsts if f)]))
    colour = {m: _METRIC_COLOURS[i % len(_METRIC_COLOURS)] for i, m in enumerate(named)}
    groups = []
    for outcome in ("pass", "error", "fail"):
        for s in samplers:
            idx = [i for i, r in enumerate(rows) if r.verdict == outcome
                   and (r.sampler if r.origin == "sampled" else r.origin) == s]
            if not idx:
                continue
            if outcome != "fail":
                c = _PASS_SPACE if outcome == "pass" else _COLOURS["error"]
                groups.append((f"{s}: {outcome} ({len(idx)})", markers[s], c, idx, False))
                continue
            by_metric: dict[str, list[int]] = {}
            for i in idx:
                by_metric.setdefault(firsts[i] or "body failed", []).append(i)
            for m, ids in by_metric.items():
                c = colour.get(m, _COLOURS["fail"])
                groups.append((f"{s}: fail, {m} first ({len(ids)})", markers[s], c, ids, True))
    return groups


def _minimized_values(rows: Sequence[CaseRow], name: str, plotted) -> dict[int, float]:
    """Plot positions of the minimized values of ``name`` (numbers only; categories by label)."""
    values, labels = plotted
    out: dict[int, float] = {}
    numbers = [float(r.params.get(name)) for r in rows if _is_number(r.params.get(name))]
    scale = _axis_scale(numbers) if numbers else 1.0
    keys: dict[str, int] | None = None  # a category's position, made once (per row: O(n²))
    for i, r in enumerate(rows):
        if not r.minimized or name not in r.minimized:
            continue
        v = r.minimized[name]
        if labels is None and _is_number(v):
            out[i] = float(v) / scale
        elif labels is not None:
            if keys is None:
                keys = {k: j for j, k in enumerate(dict.fromkeys(str(r2.params.get(name)) for r2 in rows))}
            if str(v) in keys:
                out[i] = float(keys[str(v)])  # no jitter: the category's own line
            else:
                out[i] = values[i]
    return out


def _varying(rows: Sequence[Mapping[str, Any]], names: Sequence[str]) -> list[str]:
    # A parameter that never changes (a constant) is a wasted row and column of panels.
    return [n for n in names if len({repr(r.params.get(n)) for r in rows}) > 1]


def plot_feature_space(
    path: str | os.PathLike,
    rows: Sequence[Mapping[str, Any]],
    params: Sequence[str] | None = None,
    *,
    title: str | None = None,
    metrics: Sequence[str] | None = None,
    units: Mapping[str, str] | None = None,
) -> Path | None:
    """Pairwise projections of the sampled cases; returns the PNG path.

    Passing cases are light blue, failing ones coloured by the metric they violated first
    (in ``metrics`` order when the rows do not say when), errors grey; each sampler has its
    marker; a minimized counterexample is a black star joined to where it was found.
    ``units``: ``{parameter: unit}`` for the axis labels.

    ``params`` chooses and orders the parameters (default: every parameter that varies, in
    the rows' order, at most six). One parameter gives a strip plot over the case index.
    Returns None (and writes nothing) when there are no rows or no varying parameter.
    """
    rows = [CaseRow.coerce(r) for r in rows]
    if not rows:
        return None
    names = list(params) if params is not None else list(rows[0].params)
    names = _varying(rows, names)[:_MAX_PARAMS]
    if not names:
        return None
    cols = {n: _axis_values(rows, n) for n in names}
    k = len(names)
    size = 2.6 if k > 2 else 4.2
    n_panels = max(1, k - 1)
    fig = _figure(size * n_panels + 0.6, size * n_panels + 0.4 + (0.25 if k > 2 else 0))
    groups = _point_groups(rows, metrics)
    minimized = [(i, r) for i, r in enumerate(rows) if r.minimized]
    min_cols = {n: _minimized_values(rows, n, cols[n]) for n in names}

    def scatter(ax, xs, ys, xname=None, yname=None):
        # passing first, failures on top, so a failure is never hidden under passing cases
        for label, marker, colour, idx, filled in groups:
            ax.scatter([xs[i] for i in idx], [ys[i] for i in idx], s=16 if filled else 12,
                       alpha=1.0 if filled else 0.9, marker=marker, label=label, color=colour,
                       edgecolors="none")
        if xname is None or not minimized:
            return
        mx, my = min_cols[xname], min_cols[yname]
        for i, _ in minimized:
            if mx.get(i) is None or my.get(i) is None:
                continue
            ax.plot([xs[i], mx[i]], [ys[i], my[i]], color="black", lw=0.7, alpha=0.7)
            ax.scatter([mx[i]], [my[i]], s=55, marker="*", color="black", edgecolors="none",
                       label="minimized (joined to where found)")

    def label_axis(ax, which: str, name: str):
        _, labels = cols[name]
        getattr(ax, f"set_{which}label")(_axis_name(rows, name, (units or {}).get(name)))
        if labels is not None:
            getattr(ax, f"set_{which}ticks")(range(len(labels)))
            getattr(ax, f"set_{which}ticklabels")(labels)
            getattr(ax, f"set_{which}lim")(-0.5, len(labels) - 0.5)

    if k == 1:
        fig.subplots_adjust(left=0.16, right=0.97, bottom=0.12, top=0.9)
        ax = fig.add_subplot(1, 1, 1)
        xs = [float(r.index) for r in rows]
        scatter(ax, xs, cols[names[0]][0])
        ax.set_xlabel("case index")
        label_axis(ax, "y", names[0])
        ax.legend(loc="best", fontsize=8)
    else:
        # the title on the top line, the legend's row(s) under it, the panels below both
        top = 0.45 if k > 2 else 0.75
        grid = fig.add_gridspec(n_panels, n_panels, left=0.9 / fig.get_figwidth(), right=0.98,
                                bottom=0.7 / fig.get_figheight(), top=1 - top / fig.get_figheight(),
                                wspace=0.08, hspace=0.08)
        first = None
        for row_i in range(n_panels):
            for col_j in range(row_i + 1):  # lower triangle only: each pair once
                ax = fig.add_subplot(grid[row_i, col_j])
                first = first or ax
                yi, xj = row_i + 1, col_j
                scatter(ax, cols[names[xj]][0], cols[names[yi]][0], names[xj], names[yi])
                ax.locator_params(nbins=4)
                ax.tick_params(labelsize=7)
                if row_i == n_panels - 1:
                    label_axis(ax, "x", names[xj])
                else:
                    _hide_labels(ax, "x", cols[names[xj]][1])
                if col_j == 0:
                    label_axis(ax, "y", names[yi])
                else:
                    _hide_labels(ax, "y", cols[names[yi]][1])
        handles, labels = first.get_legend_handles_labels()
        unique = dict(zip(labels, handles))
        fig.legend(list(unique.values()), list(unique.keys()), loc="upper right", fontsize=8,
                   frameon=False, ncol=1 if k > 2 else 2,
                   bbox_to_anchor=(0.99, 1 - 0.3 / fig.get_figheight()))
    fig.suptitle(title or "sampled feature space", fontsize=10)
    return _save(fig, path)


def _hide_labels(ax, which: str, labels) -> None:
    # Inner panels share their neighbours' scales; their tick labels would only collide.
    if labels is not None:
        getattr(ax, f"set_{which}ticks")(range(len(labels)))
        getattr(ax, f"set_{which}lim")(-0.5, len(labels) - 0.5)
    getattr(ax, f"set_{which}ticklabels")([])


def _finite_limits(values: Sequence[float]) -> tuple[float, float]:
    finite = [v for v in values if v is not None and math.isfinite(v)]
    if not finite:
        return -1.0, 1.0
    lo, hi = min(finite + [0.0]), max(finite + [0.0])
    pad = 0.08 * (hi - lo) if hi > lo else 1.0
    return lo - pad, hi + pad


def plot_rho_over_index(
    path: str | os.PathLike,
    rows: Sequence[Mapping[str, Any]],
    metrics: Sequence[str] | None = None,
    *,
    title: str | None = None,
) -> Path | None:
    """ρ of each metric against the case index, one panel per metric; returns the PNG path.

    Samplers are told apart by marker shape; violations (ρ < 0) are red. ±inf values are
    drawn at the top or bottom edge of the panel as triangles (a value off the scale, not a
    missing one). Returns None when there is nothing to plot.
    """
    rows = sorted((r for r in map(CaseRow.coerce, rows) if r.rho), key=lambda r: (r.sampler, r.index))
    if not rows:
        return None
    if metrics is None:
        metrics = []
        for r in rows:
            metrics += [m for m in r.rho if m not in metrics]
    metrics = list(metrics)
    samplers = list(dict.fromkeys(r.sampler for r in rows))
    markers = dict(zip(samplers, "o s D v P X *".split() * 4))
    height = 1.9 * len(metrics) + 1.1
    fig = _figure(7.5, height)
    fig.subplots_adjust(left=0.11, right=0.98, top=1 - 0.4 / height, bottom=0.75 / height, hspace=0.12)
    axes = fig.subplots(len(metrics), 1, sharex=True, squeeze=False)
    for ax, metric in zip((a[0] for a in axes), metrics):
        lo, hi = _finite_limits([r.rho.get(metric) for r in rows])
        ax.axhline(0.0, color="black", linewidth=0.8)
        ax.axhspan(lo, 0.0, color=_COLOURS["fail"], alpha=0.06)
        for sampler in samplers:
            sub = [r for r in rows if r.sampler == sampler and r.rho.get(metric) is not None]
            xs = [r.index for r in sub]
            ys = [r.rho[metric] for r in sub]
            finite = [(x, y) for x, y in zip(xs, ys) if math.isfinite(y)]
            if finite:
                ax.plot([x for x, _ in finite], [y for _, y in finite], color="#bbbbbb", linewidth=0.6, zorder=1)
                ax.scatter([x for x, _ in finite], [y for _, y in finite], s=16, zorder=2,
                           marker=markers[sampler], edgecolors="none",
                           color=[_COLOURS["fail" if y < 0 else "pass"] for _, y in finite])
            for positive, edge, mark in ((True, hi, "^"), (False, lo, "v")):
                off = [x for x, y in zip(xs, ys) if math.isinf(y) and (y > 0) == positive]
                if off:
                    # Off the scale, drawn on the panel's edge: a value, not a missing one.
                    ax.scatter(off, [edge] * len(off), marker=mark, s=22, zorder=3, clip_on=False,
                               color=_COLOURS["pass" if positive else "fail"])
        ax.set_ylim(lo, hi)
        ax.set_ylabel(f"ρ {metric}", fontsize=9)
        ax.tick_params(labelsize=7)
        ax.locator_params(axis="y", nbins=5)
    fig.legend(handles=_rho_legend(samplers, markers, rows, metrics), loc="lower center",
               ncols=6, fontsize=7, frameon=False)
    axes[-1][0].set_xlabel("case index")
    fig.suptitle(title or "robustness per metric", fontsize=10)
    return _save(fig, path)


def _rho_legend(samplers, markers, rows, metrics):
    from matplotlib.lines import Line2D

    def handle(marker, colour, label):
        return Line2D([], [], linestyle="none", marker=marker, markersize=5, color=colour, label=label)

    out = [handle("o", _COLOURS["pass"], "ρ ≥ 0 holds"), handle("o", _COLOURS["fail"], "ρ < 0 violated")]
    values = [r.rho.get(m) for r in rows for m in metrics]
    if any(v is not None and v == math.inf for v in values):
        out.append(handle("^", _COLOURS["pass"], "+inf"))
    if any(v is not None and v == -math.inf for v in values):
        out.append(handle("v", _COLOURS["fail"], "-inf"))
    if len(samplers) > 1:
        # Shape, not colour, tells samplers apart: colour already means the verdict.
        out += [handle(markers[s], "#555555", s) for s in samplers]
    return out


def plot_paths(directory: str | os.PathLike, test: str) -> dict[str, Path]:
    """Where :func:`plot_test` draws the pictures of ``test``: ``{kind: path}``."""
    base = Path(directory) / PLOTS_DIR / file_slug(test)
    return {"space": Path(f"{base}.space.png"), "rho": Path(f"{base}.rho.png")}


def plot_test(
    directory: str | os.PathLike,
    test: str,
    rows: Sequence[Mapping[str, Any]],
    *,
    metrics: Sequence[str] | None = None,
    params: Sequence[str] | None = None,
    units: Mapping[str, str] | None = None,
) -> dict[str, Path]:
    """Both pictures of one test under ``<directory>/plots/``; returns ``{kind: path}``
    for the kinds written (``"space"``, ``"rho"``). Pass the test's main-table rows (not the
    shrink candidates, which crowd the failure region)."""
    out: dict[str, Path] = {}
    for kind in PLOT_KINDS:
        path = plot_kind(directory, test, rows, kind, metrics=metrics, params=params, units=units)
        if path is not None:
            out[kind] = path
    return out


#: the pictures :func:`plot_test` draws of a test, each on its own (:func:`plot_kind`)
PLOT_KINDS = ("space", "rho")


def plot_kind(
    directory: str | os.PathLike,
    test: str,
    rows: Sequence[Mapping[str, Any]],
    kind: str,
    *,
    metrics: Sequence[str] | None = None,
    params: Sequence[str] | None = None,
    units: Mapping[str, str] | None = None,
) -> Path | None:
    """One of :func:`plot_test`'s pictures (``kind`` in :data:`PLOT_KINDS`): its path, or
    None when there is nothing to draw."""
    path = plot_paths(directory, test)[kind]
    if kind == "space":
        return plot_feature_space(path, rows, params, title=f"{test}: sampled cases",
                                  metrics=metrics, units=units)
    if kind == "rho":
        return plot_rho_over_index(path, rows, metrics, title=f"{test}: ρ per metric")
    raise ValueError(f"no plot of kind {kind!r}: one of {PLOT_KINDS}")

"""The time series of one counterexample, as one matplotlib figure.

Three panels over the run's time [s]: the ego's speed [m/s] and acceleration [m/s²]; the
centre distance and the footprint gap [m] between the ego and the *critical agent* (the one
its first violation involved); and their time to collision [s]. The thresholds of the test's
distance and TTC monitors are drawn on their panels, and the first violation is marked on
every panel. When the recording holds the ego's decisions (``meta["decisions"]``: a discretely
deciding agent's actions, or its driver's reasons), a strip above the panels shows the decision
in force over time: one coloured span per decision from the moment it changed, its name written
in the span where it fits, and a legend naming every decision. Drawn from the trajectory alone (nothing here imports the simulator); matplotlib
is imported inside the function, through its object-oriented API only.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..monitors.evidence import case_evidence, critical_agent, threshold_lines
from ..trajectory import Trajectory

__all__ = ["critical_agent", "plot_case_timeseries", "decision_spans", "TTC_CAP_S"]

#: TTC above this [s] is drawn at the top of its panel (it is +inf when the pair recedes)
TTC_CAP_S = 10.0


#: colours of the decision strip, in order of first appearance (Okabe–Ito, then greys)
DECISION_COLOURS = ("#56B4E9", "#E69F00", "#009E73", "#F0E442", "#0072B2", "#D55E00", "#CC79A7",
                    "#999999", "#DDDDDD", "#666666")


def decision_spans(traj: Trajectory) -> list[tuple[float, float, str]]:
    """``(from [s], to [s], decision)`` of each decision in force during the run, from the
    recording's ``meta["decisions"]`` (changes only); ``[]`` when it holds none."""
    changes = [(float(t), str(label)) for t, label in ((traj.meta or {}).get("decisions") or {}).get("changes", ())]
    if not changes or traj.n_steps == 0:
        return []
    end = float(traj.t[-1])
    out = []
    for (t0, label), nxt in zip(changes, [*changes[1:], (end, "")]):
        t1 = min(nxt[0], end)
        if t1 > t0 or (t0 == t1 == end and not out):
            out.append((t0, t1, label))
    return out


def _short(label: str) -> str:
    """A continuous command's label shortened for the strip: ``a +0.3 δ -0.1``."""
    return label.replace("acceleration ", "a ").replace("steering ", "δ ").replace(",", "")


def _decision_strip(ax: Any, traj: Trajectory) -> None:
    spans = decision_spans(traj)
    source = ((traj.meta or {}).get("decisions") or {}).get("source", "action")
    colours: dict[str, str] = {}
    for _, _, label in spans:
        colours.setdefault(label, DECISION_COLOURS[len(colours) % len(DECISION_COLOURS)])
    renderer = ax.figure.canvas.get_renderer()
    box = ax.get_window_extent(renderer)
    t = traj.t
    px_per_s = box.width / max(float(t[-1] - t[0]), 1e-9)
    for t0, t1, label in spans:
        ax.axvspan(t0, t1, color=colours[label], lw=0)
        ax.axvline(t0, color="white", lw=1.0)  # where the decision changed
        text = ax.text((t0 + t1) / 2, 0.5, _short(label), ha="center", va="center", fontsize=7,
                       transform=ax.get_xaxis_transform(), clip_on=True)
        if text.get_window_extent(renderer).width + 4 > (t1 - t0) * px_per_s:
            text.remove()  # too narrow for its name: the legend names its colour
    ax.set_yticks([])
    ax.set_ylabel("decision" if source == "action" else "reason", rotation=0, ha="right", va="center",
                  fontsize=8)
    from matplotlib.patches import Patch

    handles = [Patch(color=c, label=_short(label)) for label, c in colours.items()]
    ax.legend(handles=handles, loc="lower left", bbox_to_anchor=(0.0, 1.02), ncol=min(len(handles), 5),
              fontsize=7, frameon=False, handlelength=1.0, columnspacing=1.0, borderaxespad=0.0)


def plot_case_timeseries(path: str | os.PathLike, traj: Trajectory, *, agent: str | None = None,
                         first_t: float | None = None, monitors: Sequence[Any] = (),
                         title: str | None = None) -> Path:
    """Write the case's time series to ``path`` (PNG) and return the path.

    ``agent``: the critical agent's name (default: the nearest to the ego at ``first_t``);
    ``first_t`` [s]: the first violation, marked; ``monitors``: the test's monitors, whose
    distance and TTC thresholds are drawn."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    t = traj.t
    decided = bool(decision_spans(traj))
    fig = Figure(figsize=(7.5, 7.0 if decided else 6.2), dpi=80)
    FigureCanvasAgg(fig)
    if decided:
        strip, *axes = fig.subplots(4, 1, sharex=True, gridspec_kw={"height_ratios": [0.35, 2, 2, 2]})
        fig.subplots_adjust(left=0.11, right=0.88, top=0.88, bottom=0.07, hspace=0.2)
        _decision_strip(strip, traj)
    else:
        strip = None
        axes = list(fig.subplots(3, 1, sharex=True))
        fig.subplots_adjust(left=0.11, right=0.88, top=0.92, bottom=0.08, hspace=0.18)
    speed = traj.speed[0]
    accel = np.gradient(speed, t) if traj.n_steps > 1 else np.zeros_like(speed)
    ax = axes[0]
    ax.plot(t, speed, color="#0072B2", lw=1.5, label="ego speed")
    ax.set_ylabel("speed [m/s]", color="#0072B2")
    twin = ax.twinx()
    twin.plot(t, accel, color="#E69F00", lw=1.0, label="ego acceleration")
    twin.axhline(0.0, color="#E69F00", lw=0.5, alpha=0.5)
    twin.set_ylabel("acceleration [m/s²]", color="#E69F00")
    evidence = case_evidence(traj, monitors, agent=agent, t=first_t)
    k = evidence.critical
    name = traj.names[k] if k is not None else None
    if k is not None:
        dist, gap, ttc = evidence.distance_m, evidence.gap_m, evidence.ttc_s
        axes[1].plot(t, np.where(np.isfinite(dist), dist, np.nan), color="#009E73", lw=1.5,
                     label=f"centre distance to {name}")
        axes[1].plot(t, np.where(np.isfinite(gap), gap, np.nan), color="#CC79A7", lw=1.2,
                     label=f"footprint gap to {name}")
        axes[2].plot(t, np.clip(np.where(np.isnan(ttc), np.inf, ttc), 0.0, TTC_CAP_S), color="#D55E00",
                     lw=1.5, label=f"TTC with {name} (≥ {TTC_CAP_S:g} s drawn at the top)")
        axes[2].set_ylim(-0.3, TTC_CAP_S + 0.5)
    for quantity, threshold, label in threshold_lines(monitors):
        axes[1 if quantity == "distance" else 2].axhline(threshold, color="black", ls="--", lw=0.9, label=label)
    axes[1].set_ylabel("distance [m]")
    axes[2].set_ylabel("TTC [s]")
    axes[2].set_xlabel("time [s]")
    if strip is not None and first_t is not None:
        strip.axvline(first_t, color="#b30000", lw=1.2, alpha=0.8)
    for ax in axes:
        if first_t is not None:
            ax.axvline(first_t, color="#b30000", lw=1.2, alpha=0.8)
        ax.grid(alpha=0.25)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="upper right", fontsize=7, framealpha=0.8)
    if first_t is not None:
        axes[0].annotate(f"first violation {first_t:.2f} s", xy=(first_t, 1.0), xycoords=("data", "axes fraction"),
                         xytext=(3, -12), textcoords="offset points", color="#b30000", fontsize=8)
    fig.suptitle(title or f"ego and {name or 'no other agent'}", fontsize=9)
    from .plots import _save

    return _save(fig, path, colors=64, durable=False)  # one of many per-case files

"""Multi-objective monitoring: several monitors evaluated together, with a priority order.

A :class:`MonitorSet` turns one trajectory into a :class:`Verdict` — every member's result and
the vector of rho — and carries a priority order between its members (a ranked list, or a
small DAG of ``(higher, lower)`` edges). The multi-armed bandit sampler uses the order to
rank violation patterns (violating a higher-priority metric matters more). The overall
verdict fails when any member is violated; a member that cannot give a verdict (NaN, a
raising user function) makes the whole evaluation a :class:`MonitorError` naming it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from ..trajectory import Trajectory
from .base import Monitor, MonitorError, MonitorResult, as_monitor

__all__ = ["MonitorSet", "Verdict"]


@dataclass(frozen=True)
class Verdict:
    """Results of a :class:`MonitorSet` on one trajectory, in the set's member order."""

    results: Mapping[str, MonitorResult]

    @property
    def rho(self) -> dict[str, float]:
        """``{name: rho}`` in member order."""
        return {n: r.rho for n, r in self.results.items()}

    @property
    def violated(self) -> list[str]:
        """Names of the violated members (rho < 0), in member order."""
        return [n for n, r in self.results.items() if r.rho < 0]

    @property
    def ok(self) -> bool:
        return not self.violated

    @property
    def vector(self) -> np.ndarray:
        """rho as a float array in member order."""
        return np.array([r.rho for r in self.results.values()], dtype=float)

    @property
    def worst(self) -> MonitorResult | None:
        """The member with the smallest rho (None for an empty set)."""
        return min(self.results.values(), key=lambda r: r.rho, default=None)

    def to_json(self) -> dict[str, Any]:
        return {"ok": self.ok, "violated": self.violated,
                "results": {n: r.to_json() for n, r in self.results.items()}}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> "Verdict":
        return cls({n: MonitorResult.from_json(r) for n, r in data["results"].items()})


class MonitorSet:
    """Several monitors with unique names and an optional priority order.

    ``monitors``: monitors or plain functions ``trajectory -> float`` (see
    :func:`as_monitor`). ``priority``: None (unordered), a list of names highest first (need
    not name every member), or a list of ``(higher, lower)`` name pairs forming a DAG.
    Unknown names, duplicates and cycles raise :class:`MonitorError` naming the monitor.
    """

    def __init__(self, monitors: Iterable[Any], priority: Sequence[Any] | None = None):
        if isinstance(monitors, (Monitor, str)) or callable(monitors):
            monitors = [monitors]
        self.monitors: tuple[Monitor, ...] = tuple(as_monitor(m) for m in monitors)
        seen: set[str] = set()
        for m in self.monitors:
            if m.name in seen:
                raise MonitorError(
                    f"two monitors are named {m.name!r}; names must be unique in a set — "
                    f"rename one with .named('...') (e.g. distance(2.0, name='distance_2m'))"
                )
            seen.add(m.name)
        self.names: tuple[str, ...] = tuple(m.name for m in self.monitors)
        self.priority_edges: tuple[tuple[str, str], ...] = self._edges(priority)
        self.priority_order: tuple[str, ...] = self._toposort()

    # -- priority --------------------------------------------------------------------------
    def _edges(self, priority: Sequence[Any] | None) -> tuple[tuple[str, str], ...]:
        if priority is None:
            return ()
        if isinstance(priority, str) or not isinstance(priority, Sequence):
            raise MonitorError(
                f"priority must be a list of monitor names (highest first) or of "
                f"(higher, lower) pairs, got {priority!r}"
            )
        items = list(priority)
        if all(isinstance(p, str) for p in items):
            dup = {p for p in items if items.count(p) > 1}
            if dup:
                raise MonitorError(f"priority lists monitor {sorted(dup)[0]!r} more than once")
            for p in items:
                self._known(p)
            return tuple(zip(items, items[1:]))
        edges = []
        for e in items:
            if isinstance(e, str) or not isinstance(e, Sequence) or len(e) != 2 \
                    or not all(isinstance(n, str) for n in e):
                raise MonitorError(
                    f"priority entry {e!r} is neither a monitor name nor a (higher, lower) pair; "
                    "give a list of names or a list of pairs, not a mix"
                )
            hi, lo = self._known(e[0]), self._known(e[1])
            if hi == lo:
                raise MonitorError(f"priority edge ({hi!r}, {lo!r}) ranks monitor {hi!r} above itself")
            if (hi, lo) not in edges:
                edges.append((hi, lo))
        return tuple(edges)

    def _known(self, name: str) -> str:
        if name not in self.names:
            raise MonitorError(
                f"priority names monitor {name!r}, which is not in the set; members: "
                f"{', '.join(self.names) or '(none)'}"
            )
        return name

    def _toposort(self) -> tuple[str, ...]:
        """Kahn's algorithm, ties broken by member order; a cycle is an error naming it."""
        indeg = {n: 0 for n in self.names}
        out: dict[str, list[str]] = {n: [] for n in self.names}
        for hi, lo in self.priority_edges:
            out[hi].append(lo)
            indeg[lo] += 1
        order: list[str] = []
        ready = [n for n in self.names if indeg[n] == 0]
        while ready:
            n = ready.pop(0)
            order.append(n)
            for m in out[n]:
                indeg[m] -= 1
                if indeg[m] == 0:
                    ready.append(m)
            ready.sort(key=self.names.index)
        if len(order) < len(self.names):
            stuck = [n for n in self.names if n not in order]
            raise MonitorError(
                f"priority edges form a cycle through monitor {stuck[0]!r} "
                f"(involving {', '.join(repr(s) for s in stuck)})"
            )
        return tuple(order)

    def rank(self) -> dict[str, int]:
        """Priority level per member: 0 for members nothing ranks above, else 1 + the
        largest level of the members ranked directly above it."""
        level = {n: 0 for n in self.names}
        for n in self.priority_order:
            for hi, lo in self.priority_edges:
                if hi == n:
                    level[lo] = max(level[lo], level[n] + 1)
        return level

    # -- evaluation --------------------------------------------------------------------------
    def evaluate(self, trajectory: Trajectory) -> Verdict:
        """Evaluate every member; MonitorError naming the member if one cannot give a verdict."""
        results: dict[str, MonitorResult] = {}
        for m in self.monitors:
            try:
                results[m.name] = m.evaluate(trajectory)
            except MonitorError as exc:
                msg = str(exc)
                if repr(m.name) not in msg:
                    msg = f"monitor {m.name!r}: {msg}"
                raise MonitorError(msg) from exc
            except Exception as exc:
                raise MonitorError(
                    f"monitor {m.name!r} raised {type(exc).__name__}: {exc}"
                ) from exc
        return Verdict(results)

    def __len__(self) -> int:
        return len(self.monitors)

    def __iter__(self):
        return iter(self.monitors)

    def __repr__(self) -> str:
        pri = f", priority={list(self.priority_edges)}" if self.priority_edges else ""
        return f"MonitorSet({list(self.names)}{pri})"

"""Priority orders over metrics and the dominance of violation patterns (multi-objective mode).

A monitor set can rank its metrics ("a collision matters more than slow progress"). After
Viswanadha et al., RV'21, a sampled case's *violation pattern* is the set of metrics it
violates, and pattern ``p`` is better than ``q`` when every metric that ``q`` violates and
``p`` does not is outranked by some metric that ``p`` violates and ``q`` does not. With no
order this is plain set inclusion; with a total order it is lexicographic. Patterns are sets of
metric *names*: they never depend on the order in which a graph happens to be traversed (the
reference implementation indexes them by DFS position, which mixes up metrics as soon as the
traversal order differs from the declaration order).
"""

from __future__ import annotations

from typing import Any, Iterable, Sequence

from .errors import SamplerError

Pattern = frozenset  # frozenset[str]: the metrics a case violates


class PriorityOrder:
    """A strict partial order over metric names, given as a DAG of (higher, lower) edges."""

    def __init__(self, metrics: Sequence[str], edges: Iterable[tuple[str, str]] = ()):
        self.metrics: tuple[str, ...] = tuple(metrics)
        self.edges: tuple[tuple[str, str], ...] = tuple(edges)
        children: dict[str, set[str]] = {m: set() for m in self.metrics}
        for hi, lo in self.edges:
            children[hi].add(lo)
        _check_acyclic(self.metrics, children)
        # transitive closure: below[m] = every metric m outranks
        self.below: dict[str, frozenset[str]] = {}
        for m in self.metrics:
            seen: set[str] = set()
            stack = list(children[m])
            while stack:
                x = stack.pop()
                if x not in seen:
                    seen.add(x)
                    stack.extend(children[x])
            self.below[m] = frozenset(seen)
        # level = length of the longest chain above a metric (0 for the top-ranked ones)
        self.level: dict[str, int] = {}
        for m in _topological(self.metrics, children):
            self.level.setdefault(m, 0)
            for c in children[m]:
                self.level[c] = max(self.level.get(c, 0), self.level[m] + 1)

    @classmethod
    def parse(cls, priority: Any, metrics: Sequence[str] | None = None) -> "PriorityOrder":
        """Read ``priority`` (names highest first, or ``(higher, lower)`` pairs) and check it.

        ``metrics`` (optional) is the monitor set's metric names; when given, a name the order
        mentions must be one of them. Raises :class:`SamplerError` on unknown names, cycles or
        malformed input.
        """
        known = _check_names(metrics, "metrics") if metrics is not None else None
        if priority is None:
            return cls(known or ())
        if isinstance(priority, (str, bytes)) or not isinstance(priority, Iterable):
            raise SamplerError(
                "priority must be a list of metric names (highest first) or a list of "
                f"(higher, lower) pairs, got {priority!r}"
            )
        items = list(priority)
        edges: list[tuple[str, str]] = []
        names: list[str] = []
        if all(isinstance(x, str) for x in items):
            seen: set[str] = set()
            for x in items:
                if x in seen:
                    raise SamplerError(
                        f"priority lists metric {x!r} twice ({items!r}): that is a cycle"
                    )
                seen.add(x)
            names = items
            edges = list(zip(items, items[1:]))
        else:
            for e in items:
                if (isinstance(e, (str, bytes)) or not isinstance(e, Sequence) or len(e) != 2
                        or not all(isinstance(x, str) for x in e)):
                    raise SamplerError(
                        "priority must be a list of metric names (highest first) or a list of "
                        f"(higher, lower) pairs of names; {e!r} is neither"
                    )
                edges.append((e[0], e[1]))
                names.extend(e)
        if known is not None:
            unknown = [n for n in dict.fromkeys(names) if n not in known]
            if unknown:
                raise SamplerError(
                    f"priority names unknown metric(s) {unknown}; the monitors' metrics are "
                    f"{list(known)}"
                )
            all_names = list(known)
        else:
            all_names = list(dict.fromkeys(names))
        return cls(all_names, edges)

    def with_metric(self, name: str) -> "PriorityOrder":
        """The same order with one more (unranked) metric, seen first in a feedback mapping."""
        return PriorityOrder(self.metrics + (name,), self.edges)

    def outranks(self, a: str, b: str) -> bool:
        return b in self.below.get(a, ())

    def dominates(self, p: Pattern, q: Pattern) -> bool:
        """Is violation pattern ``p`` strictly better (more severe) than ``q``?"""
        if p == q:
            return False
        gained = p - q
        for m in q - p:
            if not any(m in self.below[h] for h in gained):
                return False
        return True

    def maximal(self, patterns: Iterable[Pattern]) -> list[Pattern]:
        """The patterns no other one dominates (the empty pattern is never a counterexample)."""
        ps = [p for p in dict.fromkeys(patterns) if p]
        return [p for p in ps if not any(self.dominates(o, p) for o in ps)]


def _check_names(names: Any, what: str) -> tuple[str, ...]:
    if isinstance(names, (str, bytes)) or not isinstance(names, Iterable):
        raise SamplerError(f"{what} must be a list of metric names, got {names!r}")
    out = tuple(names)
    for n in out:
        if not isinstance(n, str) or not n:
            raise SamplerError(f"{what} must be non-empty strings, got {n!r}")
    if len(set(out)) != len(out):
        raise SamplerError(f"{what} lists a metric twice: {list(out)!r}")
    return out


def _topological(metrics: Sequence[str], children: dict[str, set[str]]) -> list[str]:
    indeg = {m: 0 for m in metrics}
    for m in metrics:
        for c in children[m]:
            indeg[c] += 1
    order = [m for m in metrics if indeg[m] == 0]
    i = 0
    while i < len(order):
        for c in sorted(children[order[i]], key=metrics.index):
            indeg[c] -= 1
            if indeg[c] == 0:
                order.append(c)
        i += 1
    return order


def _check_acyclic(metrics: Sequence[str], children: dict[str, set[str]]) -> None:
    if len(_topological(metrics, children)) == len(metrics):
        return
    # name one cycle so the user sees what to fix
    color: dict[str, int] = {}
    path: list[str] = []

    def visit(m: str) -> list[str] | None:
        color[m] = 1
        path.append(m)
        for c in sorted(children[m]):
            if color.get(c) == 1:
                return path[path.index(c):] + [c]
            if c not in color:
                found = visit(c)
                if found:
                    return found
        color[m] = 2
        path.pop()
        return None

    for m in metrics:
        if m not in color:
            cyc = visit(m)
            if cyc:
                raise SamplerError(f"priority order has a cycle: {' > '.join(cyc)}")
    raise SamplerError("priority order has a cycle")  # pragma: no cover

"""Failure modes: a campaign's counterexamples grouped into a few readable kinds of failure.

Forty counterexamples of a following scenario are rarely forty different problems. An AV
engineer wants to read "12 cases: distance violated with the lead car, when
``gap < 14.2 m and lead_decel > 5.1 m/s²``" and look at one of them. :func:`failure_modes`
does that for one test × sampler campaign:

1. the failing cases are grouped by their first violated metric in priority order (the
   scenario's ``priority=``, else the monitor order) and the critical agent (the agent of
   that violation, from ``CaseRow.violations``); a failed assertion with no violated metric
   is a group of its own. A case that also violates later metrics stays with its first one:
   where two kinds of failure overlap, the overlap is not a third kind (the mode says which
   other metrics its cases violate too);
2. within a group, a shallow classification tree (CART, Gini impurity, depth ≤ 3; a few
   lines of numpy) separates the group's cases from the passing cases on the unit-cube
   coordinates of the parameters; sibling leaves of the same class are merged back; each
   leaf where the group's cases are the majority becomes a mode, its path the mode's rule
   (less the conditions it does not need to stay as pure), read as bounds in the
   parameter's own values and unit (``gap < 14.2 m``, ``weather in {wet, snow}``); a
   group's cases outside every such leaf join the nearest of its modes;
3. a group too small to split (fewer than :data:`MIN_SPLIT` cases, or no passing case to
   separate it from, or no leaf it dominates) is one mode, described by its bounding box on
   the parameters where the box is narrower than the campaign's cases.

Modes are ordered by count (``M1`` is the largest); at most ``max_modes`` are kept, and the
cases of a dropped mode join the nearest kept mode of their group, if any. Each mode has a
content ``key`` — metric, agent and the rule's parameters with their directions, not the
thresholds (for a box, metric and agent alone) — for :mod:`.compare` to tell new modes from
gone ones. It stays the same between runs whose trees split on the same parameters; with few
counterexamples another sample may split on others, and the comparison then lists the mode as
gone and a new one beside it (its rule shows whether they are the same failure). Everything is deterministic: the rows are
put in one order first, so the same rows give the same modes in whatever order they come.
Nothing here imports pytest or anything heavier than numpy.
"""

from __future__ import annotations

import collections.abc
import math
import operator
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from ..outcome import CaseRow

__all__ = ["FailureMode", "Bound", "failure_modes", "MAX_MODES", "MAX_DEPTH", "MIN_SPLIT"]

#: modes kept per campaign
MAX_MODES = 5
#: depth of the tree that separates a group from the passing cases (a rule has at most this
#: many conditions before they are merged per parameter)
MAX_DEPTH = 3
#: a group of fewer counterexamples is one mode (its bounding box), not split by a tree
MIN_SPLIT = 4
#: a bounding-box condition is shown only when the box spans less than this share of the
#: campaign's cases along that parameter (otherwise it says nothing)
_BOX_NARROW = 0.8

_SUPERSCRIPTS = {"^2": "²", "^3": "³", "^-1": "⁻¹", "^-2": "⁻²"}


@dataclass(frozen=True)
class Bound:
    """One parameter's condition in a mode's rule, in the parameter's own values.

    Numeric parameters (``kind`` continuous or integer): ``lo`` < value ≤ ``hi`` for a tree
    rule, ``lo`` ≤ value ≤ ``hi`` for a bounding box; ``None`` for an open side. Categorical
    parameters: value in ``values``. ``lo_u`` / ``hi_u`` / ``codes`` are the same condition
    on the sampler's coordinates (option indices for categorical ones), used to test cases.
    """

    parameter: str
    kind: str
    lo: float | int | None = None
    hi: float | int | None = None
    values: tuple[Any, ...] | None = None
    unit: str | None = None
    closed: bool = False  # a bounding box: both ends included
    lo_u: float | None = field(default=None, compare=False)
    hi_u: float | None = field(default=None, compare=False)
    codes: frozenset[int] | None = field(default=None, compare=False)

    @property
    def direction(self) -> str:
        """``<``, ``>``, ``<>`` (both sides) or ``in``: what the mode's key keeps of it."""
        if self.kind == "categorical":
            return "in"
        return {(True, False): ">", (False, True): "<", (True, True): "<>"}.get(
            (self.lo is not None, self.hi is not None), "")

    def text(self) -> str:
        """``gap < 14.2 m``, ``3.1 < lead_decel ≤ 5 m/s²``, ``lanes ≥ 2``, ``road in {wet, icy}``."""
        name, unit = self.parameter, _pretty_unit(self.unit)
        if self.kind == "categorical":
            return f"{name} in {{{', '.join(_fmt_option(v) for v in self.values or ())}}}"
        tail = f" {unit}" if unit else ""
        if self.kind == "integer":
            if self.lo is not None and self.hi is not None:
                return f"{name} = {self.lo}{tail}" if self.lo == self.hi else f"{self.lo} ≤ {name} ≤ {self.hi}{tail}"
            if self.lo is not None:
                return f"{name} ≥ {self.lo}{tail}"
            return f"{name} ≤ {self.hi}{tail}"
        lo_op, hi_op = ("≤", "≤") if self.closed else ("<", "<")
        if self.lo is not None and self.hi is not None:
            if self.closed and _fmt_number(self.lo) == _fmt_number(self.hi):  # one case's box
                return f"{name} = {_fmt_number(self.lo)}{tail}"
            return f"{_fmt_number(self.lo)} {lo_op} {name} {hi_op} {_fmt_number(self.hi)}{tail}"
        if self.lo is not None:
            return f"{name} {'≥' if self.closed else '>'} {_fmt_number(self.lo)}{tail}"
        return f"{name} {hi_op} {_fmt_number(self.hi)}{tail}"

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"parameter": self.parameter, "kind": self.kind}
        if self.kind == "categorical":
            out["values"] = list(self.values or ())
        else:
            out["lo"], out["hi"] = self.lo, self.hi
        if self.unit:
            out["unit"] = self.unit
        return out


@dataclass(frozen=True)
class FailureMode:
    """One kind of failure of a campaign.

    ``id``: ``M1``, ``M2``, … by decreasing count; ``key``: the content key that matches the
    same mode in another run; ``metrics``: the metrics every case of it violates, in priority
    order, the first one (its group's) first (empty for a failed assertion); ``also``: other
    metrics some of its cases violate, with how many; ``agent``: the critical agent (None
    when unknown); ``count``: its counterexamples, ``share`` of the campaign's; ``bounds``
    and ``rule``: where it happens; ``inside``: its counterexamples that satisfy the rule;
    ``precision``: of the campaign's judged cases satisfying the rule, the share violating
    the mode's first metric; ``recall``: of the group's counterexamples, the share satisfying
    the rule; ``representative``: the item id of the counterexample nearest the centre of
    the mode's cases; ``items``: every item id.
    """

    id: str
    key: str
    metrics: tuple[str, ...]
    agent: str | None
    count: int
    share: float
    bounds: tuple[Bound, ...]
    precision: float
    recall: float
    inside: int
    representative: str
    representative_params: Mapping[str, Any]
    items: tuple[str, ...]
    kind: str = "tree"  # "tree": a leaf of the tree; "box": a bounding box
    also: Mapping[str, int] = field(default_factory=dict)

    @property
    def rule(self) -> str:
        return " and ".join(b.text() for b in self.bounds) if self.bounds else "anywhere in the space"

    @property
    def what(self) -> str:
        """``distance with lead`` — the group, as one phrase."""
        metrics = ", ".join(self.metrics) or "assertion"
        return f"{metrics} with {self.agent}" if self.agent else metrics

    def to_json(self) -> dict[str, Any]:
        """The mode for ``summary.json``: everything but the list of items."""
        from ..codec import jsonable

        return {"id": self.id, "key": self.key, "metrics": list(self.metrics), "also": dict(self.also),
                "agent": self.agent,
                "count": self.count, "share": round(self.share, 6), "rule": self.rule,
                "bounds": [b.to_json() for b in self.bounds], "kind": self.kind,
                "inside": self.inside, "precision": round(self.precision, 6),
                "recall": round(self.recall, 6),
                "representative": {"item": self.representative,
                                   "params": jsonable(dict(self.representative_params))}}


# --------------------------------------------------------------------------- text


def _pretty_unit(unit: str | None) -> str:
    if not unit:
        return ""
    for plain, sup in _SUPERSCRIPTS.items():
        unit = unit.replace(plain, sup)
    return unit


def _fmt_number(x: float | int) -> str:
    if isinstance(x, int) or float(x).is_integer() and abs(x) < 1e6:
        return str(int(x))
    a = abs(float(x))
    if a >= 1000 or a < 0.01:
        return f"{x:.4g}"
    return f"{x:.3g}"


def _fmt_option(v: Any) -> str:
    return v if isinstance(v, str) else repr(v)


# --------------------------------------------------------------------------- the tree


def _gini_sum(n: np.ndarray | float, pos: np.ndarray | float) -> np.ndarray | float:
    """n · Gini impurity of a node with ``pos`` positives among ``n`` (0 for n = 0)."""
    n = np.asarray(n, dtype=float)
    pos = np.asarray(pos, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(n > 0, 2.0 * pos * (n - pos) / np.where(n > 0, n, 1.0), 0.0)
    return out


@dataclass
class _Node:
    idx: np.ndarray
    pos: int
    depth: int
    dim: int | None = None
    threshold: float | None = None  # numeric: left is x <= threshold
    left_codes: frozenset[int] | None = None  # categorical: left is code in left_codes
    left: "_Node | None" = None
    right: "_Node | None" = None

    @property
    def failing(self) -> bool:
        return 2 * self.pos >= len(self.idx) and self.pos > 0

    @property
    def leaf(self) -> bool:
        return self.left is None


def _best_split(X: np.ndarray, y: np.ndarray, idx: np.ndarray, categorical: np.ndarray
                ) -> tuple[float, int, float | None, frozenset[int] | None] | None:
    """The split of ``idx`` with the lowest summed Gini impurity, if it improves on none."""
    n = len(idx)
    yy = y[idx]
    pos = int(yy.sum())
    parent = float(_gini_sum(n, pos))
    best: tuple[float, int, float | None, frozenset[int] | None] | None = None
    for j in range(X.shape[1]):
        x = X[idx, j]
        if categorical[j]:
            codes = x.astype(int)
            uniq = np.unique(codes)
            if len(uniq) < 2:
                continue
            n_c = np.array([np.sum(codes == c) for c in uniq], dtype=float)
            p_c = np.array([np.sum(yy[codes == c]) for c in uniq], dtype=float)
            # binary target: the best subset split is a prefix of the codes ordered by rate
            order = np.lexsort((uniq, p_c / n_c))
            nl, pl = np.cumsum(n_c[order])[:-1], np.cumsum(p_c[order])[:-1]
            scores = _gini_sum(nl, pl) + _gini_sum(n - nl, pos - pl)
            k = int(np.argmin(scores))
            if best is None or scores[k] < best[0] - 1e-12:
                best = (float(scores[k]), j, None, frozenset(int(c) for c in uniq[order[:k + 1]]))
        else:
            order = np.argsort(x, kind="stable")
            xs, ys = x[order], yy[order]
            cut = np.nonzero(np.diff(xs) > 0)[0]  # split after position i
            if len(cut) == 0:
                continue
            cum = np.cumsum(ys)
            nl = cut + 1.0
            pl = cum[cut]
            scores = _gini_sum(nl, pl) + _gini_sum(n - nl, pos - pl)
            k = int(np.argmin(scores))
            if best is None or scores[k] < best[0] - 1e-12:
                i = cut[k]
                best = (float(scores[k]), j, float(0.5 * (xs[i] + xs[i + 1])), None)
    if best is None or best[0] >= parent - 1e-9:
        return None
    return best


def _grow(X: np.ndarray, y: np.ndarray, idx: np.ndarray, categorical: np.ndarray, depth: int,
          max_depth: int) -> _Node:
    node = _Node(idx=idx, pos=int(y[idx].sum()), depth=depth)
    if depth >= max_depth or node.pos in (0, len(idx)):
        return node
    split = _best_split(X, y, idx, categorical)
    if split is None:
        return node
    _, j, threshold, codes = split
    x = X[idx, j]
    go_left = np.isin(x.astype(int), list(codes)) if codes is not None else x <= threshold
    node.dim, node.threshold, node.left_codes = j, threshold, codes
    node.left = _grow(X, y, idx[go_left], categorical, depth + 1, max_depth)
    node.right = _grow(X, y, idx[~go_left], categorical, depth + 1, max_depth)
    # two leaves saying the same thing are one region
    if node.left.leaf and node.right.leaf and node.left.failing == node.right.failing:
        node.dim = node.threshold = node.left_codes = node.left = node.right = None
    return node


def _failing_leaves(node: _Node, path: tuple = ()) -> list[tuple[_Node, tuple]]:
    """(leaf, path) of each leaf the group dominates; a path is ((dim, op, value), …)."""
    if node.leaf:
        return [(node, path)] if node.failing else []
    j = node.dim
    if node.left_codes is not None:
        left, right = (j, "in", node.left_codes), (j, "not in", node.left_codes)
    else:
        left, right = (j, "<=", node.threshold), (j, ">", node.threshold)
    return _failing_leaves(node.left, path + (left,)) + _failing_leaves(node.right, path + (right,))


# --------------------------------------------------------------------------- regions


@dataclass(frozen=True)
class _Dim:
    name: str
    kind: str  # continuous, integer, categorical
    dist: Any


def _dims(space: Any) -> list[_Dim] | None:
    parameters = getattr(space, "parameters", None)
    dims = getattr(space, "dims", None)
    if not isinstance(parameters, Mapping) or dims is None:
        return None
    return [_Dim(d.name, d.kind, parameters[d.name]) for d in dims]


def _coordinates(dims: Sequence[_Dim], params: Mapping[str, Any]) -> np.ndarray | None:
    """Unit-cube coordinates of numeric parameters, option indices of categorical ones."""
    out = []
    try:
        for d in dims:
            value = params[d.name]
            out.append(float(d.dist.index(value)) if d.kind == "categorical" else float(d.dist.to_unit(value)))
    except (KeyError, ValueError, TypeError, ArithmeticError):
        return None
    x = np.array(out, dtype=float)
    return x if np.all(np.isfinite(x)) else None


def _path_bounds(dims: Sequence[_Dim], path: tuple, X: np.ndarray) -> list[Bound]:
    """A tree path as one bound per parameter, in declaration order."""
    lo: dict[int, float] = {}
    hi: dict[int, float] = {}
    codes: dict[int, frozenset[int]] = {}
    for j, op, value in path:
        if op == "<=":
            hi[j] = min(hi.get(j, math.inf), value)
        elif op == ">":
            lo[j] = max(lo.get(j, -math.inf), value)
        else:
            every = frozenset(range(dims[j].dist.n_values))
            inside = value if op == "in" else every - value
            codes[j] = codes.get(j, every) & inside
    out = []
    for j, d in enumerate(dims):
        if d.kind == "categorical":
            if j in codes:
                out.append(_categorical(d, codes[j]))
        elif j in lo or j in hi:
            out.append(_numeric(d, lo.get(j), hi.get(j), closed=False))
    return out


def _categorical(d: _Dim, codes: frozenset[int]) -> Bound:
    options = d.dist.options
    return Bound(d.name, "categorical", values=tuple(options[c] for c in sorted(codes)), unit=d.dist.unit,
                 codes=frozenset(codes))


def _numeric(d: _Dim, lo_u: float | None, hi_u: float | None, *, closed: bool) -> Bound:
    """A numeric bound from unit coordinates: a tree threshold lies between two cases'
    coordinates, a box's ends are cases' own coordinates."""
    lo = hi = None
    if d.kind == "integer":
        # value v sits at coordinate (v - lo + 0.5) / n, the centre of its stratum
        n, base = d.dist.n_values, d.dist.lo
        if closed:  # a box's ends are cases' own coordinates
            lo = None if lo_u is None else base + int(round(lo_u * n - 0.5))
            hi = None if hi_u is None else base + int(round(hi_u * n - 0.5))
        else:  # coordinate > lo_u, coordinate <= hi_u
            lo = None if lo_u is None else base + int(math.floor(lo_u * n - 0.5 + 1e-9)) + 1
            hi = None if hi_u is None else base + int(math.floor(hi_u * n - 0.5 + 1e-9))
    else:
        lo = None if lo_u is None else float(d.dist.from_unit(lo_u))
        hi = None if hi_u is None else float(d.dist.from_unit(hi_u))
    return Bound(d.name, d.kind, lo=lo, hi=hi, unit=d.dist.unit, closed=closed, lo_u=lo_u, hi_u=hi_u)


def _inside(bounds: Sequence[Bound], dims: Sequence[_Dim], X: np.ndarray) -> np.ndarray:
    """Which rows of ``X`` satisfy every bound."""
    ok = np.ones(len(X), dtype=bool)
    col = {d.name: j for j, d in enumerate(dims)}
    for b in bounds:
        x = X[:, col[b.parameter]]
        if b.codes is not None:
            ok &= np.isin(x.astype(int), list(b.codes))
            continue
        eps = 1e-12
        if b.lo_u is not None:
            ok &= (x >= b.lo_u - eps) if b.closed else (x > b.lo_u)
        if b.hi_u is not None:
            ok &= (x <= b.hi_u + eps)
    return ok


def _box_bounds(dims: Sequence[_Dim], Xg: np.ndarray, Xall: np.ndarray) -> list[Bound]:
    """The group's bounding box on the parameters where it is narrower than the campaign's."""
    out = []
    for j, d in enumerate(dims):
        if d.kind == "categorical":
            mine = frozenset(int(c) for c in np.unique(Xg[:, j]))
            seen = frozenset(int(c) for c in np.unique(Xall[:, j]))
            if mine < seen:
                out.append(_categorical(d, mine))
            continue
        lo_all, hi_all = float(Xall[:, j].min()), float(Xall[:, j].max())
        lo, hi = float(Xg[:, j].min()), float(Xg[:, j].max())
        span = hi_all - lo_all
        if span <= 0 or (hi - lo) >= _BOX_NARROW * span:
            continue
        # only the sides that actually cut something off
        cut_lo = lo > lo_all + 1e-12
        cut_hi = hi < hi_all - 1e-12
        if cut_lo or cut_hi:
            out.append(_numeric(d, lo if cut_lo else None, hi if cut_hi else None, closed=True))
    return out


def _distance_to(bounds: Sequence[Bound], dims: Sequence[_Dim], x: np.ndarray) -> float:
    """How far the point ``x`` lies outside a region (unit-cube distance; 1 per wrong option)."""
    col = {d.name: j for j, d in enumerate(dims)}
    total = 0.0
    for b in bounds:
        v = x[col[b.parameter]]
        if b.codes is not None:
            total += 0.0 if int(v) in b.codes else 1.0
            continue
        gap = 0.0
        if b.lo_u is not None and v < b.lo_u:
            gap = b.lo_u - v
        if b.hi_u is not None and v > b.hi_u:
            gap = v - b.hi_u
        total += gap * gap
    return math.sqrt(total)


def _purity(bounds: Sequence[Bound], dims: Sequence[_Dim], X: np.ndarray, mine: np.ndarray,
            passing: np.ndarray) -> tuple[float, int]:
    inside = _inside(bounds, dims, X)
    hits, misses = int((inside & mine).sum()), int((inside & passing).sum())
    return (hits / (hits + misses) if hits + misses else 0.0), hits


def _simplify(bounds: list[Bound], dims: Sequence[_Dim], X: np.ndarray, mine: np.ndarray,
              passing: np.ndarray, slack: float = 0.02) -> list[Bound]:
    """Drop the conditions a rule does not need: a tree path also carries the splits that
    parted it from a sibling region of the same group. A condition goes when without it the
    region is as pure as the tree's (group cases against passing cases, within ``slack``) and
    holds at least as many of the group's cases; the one whose removal leaves the purest rule
    first."""
    bounds = list(bounds)
    purity, hits = _purity(bounds, dims, X, mine, passing)
    while len(bounds) > 1:
        options = []
        for k in range(len(bounds)):
            rest = bounds[:k] + bounds[k + 1:]
            p, h = _purity(rest, dims, X, mine, passing)
            if p >= purity - slack and h >= hits:
                options.append((-p, k, rest, h))
        if not options:
            break
        _, _, bounds, hits = min(options, key=lambda o: (o[0], o[1]))
    return bounds


# --------------------------------------------------------------------------- modes


def _violated(row: CaseRow, priority: Sequence[str]) -> list[str]:
    """The row's violated metrics in priority order (undeclared ones after, in row order)."""
    violated = [m for m, v in row.rho.items() if v is not None and not math.isnan(v) and v < 0]
    rank = {m: i for i, m in enumerate(priority)}
    names = list(row.rho)
    return sorted(violated, key=lambda m: (rank.get(m, len(rank)), names.index(m)))


def _group_of(row: CaseRow, violated: Sequence[str]) -> tuple[str | None, str | None]:
    """(first violated metric, its agent); (None, None) for a failed assertion."""
    if not violated:
        return None, None
    where = (row.violations or {}).get(violated[0]) or {}
    return violated[0], None if where.get("agent") is None else str(where["agent"])


@dataclass
class _Draft:
    group: tuple[str | None, str | None]
    bounds: list[Bound]
    kind: str
    members: list[int]  # positions in the campaign's rows
    precision: float
    recall: float
    region: np.ndarray | None = None  # which placed cases satisfy the rule


def _mode_key(metric: str | None, agent: str | None, bounds: Sequence[Bound]) -> str:
    rule = ",".join(f"{b.parameter}{b.direction}" for b in bounds) or "*"
    return f"{metric or 'assertion'}|{agent or '-'}|{rule}"


def failure_modes(rows: Sequence[CaseRow | Mapping[str, Any]], space: Any = None,
                  metrics: Sequence[str] = (), *, max_modes: int = MAX_MODES,
                  max_depth: int = MAX_DEPTH) -> list[FailureMode]:
    """The failure modes of one test × sampler campaign.

    ``rows``: the campaign's error-table rows (shrink candidates and errors are left out
    here); ``space``: the test's :class:`~pytest_avscenario.space.FeatureSpace` (without it,
    the modes are the groups, with no rule); ``metrics``: the monitor names in priority
    order. Returns at most ``max_modes`` modes, the largest first.
    """
    rows = [r for r in map(CaseRow.coerce, rows) if r.origin != "shrink" and r.verdict in ("pass", "fail")]
    # one order whatever order the rows came in (under xdist: as workers finished), so that
    # ties in the tree and the representative fall the same way in every run
    # (origin, index, item) as three stable sorts, last key first: the same order without a
    # key tuple per row (100,000 rows: ~10 MB at once, at the end of the run's peak)
    for key in ("item", "index", "origin"):
        rows.sort(key=operator.attrgetter(key))
    failing = [i for i, r in enumerate(rows) if r.verdict == "fail"]
    if not failing:
        return []
    violated = {i: _violated(rows[i], metrics) for i in failing}
    groups: dict[tuple[str | None, str | None], list[int]] = {}
    for i in failing:
        groups.setdefault(_group_of(rows[i], violated[i]), []).append(i)

    dims = _dims(space)
    # the placed cases' coordinates filled into one array: an array per case (and a dict of
    # them) was ~0.5 KB a case at the end of the run (100,000 cases: ~50 MB at its peak)
    # and which row is which row of X in one array too: a dict of them was ~90 B a row
    slot = np.full(len(rows), -1, dtype=np.intp)
    X = np.zeros((0, len(dims or ())))
    if dims:
        X = np.empty((len(rows), len(dims)))
        n = 0
        for i, r in enumerate(rows):
            x = _coordinates(dims, r.params)
            if x is not None:
                X[n] = x
                slot[i] = n
                n += 1
        X = X[:n]
    placed = np.flatnonzero(slot >= 0)
    where = _Slots(slot)
    coords = _Placed(X, where)
    categorical = np.array([d.kind == "categorical" for d in dims or ()], dtype=bool)
    is_pass = np.fromiter((r.verdict == "pass" for r in rows), dtype=bool, count=len(rows))
    passing = is_pass[placed]

    def violates(metric: str | None) -> np.ndarray:
        """Which placed cases fail that way: violate ``metric`` (None: fail with none)."""
        out = np.zeros(len(rows), dtype=bool)
        for i, v in violated.items():
            out[i] = metric in v if metric else not v
        return out[placed]

    drafts: list[_Draft] = []
    for group, members in groups.items():
        in_space = [i for i in members if i in where]
        if not dims or not in_space:
            drafts.append(_Draft(group, [], "box", list(members), len(members) / max(len(rows), 1), 1.0))
            continue
        mine = np.zeros(len(placed), dtype=bool)
        mine[[where[i] for i in in_space]] = True
        train = np.nonzero(mine | passing)[0]
        found: list[tuple[list[Bound], str]] = []
        if len(in_space) >= MIN_SPLIT and passing.any():
            tree = _grow(X, mine.astype(int), train, categorical, 0, max_depth)
            found = []
            for _, path in _failing_leaves(tree):
                bounds = _simplify(_path_bounds(dims, path, X), dims, X, mine, passing)
                if bounds and all(bounds != other for other, _ in found):
                    found.append((bounds, "tree"))
        if not found:
            found = [(_box_bounds(dims, X[mine], X), "box")]
        regions = [_inside(b, dims, X) for b, _ in found]
        # each case of the group to the region that holds it, else the nearest
        assigned: list[list[int]] = [[] for _ in found]
        for i in in_space:
            x = X[where[i]]
            k = next((k for k, reg in enumerate(regions) if reg[where[i]]), None)
            if k is None:
                k = min(range(len(found)), key=lambda k: (_distance_to(found[k][0], dims, x), k))
            assigned[k].append(i)
        outside = [i for i in members if i not in where]
        if outside:  # parameters that do not fit the space: with the group's largest mode
            assigned[max(range(len(found)), key=lambda k: (len(assigned[k]), -k))].extend(outside)
        same_way = violates(group[0])
        for (bounds, kind), reg, items in zip(found, regions, assigned):
            if not items:
                continue
            n_in = int(reg.sum())
            hits = int((reg & mine).sum())
            drafts.append(_Draft(group, bounds, kind, sorted(items),
                                 int((reg & same_way).sum()) / n_in if n_in else 0.0, hits / len(in_space), reg))

    drafts.sort(key=lambda d: (-len(d.members), _mode_key(*d.group, d.bounds)))
    kept, dropped = drafts[:max_modes], drafts[max_modes:]
    for d in dropped:  # to the nearest kept mode of the same group, if there is one
        same = [k for k in kept if k.group == d.group]
        if not same:
            continue
        for i in d.members:
            x = X[where[i]] if i in where else None
            target = same[0] if x is None else min(same, key=lambda k: _distance_to(k.bounds, dims or [], x))
            target.members.append(i)
    for d in kept:
        d.members.sort()
    kept.sort(key=lambda d: (-len(d.members), _mode_key(*d.group, d.bounds)))

    n_fail = len(failing)
    out = []
    keys: dict[str, int] = {}
    for n, d in enumerate(kept, 1):
        # a box (a group too small to split) is bounded by whatever cases it happened to
        # hold: its key is its group's alone, so the same few failures match between runs
        key = _mode_key(*d.group, d.bounds) if d.kind != "box" else _mode_key(*d.group, ()).replace("|*", "|box")
        keys[key] = keys.get(key, 0) + 1
        if keys[key] > 1:
            key += f"#{keys[key]}"
        rep = _representative(d.members, coords)
        inside = len(d.members) if d.region is None else \
            sum(1 for i in d.members if i in where and d.region[where[i]])
        every = [m for m in violated[d.members[0]] if all(m in violated[i] for i in d.members)]
        also: dict[str, int] = {}
        for i in d.members:
            for m in violated[i]:
                if m not in every:
                    also[m] = also.get(m, 0) + 1
        rank = {m: k for k, m in enumerate(metrics)}
        also = {m: also[m] for m in sorted(also, key=lambda m: (rank.get(m, len(rank)), m))}
        out.append(FailureMode(
            id=f"M{n}", key=key, metrics=tuple(every), also=also, agent=d.group[1], count=len(d.members),
            share=len(d.members) / n_fail, bounds=tuple(d.bounds), precision=d.precision,
            recall=d.recall, inside=inside, representative=rows[rep].item,
            representative_params=dict(rows[rep].params), items=tuple(rows[i].item for i in d.members),
            kind=d.kind))
    return out


class _Slots(collections.abc.Mapping):
    """Row index -> its row of the coordinates' array, for the rows placed (``slot`` >= 0)."""

    __slots__ = ("_slot",)

    def __init__(self, slot: np.ndarray):
        self._slot = slot

    def __getitem__(self, i: int) -> int:
        k = int(self._slot[i])
        if k < 0:
            raise KeyError(i)
        return k

    def __contains__(self, i: object) -> bool:
        return self._slot[i] >= 0

    def __iter__(self) -> Any:
        return iter(np.flatnonzero(self._slot >= 0).tolist())

    def __len__(self) -> int:
        return int(np.count_nonzero(self._slot >= 0))


class _Placed(collections.abc.Mapping):
    """Row index -> its coordinates (a row of ``X``), for the rows ``where`` places."""

    __slots__ = ("_X", "_where")

    def __init__(self, X: np.ndarray, where: Mapping[int, int]):
        self._X, self._where = X, where

    def __getitem__(self, i: int) -> np.ndarray:
        return self._X[self._where[i]]

    def __contains__(self, i: object) -> bool:
        return i in self._where

    def __iter__(self) -> Any:
        return iter(self._where)

    def __len__(self) -> int:
        return len(self._where)


def _representative(members: Sequence[int], coords: Mapping[int, np.ndarray]) -> int:
    """The member nearest the centre of the members' coordinates (the first on a tie)."""
    placed = [i for i in members if i in coords]
    if not placed:
        return members[0]
    P = np.vstack([coords[i] for i in placed])
    d = np.linalg.norm(P - P.mean(axis=0), axis=1)
    return placed[int(np.argmin(d))]


def mode_of_items(modes: Sequence[FailureMode]) -> dict[str, str]:
    """``{item id: mode id}`` for the counterexample table's "mode" column."""
    return {item: m.id for m in modes for item in m.items}

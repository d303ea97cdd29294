"""Signal temporal logic over trajectories: custom requirements as formulas.

Signals are per-step numbers read from a trajectory (the ego's speed, the gap to an agent,
a recorded signal, a user function); comparing one with a constant gives an atomic
predicate (``ego_speed() >= 5`` has robustness ``speed - 5``); :func:`always`,
:func:`eventually` (optionally within a time window [s]), :func:`until`, :func:`and_`,
:func:`or_`, :func:`not_` and :func:`implies` combine them with the standard quantitative
semantics on discrete time: always/and = min, eventually/or = max, not = negation, windows
cut at the end of the trace, an empty window gives +inf for always and -inf for eventually,
and ``phi until psi`` at step k is ``max over j in the window of min(psi(j), min over
k <= i < j of phi(i))`` (the semantics of RTAMT's discrete-time interpreter). A formula is a
:class:`Monitor`: its rho is the robustness at the first step, and its result names the
step and agent that decided it.

Time is the steps where the ego is present (absent steps are left out, not turned into NaN);
windows are in seconds of the trajectory's own time axis, so a non-uniform ``t`` works.
Every operator is a whole-array numpy computation: windowed min/max use a sparse table
(O(T log T)); until with an unbounded window an associative scan (O(T log T)), with a
bounded one a (T x window) matrix evaluated in row blocks.
"""

from __future__ import annotations

import math
import numbers
from typing import Any, Callable

import numpy as np

from ..trajectory import Trajectory
from .base import Monitor, MonitorError, MonitorResult, check_positive, check_threshold, factory
from .metrics import headway, pairwise_distance, pairwise_ttc, footprint_gap

__all__ = [
    "Signal", "Formula",
    "always", "eventually", "until", "and_", "or_", "not_", "implies",
    "ego_speed", "ego_acceleration", "lane_offset", "gap", "ttc_to", "headway_to", "signal",
    "predicate",
]

_EPS_T = 1e-9  # [s] tolerance when matching window bounds to sample times


# -- evaluation context -------------------------------------------------------------------------

class _Ctx:
    """One formula evaluation: the kept steps (ego present) and a memo of node series."""

    def __init__(self, traj: Trajectory):
        self.traj = traj
        self.steps = np.flatnonzero(traj.present[0])
        if self.steps.size == 0:
            raise MonitorError("the ego is never present in the trajectory")
        self.t = traj.t[self.steps]
        self.n = self.steps.size
        self.memo: dict[int, Any] = {}


# -- signals ------------------------------------------------------------------------------------

class Signal:
    """A per-step number read from a trajectory, with the agent it refers to per step.

    ``fn(trajectory) -> (values, agents)``: ``values`` shape ``(T,)``; ``agents`` an int
    array ``(T,)`` of agent indices (-1 for none) or None. Compare with a number or another
    signal to get a predicate; ``+``, ``-``, unary ``-``, ``*`` by a number and ``abs`` build
    new signals.
    """

    def __init__(self, name: str, fn: Callable[[Trajectory], tuple[np.ndarray, np.ndarray | None]]):
        self.name = name
        self._fn = fn

    def values(self, traj: Trajectory) -> tuple[np.ndarray, np.ndarray | None]:
        vals, agents = self._fn(traj)
        vals = np.asarray(vals, dtype=float)
        if vals.shape != (traj.n_steps,):
            raise MonitorError(
                f"signal {self.name!r} has shape {vals.shape}, expected ({traj.n_steps},) "
                "(one value per step)"
            )
        return vals, agents

    # comparisons make predicates; `5 <= s` reflects to `s >= 5`
    def __ge__(self, other: Any) -> "Formula":
        return _compare(self, ">=", other)

    def __gt__(self, other: Any) -> "Formula":
        return _compare(self, ">", other)

    def __le__(self, other: Any) -> "Formula":
        return _compare(self, "<=", other)

    def __lt__(self, other: Any) -> "Formula":
        return _compare(self, "<", other)

    def _combine(self, other: Any, op: str, f: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> "Signal":
        if isinstance(other, Signal):
            def fn(traj: Trajectory) -> tuple[np.ndarray, np.ndarray | None]:
                a, ia = self.values(traj)
                b, ib = other.values(traj)
                return f(a, b), _merge_agents(ia, ib)
            return Signal(f"({self.name} {op} {other.name})", fn)
        c = _const(other, f"{self.name} {op} ...")
        return Signal(f"({self.name} {op} {c:g})", lambda traj: _apply(self, traj, lambda a: f(a, c)))

    def __add__(self, other: Any) -> "Signal":
        return self._combine(other, "+", np.add)

    __radd__ = __add__

    def __sub__(self, other: Any) -> "Signal":
        return self._combine(other, "-", np.subtract)

    def __rsub__(self, other: Any) -> "Signal":
        return (-self)._combine(other, "+", np.add)

    def __mul__(self, other: Any) -> "Signal":
        c = _const(other, f"{self.name} * ...")
        return Signal(f"({c:g} * {self.name})", lambda traj: _apply(self, traj, lambda a: a * c))

    __rmul__ = __mul__

    def __neg__(self) -> "Signal":
        return Signal(f"-{self.name}", lambda traj: _apply(self, traj, np.negative))

    def __abs__(self) -> "Signal":
        return Signal(f"|{self.name}|", lambda traj: _apply(self, traj, np.abs))

    __hash__ = object.__hash__

    def __repr__(self) -> str:
        return f"<Signal {self.name}>"


def _apply(sig: Signal, traj: Trajectory, f: Callable[[np.ndarray], np.ndarray]):
    v, a = sig.values(traj)
    return f(v), a


def _merge_agents(a: np.ndarray | None, b: np.ndarray | None) -> np.ndarray | None:
    if a is None:
        return b
    if b is None:
        return a
    return np.where(a >= 0, a, b)


def _const(x: Any, where: str) -> float:
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, numbers.Real):
        raise MonitorError(f"{where}: expected a number or a signal, got {type(x).__name__}: {x!r:.60}")
    x = float(x)
    if math.isnan(x):
        raise MonitorError(f"{where}: the constant is NaN")
    return x


def _nearest(mat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Min over other agents of an ``(A-1, T)`` matrix, and which agent (index into names)."""
    if mat.shape[0] == 0:
        return np.full(mat.shape[1], np.inf), np.full(mat.shape[1], -1)
    row = np.argmin(mat, axis=0)
    vals = mat[row, np.arange(mat.shape[1])]
    return vals, np.where(np.isfinite(vals), row + 1, -1)


def _agent_row(traj: Trajectory, agent: str | int, mat: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray]:
    idx = traj.agent(agent).index if isinstance(agent, str) else int(agent)
    if not 1 <= idx < traj.n_agents:
        raise MonitorError(f"{what}: agent {agent!r} is not another agent of the trajectory "
                           f"(agents: {list(traj.names)})")
    return mat[idx - 1], np.full(traj.n_steps, idx)


def _pairwise_signal(name: str, agent: str | int | None,
                     compute: Callable[[Trajectory], np.ndarray]) -> Signal:
    def fn(traj: Trajectory) -> tuple[np.ndarray, np.ndarray]:
        mat = compute(traj)
        if agent is None:
            return _nearest(mat)
        try:
            return _agent_row(traj, agent, mat, name)
        except KeyError as exc:
            raise MonitorError(f"{name}: {exc.args[0]}") from None
    label = name if agent is None else f"{name}[{agent}]"
    return Signal(label, fn)


@factory
def ego_speed() -> Signal:
    """The ego's speed [m/s]."""
    return Signal("ego_speed", lambda traj: (traj.speed[0], None))


@factory
def ego_acceleration() -> Signal:
    """The ego's longitudinal acceleration [m/s²]: time derivative of its speed."""
    def fn(traj: Trajectory) -> tuple[np.ndarray, None]:
        if traj.n_steps < 2:
            return np.zeros(traj.n_steps), None
        return np.gradient(traj.speed[0], traj.t), None
    return Signal("ego_acceleration", fn)


@factory
def lane_offset() -> Signal:
    """The ego's distance [m] from its lane's centre line (``|lane_offset|``)."""
    return Signal("lane_offset", lambda traj: (np.abs(traj.lane_offset[0]), None))


@factory
def gap(agent: str | int | None = None, *, footprint: bool = False) -> Signal:
    """Distance [m] from the ego to ``agent`` (a name or index), or to the nearest other
    agent when None; centre distance, or footprint gap with ``footprint=True``. +inf where
    the agent is absent (it cannot be close)."""
    return _pairwise_signal("gap", agent, footprint_gap if footprint else pairwise_distance)


@factory
def ttc_to(agent: str | int | None = None, *, radius: float = 5.0) -> Signal:
    """Time to collision [s] of the ego with ``agent``, or the smallest over other agents;
    definition as in :func:`~pytest_avscenario.monitors.ttc` (+inf when not on a collision
    course or absent)."""
    radius = check_positive("ttc_to", radius, "radius")
    return _pairwise_signal("ttc", agent, lambda traj: pairwise_ttc(traj, radius))


@factory
def headway_to(agent: str | int | None = None) -> Signal:
    """Time headway [s] of the ego behind ``agent`` or the nearest vehicle ahead in its lane
    (see :func:`~pytest_avscenario.monitors.metrics.headway`); +inf when none is ahead."""
    return _pairwise_signal("headway", agent, headway)


@factory
def signal(source: str | Callable[[Trajectory], Any], name: str | None = None) -> Signal:
    """A signal from the trajectory's recorded ``signals[source]`` (a name), or from a user
    function ``trajectory -> array of shape (T,)``."""
    if isinstance(source, str):
        def from_rec(traj: Trajectory) -> tuple[np.ndarray, None]:
            if source not in traj.signals:
                raise MonitorError(f"the trajectory has no signal {source!r}; recorded: "
                                   f"{sorted(traj.signals) or 'none'}")
            return np.asarray(traj.signals[source], dtype=float), None
        return Signal(name or source, from_rec)
    if not callable(source):
        raise MonitorError(f"signal() takes a recorded signal name or a function "
                           f"trajectory -> array, got {type(source).__name__}")
    label = name or getattr(source, "__name__", "signal")
    return Signal("lambda" if label == "<lambda>" else label, lambda traj: (source(traj), None))


# -- formulas -----------------------------------------------------------------------------------

class Formula(Monitor):
    """An STL formula over a trajectory; as a monitor its rho is the robustness at step 0."""

    threshold = None

    def series(self, trajectory: Trajectory) -> tuple[np.ndarray, np.ndarray]:
        """Robustness at every kept step (ego present) and the times [s] of those steps."""
        ctx = _Ctx(trajectory)
        return self._series(ctx).copy(), ctx.t.copy()

    def _series(self, ctx: _Ctx) -> np.ndarray:
        key = id(self)
        if key not in ctx.memo:
            ctx.memo[key] = self._compute(ctx)
        return ctx.memo[key]

    def _compute(self, ctx: _Ctx) -> np.ndarray:
        raise NotImplementedError

    def _witness(self, ctx: _Ctx, k: int) -> tuple[int, int]:
        """(kept step, agent index or -1) that decided the robustness at kept step k."""
        return k, -1

    def _evaluate(self, traj: Trajectory) -> MonitorResult:
        try:
            ctx = _Ctx(traj)
        except MonitorError as exc:
            raise MonitorError(f"monitor {self.name!r}: {exc}") from None
        rho = float(self._series(ctx)[0])
        if math.isnan(rho):
            return MonitorResult(self.name, rho, None, None, None, "robustness is NaN")
        k, a = self._witness(ctx, 0)
        step = int(ctx.steps[k])
        who = traj.names[a] if a >= 0 else None
        t = float(traj.t[step])
        detail = f"{self.name}: rho {rho:.3g} decided at t={t:.2f} s" + (f" by {who}" if who else "")
        return MonitorResult(self.name, rho, None, t, who, detail)

    # sugar: a & b, a | b, ~a
    def __and__(self, other: "Formula") -> "Formula":
        return and_(self, other)

    def __or__(self, other: "Formula") -> "Formula":
        return or_(self, other)

    def __invert__(self) -> "Formula":
        return not_(self)

    def __repr__(self) -> str:
        return f"<Formula {self.name}>"


def _formula(x: Any, where: str) -> Formula:
    if isinstance(x, Formula):
        return x
    if isinstance(x, Signal):
        raise MonitorError(f"{where}: {x.name} is a signal, not a formula; compare it with a "
                           f"bound, e.g. {x.name} >= 5.0")
    if getattr(x, "_avs_monitor_factory", False):
        raise MonitorError(f"{where}: {x.__name__} is a factory; call it, e.g. {x.__name__}()")
    if isinstance(x, Monitor):
        raise MonitorError(f"{where}: monitor {x.name!r} gives one number per trajectory, not a "
                           "signal over time; use a signal comparison (e.g. gap() >= 5.0)")
    raise MonitorError(f"{where}: expected a formula (e.g. ego_speed() >= 5.0), got "
                       f"{type(x).__name__}: {x!r:.60}")


class _Predicate(Formula):
    def __init__(self, sig: Signal, op: str, rhs: Signal | float):
        self.sig, self.op, self.rhs = sig, op, rhs
        rname = rhs.name if isinstance(rhs, Signal) else f"{rhs:g}"
        self.name = f"{sig.name} {op} {rname}"

    def _compute(self, ctx: _Ctx) -> np.ndarray:
        diff = self.sig - self.rhs if isinstance(self.rhs, Signal) else self.sig - self.rhs
        v, agents = diff.values(ctx.traj)
        v = v[ctx.steps]
        bad = np.isnan(v)
        if bad.any():
            k = int(np.argmax(bad))
            raise MonitorError(f"signal in {self.name!r} is NaN at t={ctx.t[k]:.3f} s")
        ctx.memo[("agents", id(self))] = None if agents is None else np.asarray(agents)[ctx.steps]
        # ">" and ">=" share one robustness: the boundary case has rho 0 and counts as holding
        return v if self.op in (">=", ">") else -v

    def _witness(self, ctx: _Ctx, k: int) -> tuple[int, int]:
        self._series(ctx)
        agents = ctx.memo.get(("agents", id(self)))
        return k, (-1 if agents is None else int(agents[k]))


def _compare(sig: Signal, op: str, other: Any) -> Formula:
    if isinstance(other, Signal):
        return _Predicate(sig, op, other)
    return _Predicate(sig, op, _const(other, f"{sig.name} {op} ..."))


class _Func(Formula):
    def __init__(self, fn: Callable[[Trajectory], Any], name: str):
        self.fn, self.name = fn, name

    def _compute(self, ctx: _Ctx) -> np.ndarray:
        v = np.asarray(self.fn(ctx.traj), dtype=float)
        if v.shape != (ctx.traj.n_steps,):
            raise MonitorError(f"predicate {self.name!r} returned shape {v.shape}, expected "
                               f"({ctx.traj.n_steps},)")
        v = v[ctx.steps]
        if np.isnan(v).any():
            k = int(np.argmax(np.isnan(v)))
            raise MonitorError(f"predicate {self.name!r} is NaN at t={ctx.t[k]:.3f} s")
        return v


@factory
def predicate(fn: Callable[[Trajectory], Any], name: str | None = None) -> Formula:
    """An atomic formula from a user function ``trajectory -> robustness array (T,)``."""
    if not callable(fn):
        raise MonitorError(f"predicate() needs a function trajectory -> array, got {fn!r:.60}")
    label = name or getattr(fn, "__name__", "predicate")
    return _Func(fn, "lambda" if label == "<lambda>" else label)


class _Not(Formula):
    def __init__(self, phi: Formula):
        self.phi = phi
        self.name = f"not({phi.name})"

    def _compute(self, ctx: _Ctx) -> np.ndarray:
        return -self.phi._series(ctx)

    def _witness(self, ctx: _Ctx, k: int) -> tuple[int, int]:
        return self.phi._witness(ctx, k)


class _NAry(Formula):
    _op = ""
    _reduce: Callable = np.minimum.reduce
    _pick: Callable = np.argmin

    def __init__(self, *phis: Formula, label: str | None = None):
        self.phis = phis
        self.name = label or f"{self._op}({', '.join(p.name for p in phis)})"

    def _compute(self, ctx: _Ctx) -> np.ndarray:
        return type(self)._reduce(np.stack([p._series(ctx) for p in self.phis]), axis=0)

    def _witness(self, ctx: _Ctx, k: int) -> tuple[int, int]:
        col = np.array([p._series(ctx)[k] for p in self.phis])
        return self.phis[int(type(self)._pick(col))]._witness(ctx, k)


class _And(_NAry):
    _op = "and"
    _reduce = np.minimum.reduce
    _pick = np.argmin


class _Or(_NAry):
    _op = "or"
    _reduce = np.maximum.reduce
    _pick = np.argmax


@factory
def and_(*phis: Formula) -> Formula:
    """Conjunction: robustness = min of the operands'."""
    if not phis:
        raise MonitorError("and_() needs at least one formula")
    return _And(*(_formula(p, "and_") for p in phis))


@factory
def or_(*phis: Formula) -> Formula:
    """Disjunction: robustness = max of the operands'."""
    if not phis:
        raise MonitorError("or_() needs at least one formula")
    return _Or(*(_formula(p, "or_") for p in phis))


@factory
def not_(phi: Formula) -> Formula:
    """Negation: robustness = minus the operand's."""
    return _Not(_formula(phi, "not_"))


@factory
def implies(phi: Formula, psi: Formula) -> Formula:
    """``phi -> psi`` = ``or_(not_(phi), psi)``."""
    phi, psi = _formula(phi, "implies"), _formula(psi, "implies")
    return _Or(_Not(phi), psi, label=f"implies({phi.name}, {psi.name})")


# -- windows ------------------------------------------------------------------------------------

def _window(where: str, within: Any) -> tuple[float, float]:
    if within is None:
        return 0.0, math.inf
    try:
        a, b = within
    except (TypeError, ValueError):
        raise MonitorError(f"{where}: within must be a (start, end) pair in seconds, got {within!r}") from None
    a = check_positive(where, a, "window start", allow_zero=True)
    if isinstance(b, numbers.Real) and not isinstance(b, bool) and b == math.inf:
        b = math.inf
    else:
        b = check_threshold(where, b, "window end")
    if b < a:
        raise MonitorError(f"{where}: window ({a:g}, {b:g}) ends before it starts")
    return a, b


def _bounds(ctx: _Ctx, a: float, b: float) -> tuple[np.ndarray, np.ndarray]:
    """Per kept step k, the index range [lo, hi) of steps j with t_j - t_k in [a, b]."""
    lo = np.searchsorted(ctx.t, ctx.t + a - _EPS_T, side="left")
    hi = np.searchsorted(ctx.t, ctx.t + b + _EPS_T, side="right") if math.isfinite(b) \
        else np.full(ctx.n, ctx.n)
    return lo, np.maximum(hi, lo)


def _range_reduce(x: np.ndarray, lo: np.ndarray, hi: np.ndarray, op: np.ufunc, empty: float) -> np.ndarray:
    """``op``-reduction of x over each [lo, hi) with a sparse table (idempotent ops only)."""
    n = x.size
    levels = [x]
    width = 1
    while 2 * width <= n:  # log2(n) levels, not a loop over steps
        prev = levels[-1]
        nxt = prev.copy()
        nxt[: n - width] = op(prev[: n - width], prev[width:])
        levels.append(nxt)
        width *= 2
    table = np.stack(levels)
    length = hi - lo
    nonempty = length > 0
    lvl = np.zeros_like(length)
    lvl[nonempty] = np.floor(np.log2(length[nonempty])).astype(int)
    lo_c = np.minimum(lo, n - 1)
    right = np.clip(hi - (1 << lvl), 0, n - 1)
    out = op(table[lvl, lo_c], table[lvl, right])
    return np.where(nonempty, out, empty)


def _fmt_window(a: float, b: float, unbounded: bool) -> str:
    return "" if unbounded else f"[{a:g},{b:g}]"


class _Temporal(Formula):
    _op = ""
    _ufunc: np.ufunc = np.minimum
    _empty = math.inf
    _pick = staticmethod(np.argmin)

    def __init__(self, phi: Formula, within: Any):
        self.phi = phi
        self.a, self.b = _window(self._op, within)
        self.name = f"{self._op}{_fmt_window(self.a, self.b, within is None)}({phi.name})"

    def _compute(self, ctx: _Ctx) -> np.ndarray:
        lo, hi = _bounds(ctx, self.a, self.b)
        return _range_reduce(self.phi._series(ctx), lo, hi, self._ufunc, self._empty)

    def _witness(self, ctx: _Ctx, k: int) -> tuple[int, int]:
        lo, hi = _bounds(ctx, self.a, self.b)
        if hi[k] <= lo[k]:
            return k, -1
        j = int(lo[k] + self._pick(self.phi._series(ctx)[lo[k]:hi[k]]))
        return self.phi._witness(ctx, j)


class _Always(_Temporal):
    _op = "always"
    _ufunc = np.minimum
    _empty = math.inf
    _pick = staticmethod(np.argmin)


class _Eventually(_Temporal):
    _op = "eventually"
    _ufunc = np.maximum
    _empty = -math.inf
    _pick = staticmethod(np.argmax)


@factory
def always(phi: Formula, within: tuple[float, float] | None = None) -> Formula:
    """``phi`` holds at every step of the window ``within`` = (start, end) [s] from now
    (None: from now to the end of the trace). Robustness = min over the window; +inf when the
    window holds no step."""
    return _Always(_formula(phi, "always"), within)


@factory
def eventually(phi: Formula, within: tuple[float, float] | None = None) -> Formula:
    """``phi`` holds at some step of the window ``within`` = (start, end) [s] from now.
    Robustness = max over the window; -inf when the window holds no step."""
    return _Eventually(_formula(phi, "eventually"), within)


class _Until(Formula):
    #: cells of the (rows x window) matrix evaluated at once; bounds memory for long traces
    BLOCK_CELLS = 1 << 20

    def __init__(self, phi: Formula, psi: Formula, within: Any):
        self.phi, self.psi = phi, psi
        self.a, self.b = _window("until", within)
        self.name = f"until{_fmt_window(self.a, self.b, within is None)}({phi.name}, {psi.name})"

    def _candidates(self, ctx: _Ctx, rows: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                    width: int) -> np.ndarray:
        """For each row k and offset m: min(psi(k+m), min phi[k, k+m)) if k+m is in the
        window, else -inf."""
        phi, psi = self.phi._series(ctx), self.psi._series(ctx)
        n = ctx.n
        j = rows[:, None] + np.arange(width)[None, :]
        jc = np.minimum(j, n - 1)
        phi_j = np.where(j < n, phi[jc], np.inf)
        # min of phi over [k, j): running min along the row, shifted right by one
        run = np.minimum.accumulate(phi_j, axis=1)
        before = np.concatenate([np.full((rows.size, 1), np.inf), run[:, :-1]], axis=1)
        cand = np.minimum(psi[jc], before)
        valid = (j >= lo[rows][:, None]) & (j < hi[rows][:, None])
        return np.where(valid, cand, -np.inf)

    def _compute(self, ctx: _Ctx) -> np.ndarray:
        lo, hi = _bounds(ctx, self.a, self.b)
        if not math.isfinite(self.b):
            return self._compute_unbounded(ctx, lo)
        width = int(max(1, (hi - np.arange(ctx.n)).max()))
        block = max(1, self.BLOCK_CELLS // width)
        out = np.empty(ctx.n)
        for start in range(0, ctx.n, block):  # blocks of rows, not single steps
            rows = np.arange(start, min(ctx.n, start + block))
            out[rows] = self._candidates(ctx, rows, lo, hi, width).max(axis=1)
        return out

    def _compute_unbounded(self, ctx: _Ctx, lo: np.ndarray) -> np.ndarray:
        """Window [a, inf): O(T log T) without the (T x T) matrix.

        Unbounded until from step m, U(m) = max(psi(m), min(phi(m), U(m+1))) with
        U(n) = -inf, applies clamp maps f_m(x) = max(P, min(Q, x)) right to left. Clamp maps
        compose into clamp maps — f1∘f2 has P = max(P1, min(Q1, P2)), Q = min(Q1, Q2) — so
        all suffix compositions come from a Hillis-Steele scan in log2(T) whole-array
        passes, and U(m) is the P of the suffix starting at m. A window start a > 0 then
        needs phi over [k, lo_k) as well: rho(k) = min(min phi[k, lo_k), U(lo_k)).
        """
        phi, psi = self.phi._series(ctx), self.psi._series(ctx)
        n = ctx.n
        P, Q = psi.copy(), phi.copy()
        stride = 1
        while stride < n:  # log2(n) passes over whole arrays
            P_next = P.copy()
            P_next[: n - stride] = np.maximum(P[: n - stride], np.minimum(Q[: n - stride], P[stride:]))
            Q[: n - stride] = np.minimum(Q[: n - stride], Q[stride:])
            P = P_next
            stride *= 2
        U = np.append(P, -np.inf)  # U(n) = -inf: no step left to satisfy psi
        head = _range_reduce(phi, np.arange(n), lo, np.minimum, math.inf)
        return np.minimum(head, U[np.minimum(lo, n)])

    def _witness(self, ctx: _Ctx, k: int) -> tuple[int, int]:
        lo, hi = _bounds(ctx, self.a, self.b)
        if hi[k] <= lo[k]:
            return k, -1
        width = int(hi[k] - k)
        cand = self._candidates(ctx, np.array([k]), lo, hi, width)[0]
        m = int(np.argmax(cand))
        j = k + m
        psi = self.psi._series(ctx)
        if m == 0 or psi[j] <= cand[m]:
            return self.psi._witness(ctx, j)
        phi = self.phi._series(ctx)
        return self.phi._witness(ctx, k + int(np.argmin(phi[k:j])))


@factory
def until(phi: Formula, psi: Formula, within: tuple[float, float] | None = None) -> Formula:
    """``phi`` holds until ``psi`` does, and ``psi`` does within ``within`` = (start, end)
    [s]: robustness at k = max over j in the window of min(psi(j), min over k <= i < j of
    phi(i)); -inf when the window holds no step."""
    return _Until(_formula(phi, "until"), _formula(psi, "until"), within)

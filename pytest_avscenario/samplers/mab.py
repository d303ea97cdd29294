"""The multi-armed bandit sampler (``mab``): the active sampler the paper ran beside Halton.

Each coordinate of the unit cube is cut into buckets (arms, see :mod:`._buckets`). To propose a
case, every dimension independently plays the UCB1 rule — the bucket with the highest
empirical reward plus ``exploration * sqrt(2 ln t / n_bucket)`` — and the case is drawn
uniformly inside the chosen buckets. A case's reward is 1 for a counterexample and, unlike the
reference, ``near_miss * exp(-rho / scale)`` otherwise, with ``scale`` the running mean of
``|rho|``: the bandit climbs towards failures from the first sample instead of being uniform
random until it stumbles on one.

Multi-objective mode (a ``priority`` order over the metrics; Viswanadha et al., RV'21): a
case's violation pattern is the set of metrics it violates; the sampler keeps the patterns
that no other pattern seen so far dominates under the priority order
(:class:`.priority.PriorityOrder`), and a case earns counterexample credit only while its
pattern is maximal, so arms that produced what is now a lesser failure lose that credit.
Each metric weighs ``2 ** -level`` (level 0 = top priority): a pattern's credit is
``1 - near_miss`` times its share of the total weight, and the near-miss part is the
weighted mean closeness over all metrics — so a bucket that violates a low-priority metric
close to a high-priority one keeps pulling the search toward the high-priority failure.
With one objective this reduces to the rule above (1 for a counterexample).
Patterns are sets of metric names, never traversal positions.
"""

from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from ._buckets import Buckets
from .base import ActiveSampler, Rho, _rng_state, check_float, check_int
from .priority import Pattern

_SINGLE = "rho"  # the pattern name of a counterexample in single-objective mode
_RBLOCK = 64  # asks served by one generator call


class MultiArmedBanditSampler(ActiveSampler):
    """UCB1 bandit over per-dimension buckets.

    Options: ``buckets`` (per continuous dimension, default 5 like VerifAI), ``exploration``
    (the UCB constant, default 0.3; VerifAI's rule is ``exploration=1``), ``near_miss``
    (weight of the near-miss reward in [0, 1], default 0.8; 0 gives the reference's 0/1
    reward), ``jitter`` (default 0.1: UCB values closer than this count as tied and are
    chosen between at random), plus ``metrics`` and ``priority``.

    Why the jitter: every dimension sees the same reward for a case, so with a deterministic
    argmax the dimensions' statistics stay permutations of one another and they move in
    lock-step through ``buckets`` cells of the whole grid — with near-miss rewards the
    bandit then never reaches a failure off that diagonal. Randomized near-ties decouple them.
    """

    name = "mab"
    multi_objective = True
    options = ActiveSampler.options + ("buckets", "exploration", "near_miss", "jitter")

    def __init__(self, space, seed=0, buckets: int = 5, exploration: float = 0.3,
                 near_miss: float = 0.8, jitter: float = 0.1, **options: Any):
        super().__init__(space, seed=seed, **options)
        self.n_buckets = check_int(buckets, "mab buckets")
        self.exploration = check_float(exploration, "mab exploration")
        self.near_miss = check_float(near_miss, "mab near_miss", 0.0, 1.0)
        self.jitter = check_float(jitter, "mab jitter")
        self.grid = Buckets(self.space, self.n_buckets)
        n = self.grid.d * self.grid.B
        self._valid = self.grid.valid.ravel()
        # arrays over flat arms i * B + j; pulls start at 1: one pseudo-pull with reward 0
        # per arm (as VerifAI) keeps the UCB term finite. Padding arms are never chosen.
        self.pulls = np.where(self._valid, 1.0, np.inf)
        self.total = np.zeros(n)  # reward per arm: near misses + counterexample credit
        self.ce_sum = np.zeros(n)  # the credit part: pulls whose pattern is now maximal
        self.patterns: dict[Pattern, np.ndarray] = {}
        self.maximal: set[Pattern] = set()
        self.scale: dict[str, list[float]] = {}  # metric -> [sum |rho|, count] (finite rho)
        self._nr = n + self.grid.d
        self._rblock = np.zeros((0, self._nr))
        self._rpos = 0
        self._block_rng: dict[str, Any] | None = None  # generator state before the block
        self._refresh()

    # -- proposing ----------------------------------------------------------------------
    def _refresh(self) -> None:
        # cached per arm so that ask is a few array operations
        self._mean = np.where(self._valid, self.total / self.pulls, -np.inf)
        self._rsqrt = np.sqrt(2.0 / self.pulls)

    def ask_unit(self) -> np.ndarray:
        self.n_asked += 1
        g = self.grid
        n = g.d * g.B
        k = self.exploration * math.sqrt(math.log(self.n_told + 1))
        r = self._random_row()
        ucb = self._mean + k * self._rsqrt
        ucb += r[:n]  # the tie-breaking jitter, pre-scaled
        fi = ucb.reshape(g.d, g.B).argmax(1) + g.row_offset
        return g.flat_lo[fi] + r[n:] * g.flat_width[fi]

    def _random_row(self) -> np.ndarray:
        # uniforms are drawn _RBLOCK asks at a time (one generator call per ask cost as much
        # as the rest of ask); the state keeps the generator as it was before the block and
        # the position in it, and restore draws the block again
        if self._rpos >= len(self._rblock):
            self._block_rng = _rng_state(self.rng)
            self._draw_block()
        self._rpos += 1
        return self._rblock[self._rpos - 1]

    def _draw_block(self) -> None:
        self._rblock = self.rng.random((_RBLOCK, self._nr))
        self._rblock[:, : self.grid.d * self.grid.B] *= self.jitter + 1e-9
        self._rpos = 0

    def arm_values(self) -> np.ndarray:
        """Each arm's empirical reward, shape ``(d, B)`` (-inf for padding arms)."""
        return self._mean.reshape(self.grid.d, self.grid.B).copy()

    # -- learning -----------------------------------------------------------------------
    def _learn(self, u: Any, r: float | None, rho: Rho) -> None:
        fi = self.grid.flat_index(u)
        pulls = self.pulls[fi] + 1.0
        self.pulls[fi] = pulls
        if r is None:
            # an invalid case: visited (so the arm is not replayed forever) but no evidence
            # either way; adding the arm's current mean leaves the mean unchanged
            add = self._mean[fi]
        else:
            pattern, closeness = self._judge(r, rho)
            add = self.near_miss * closeness
            if pattern:
                counts = self.patterns.get(pattern)
                if counts is None:  # a new pattern may change the maximal set
                    self.total[fi] += add
                    counts = self.patterns[pattern] = np.zeros_like(self.total)
                    counts[fi] += 1.0
                    self._update_maximal()  # recomputes every arm's mean
                    return
                counts[fi] += 1.0
                if pattern in self.maximal:
                    credit = self._credit(pattern)
                    self.ce_sum[fi] += credit
                    add += credit
        total = self.total[fi] + add
        self.total[fi] = total
        self._mean[fi] = total / pulls
        self._rsqrt[fi] = np.sqrt(2.0 / pulls)

    def _update_maximal(self) -> None:
        new = set(self.order.maximal(self.patterns)) if self.multi else set(self.patterns)
        self.maximal = new
        near = self.total - self.ce_sum
        self.ce_sum = np.zeros_like(self.total)
        for p in new:
            self.ce_sum += self._credit(p) * self.patterns[p]
        self.total = near + self.ce_sum
        self._refresh()

    def _weight(self, metric: str) -> float:
        return 2.0 ** -self.order.level.get(metric, 0)

    def _credit(self, pattern: Pattern) -> float:
        """Counterexample reward of a maximal pattern: (1 - near_miss) times the share of the
        priority weight its metrics carry (1 for a single objective)."""
        if not self.multi:
            return 1.0 - self.near_miss
        total = sum(self._weight(m) for m in self.order.metrics)
        return (1.0 - self.near_miss) * sum(self._weight(m) for m in pattern) / total

    def _judge(self, r: float, rho: Rho) -> tuple[Pattern, float]:
        """Violation pattern of one valid case and its closeness to failing, in [0, 1].

        Closeness is 1 for a violated metric and exp(-rho / scale) otherwise, averaged over
        the metrics with weight ``2 ** -level`` (level 0 = top priority)."""
        if not (self.multi and isinstance(rho, Mapping)):
            if self.multi and _SINGLE not in self.order.level:
                self._add_metric(_SINGLE)
            return (frozenset((_SINGLE,)) if r < 0 else frozenset()), self._closeness(_SINGLE, r)
        for m in rho:
            if m not in self.order.level:
                self._add_metric(m)  # unranked metric seen first here
        violated = frozenset(m for m, v in rho.items() if float(v) < 0)
        num = den = 0.0
        for m, v in rho.items():
            w = self._weight(m)
            num += w * self._closeness(m, float(v))
            den += w
        return violated, num / den

    def _add_metric(self, name: str) -> None:
        self.order = self.order.with_metric(name)
        if self.patterns:
            self._update_maximal()  # credits are shares of the total weight

    def _closeness(self, metric: str, v: float) -> float:
        """exp(-rho/scale) for rho >= 0: 1 at the boundary, -> 0 far from it."""
        acc = self.scale.get(metric)
        if math.isfinite(v):
            if acc is None:
                acc = self.scale[metric] = [0.0, 0]
            acc[0] += abs(v)
            acc[1] += 1
        if v <= 0:
            return 1.0
        if not math.isfinite(v) or acc is None or acc[0] <= 0:
            return 0.0
        return math.exp(-v * acc[1] / acc[0])

    # -- state --------------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        st = super().state()
        if 0 < self._rpos < len(self._rblock):
            # compact: the generator as it was before the current block, and the position
            st["rng"] = self._block_rng
        st.update(
            pulls=np.where(self._valid, self.pulls, -1.0).tolist(),
            block_pos=self._rpos if self._rpos < len(self._rblock) else 0,
            total=self.total.tolist(),
            ce_sum=self.ce_sum.tolist(),
            patterns=[[sorted(p), c.tolist()] for p, c in self.patterns.items()],
            scale=self.scale,
            metrics=list(self.order.metrics),
        )
        return st

    def restore(self, state: Mapping[str, Any]) -> None:
        super().restore(state)
        pulls = np.array(state["pulls"], dtype=float)
        self.pulls = np.where(pulls < 0, np.inf, pulls)
        self._rblock = np.zeros((0, self._nr))
        self._rpos = 0
        if state.get("block_pos"):
            self._block_rng = state["rng"]
            self._draw_block()
            self._rpos = int(state["block_pos"])
        self.total = np.array(state["total"], dtype=float)
        self.ce_sum = np.array(state["ce_sum"], dtype=float)
        for m in state.get("metrics", ()):
            if m not in self.order.level:
                self.order = self.order.with_metric(m)
        self.patterns = {frozenset(p): np.array(c, dtype=float) for p, c in state["patterns"]}
        self.scale = {k: [float(v[0]), int(v[1])] for k, v in state["scale"].items()}
        # the sums come back exactly as saved; only the maximal set and caches are derived
        self.maximal = set(self.order.maximal(self.patterns)) if self.multi else set(self.patterns)
        self._refresh()

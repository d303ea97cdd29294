"""The cross-entropy sampler (``ce``): a per-dimension bucket distribution pulled toward elites.

Each coordinate of the unit cube is cut into buckets (see :mod:`._buckets`) with a categorical
distribution over them, initially uniform; a case is drawn by picking a bucket per dimension
from its distribution and a point uniformly inside. Every ``batch`` valid cases the elite set
— the ``elite`` fraction of all cases told so far with the lowest rho — is counted per
dimension and bucket, and each distribution moves toward those frequencies by ``smoothing``
(the smoothed cross-entropy update), then ``floor`` of the uniform is mixed in so no bucket
is ever starved. Elites are a quantile of rho, not "rho < 0": the sampler learns from every
case of its first batch on, where the reference learns nothing until a counterexample has
been found.

Points of one batch are drawn together when the distribution changes, so ask is a list pop.
"""

from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from ._buckets import Buckets
from .base import ActiveSampler, Rho, check_float, check_int, json_float


class CrossEntropySampler(ActiveSampler):
    """Cross-entropy over per-dimension bucket distributions.

    Options: ``buckets`` (per continuous dimension, default 5 like VerifAI), ``elite``
    (quantile of lowest rho that forms the elite set, default 0.1), ``smoothing`` (step
    toward the elite frequencies in (0, 1], default 0.3), ``batch`` (valid cases between
    updates, default 10), ``floor`` (share of the uniform mixed in after each update,
    default 0.05), plus ``metrics`` and ``priority`` (``ce`` minimizes the worst metric, or
    with a priority the worst top-ranked one).

    Defaults were chosen on the benchmark's ball problem and checked on held-out seeds;
    updating after every case (``batch=1``) or earlier in the first batch learned from too
    few cases and was slower there.
    """

    name = "ce"
    options = ActiveSampler.options + ("buckets", "elite", "smoothing", "batch", "floor")

    def __init__(self, space, seed=0, buckets: int = 5, elite: float = 0.1,
                 smoothing: float = 0.3, batch: int = 10, floor: float = 0.05, **options: Any):
        super().__init__(space, seed=seed, **options)
        self.n_buckets = check_int(buckets, "ce buckets")
        self.elite = check_float(elite, "ce elite", 0.0, 1.0, lo_open=True)
        self.smoothing = check_float(smoothing, "ce smoothing", 0.0, 1.0, lo_open=True)
        self.batch = check_int(batch, "ce batch")
        self.floor = check_float(floor, "ce floor", 0.0, 1.0)
        self.grid = Buckets(self.space, self.n_buckets)
        g = self.grid
        self._interior = np.arange(g.B)[None, :] < (g.k - 1)[:, None]
        cdf_start = np.concatenate([[0], np.cumsum(g.k - 1)[:-1]]).astype(int) \
            if g.d else np.zeros(0, dtype=int)
        self._arm_offset = g.row_offset - cdf_start
        # uniform over the buckets that can hold a case (a zero-weight choice cannot)
        n_valid = np.maximum(g.valid.sum(1, keepdims=True), 1)
        self._floor_uniform = self.floor * g.valid / n_valid
        prob = np.where(g.valid, g.width, 0.0)  # uniform on the unit cube
        self._set_prob(prob / np.maximum(prob.sum(1, keepdims=True), 1e-300))
        # valid cases told: unit points and rho, in arrays grown by doubling
        self._n = 0
        self._U = np.zeros((16, g.d))
        self._R = np.zeros(16)
        self._queue: list[list[float]] = []  # points of the current batch, reversed
        self._pqueue: list[dict[str, Any]] = []  # and as parameter dicts
        self._since = 0

    # -- proposing ----------------------------------------------------------------------
    def _fill(self) -> None:
        pts = self._draw(self.batch)[::-1]
        self._queue = pts.tolist()
        self._pqueue = self._params_many(pts)  # the same points as parameter dicts

    def ask_unit(self) -> np.ndarray:
        self.n_asked += 1
        if not self._queue:
            self._fill()
        self._pqueue.pop()
        return np.array(self._queue.pop(), dtype=float)

    def ask(self) -> dict[str, Any]:
        self.n_asked += 1
        if not self._queue:
            self._fill()
        self._queue.pop()
        return self._pqueue.pop()

    def _draw(self, m: int) -> np.ndarray:
        g = self.grid
        r = self.rng.random((2, m, g.d))
        # inverse CDF per dimension in one searchsorted: dimension i's CDF is shifted by 4i
        # and has only its k-1 interior edges, so the count is start_i + bucket, bucket < k
        fi = np.searchsorted(self._cdf, r[0] + g._shift, "right") + self._arm_offset
        return g.flat_lo[fi] + r[1] * g.flat_width[fi]

    def _set_prob(self, p: np.ndarray) -> None:
        self.prob = p
        g = self.grid
        # interior edges only (the last bucket takes the rest, whatever the round-off)
        self._cdf = (np.cumsum(p, 1) + g._shift[:, None])[self._interior]

    # -- learning -----------------------------------------------------------------------
    def _learn(self, u: Any, r: float | None, rho: Rho) -> None:
        if r is None:
            return  # an invalid case is no evidence: neither elite nor pass
        if self._n == len(self._R):
            self._U = np.concatenate([self._U, np.zeros_like(self._U)])
            self._R = np.concatenate([self._R, np.zeros_like(self._R)])
        self._U[self._n] = u
        self._R[self._n] = r
        self._n += 1
        self._since += 1
        if self._since >= self.batch:
            self._update()

    def _update(self) -> None:
        self._since = 0
        g = self.grid
        n = self._n
        rho = self._R[:n]
        m = max(1, int(math.ceil(self.elite * n)))
        elite = np.argpartition(rho, m - 1)[:m] if m < n else np.arange(n)
        counts = np.bincount(g.flat_index(self._U[elite]).ravel(), minlength=g.d * g.B)
        # p <- (1 - floor) * ((1 - smoothing) * p + smoothing * elite frequencies)
        #      + floor * uniform, folded into one affine step. Each row of p, of the elite
        # frequencies and of the uniform sums to 1, so p stays normalized, and every
        # selectable bucket keeps at least floor / (its dimension's selectable buckets).
        keep = (1.0 - self.floor) * (1.0 - self.smoothing)
        gain = (1.0 - self.floor) * self.smoothing / m
        self._set_prob(keep * self.prob + gain * counts.reshape(g.d, g.B) + self._floor_uniform)
        self._queue, self._pqueue = [], []  # the rest came from the old distribution

    # -- state --------------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        st = super().state()
        st.update(prob=self.prob.tolist(), u=self._U[: self._n].tolist(),
                  rho=[json_float(x) for x in self._R[: self._n].tolist()],
                  since=self._since,
                  queue=self._queue)
        return st

    def restore(self, state: Mapping[str, Any]) -> None:
        super().restore(state)
        self._set_prob(np.array(state["prob"], dtype=float).reshape(self.prob.shape))
        self._n = len(state["rho"])
        cap = max(16, 1 << max(self._n - 1, 0).bit_length())
        self._U = np.zeros((cap, self.grid.d))
        self._R = np.zeros(cap)
        if self._n:
            self._U[: self._n] = np.array(state["u"], dtype=float).reshape(self._n, self.grid.d)
            self._R[: self._n] = [float(x) for x in state["rho"]]
        self._since = int(state["since"])
        self._queue = [[float(x) for x in q] for q in state["queue"]]
        self._pqueue = self._params_many(
            np.array(self._queue, dtype=float).reshape(len(self._queue), self.d))

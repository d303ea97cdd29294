"""Per-dimension buckets of the unit cube, shared by the bandit and cross-entropy samplers.

A continuous coordinate is cut into ``n`` equal buckets; an integer or categorical one into
its own strata (one bucket per value, weighted as the space weights it), so a bucket is a
value and the bandit learns which lane or weather fails. All arrays are padded to the widest
dimension, ``(d, B)``, so choosing and updating buckets is a handful of numpy calls whatever
the dimension; padding buckets have zero width and are never chosen.
"""

from __future__ import annotations

import numpy as np

from ..space import FeatureSpace

# Above this many values an integer parameter is bucketed like a continuous one: one arm per
# value would take longer to explore than the whole sample budget.
MAX_DISCRETE_ARMS = 64


class Buckets:
    """The bucket grid of a feature space: ``lo``/``width`` per (dimension, bucket)."""

    def __init__(self, space: FeatureSpace, n: int):
        edges: list[np.ndarray] = []
        for dim in space.dims:
            dist = space.parameters[dim.name]
            if dim.kind == "categorical" and dim.n_values <= MAX_DISCRETE_ARMS:
                e = np.concatenate([[0.0], np.cumsum(dist.weights)])
                e[-1] = 1.0
            elif dim.kind == "integer" and dim.n_values <= MAX_DISCRETE_ARMS:
                e = np.linspace(0.0, 1.0, dim.n_values + 1)
            else:
                e = np.linspace(0.0, 1.0, n + 1)
            edges.append(e)
        self.d = len(edges)
        self.k = np.array([len(e) - 1 for e in edges], dtype=int)
        self.B = int(self.k.max()) if self.d else n
        self.lo = np.zeros((self.d, self.B))
        self.width = np.zeros((self.d, self.B))
        # inner edges; padding with +inf keeps the bucket index of u at "edges <= u" counted
        self.inner = np.full((self.d, max(self.B - 1, 0)), np.inf)
        for i, e in enumerate(edges):
            k = len(e) - 1
            self.lo[i, :k] = e[:-1]
            self.width[i, :k] = np.diff(e)
            self.inner[i, : k - 1] = e[1:-1]
        self.valid = self.width > 0
        self.rows = np.arange(self.d)
        # flat layout: arm (i, j) is i * B + j; one searchsorted finds every coordinate's
        # bucket once dimension i's edges are shifted by 4 * i (u never leaves (-1.5, 2.5))
        self.row_offset = self.rows * self.B
        self.flat_lo = self.lo.ravel()
        self.flat_width = self.width.ravel()
        self._shift = 4.0 * self.rows
        self._flat_edges = np.concatenate(
            [e[1:-1] + 4.0 * i for i, e in enumerate(edges)] or [np.zeros(0)])
        self._starts = np.concatenate([[0], np.cumsum(self.k - 1)[:-1]]).astype(int) \
            if self.d else np.zeros(0, dtype=int)
        self._arm_offset = self.row_offset - self._starts

    def index(self, u: np.ndarray) -> np.ndarray:
        """Bucket of each coordinate of one point ``u`` (shape ``(d,)``)."""
        return np.searchsorted(self._flat_edges, u + self._shift, "right") - self._starts

    def flat_index(self, u: np.ndarray) -> np.ndarray:
        """Flat arm index ``i * B + bucket`` of each coordinate of ``u`` (``(d,)`` or
        ``(n, d)``)."""
        return np.searchsorted(self._flat_edges, u + self._shift, "right") + self._arm_offset

    def index_many(self, U: np.ndarray) -> np.ndarray:
        """Buckets of many points ``U`` (shape ``(n, d)``) -> ``(n, d)`` ints."""
        return (U[:, :, None] >= self.inner[None]).sum(2)

    def point(self, b: np.ndarray, r: np.ndarray) -> np.ndarray:
        """The point at relative position ``r`` in [0, 1) inside buckets ``b`` (any shape)."""
        return self.lo[self.rows, b] + r * self.width[self.rows, b]

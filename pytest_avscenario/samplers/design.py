"""Boundary initial designs: corners of the unit cube, chosen to spread out.

Failures of a driving scenario often sit where its parameters are extreme — the shortest
gap, the slowest lead, the earliest cut-in — because the ranges a team declares are the
edges of what its stack must handle (boundary-value testing). A uniform draw reaches a
corner region of a 5-parameter box almost never, so an active sampler starts from a few
corners, each as far (in Hamming distance over the ordered coordinates) from the corners
already chosen as possible, ties broken by the sampler's generator: the first two are
opposite, and every ordered coordinate takes both of its extremes early. Categorical
coordinates have no extremes; they get a uniform value (any category).
"""

from __future__ import annotations

import itertools

import numpy as np

from ..space import FeatureSpace

# Above this many ordered coordinates, corners are picked among a random sample of this
# many candidates instead of all 2^k of them.
_ALL_CORNERS_MAX_DIMS = 10
_CANDIDATES = 1024


def ordered_mask(space: FeatureSpace) -> np.ndarray:
    """Which coordinates of the unit cube have a meaningful low and high end."""
    return np.array([dim.kind != "categorical" for dim in space.dims], dtype=bool)


def corner_design(space: FeatureSpace, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` corners of the unit cube of ``space`` (``(n, d)``), greedily spread out — at most
    ``2**k`` when every coordinate is ordered (k of them), so no case is asked twice."""
    d = space.d
    ordered = ordered_mask(space)
    k = int(ordered.sum())
    if k == d and k < 63:
        n = min(n, 2 ** k)
    out = rng.random((n, d))  # categorical coordinates keep these
    if k == 0 or n == 0:
        return out
    if k <= _ALL_CORNERS_MAX_DIMS:
        cand = np.array(list(itertools.product((0.0, 1.0), repeat=k)))
        cand = cand[rng.permutation(len(cand))]
    else:
        cand = (rng.random((_CANDIDATES, k)) < 0.5).astype(float)
    chosen = np.zeros((0, k))
    for i in range(n):
        if len(chosen) == 0:
            j = 0
        else:
            ham = np.abs(cand[:, None, :] - chosen[None, :, :]).sum(2).min(1)
            if len(chosen) >= len(cand):
                j = i % len(cand)  # every corner used: cycle
            else:
                ham[(ham == 0)] = -1  # an already chosen corner is the last resort
                j = int(np.argmax(ham))
        chosen = np.vstack([chosen, cand[j]])
        out[i, ordered] = cand[j]
    return out

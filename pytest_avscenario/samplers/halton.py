"""Halton low-discrepancy sampling, the paper's coverage sampler.

Unscrambled by default so runs compare with the paper and with VerifAI's Halton sampler:
point ``i`` has coordinate ``j`` equal to the radical inverse of ``i`` in the ``j``-th prime
base, computed here with numpy (so collecting a Halton test does not pay for importing
scipy.stats). ``scramble=True`` gives scipy.stats.qmc's randomized (seeded) sequence. The
unscrambled sequence starts at the origin, a degenerate corner case; like VerifAI we skip it
(``skip``, default 1). Integer and categorical dimensions take their coordinate of the same
Halton point, which stratifies them over their values.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from .base import Sampler, SamplerError


def first_primes(n: int) -> list[int]:
    primes: list[int] = []
    k = 2
    while len(primes) < n:
        if all(k % p for p in primes if p * p <= k):
            primes.append(k)
        k += 1
    return primes


def radical_inverse(indices: np.ndarray, base: int) -> np.ndarray:
    """Van der Corput radical inverse of non-negative integer ``indices`` in ``base``."""
    i = np.asarray(indices, dtype=np.int64).copy()
    out = np.zeros(i.shape, dtype=float)
    scale = 1.0 / base
    while np.any(i > 0):
        i, digit = np.divmod(i, base)
        out += digit * scale
        scale /= base
    return out


def halton_points(start: int, n: int, d: int) -> np.ndarray:
    """Rows ``start .. start+n-1`` of the unscrambled ``d``-dimensional Halton sequence."""
    idx = np.arange(start, start + n, dtype=np.int64)
    return np.stack([radical_inverse(idx, b) for b in first_primes(d)], axis=1) if d else np.zeros((n, 0))


class HaltonSampler(Sampler):
    name = "halton"
    active = False
    options = ("scramble", "skip")

    def __init__(self, space, seed=0, scramble: bool = False, skip: int = 1, **options: Any):
        super().__init__(space, seed=seed, **options)
        if isinstance(skip, bool) or not isinstance(skip, int) or skip < 0:
            raise SamplerError(f"halton skip must be an int >= 0, got {skip!r}")
        self.scramble = bool(scramble)
        self.skip = skip
        self._engine = self._make_engine() if self.scramble else None

    def _make_engine(self) -> Any:
        from scipy.stats import qmc

        rng = self.seed if isinstance(self.seed, np.random.Generator) else np.random.default_rng(self.seed)
        engine = qmc.Halton(d=max(self.d, 1), scramble=True, seed=rng)
        engine.fast_forward(self.skip + self.n_asked)
        return engine

    def ask_unit(self) -> np.ndarray:
        return self.sample_unit(1)[0]

    def sample_unit(self, n: int) -> np.ndarray:
        if self._engine is not None:
            pts = self._engine.random(n)[:, : self.d]
        else:
            pts = halton_points(self.skip + self.n_asked, n, self.d)
        self.n_asked += n
        return pts

    def state(self) -> dict[str, Any]:
        st = super().state()
        st.update(scramble=self.scramble, skip=self.skip)
        return st

    def restore(self, state: Mapping[str, Any]) -> None:
        super().restore(state)
        if self.scramble:
            # a scrambled engine's permutations come from the seed: rebuild, then fast-forward
            self._engine = self._make_engine()

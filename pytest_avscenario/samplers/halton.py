"""Halton low-discrepancy sampling (scipy.stats.qmc), the paper's coverage sampler.

Unscrambled by default so runs compare with the paper and with VerifAI's Halton sampler;
``scramble=True`` gives a randomized (seeded) sequence. The unscrambled sequence starts at
the origin, a degenerate corner case; like VerifAI we skip it (``skip``, default 1).
Integer and categorical dimensions take their coordinate of the same Halton point, which
stratifies them over their values.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from .base import Sampler


class HaltonSampler(Sampler):
    name = "halton"
    active = False
    options = ("scramble", "skip")

    def __init__(self, space, seed=0, scramble: bool = False, skip: int = 1, **options: Any):
        super().__init__(space, seed=seed, **options)
        from scipy.stats import qmc

        if int(skip) < 0:
            from .base import SamplerError

            raise SamplerError(f"halton skip must be >= 0, got {skip!r}")
        self.scramble = bool(scramble)
        self.skip = int(skip)
        self._engine = qmc.Halton(d=max(self.d, 1), scramble=self.scramble, seed=self.rng)
        if self.skip:
            self._engine.fast_forward(self.skip)

    def ask_unit(self) -> np.ndarray:
        return self.sample_unit(1)[0]

    def sample_unit(self, n: int) -> np.ndarray:
        self.n_asked += n
        pts = self._engine.random(n)
        return pts[:, : self.d]

    def state(self) -> dict[str, Any]:
        st = super().state()
        st.update(scramble=self.scramble, skip=self.skip)
        return st

    def restore(self, state: Mapping[str, Any]) -> None:
        from scipy.stats import qmc

        super().restore(state)
        # a scrambled engine's permutations come from the seed; re-create and fast-forward
        rng = self.seed if isinstance(self.seed, np.random.Generator) else np.random.default_rng(self.seed)
        self._engine = qmc.Halton(d=max(self.d, 1), scramble=self.scramble, seed=rng)
        self._engine.fast_forward(self.skip + self.n_asked)

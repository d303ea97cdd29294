"""Uniform random sampling of the unit cube with a seeded numpy Generator."""

from __future__ import annotations

import numpy as np

from .base import Sampler


class RandomSampler(Sampler):
    name = "random"
    active = False

    def ask_unit(self) -> np.ndarray:
        self.n_asked += 1
        return self.rng.random(self.d)

    def sample_unit(self, n: int) -> np.ndarray:
        self.n_asked += n
        return self.rng.random((n, self.d))

"""The simulated-annealing sampler (``sa``): a Metropolis walk downhill in rho.

The walk holds a current case. Each proposal is the current point plus a Gaussian step
(standard deviation ``step``, reflected at the faces of the unit cube); the told rho is
accepted if it is lower, and otherwise with the Metropolis probability
``exp(-delta / (T * scale))``, where ``scale`` is the running mean of ``|delta|`` so the
temperature is in units of the monitor's own rho differences. After every proposal the
temperature cools by ``cooling`` and the step shrinks by ``shrink`` down to ``min_step``, so
the walk goes from exploring to refining. When ``restart`` proposals in a row have not
improved the best rho of the current walk, it restarts from a fresh uniform point with the
initial step and temperature — a falsifier wants many basins, not one polished minimum.
Unlike the reference (which never leaves its first mode and is uniform random), every
proposal here is a local move from the current case.
"""

from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from .base import ActiveSampler, Rho, check_float, check_int, json_float


class SimulatedAnnealingSampler(ActiveSampler):
    """Simulated annealing over rho with a shrinking Gaussian proposal.

    Options: ``step`` (initial proposal standard deviation on the unit cube, default 0.15),
    ``min_step`` (default 0.02), ``shrink`` (step factor per proposal, default 0.97),
    ``temperature`` (initial, in units of typical |delta rho|, default 1.0), ``cooling``
    (per proposal, default 0.9), ``restart`` (proposals without improvement before a restart,
    default 30), ``jump`` (probability that an integer or categorical coordinate is redrawn
    uniformly in a proposal, default 0.2), plus ``metrics`` and ``priority`` (``sa``
    minimizes the worst metric, or with a priority the worst top-ranked one).
    """

    name = "sa"
    options = ActiveSampler.options + ("step", "min_step", "shrink", "temperature", "cooling",
                                       "restart", "jump")

    def __init__(self, space, seed=0, step: float = 0.15, min_step: float = 0.02,
                 shrink: float = 0.97, temperature: float = 1.0, cooling: float = 0.9,
                 restart: int = 30, jump: float = 0.2, **options: Any):
        super().__init__(space, seed=seed, **options)
        self.step0 = check_float(step, "sa step", 0.0, 1.0, lo_open=True)
        self.min_step = check_float(min_step, "sa min_step", 0.0, self.step0)
        self.shrink = check_float(shrink, "sa shrink", 0.0, 1.0, lo_open=True)
        self.temp0 = check_float(temperature, "sa temperature")
        self.cooling = check_float(cooling, "sa cooling", 0.0, 1.0)
        self.patience = check_int(restart, "sa restart")
        self.jump = check_float(jump, "sa jump", 0.0, 1.0)
        self._discrete = ~self.space.continuous_mask()
        self._any_discrete = bool(self._discrete.any())
        self.x: np.ndarray | None = None  # current case (unit cube) and its rho
        self.fx = math.inf
        self.best = math.inf  # best rho of the current walk
        self.step = self.step0
        self.temp = self.temp0
        self.stall = 0
        self.n_accepted = 0
        self.n_restarts = 0
        self._dsum = 0.0  # running sum and count of finite |delta|
        self._dn = 0

    # -- proposing ----------------------------------------------------------------------
    def ask_unit(self) -> np.ndarray:
        self.n_asked += 1
        if self.x is None or self.d == 0:
            return self.rng.random(self.d)
        y = self.x + self.step * self.rng.standard_normal(self.d)
        if y.min() < 0.0 or y.max() > 1.0:
            y = np.abs(y) % 2.0  # reflect at 0 and 1 (a step may cross the cube repeatedly)
            y = np.where(y > 1.0, 2.0 - y, y)
        if self._any_discrete:
            # a shrunken Gaussian step can no longer leave an integer/categorical stratum,
            # so those coordinates are also redrawn uniformly now and then
            z = self.rng.random(2 * self.d)
            y = np.where(self._discrete & (z[: self.d] < self.jump), z[self.d:], y)
        return y

    # -- learning -----------------------------------------------------------------------
    def _learn(self, u: Any, r: float | None, rho: Rho) -> None:
        if self.x is None:
            if r is not None:  # the walk starts at its first valid case
                self.x, self.fx, self.best = np.array(u, dtype=float), r, r
            return
        if r is not None:
            if self.accepts(self.fx, r):
                self.x, self.fx = np.array(u, dtype=float), r
                self.n_accepted += 1
            if r < self.best:
                self.best, self.stall = r, 0
            else:
                self.stall += 1
        else:
            self.stall += 1  # an invalid proposal is rejected
        self.temp *= self.cooling
        self.step = max(self.step * self.shrink, self.min_step)
        if self.stall >= self.patience:
            self.x, self.fx, self.best = None, math.inf, math.inf
            self.step, self.temp, self.stall = self.step0, self.temp0, 0
            self.n_restarts += 1

    def accepts(self, current: float, proposed: float) -> bool:
        """The Metropolis rule; draws from the sampler's generator only for uphill moves."""
        if proposed <= current or (math.isinf(current) and current == proposed):
            if math.isfinite(proposed) and math.isfinite(current):
                self._note(current - proposed)
            return True
        if math.isinf(proposed):
            return False  # +inf (holds trivially) never replaces a finite rho
        delta = proposed - current
        self._note(delta)
        scale = self._dsum / self._dn
        if self.temp <= 0.0 or scale <= 0.0:
            return False
        return bool(self.rng.random() < math.exp(-delta / (self.temp * scale)))

    def _note(self, delta: float) -> None:
        self._dsum += abs(delta)
        self._dn += 1

    # -- state --------------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        st = super().state()
        st.update(x=None if self.x is None else self.x.tolist(), fx=json_float(self.fx),
                  best=json_float(self.best), step=self.step, temp=self.temp, stall=self.stall,
                  n_accepted=self.n_accepted, n_restarts=self.n_restarts,
                  dsum=self._dsum, dn=self._dn)
        return st

    def restore(self, state: Mapping[str, Any]) -> None:
        super().restore(state)
        self.x = None if state["x"] is None else np.array(state["x"], dtype=float)
        self.fx, self.best = float(state["fx"]), float(state["best"])
        self.step, self.temp = float(state["step"]), float(state["temp"])
        self.stall = int(state["stall"])
        self.n_accepted, self.n_restarts = int(state["n_accepted"]), int(state["n_restarts"])
        self._dsum, self._dn = float(state["dsum"]), int(state["dn"])

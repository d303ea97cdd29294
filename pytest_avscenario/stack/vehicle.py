"""The ego a stack out of process drives: it asks the stack each step and applies the answer.

A ``MotionRequest`` becomes (acceleration, steering) for highway-env's bicycle model, as an
in-process driver's answer does (same clipping); a ``TrafficUpdate`` is the state the stack
moved its vehicle to, put in place of the model's step after :class:`~.client.OSIStack`
checked it is physically possible. The recorded command is then the one that state implies.
Imports highway-env (through the engine): loaded only when an OSI stack drives.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..sim import control
from ..sim.engine import DriverEgo, Vehicle

__all__ = ["StackEgo"]


class StackEgo(DriverEgo):
    """:class:`~pytest_avscenario.sim.engine.DriverEgo` whose driver is an ``OSIStack``."""

    _next: Any = None

    def act(self, action: Any = None) -> None:
        if self.crashed:
            return  # as an in-process driver: a crashed ego is no longer asked
        kind, values = self.driver.exchange(self)
        if kind == "action":
            a, d = values
            a = min(max(a, -control.MAX_DECELERATION), control.MAX_ACCELERATION)
            d = min(max(d, -control.MAX_STEERING), control.MAX_STEERING)
        else:
            self._next = values
            x, y, h, v = values
            dt = self.world.dt
            a = (v - float(self.speed)) / dt
            turn = math.atan2(math.sin(h - self.heading), math.cos(h - self.heading))
            v0 = float(self.speed) if abs(self.speed) > 1e-6 else 1e-6
            sin_beta = max(-1.0, min(1.0, turn / dt * (0.5 * self.LENGTH) / v0))
            d = math.atan(2.0 * math.tan(math.asin(sin_beta)))
        Vehicle.act(self, {"acceleration": a, "steering": d})

    def step(self, dt: float) -> None:
        nxt, self._next = self._next, None
        if nxt is None or self.crashed:
            super().step(dt)
            return
        x, y, h, v = nxt
        self.position = np.array([x, y], dtype=float)
        self.heading = h
        self.speed = v
        self.on_state_update()

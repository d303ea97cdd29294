"""The ego a stack out of process drives: it asks the stack each step and applies the answer.

A ``MotionRequest`` becomes (acceleration, steering) for highway-env's bicycle model, as an
in-process driver's answer does (same clipping, same vehicle constants as the world's
driven ego); a ``TrafficUpdate`` is the state the stack moved its vehicle to, put in place
of the model's step after :class:`~.client.OSIStack` checked it is physically possible. The
recorded command is then the one that state implies.

The class is made through ``world.agent_class`` (as highway-env agents are), so this
package reaches the simulator's engine only through the world; highway-env's core is
loaded by then, since the world built its road first.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..sim import control

__all__ = ["make_stack_ego"]

_CLASS: list = []


def _stack_vehicle() -> type:
    if _CLASS:
        return _CLASS[0]
    from highway_env.vehicle.kinematics import Vehicle

    class StackVehicle(Vehicle):
        """highway-env's kinematic vehicle whose every step is decided by an ``OSIStack``."""

        LENGTH = 5.0  # the world's driven ego's constants (engine.Actor)
        WIDTH = 2.0
        MAX_SPEED = 40.0
        MIN_SPEED = -10.0
        HISTORY_SIZE = 0
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
                _, _, h, v = values
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

    _CLASS.append(StackVehicle)
    return StackVehicle


def make_stack_ego(world: Any, position: Any, heading: float, speed: float) -> Any:
    """The ego vehicle of a case driven by an ``OSIStack`` (its ``driver`` set by the world)."""
    cls = world.agent_class(_stack_vehicle())
    return cls(None, position, heading, speed)

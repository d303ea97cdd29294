"""What the autopilot knows of the other agents: one perception snapshot, reduced for planning.

The observation's agent states are turned once per step into plain-float records with the
few numbers the planner reads (position, velocity, heading as cos/sin, half extents, kind
flags); the autopilot keeps a short history of them to see the world with a latency.
"""

from __future__ import annotations

import math
from typing import Any

__all__ = ["Seen", "Perceived", "EMPTY"]


class Seen:
    """One perceived agent (world frame), reduced to what the planner reads."""

    __slots__ = ("x", "y", "vx", "vy", "c", "s", "hl", "hw", "ped", "bus", "arm", "name")

    def __init__(self, a: Any) -> None:
        self.x, self.y, self.vx, self.vy = float(a.x), float(a.y), float(a.vx), float(a.vy)
        self.c, self.s = math.cos(a.heading), math.sin(a.heading)
        self.hl, self.hw = 0.5 * float(a.length), 0.5 * float(a.width)
        self.ped = a.kind == "pedestrian"
        self.arm = bool(a.flags and a.flags.get("stop_arm"))
        self.bus = a.kind == "bus" or self.arm
        self.name = a.name


class Perceived:
    """One perception snapshot of the other agents.

    Plain Python per agent: with the few agents of a scenario, scalar math beats numpy's
    per-call overhead; arrays are built only for the conflict prediction.
    """

    __slots__ = ("agents", "n")

    def __init__(self, agents: tuple) -> None:
        self.agents = tuple(Seen(a) for a in agents)
        self.n = len(self.agents)


EMPTY = Perceived(())

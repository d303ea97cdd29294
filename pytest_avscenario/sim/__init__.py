"""The simulator layer: worlds built on highway-env, agents, behaviours, drivers, recording.

``from pytest_avscenario.sim import World, SimError, behaviors`` is cheap: this package and
:mod:`.behaviors` import neither highway-env nor pygame, matplotlib or pandas. highway-env is
imported when a :class:`World` builds its first road; pygame when a world renders.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from .errors import DriverError, SimError

if TYPE_CHECKING:  # pragma: no cover
    from .world import World

__all__ = ["World", "SimError", "DriverError", "Trajectory", "Observation", "behaviors",
           "drivers", "places"]

_LAZY = {
    "World": (".world", "World"),
    "Trajectory": ("..trajectory", "Trajectory"),  # the sim -> monitors contract lives apart
    "Observation": (".observation", "Observation"),
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        mod, attr = _LAZY[name]
        value = getattr(importlib.import_module(mod, __name__), attr)
        globals()[name] = value
        return value
    if name in ("behaviors", "drivers", "places"):
        import importlib

        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

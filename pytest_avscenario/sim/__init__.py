"""The simulator layer: worlds built on highway-env, agents, behaviours, drivers, recording.

``from pytest_avscenario.sim import World, SimError, behaviors`` is cheap: this package and
:mod:`.behaviors` import neither highway-env nor pygame, matplotlib or pandas. highway-env is
imported when a :class:`World` builds its first road; pygame when a world renders.

One concept per module; scenario code talks to :mod:`.world`, the rest talk to each other:

* :mod:`.world` — the façade: build one road, place agents, run, keep the trajectory; its
  small interface for the engine, roads and behaviours (``lane_index``, ``reindex``,
  ``movers``, ``observe``, ``turn_route``, ``all_way_stop``).
* :mod:`.roads`, :mod:`.network` — the road types (straight, two-way, intersection) and a
  network of intersections joined by links; :mod:`.highway` — highways of straight and
  curved segments with lane drops and on-ramps.
* :mod:`.places` — lanes, spots, stop lines, crosswalks, routes: what scenarios name.
* :mod:`.lanes` — lane tracking: the index of a road's lanes, stop marks, where agents are.
* :mod:`.engine` — our highway-env lane, road and vehicle subclasses (the only module that
  imports highway-env at import time); :mod:`._hwenv` loads its core without gym.
* :mod:`.behaviors` — what non-ego agents do; :mod:`.control` — the control laws they use.
* :mod:`.right_of_way` — the all-way-stop rule, shared by behaviours and the autopilot.
* :mod:`.signals` — traffic lights, stop signs and stop lines read from a map file (or a
  built intersection's lights), the lights' fixed-time plan, when a driver stops for one.
* :mod:`.geometry` — angle wrapping and footprint overlap.
* :mod:`.observation` — what a driver sees; :mod:`.view` — the read-only view of the whole
  scene (``world.view()``); :mod:`.drivers` — who drives the ego (the autopilot with its
  route path, perception, junction and parking modules; ``highway_agent``, an agent trained
  on highway-env in highway-env's frame).
* :mod:`.recording` — per-step recording into the Trajectory the monitors read.
* :mod:`.render` — PNG/GIF pictures of a recorded run and the annotated still; :mod:`.clip`
  — a run coded compactly for the card's player and the still (no monitor or report import:
  the evidence it shows comes from :mod:`pytest_avscenario.monitors.evidence`);
  :mod:`.errors` — SimError, DriverError.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from .errors import AgentSpeedWarning, AgentStepWarning, DriverError, SimError, SimWarning

if TYPE_CHECKING:  # pragma: no cover
    from .world import World

__all__ = ["World", "SimError", "DriverError", "SimWarning", "AgentStepWarning",
           "AgentSpeedWarning", "Trajectory", "Observation", "behaviors", "drivers", "places"]

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

"""scenariogeneration's writers, imported without what the exports never use.

``import scenariogeneration`` imports scipy.integrate (for the arc length of spirals and
parametric cubics, which the exports do not write), and with it scipy.optimize and
scipy.special, and xmlschema (for its OpenSCENARIO reader): 0.9 s of CPU per process that
exports (2.4-4 s of wall time on a loaded 2-core machine), 0.06 s without them. So
:func:`load` imports scenariogeneration with two stand-ins in ``sys.modules`` for the time of
that import only: ``scipy.integrate`` with a ``quad`` that imports the real module when it is
first called, and ``xmlschema`` that imports the real module at its first attribute. Modules
that bound them (``scenariogeneration.xodr.geometry.quad``,
``scenariogeneration.xosc.xosc_reader.xmlschema``) work as before, importing the real thing
when they are used; every other import afterwards gets the real modules.
"""

from __future__ import annotations

import importlib
import sys
import threading
import types
from typing import Any

__all__ = ["load"]

_LOCK = threading.Lock()


class _Deferred(types.ModuleType):
    """A module imported for real at its first attribute."""

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        return getattr(_real(self.__name__), name)


def _real(name: str) -> types.ModuleType:
    mod = sys.modules.get(name)
    if isinstance(mod, _Deferred):
        del sys.modules[name]
    return importlib.import_module(name)


def _quad(*args: Any, **kwargs: Any) -> Any:
    return _real("scipy.integrate").quad(*args, **kwargs)


def load() -> tuple[Any, Any]:
    """``(scenariogeneration.xodr, scenariogeneration.xosc)``."""
    with _LOCK:
        if "scenariogeneration.xosc" not in sys.modules:
            placed = []
            for name in ("scipy.integrate", "xmlschema"):
                if name not in sys.modules:
                    sys.modules[name] = stand_in = _Deferred(name)
                    placed.append((name, stand_in))
            if any(name == "scipy.integrate" for name, _ in placed):
                sys.modules["scipy.integrate"].quad = _quad
            try:
                importlib.import_module("scenariogeneration")
            finally:
                for name, stand_in in placed:
                    if sys.modules.get(name) is stand_in:
                        del sys.modules[name]
    from scenariogeneration import xodr, xosc

    return xodr, xosc

"""The driver under test of a session and of each case, as the report records it.

The options name one driver (``--avs-driver``, ini ``avs_driver``, else the autopilot); a
conftest or test module may override the ``avs_driver`` fixture, and then the case's driver
is that fixture's value. Identities are plain dicts (:mod:`pytest_avscenario.sim.drivers.identity`).
"""

from __future__ import annotations

import inspect
import os
from typing import Any

import pytest

from .stash import driver_key, settings_key

#: the module whose ``avs_driver`` fixture is the plugin's own (any other is a user's)
_OWN_FIXTURES = f"{__package__}.hooks"


def session_driver(config: pytest.Config) -> dict[str, Any]:
    """The identity of the driver the options name (``--avs-driver``, ini ``avs_driver``, the
    default autopilot), with where it came from; computed once per process."""
    found = config.stash.get(driver_key, None)
    if found is None:
        settings = config.stash[settings_key]
        name = settings.driver
        if name is None or (isinstance(name, str) and ":" not in name):
            # a built-in name (the options checked it): said without importing the drivers,
            # so the header of a run without scenario tests loads no simulator and no numpy
            found = {"name": (name or "autopilot").strip(), "kind": "builtin"}
        else:
            from ..sim.drivers.identity import describe

            found = describe(name)
        found["from"] = ("--avs-driver" if "driver" in settings.command_line
                         else "ini avs_driver" if config.getini("avs_driver") not in (None, "")
                         else "default")
        config.stash[driver_key] = found
    return found


def driver_identity(item: pytest.Item) -> dict[str, Any] | None:
    """Who drives the ego of ``item``'s case: the options' driver, or the value of the
    ``avs_driver`` fixture a conftest or module overrides (its class, or what its
    ``describe()`` says), with the fixture's file. None for a test without a driver."""
    if "avs_driver" not in getattr(item, "fixturenames", ()):
        return None  # no `world` nor `avs_driver`: no ego under test
    defs = item._fixtureinfo.name2fixturedefs.get("avs_driver", ())
    if not defs or getattr(defs[-1].func, "__module__", None) == _OWN_FIXTURES:
        return session_driver(item.config)
    funcargs = getattr(item, "funcargs", {})
    if "avs_driver" not in funcargs:
        return None  # its fixture did not run (an earlier one failed): unknown, not guessed
    from ..sim.drivers.identity import describe

    out = describe(funcargs["avs_driver"])
    try:
        where = os.path.relpath(inspect.getsourcefile(defs[-1].func) or "", item.config.rootpath)
    except (TypeError, ValueError):
        where = ""
    out["from"] = f"avs_driver fixture ({where})" if where else "avs_driver fixture"
    return out

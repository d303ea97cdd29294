"""The driver under test of a session and of each case, as the report records it.

The options name one driver (``--avs-driver``, ini ``avs_driver``, else the autopilot); a
conftest or test module may override the ``avs_driver`` fixture, and then the case's driver
is that fixture's value (:func:`.items.driver_identity`). Identities are plain dicts
(:mod:`pytest_avscenario.sim.drivers.identity`).
"""

from __future__ import annotations

from typing import Any

import pytest

from .stash import driver_key, settings_key


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

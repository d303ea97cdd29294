"""pytest-avscenario: scenario-based falsification of autonomous-vehicle stacks in pytest.

A test declares an abstract scenario with :func:`scenario`; the plugin expands it into
concrete cases, simulates each on highway-env with the AV under test driving, judges the
trajectory with monitors (:mod:`pytest_avscenario.monitors`), minimizes failures and reports.
Importing this package is light: no simulator, scipy or plotting library is loaded.
"""

import importlib
from typing import Any

# Names are loaded on first use (PEP 562): pytest loads the plugin, and with it this package, in
# every run of a repository that has it installed, scenario tests or not; numpy (the
# distributions, the Case) must not be part of that price.
_LAZY = {
    "Case": "case",
    "example": "markers", "scenario": "markers",
    "Choice": "space", "Constant": "space", "Distribution": "space", "FeatureSpace": "space",
    "IntRange": "space", "Normal": "space", "SpaceError": "space", "Uniform": "space",
    "MapLane": "sim.opendrive",
}

__version__ = "0.1.0"

__all__ = [
    "Case",
    "Choice",
    "Constant",
    "Distribution",
    "FeatureSpace",
    "IntRange",
    "MapLane",
    "Normal",
    "SpaceError",
    "Uniform",
    "example",
    "scenario",
    "__version__",
]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value  # once: later lookups do not come here
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))

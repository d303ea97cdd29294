"""pytest-avscenario: scenario-based falsification of autonomous-vehicle stacks in pytest.

A test declares an abstract scenario with :func:`scenario`; the plugin expands it into
concrete cases, simulates each on highway-env with the AV under test driving, judges the
trajectory with monitors (:mod:`pytest_avscenario.monitors`), minimizes failures and reports.
Importing this package is light: no simulator, scipy or plotting library is loaded.
"""

from .case import Case
from .markers import example, scenario
from .space import Choice, Constant, Distribution, FeatureSpace, IntRange, Normal, SpaceError, Uniform

__version__ = "0.1.0"

__all__ = [
    "Case",
    "Choice",
    "Constant",
    "Distribution",
    "FeatureSpace",
    "IntRange",
    "Normal",
    "SpaceError",
    "Uniform",
    "example",
    "scenario",
    "__version__",
]

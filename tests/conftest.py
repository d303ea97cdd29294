"""Shared test setup.

``pytester`` runs pytest in this process and afterwards forgets every module the run
imported; numpy/scipy C extensions cannot be loaded twice in one process, so the heavy
dependencies a scenario run imports are imported here, once, before any pytester run.
"""

import importlib

pytest_plugins = ["pytester"]

for _mod in ("numpy.fft", "scipy.stats", "scipy.spatial", "scipy.optimize", "shapely.geometry",
             "highway_env", "matplotlib"):
    try:
        importlib.import_module(_mod)
    except ImportError:  # pragma: no cover - a missing optional part shows in its own tests
        pass

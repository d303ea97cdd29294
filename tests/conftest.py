"""Shared test setup.

``pytester`` runs pytest in this process and afterwards forgets every module the run
imported. numpy/scipy C extensions cannot be loaded twice in one process, and a re-imported
module brings new classes that objects from the old import are not instances of; so the
modules a scenario run imports lazily are imported here, once, before any pytester run.
"""

import importlib
from pathlib import Path

pytest_plugins = ["pytester"]

for _mod in ("numpy.fft", "scipy.stats", "scipy.spatial", "scipy.optimize", "shapely.geometry",
             "highway_env", "matplotlib", "PIL.Image", "hypothesis",
             # the plugin's own lazily imported modules: a run must not re-import them while
             # classes from an earlier run's import are still referenced
             "pytest_avscenario.sim.world", "pytest_avscenario.sim.roads",
             "pytest_avscenario.sim.places", "pytest_avscenario.sim.behaviors",
             "pytest_avscenario.sim.engine", "pytest_avscenario.sim.render",
             "pytest_avscenario.sim.drivers.autopilot", "pytest_avscenario.monitors",
             "pytest_avscenario.report.build", "pytest_avscenario.report.plots",
             "pytest_avscenario.report.recording", "pytest_avscenario.report.player",
             # stacks out of process: protobuf aborts the process when osi3's generated
             # modules are imported a second time
             "zmq", "osi3.osi_sensorview_pb2", "osi3.osi_motionrequest_pb2",
             "osi3.osi_trafficupdate_pb2", "osi3.osi_version_pb2", "google.protobuf.message",
             "pytest_avscenario.stack.client", "pytest_avscenario.stack.kit",
             "pytest_avscenario.stack.vehicle",
             "pytest_avscenario.shrink", "pytest_avscenario.db"):
    try:
        importlib.import_module(_mod)
    except ImportError:  # pragma: no cover - a missing optional part shows in its own tests
        pass


import pytest  # noqa: E402


@pytest.fixture(autouse=True)
def _terminal_like_output(monkeypatch):
    """Inner pytest runs print as on a terminal, whatever machine runs the suite: with ``CI``
    set, pytest writes whole failure messages into the short test summary too, which would
    change what the tests read from the output."""
    monkeypatch.delenv("CI", raising=False)
    monkeypatch.delenv("BUILD_NUMBER", raising=False)
    # an inner run is never this suite's xdist worker: under `-n 2` it would inherit the
    # worker's name, which plugins read as "xdist is running me" (pytest-benchmark then warns)
    monkeypatch.delenv("PYTEST_XDIST_WORKER", raising=False)
    monkeypatch.delenv("PYTEST_XDIST_WORKER_COUNT", raising=False)


_SLOW = Path(__file__).with_name("slow_tests.txt")


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(session, config, items):
    """Mark the long runs listed in ``slow_tests.txt`` ``slow`` before ``-m`` selects; a line
    naming no collected test is an error (a renamed test would silently join the fast loop)."""
    listed = {line.strip() for line in _SLOW.read_text().splitlines()
              if line.strip() and not line.startswith("#")}
    seen = set()
    for item in items:
        if item.nodeid in listed:
            item.add_marker(pytest.mark.slow)
            seen.add(item.nodeid)
    whole_run = not config.args or config.args == ["tests"] or config.args == [str(_SLOW.parent)]
    if whole_run and not config.getoption("keyword") and listed - seen:
        raise pytest.UsageError(f"{_SLOW.name} names tests that do not exist: "
                                + ", ".join(sorted(listed - seen)))

"""What an xdist controller imports while its workers run (pytest_plugin/preload.py): only what
the end of the run imports anyway — scipy's ε-coverage modules for a scenario space with a
continuous parameter, not for one of choices and integers alone. (The Ctrl-C it speeds up is
tested in test_hardening_process.py; its seconds are bench/bench_stop.py's.)"""

from __future__ import annotations

from pytest_avscenario.pytest_plugin.preload import _has_continuous
from pytest_avscenario.space import Choice, FeatureSpace, IntRange, Uniform


def test_scipy_is_loaded_ahead_only_for_a_space_whose_coverage_needs_it():
    mixed = FeatureSpace({"gap": Uniform(5, 40), "lane": Choice([0, 1])}).describe()
    discrete = FeatureSpace({"lane": Choice([0, 1]), "cars": IntRange(1, 4)}).describe()
    assert _has_continuous(mixed)
    assert not _has_continuous(discrete)
    # a description the report cannot rebuild either: loaded ahead (the report tries, says why)
    assert _has_continuous({"gap": {"type": "Warped"}})

"""The driver under test in the report: which stack each test's cases ran, for the run as a
whole, and whether a baseline run was another stack.

Each error-table row carries the identity of the driver that drove its ego (``row.driver``,
see :mod:`pytest_avscenario.sim.drivers.identity`). A test's driver is the one its rows
agree on; the run's is the one its tests agree on. Where they differ (a conftest overrides
``avs_driver`` for some tests only), the identity is ``{"name": "several", "kind":
"several", "drivers": [...]}`` — the report then says so rather than picking one.
"""

from __future__ import annotations

import json
from typing import Any, Iterable, Mapping

from ..outcome import CaseRow
from ..sim.drivers.identity import identity_text, same_driver

__all__ = ["drivers_of", "driver_properties", "baseline_driver_warning"]


def _key(identity: Mapping[str, Any]) -> str:
    # where it was configured does not make it another driver
    return json.dumps({k: v for k, v in identity.items() if k != "from"}, sort_keys=True, default=str)


def _agreed(identities: Iterable[Mapping[str, Any]]) -> dict[str, Any] | None:
    unique = {}
    for ident in identities:
        unique.setdefault(_key(ident), dict(ident))
    if not unique:
        return None
    if len(unique) == 1:
        return next(iter(unique.values()))
    return {"name": "several", "kind": "several", "drivers": list(unique.values())}


def drivers_of(rows: Iterable[CaseRow], default: Mapping[str, Any] | None = None
               ) -> tuple[dict[str, Any] | None, dict[str, dict[str, Any]]]:
    """``(the run's driver, {test: its driver})`` from the rows; ``default`` (the options'
    driver) is the run's when no row names one (every test without a driver)."""
    by_test: dict[str, list[Mapping[str, Any]]] = {}
    for r in rows:
        if r.driver is not None and r.origin != "shrink":
            by_test.setdefault(r.test, []).append(r.driver)
    tests = {test: _agreed(idents) for test, idents in by_test.items()}
    tests = {t: d for t, d in tests.items() if d is not None}
    run = _agreed(tests.values())
    return (run if run is not None else (dict(default) if default else None)), tests


def driver_properties(run: Mapping[str, Any] | None, tests: Mapping[str, Mapping[str, Any]]) -> dict[str, str]:
    """JUnit suite properties: ``avs.driver`` (the line people read), ``avs.driver.<key>``
    for name, kind, file, sha256 and the rest, and ``avs.test[<test>].driver`` for each test
    whose driver is not the run's one driver."""
    props: dict[str, str] = {}
    if not run:
        return props
    props["avs.driver"] = identity_text(run)
    if run.get("kind") != "several":
        for key, value in run.items():
            if value is not None:
                props[f"avs.driver.{key}"] = str(value)
    for test, ident in tests.items():
        if run.get("kind") == "several" or not same_driver(ident, run):
            props[f"avs.test[{test}].driver"] = identity_text(ident)
    return props


def baseline_driver_warning(run: Mapping[str, Any] | None, baseline: Any) -> str | None:
    """One line when ``--avs-baseline``'s run recorded another driver than this run's:
    a comparison of two stacks, not a regression check of one. None when they agree or the
    baseline recorded none (a summary from before drivers were recorded)."""
    before = getattr(baseline, "driver", None)
    if not run or not before or same_driver(run, before):
        return None
    return (f"the baseline {getattr(baseline, 'path', '')} was run with driver "
            f"{identity_text({k: v for k, v in before.items() if k != 'from'})}, this run with "
            f"{identity_text({k: v for k, v in run.items() if k != 'from'})}: the comparison is "
            "between two different stacks")

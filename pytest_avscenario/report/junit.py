"""Scenario results in JUnit XML, the format every CI server reads.

Two levels, both as ``<property name=… value=…>`` elements:

* per case (one ``<testcase>`` per simulated case): :func:`case_properties` turns an
  error-table row into ``avs.params``, ``avs.rho.<metric>``, ``avs.verdict`` … pairs. The
  plugin appends them to ``item.user_properties`` during the run; pytest's own JUnit writer
  puts them in the test case's ``<properties>`` in every ``junit_family``, without the
  warning ``record_property`` gives under xunit2, and xdist carries them from the workers.
* per suite (the run): seed, versions and the paper's per-test numbers from
  :func:`.summary.suite_properties`. ``record_testsuite_property`` is lost under xdist (its
  writes happen on workers, which write no XML), so they are added on the controller after
  all reports are in: either through pytest's ``LogXML.add_global_property`` before pytest
  writes the file (:func:`add_suite_properties_to_logxml`), or by rewriting the written file
  atomically (:func:`add_suite_properties`), which needs no private pytest API.

junit_family: we keep pytest's default ``xunit2``, the flavour of the Jenkins xunit
plugin's ``junit-10.xsd`` that junitparser's ``xunit2`` module models. ``xunit1`` adds
``file``/``line`` attributes that schema rejects and buys nothing for properties. One caveat
holds for every family: the strict ``junit-10.xsd`` has no ``<properties>`` inside
``<testcase>`` (pytest's docs warn that per-test properties "break schema verification");
the Jenkins JUnit plugin, GitLab and junitparser read them all the same. Suite-level
properties are valid under the strict schema, so for strict consumers (Jenkins' xUnit plugin)
each case's properties can go there instead, named ``avs.case[<item>].<name>``
(:func:`case_suite_properties`, ``--avs-junit=strict``). Nothing here imports pytest.
"""

from __future__ import annotations

import json
import os
import re
import xml.etree.ElementTree as ET
from typing import Any, Iterable, Mapping

from ..codec import jsonable, rho_to_str
from ..outcome import CaseRow
from .table import atomic_write_bytes

__all__ = [
    "case_properties",
    "case_suite_properties",
    "add_suite_properties",
    "add_suite_properties_to_logxml",
    "read_properties",
    "xml_safe",
]

# XML 1.0 forbids most control characters even when escaped; pytest shows them as "#xNN"
# and so do we, so a stray byte in a parameter value cannot make the file unreadable.
_ILLEGAL_XML = re.compile("[^\u0009\u000a\u000d\u0020-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")


def xml_safe(value: Any) -> str:
    """``str(value)`` with characters XML cannot hold replaced by ``#xNN``."""
    return _ILLEGAL_XML.sub(lambda m: f"#x{ord(m.group()):02X}", str(value))


def _num(value: float | None) -> str:
    return "" if value is None else rho_to_str(value)


def case_properties(
    row: CaseRow | Mapping[str, Any],
    *,
    minimized: Mapping[str, Any] | None = None,
    shrink_sims: int | None = None,
) -> list[tuple[str, str]]:
    """The ``(name, value)`` properties of one case, for ``item.user_properties``.

    ``avs.sampler``, ``avs.index``, ``avs.seed``, ``avs.origin``, ``avs.params`` (JSON,
    keys in declaration order), ``avs.rho.<metric>`` (``repr`` of the float, ``inf`` /
    ``-inf``), ``avs.verdict``, ``avs.sim_time_s``; for a shrunk counterexample also
    ``avs.minimized`` (JSON of the minimal parameters), ``avs.minimized_rho.<metric>`` (the
    minimized case's own robustness; ``avs.rho.*`` are the case as found's) and
    ``avs.shrink_sims`` (simulations the shrinking spent), from the row unless given; ``avs.error`` when the simulation raised;
    ``avs.avoidable.<metric>`` (``true``/``false``/``unknown``) for a counterexample judged
    against the reference driver, ``avs.conflict.<metric>`` (the other agent of the conflict
    it was judged on, ``agent@seconds``), ``avs.minimized_avoidable.<metric>`` for the
    minimized case's own judgement, and ``avs.unsafe_first`` (``agent@seconds``);
    ``avs.driving_score``, ``avs.route_completion`` (0..1) and ``avs.infractions`` (the
    Leaderboard infraction kinds, comma-separated) when the run has a driving score.
    """
    r = CaseRow.coerce(row)
    minimized = r.minimized if minimized is None else minimized
    shrink_sims = r.shrink_sims if shrink_sims is None else shrink_sims
    props = [
        ("avs.sampler", r.sampler),
        ("avs.index", str(r.index)),
        ("avs.seed", "" if r.seed is None else str(r.seed)),
        ("avs.origin", r.origin),
        ("avs.params", json.dumps(jsonable(dict(r.params)), ensure_ascii=False)),
    ]
    props += [(f"avs.rho.{m}", _num(v)) for m, v in r.rho.items()]
    props += [("avs.verdict", r.verdict), ("avs.sim_time_s", f"{r.sim_time_s:.4f}")]
    if r.score is not None:
        props.append(("avs.driving_score", f"{r.driving_score:.6g}"))
        props.append(("avs.route_completion", f"{float(r.score['route_completion']):.6g}"))
        kinds = [i.get("kind") for i in r.score.get("infractions", ())]
        if kinds:
            props.append(("avs.infractions", ",".join(str(k) for k in kinds)))
    if minimized is not None:
        props.append(("avs.minimized", json.dumps(jsonable(dict(minimized)), ensure_ascii=False)))
    if shrink_sims is not None:
        props.append(("avs.shrink_sims", str(int(shrink_sims))))
    if minimized is not None and r.minimized_rho is not None:  # avs.rho.* is the case as found
        props += [(f"avs.minimized_rho.{m}", _num(v)) for m, v in r.minimized_rho.items()]
    if r.error:
        props.append(("avs.error", r.error))
    if r.flaky:
        props.append(("avs.flaky", "true"))
    for m, ok in (r.avoidable or {}).items():
        props.append((f"avs.avoidable.{m}", {True: "true", False: "false"}.get(ok, "unknown")))
    for m, c in (r.conflicts or {}).items():
        props.append((f"avs.conflict.{m}", f"{c.get('agent')}@{c.get('t')}"))
    for m, ok in (r.minimized_avoidable or {}).items():
        props.append((f"avs.minimized_avoidable.{m}", {True: "true", False: "false"}.get(ok, "unknown")))
    if r.unsafe_first:
        props.append(("avs.unsafe_first", f"{r.unsafe_first.get('agent')}@{r.unsafe_first.get('t')}"))
    return [(name, xml_safe(value)) for name, value in props]


def case_suite_properties(row: CaseRow | Mapping[str, Any]) -> dict[str, str]:
    """One case's properties at suite level, ``avs.case[<item>].<name>``: where the strict
    junit-10 schema allows them (it has no ``<properties>`` inside ``<testcase>``)."""
    r = CaseRow.coerce(row)
    return {f"avs.case[{xml_safe(r.item)}].{name[len('avs.'):]}": value
            for name, value in case_properties(r)}


def add_suite_properties_to_logxml(logxml: Any, props: Mapping[str, Any]) -> None:
    """Add suite properties through pytest's JUnit writer before it writes the file.

    ``logxml`` is ``config.stash.get(_pytest.junitxml.xml_key, None)`` on the controller
    (None when ``--junitxml`` is not given, or on an xdist worker: then nothing to do). Call
    it from a ``pytest_sessionfinish`` hook marked ``tryfirst=True``: pytest's writer is a
    plain ``pytest_sessionfinish`` of a plugin registered at configure time, so ``tryfirst``
    runs ours before it writes. Existing properties of the same name are replaced.
    """
    if logxml is None:
        return
    names = set(props)
    kept = [(n, v) for n, v in getattr(logxml, "global_properties", []) if n not in names]
    logxml.global_properties[:] = kept
    for name, value in props.items():
        logxml.add_global_property(str(name), xml_safe(value))


def add_suite_properties(path: str | os.PathLike, props: Mapping[str, Any]) -> None:
    """Add ``props`` to every ``<testsuite>`` of an already written JUnit XML file.

    For use on the controller after pytest wrote the file: a ``pytest_sessionfinish`` hook
    marked ``trylast=True``, or ``pytest_unconfigure``. Properties of the same name are
    replaced (calling twice is harmless); the ``<properties>`` element goes first in the
    suite, where pytest and Ant put it. The file is rewritten atomically.
    """
    tree = ET.parse(os.fspath(path))
    root = tree.getroot()
    suites = [root] if root.tag == "testsuite" else root.findall("testsuite")
    if not suites:
        raise ValueError(f"{path}: no <testsuite> element; is this a JUnit XML file?")
    for suite in suites:
        node = suite.find("properties")
        if node is None:
            node = ET.Element("properties")
            suite.insert(0, node)
        for prop in list(node):
            if prop.get("name") in props:
                node.remove(prop)
        for name, value in props.items():
            ET.SubElement(node, "property", name=xml_safe(name), value=xml_safe(value))
    data = ET.tostring(root, encoding="utf-8", xml_declaration=True)
    atomic_write_bytes(path, data)


def read_properties(path: str | os.PathLike) -> dict[str, Any]:
    """Suite and per-case properties of a JUnit file, for tests and tools.

    ``{"suite": {name: value}, "cases": {"<classname>::<name>": [(name, value), …]}}``.
    """
    root = ET.parse(os.fspath(path)).getroot()
    suites: Iterable[ET.Element] = [root] if root.tag == "testsuite" else root.iter("testsuite")
    out: dict[str, Any] = {"suite": {}, "cases": {}}
    for suite in suites:
        for prop in suite.findall("properties/property"):
            out["suite"][prop.get("name")] = prop.get("value")
        for case in suite.findall("testcase"):
            key = f"{case.get('classname')}::{case.get('name')}"
            out["cases"][key] = [(p.get("name"), p.get("value")) for p in case.findall("properties/property")]
    return out

"""JUnit XML: per-case and suite properties written by a real pytest run, read back by a
JUnit library (junitparser) and validated against the xunit2 schema CI servers use.

The pytester project's conftest wires the report helpers into pytest's hooks the way the
plugin does: rows travel on the report (so xdist carries them), the controller summarizes,
and the suite properties go in either through pytest's LogXML before it writes or by
rewriting the written file.
"""

import json
import math
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from pytest_avscenario.report.junit import add_suite_properties, case_properties, read_properties, xml_safe

DATA = Path(__file__).parent / "data"
TEST = "test_scen.py::test_follow"

CONFTEST = """
import os
import pytest
from pytest_avscenario.report.junit import add_suite_properties, add_suite_properties_to_logxml
from pytest_avscenario.report.summary import TestInfo, suite_properties, summarize
from pytest_avscenario.outcome import CaseRow
from pytest_avscenario.space import FeatureSpace, Uniform

ROWS = pytest.StashKey[list]()
INFO = {"test_scen.py::test_follow": TestInfo(
    metrics=("distance", "ttc"), space=FeatureSpace({"gap": Uniform(10.0, 40.0), "label": "x"}))}


def _props(config):
    summary = summarize(config.stash[ROWS], INFO)
    return suite_properties(summary, seed=7, versions={"pytest-avscenario": "0.1.0", "highway-env": "1.12.1"})


class ViaLogXML:
    @pytest.hookimpl(tryfirst=True)
    def pytest_sessionfinish(self, session):
        from _pytest.junitxml import xml_key
        add_suite_properties_to_logxml(session.config.stash.get(xml_key, None), _props(session.config))


class ViaRewrite:
    @pytest.hookimpl(trylast=True)
    def pytest_sessionfinish(self, session):
        path = session.config.option.xmlpath
        if path:
            add_suite_properties(path, _props(session.config))


def pytest_configure(config):
    config.stash[ROWS] = []
    if not hasattr(config, "workerinput"):
        mode = os.environ["AVS_JUNIT_MODE"]
        config.pluginmanager.register(ViaLogXML() if mode == "logxml" else ViaRewrite())


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item, call):
    report = yield
    row = getattr(item, "avs_row", None)
    if row is not None and report.when == "call":
        report.avs_row = CaseRow.coerce(row).to_json()  # plain JSON data survives xdist's serialization
    return report


def pytest_runtest_logreport(report):
    row = getattr(report, "avs_row", None)
    if row is not None:
        pytest.avs_config.stash[ROWS].append(CaseRow.from_json(row))


@pytest.hookimpl(trylast=True)
def pytest_sessionstart(session):
    pytest.avs_config = session.config
"""

TEST_MODULE = """
import math
import pytest
from pytest_avscenario.report.junit import case_properties


@pytest.mark.parametrize("i", range(4))
def test_follow(request, i):
    gap = 10.0 + 10 * i
    rho = {"distance": gap - 25.0, "ttc": -0.5 if i == 3 else math.inf}
    verdict = "fail" if min(rho.values()) < 0 else "pass"
    row = {"test": "test_scen.py::test_follow", "item": request.node.nodeid, "sampler": "halton",
           "index": i, "seed": 7, "origin": "sampled", "params": {"gap": gap, "label": "<lead & co>"},
           "rho": rho, "verdict": verdict, "sim_time_s": 0.01, "error": None}
    request.node.avs_row = row
    extra = {"minimized": {"gap": 24.5, "label": "<lead & co>"}, "shrink_sims": 17} if i == 0 else {}
    request.node.user_properties.extend(case_properties(row, **extra))
    assert verdict == "pass", "a safety metric was violated"
"""


def _validate(xml_path: Path, xsd: str):
    xmlschema = pytest.importorskip("xmlschema", reason="schema validation needs the xmlschema package")
    xmlschema.XMLSchema(str(DATA / xsd)).validate(str(xml_path))


def _run(pytester, monkeypatch, mode, xdist=False):
    monkeypatch.setenv("AVS_JUNIT_MODE", mode)
    pytester.makeconftest(CONFTEST)
    pytester.makepyfile(test_scen=TEST_MODULE)
    # The real plugin stays out: this test exercises the report helpers with its own wiring.
    args = ["--junitxml=out.xml", "-p", "no:cacheprovider", "-p", "no:randomly", "-p", "no:avscenario"]
    if xdist:
        pytest.importorskip("xdist")
        result = pytester.runpytest_subprocess(*args, "-n", "2")
    else:
        result = pytester.runpytest(*args)
    result.assert_outcomes(passed=1, failed=3)
    assert "PytestWarning" not in result.stdout.str()  # user_properties: no xunit2 warning
    return pytester.path / "out.xml"


def _check_with_junitparser(xml_path: Path):
    from junitparser.xunit2 import JUnitXml

    xml = JUnitXml.fromfile(str(xml_path))
    (suite,) = list(xml)
    suite_props = {p.name: p.value for p in suite.properties()}
    key = f"avs.test[{TEST}][halton]"
    assert suite_props["avs.seed"] == "7"
    assert suite_props["avs.version.highway-env"] == "1.12.1"
    assert suite_props[f"{key}.samples"] == "4"
    assert suite_props[f"{key}.violations.distance"] == "2"
    assert suite_props[f"{key}.violations.ttc"] == "1"
    assert 0 < float(suite_props[f"{key}.epsilon"]) <= 1
    cases = {c.name: c for c in suite}
    assert sorted(cases) == [f"test_follow[{i}]" for i in range(4)]
    first = {p.name: p.value for p in cases["test_follow[0]"].properties()}
    assert json.loads(first["avs.params"]) == {"gap": 10.0, "label": "<lead & co>"}
    assert float(first["avs.rho.distance"]) == -15.0 and first["avs.rho.ttc"] == "inf"
    assert first["avs.verdict"] == "fail" and first["avs.shrink_sims"] == "17"
    assert json.loads(first["avs.minimized"])["gap"] == 24.5
    last = {p.name: p.value for p in cases["test_follow[3]"].properties()}
    assert last["avs.rho.ttc"] == "-0.5" and "avs.minimized" not in last
    assert not cases["test_follow[0]"].is_passed and cases["test_follow[2]"].is_passed


def _strip_case_properties(src: Path, dst: Path) -> None:
    tree = ET.parse(src)
    for case in tree.getroot().iter("testcase"):
        for props in case.findall("properties"):
            case.remove(props)
    tree.write(dst, encoding="utf-8", xml_declaration=True)


@pytest.mark.parametrize("mode", ["logxml", "rewrite"])
def test_junit_file_has_case_and_suite_properties_and_validates(pytester, monkeypatch, mode):
    xml_path = _run(pytester, monkeypatch, mode)
    _check_with_junitparser(xml_path)
    _validate(xml_path, "junit-xunit2.xsd")
    # Against the strict schema only the per-case properties are in the way; everything we
    # add at suite level is valid there too.
    stripped = pytester.path / "stripped.xml"
    _strip_case_properties(xml_path, stripped)
    _validate(stripped, "junit-xunit2-strict.xsd")
    xmlschema = pytest.importorskip("xmlschema")
    with pytest.raises(xmlschema.XMLSchemaValidationError, match="properties"):
        xmlschema.XMLSchema(str(DATA / "junit-xunit2-strict.xsd")).validate(str(xml_path))


def test_suite_properties_reach_the_controller_file_under_xdist(pytester, monkeypatch):
    xml_path = _run(pytester, monkeypatch, "logxml", xdist=True)
    _check_with_junitparser(xml_path)
    _validate(xml_path, "junit-xunit2.xsd")


def test_the_schema_rejects_what_ci_would_reject(tmp_path):
    bad = tmp_path / "bad.xml"
    bad.write_text('<testsuites><testsuite name="s" tests="1" failures="0" errors="0">'
                   '<testcase classname="c"/></testsuite></testsuites>')  # a case without a name
    xmlschema = pytest.importorskip("xmlschema")
    with pytest.raises(xmlschema.XMLSchemaValidationError):
        _validate(bad, "junit-xunit2.xsd")


def test_rewrite_is_idempotent_and_keeps_other_properties(tmp_path):
    path = tmp_path / "j.xml"
    path.write_text('<?xml version="1.0"?><testsuites><testsuite name="pytest" tests="0" failures="0" '
                    'errors="0"><properties><property name="ci.job" value="42"/></properties>'
                    "</testsuite></testsuites>")
    add_suite_properties(path, {"avs.seed": "1", "avs.note": "a\x01b"})
    add_suite_properties(path, {"avs.seed": "2"})
    props = read_properties(path)["suite"]
    assert props == {"ci.job": "42", "avs.note": "a#x01b", "avs.seed": "2"}
    _validate(path, "junit-xunit2-strict.xsd")


def test_case_properties_encode_infinities_and_control_characters():
    row = {"test": "t::a", "sampler": "mab", "index": 3, "seed": None, "origin": "replay",
           "params": {"name": "bad\x07byte"}, "rho": {"ttc": math.inf, "lane": -math.inf},
           "verdict": "error", "sim_time_s": 1.0, "error": "boom <here>"}
    props = dict(case_properties(row))
    assert props["avs.rho.ttc"] == "inf" and props["avs.rho.lane"] == "-inf"
    assert props["avs.seed"] == "" and props["avs.error"] == "boom <here>"
    assert "\x07" not in props["avs.params"] and xml_safe("\x07") == "#x07"
    assert "avs.minimized" not in props and "avs.shrink_sims" not in props


@pytest.mark.parametrize("xdist", [False, True])
def test_strict_mode_writes_a_file_valid_against_the_junit_10_schema(pytester, xdist):
    pytester.makepyfile(test_gap="""
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import distance
from pytest_avscenario.trajectory import Trajectory

@scenario(x=Uniform(0, 1), samples=4, monitors=[distance(5.0, kind="centre")], accept=["distance"])
def test_gap(case):
    gap = 20 * case.x
    return Trajectory.from_arrays([0.0, 0.1], {"ego": {"x": [0.0, 0.0], "y": [0.0, 0.0]},
                                               "lead": {"x": [gap, gap], "y": [3.0, 3.0]}})
""")
    args = ["--avs-db=none", "--avs-seed=1", "--avs-junit=strict", "--junitxml=out.xml",
            "-p", "no:cacheprovider"]
    if xdist:
        pytest.importorskip("xdist")
        result = pytester.runpytest_subprocess(*args, "-n", "2")
    else:
        result = pytester.runpytest(*args)
    assert result.ret == pytest.ExitCode.TESTS_FAILED  # halton-003 (x = 0.125) violates distance
    xml_path = pytester.path / "out.xml"
    _validate(xml_path, "junit-xunit2-strict.xsd")
    props = read_properties(xml_path)
    assert all(not p for p in props["cases"].values())  # nothing inside <testcase>
    suite = props["suite"]
    assert suite["avs.case[test_gap.py::test_gap[halton-003]].verdict"] == "fail"
    assert float(suite["avs.case[test_gap.py::test_gap[halton-003]].rho.distance"]) < 0
    assert json.loads(suite["avs.case[test_gap.py::test_gap[halton-000]].params"]) == {"x": 0.5}
    assert suite["avs.test[test_gap.py::test_gap][halton].verdict"].startswith("rejected; ")


ACCEPTED = """
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import distance, ttc
from pytest_avscenario.trajectory import Trajectory

@scenario(x=Uniform(0, 1), samples=4, monitors=[distance(5.0, kind="centre"), ttc(2.0)],
          accept=["ttc"])
def test_gap(case):
    gap = 20 * case.x
    return Trajectory.from_arrays([0.0, 0.1], {"ego": {"x": [0.0, 0.0], "y": [0.0, 0.0]},
                                               "lead": {"x": [gap, gap], "y": [3.0, 3.0]}})
"""


@pytest.mark.parametrize("how", ["xfail", "skipped", "passed", "ini:passed"])
def test_accepted_counterexamples_appear_as_asked_in_junit(pytester, how):
    """--avs-junit-accepted: an accepted counterexample (distance violated, only ttc gates)
    is an xfail (default), a plain skip, or a passing test case that keeps the
    counterexample in its properties, so dashboards need not list it among skips."""
    pytester.makepyfile(test_gap=ACCEPTED)
    args = ["--avs-db=none", "--avs-seed=1", "--junitxml=out.xml", "-p", "no:cacheprovider",
            "--avs-report=none", "-p", "no:xdist"]
    if how.startswith("ini:"):
        how = how[4:]
        pytester.makeini(f"[pytest]\navs_junit_accepted = {how}\n")
    else:
        args.append(f"--avs-junit-accepted={how}")
    result = pytester.runpytest(*args)
    assert result.ret == pytest.ExitCode.OK  # only ttc gates; distance violations are accepted
    root = ET.parse(pytester.path / "out.xml").getroot()
    case = next(c for c in root.iter("testcase") if c.get("name") == "test_gap[halton-003]")
    skipped = case.find("skipped")
    props = dict((p.get("name"), p.get("value")) for p in case.iter("property"))
    assert props["avs.verdict"] == "fail" and float(props["avs.rho.distance"]) < 0
    if how == "passed":
        assert skipped is None and case.find("failure") is None
        assert "distance" in props["avs.accepted"]
        assert result.parseoutcomes().get("xfailed", 0) == 0
    else:
        assert skipped is not None and "avs.accepted" not in props
        assert (skipped.get("type") == "pytest.xfail") == (how == "xfail")
        assert result.parseoutcomes().get("xfailed" if how == "xfail" else "skipped", 0) >= 1
    _validate(pytester.path / "out.xml", "junit-xunit2.xsd")


def test_a_bad_junit_accepted_value_is_a_usage_error(pytester):
    pytester.makepyfile(test_gap=ACCEPTED)
    result = pytester.runpytest("--avs-junit-accepted=hidden", "-p", "no:xdist")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    assert "hidden" in (result.stdout.str() + result.stderr.str())

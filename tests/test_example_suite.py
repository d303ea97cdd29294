"""The product's main job in quick mode, as CI runs it: the example scenario suite with
5 cases per scenario and sampler on the built-in autopilot (``example_tests/ci_quick.sh``:
every nominal case passes, no case is an error, every test ran its cases, report written,
every campaign accepted under ``--avs-accept regressions``)."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.slow
def test_example_suite_quick_mode(tmp_path):
    pytest.importorskip("xdist")
    # AVS_EXAMPLE_REPORT (set by .ci/run): keep the report there, where ASAM's checkers then
    # check its exports (.ci/asam-qc.sh) without running the suite a second time
    report = Path(os.environ.get("AVS_EXAMPLE_REPORT") or tmp_path / "report")
    # the script calls `pytest`: make it this interpreter's
    path = os.pathsep.join([str(Path(sys.executable).parent), os.environ.get("PATH", "")])
    env = dict(os.environ, AVS_CI_REPORT=str(report), PATH=path)
    out = subprocess.run(["bash", str(ROOT / "example_tests" / "ci_quick.sh")], cwd=ROOT, env=env,
                         capture_output=True, text=True, timeout=900)
    assert out.returncode == 0, (out.stdout[-3000:], out.stderr[-3000:])
    summary = json.loads((report / "summary.json").read_text())
    assert {t["sampler"] for t in summary["tests"]} >= {"halton", "mab"}
    # the trained-agent example runs only where stable-baselines3 is installed
    assert len({t["test"] for t in summary["tests"] if "test_trained_agent" not in t["test"]}) == 19
    assert all(t["samples"] == 5 and t["errors"] == 0 for t in summary["tests"])
    assert {t["verdict"] for t in summary["tests"]} == {"accepted"}
    assert (report / "index.html").exists()

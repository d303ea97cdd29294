"""The README's CI recipe works as written: the files in docs/ci are the README's blocks, their
pytest command runs the scenario folder by path so its conftest's defaults apply, and a second
run compares with the first's summary as its baseline."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
README = (ROOT / "README.md").read_text()
GATING = README.split("## Gating CI", 1)[1].split("\n## ", 1)[0]

# always fails: a distance nobody keeps, so each sampled case is a counterexample (accepted
# by the recipe's collision gate) and the conftest's "minimize only the first" shows
ALWAYS_FAILS = """
from pytest_avscenario import Uniform, scenario
from pytest_avscenario.monitors import collision, distance
from pytest_avscenario.trajectory import Trajectory

@scenario(x=Uniform(0.0, 1.0), samples=5, monitors=[collision(), distance(500.0, kind="centre")])
def test_far(case):
    return Trajectory.from_arrays([0.0, 0.1], {"ego": {"x": [0.0, 0.0], "y": [0.0, 0.0]},
                                               "lead": {"x": [20 + case.x, 20 + case.x], "y": [0.0, 0.0]}})
"""


def _yaml_blocks() -> list[str]:
    return re.findall(r"```yaml\n(.*?)```", GATING, re.S)


def _command(yaml: str) -> str:
    (line,) = [l.strip() for l in yaml.splitlines() if re.match(r"\s*(- |run: )?(run: )?pytest ", l)]
    return re.sub(r"^(- )?(run: )?", "", line)


def test_the_readme_prints_the_ci_files_exactly():
    blocks = _yaml_blocks()
    assert blocks == [(ROOT / "docs/ci/github-scenarios.yml").read_text(),
                      (ROOT / "docs/ci/gitlab-ci.yml").read_text()]


def test_both_recipes_run_the_scenario_folder_by_path_and_fetch_mains_baseline():
    github, gitlab = _yaml_blocks()
    for yaml in (github, gitlab):
        cmd = _command(yaml)
        assert cmd.startswith("pytest example_tests -m scenario"), cmd
        assert "--avs-baseline=" in cmd and "--junitxml=avs-junit.xml" in cmd
    # GitHub: another run's artifact needs its id and a token; a red main stores one too
    assert "gh run list --workflow scenarios.yml --branch main --status" in github
    assert "gh run download" in github and "actions: read" in github
    assert "avs-baseline-red" in github and "if: always() && github.ref == 'refs/heads/main'" in github
    # GitLab: the job-artifacts API of main's latest pipeline; a red main still publishes
    assert "/jobs/artifacts/main/raw/avs-report/summary.json?job=scenarios" in gitlab
    assert "exit_codes: [1]" in gitlab and "when: always" in gitlab


def _fresh_folder(tmp_path: Path) -> Path:
    """A project as a user lays it out: the scenario folder with the example suite's conftest,
    the README's complete example and a test that always fails, and the README's ini."""
    scen = tmp_path / "example_tests"
    scen.mkdir()
    shutil.copy(ROOT / "example_tests" / "conftest.py", scen / "conftest.py")
    example = re.search(r"## A complete example\n\n```python\n(.*?)```", README, re.S).group(1)
    (scen / "test_following.py").write_text(example)
    (scen / "test_far.py").write_text(ALWAYS_FAILS)
    (ini,) = re.findall(r"```ini\n(.*?)```", GATING, re.S)
    (tmp_path / "pytest.ini").write_text(ini)
    return tmp_path


def _run(folder: Path, command: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTEST_ADDOPTS="--avs-samples=5 -p no:cacheprovider",
               PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}",
               PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    env.pop("PYTEST_XDIST_WORKER", None)
    env.pop("PYTEST_XDIST_TESTRUNUID", None)
    return subprocess.run(["bash", "-c", command], cwd=folder, env=env, capture_output=True,
                          text=True, timeout=600)


@pytest.mark.slow
def test_the_recipe_runs_from_a_fresh_folder_and_the_second_run_compares_with_the_first(tmp_path):
    pytest.importorskip("xdist")
    folder = _fresh_folder(tmp_path)
    # the ini block's own command, then the GitHub recipe's (with the baseline it fetched)
    ini_cmd = re.search(r"```\n\n    (pytest example_tests[^\n]*)\n", GATING).group(1)
    first = _run(folder, ini_cmd)
    out = first.stdout + first.stderr
    # the collision gate: the far-apart counterexamples are accepted, nothing collides
    assert first.returncode == 0, out
    summary = json.loads((folder / "avs-report" / "summary.json").read_text())
    far = [t for t in summary["tests"] if t["test"].endswith("test_far")]
    assert far and all(t["counterexamples"] == 5 for t in far)
    # the scenario folder's conftest applied: only the first failure per campaign and xdist
    # worker minimized (at the plugin's default all five would be)
    assert all(t["minimized"] <= 2 for t in far), far
    assert (folder / "avs-junit.xml").is_file()
    # the next pipeline: main's summary fetched as baseline/summary.json
    (folder / "baseline").mkdir()
    shutil.copy(folder / "avs-report" / "summary.json", folder / "baseline" / "summary.json")
    github = _command(_yaml_blocks()[0])
    second = _run(folder, github)
    out2 = second.stdout + second.stderr
    assert second.returncode == 0, out2
    assert "baseline" in out2 and "baseline/summary.json" in out2, out2

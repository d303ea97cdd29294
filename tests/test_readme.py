"""The README's promises that CI and new users depend on."""

from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _commands() -> list[str]:
    lines = (ROOT / "README.md").read_text().splitlines()
    return [l.strip() for l in lines[:12] if l.startswith("    ")]


def test_readme_opens_with_the_two_commands():
    cmds = _commands()
    assert len(cmds) == 2
    assert "example_tests" in cmds[0] and cmds[0].startswith("pip install")
    assert cmds[1].startswith('pip install -e ".[test]"') and "pytest tests" in cmds[1]


def test_ci_runs_exactly_the_readme_test_command():
    test_cmd = _commands()[1].split("&&", 1)[1].strip()
    ci = [l.strip() for l in (ROOT / ".ci" / "run").read_text().splitlines()
          if l.strip() and not l.strip().startswith("#")]
    pytest_lines = [l for l in ci if l.startswith("pytest")]
    # the README's command first, exactly; then only the marked slow set
    assert pytest_lines[0] == test_cmd
    assert all(l == f"{test_cmd} -m slow" for l in pytest_lines[1:])

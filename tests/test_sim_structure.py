"""The simulator package keeps one concept per module: no reach into the World's private
state from outside world.py (import cycles anywhere in the package: test_layout.py)."""

import ast
import pathlib

import pytest_avscenario.sim as sim

SIM = pathlib.Path(sim.__file__).parent


def _modules():
    for path in sorted(SIM.rglob("*.py")):
        rel = path.relative_to(SIM).with_suffix("")
        parts = [p for p in rel.parts if p != "__init__"]
        yield ".".join(parts), path, ast.parse(path.read_text())


def test_nothing_outside_world_py_reads_the_worlds_private_attributes():
    offenders = []
    for name, path, tree in _modules():
        if name == "world":
            continue
        for node in ast.walk(tree):
            if not (isinstance(node, ast.Attribute) and node.attr.startswith("_")
                    and not node.attr.startswith("__")):
                continue
            base = node.value
            owner = base.attr if isinstance(base, ast.Attribute) else getattr(base, "id", "")
            if owner in ("world", "w"):
                offenders.append(f"{path.name}:{node.lineno} {owner}.{node.attr}")
    assert offenders == []

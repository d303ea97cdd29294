"""The simulator package keeps one concept per module: no reach into the World's private
state from outside world.py, and no import cycle inside sim/."""

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


def test_no_import_cycle_inside_sim():
    graph = {}
    for name, path, tree in _modules():
        package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
        deps = set()
        for node in ast.walk(tree):  # lazy imports inside functions count too
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package[:len(package) - (node.level - 1)]
                    target = ".".join(base + ([node.module] if node.module else []))
                elif (node.module or "").startswith("pytest_avscenario.sim."):
                    target = node.module[len("pytest_avscenario.sim."):]
                else:
                    continue
                deps.add(target)
                deps.update(f"{target}.{a.name}".lstrip(".") for a in node.names)
        graph[name] = deps
    graph = {m: {d for d in deps if d in graph and d not in ("", m)} for m, deps in graph.items()}

    def visit(m, stack):
        for d in graph[m]:
            assert d not in stack, "import cycle: " + " -> ".join(stack + [d])
            visit(d, stack + [d])

    for m in graph:
        visit(m, [m])

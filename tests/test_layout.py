"""The package's layering: only the pytest side imports pytest, monitors know trajectories and
not the simulator, the simulator knows neither the monitors nor the report, nothing outside
the monitors asks which concrete monitor it holds, and no module imports itself back through
others."""

import ast
import subprocess
import sys
from pathlib import Path

import pytest

import pytest_avscenario

PACKAGE = Path(pytest_avscenario.__file__).parent
NAME = "pytest_avscenario"


def _modules() -> dict[str, Path]:
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def _is_package(module: str) -> bool:
    return MODULES[module].name == "__init__.py"


def _imports(module: str, top_level_only: bool = False) -> set[str]:
    """Modules of this package (and 'pytest') that ``module`` imports, anywhere in its code
    (functions included) or at its top level only (``if TYPE_CHECKING`` blocks excluded)."""
    tree = ast.parse(MODULES[module].read_text())
    base = module if _is_package(module) else module.rpartition(".")[0]

    def walk(node: ast.AST):
        for child in ast.iter_child_nodes(node):
            if top_level_only and isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            if top_level_only and isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                continue
            yield child
            yield from walk(child)

    found = set()
    for node in walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                anchor = base.split(".")
                anchor = anchor[: len(anchor) - (node.level - 1)]
                target = ".".join(anchor + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            # `from pkg import sub` imports the module pkg.sub; `from mod import name`, mod
            names = [f"{target}.{a.name}" if f"{target}.{a.name}" in MODULES else target
                     for a in node.names]
        else:
            continue
        for n in names:
            if n.split(".")[0] in ("pytest", "_pytest"):
                found.add("pytest")
            elif n in MODULES:
                found.add(n)
    found.discard(module)
    return found


def test_only_the_pytest_side_imports_pytest_at_module_level():
    offenders = sorted(m for m in MODULES if not m.startswith(f"{NAME}.pytest_plugin")
                       and "pytest" in _imports(m, top_level_only=True))
    assert offenders == []


def test_monitors_know_trajectories_not_the_simulator():
    monitors = [m for m in MODULES if m.startswith(f"{NAME}.monitors")]
    reach = {(m, i) for m in monitors for i in _imports(m) if i.startswith(f"{NAME}.sim")}
    assert reach == set()


def _upward(package: str, forbidden: tuple[str, ...]) -> set[tuple[str, str]]:
    """(module, import) pairs where a module of ``package`` imports one of ``forbidden``."""
    inside = [m for m in MODULES if m == f"{NAME}.{package}" or m.startswith(f"{NAME}.{package}.")]
    return {(m, i) for m in inside for i in _imports(m)
            if any(i == f"{NAME}.{f}" or i.startswith(f"{NAME}.{f}.") for f in forbidden)}


def test_the_simulator_imports_neither_monitors_nor_report():
    # the simulator records and draws; judging (monitors) and reporting sit above it, so a
    # second simulator or a stack out of process never drags them in
    assert _upward("sim", ("monitors", "report")) == set()


def test_the_simulator_rule_sees_an_upward_import(tmp_path, monkeypatch):
    # negative control: a sim module importing the report (as render.py once did for its
    # atomic writer) or the monitors (as the clip once did for TTC) is caught, even inside a
    # function
    probe = f"{NAME}.sim._probe_up"
    (tmp_path / "up.py").write_text("def f():\n    from ..report.folder import atomic_write_bytes\n"
                                    "    from ..monitors.metrics import pairwise_ttc\n")
    monkeypatch.setitem(MODULES, probe, tmp_path / "up.py")
    assert _upward("sim", ("monitors", "report")) == {
        (probe, f"{NAME}.report.folder"), (probe, f"{NAME}.monitors.metrics")}
    with pytest.raises(AssertionError):
        test_the_simulator_imports_neither_monitors_nor_report()


def _concrete_monitor_classes() -> set[str]:
    """Names of the classes the monitors package defines (Monitor itself excepted: asking
    whether something is a monitor at all is fine)."""
    names = set()
    for m in MODULES:
        if m.startswith(f"{NAME}.monitors"):
            tree = ast.parse(MODULES[m].read_text())
            names |= {n.name for n in ast.walk(tree) if isinstance(n, ast.ClassDef)}
    return names - {"Monitor", "MonitorError", "MonitorResult", "Verdict"}


def _switches_on(module: str, classes: set[str]) -> set[str]:
    """Concrete monitor classes ``module`` tests with isinstance/issubclass or a ``type(x) is``."""
    tree = ast.parse(MODULES[module].read_text())
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) \
                and node.func.id in ("isinstance", "issubclass") and len(node.args) == 2:
            found |= {n.id if isinstance(n, ast.Name) else n.attr for n in ast.walk(node.args[1])
                      if isinstance(n, (ast.Name, ast.Attribute))}
        elif isinstance(node, ast.Compare) and "type(" in ast.unparse(node.left):
            found |= {n.id if isinstance(n, ast.Name) else n.attr for c in node.comparators
                      for n in ast.walk(c) if isinstance(n, (ast.Name, ast.Attribute))}
    return found & classes


def test_nothing_outside_the_monitors_switches_on_a_concrete_monitor():
    # the monitors give their own evidence (Monitor.series, monitors.evidence): pictures,
    # recordings and the pytest side hold monitors without asking which one they hold
    classes = _concrete_monitor_classes()
    outside = [m for m in MODULES if not m.startswith(f"{NAME}.monitors")]
    assert {m: _switches_on(m, classes) for m in outside if _switches_on(m, classes)} == {}


def test_the_monitor_switch_rule_sees_a_switch(tmp_path, monkeypatch):
    # negative control: the picture code's old ``isinstance(m, TTCMonitor)`` is caught
    probe = f"{NAME}.report._probe_switch"
    (tmp_path / "switch.py").write_text(
        "def radius(monitors):\n"
        "    from ..monitors.metrics import TTCMonitor\n"
        "    return next((m.radius for m in monitors if isinstance(m, (TTCMonitor,))), 5.0)\n")
    monkeypatch.setitem(MODULES, probe, tmp_path / "switch.py")
    assert _switches_on(probe, _concrete_monitor_classes()) == {"TTCMonitor"}
    with pytest.raises(AssertionError):
        test_nothing_outside_the_monitors_switches_on_a_concrete_monitor()


def test_nothing_below_the_pytest_side_imports_it():
    below = [m for m in MODULES if not m.startswith(f"{NAME}.pytest_plugin")]
    reach = {(m, i) for m in below for i in _imports(m) if i.startswith(f"{NAME}.pytest_plugin")}
    assert reach == set()


def test_no_import_cycle_in_the_package():
    graph = {m: _imports(m) - {"pytest"} for m in MODULES}
    # Tarjan's strongly connected components: any component of more than one module is a cycle
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10_000))
    for v in graph:
        if v not in index:
            visit(v)
    assert cycles == []


def test_the_cycle_check_sees_a_cycle(tmp_path, monkeypatch):
    # the check above must be able to fail: two modules importing each other are found
    a, b = f"{NAME}._probe_a", f"{NAME}._probe_b"
    (tmp_path / "a.py").write_text("from ._probe_b import x\n")
    (tmp_path / "b.py").write_text("def f():\n    from ._probe_a import y\n")
    monkeypatch.setitem(MODULES, a, tmp_path / "a.py")
    monkeypatch.setitem(MODULES, b, tmp_path / "b.py")
    assert _imports(a) == {b} and _imports(b) == {a}
    with pytest.raises(AssertionError):
        test_no_import_cycle_in_the_package()


@pytest.mark.parametrize("module", ["space", "samplers", "monitors", "sim", "report", "executors",
                                    "outcome", "trajectory", "shrink", "db", "runner", "files",
                                    "campaign", "campaign.pipeline", "campaign.script"])
def test_importing_the_library_loads_no_pytest(module):
    # a real process: this one has pytest loaded already
    code = (f"import sys, {NAME}.{module}\n"
            "loaded = sorted(m for m in ('pytest', '_pytest') if m in sys.modules)\n"
            "assert not loaded, loaded\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


def _pytest_reach(package: str) -> set[tuple[str, str]]:
    """(module, import) pairs where a module of ``package`` imports pytest or the pytest side,
    anywhere in its code (functions included)."""
    inside = [m for m in MODULES if m == f"{NAME}.{package}" or m.startswith(f"{NAME}.{package}.")]
    return {(m, i) for m in inside for i in _imports(m)
            if i == "pytest" or i.startswith(f"{NAME}.pytest_plugin")}


def test_the_campaign_engine_knows_no_pytest():
    # the campaign runs from a script as it runs under pytest: the pytest side adapts items,
    # options and reports to it, never the other way round
    assert _pytest_reach("campaign") == set()


def test_the_campaign_rule_sees_pytest(tmp_path, monkeypatch):
    # negative control: a campaign module reaching for pytest (as the pipeline once did for
    # its warnings) or for the plugin's stash, even inside a function, is caught
    probe = f"{NAME}.campaign._probe_pytest"
    (tmp_path / "p.py").write_text("def f():\n    import pytest\n"
                                   "    from ..pytest_plugin.stash import row_key\n")
    monkeypatch.setitem(MODULES, probe, tmp_path / "p.py")
    assert _pytest_reach("campaign") == {(probe, "pytest"), (probe, f"{NAME}.pytest_plugin.stash")}
    with pytest.raises(AssertionError):
        test_the_campaign_engine_knows_no_pytest()


def _pytest_private_names() -> set[str]:
    """The private names of pytest's own objects: ``self._x = ...`` and ``def _x`` in _pytest."""
    import _pytest

    names = set()
    for path in Path(_pytest.__file__).parent.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store) \
                    and isinstance(node.value, ast.Name) and node.value.id == "self":
                names.add(node.attr)
            elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                names.add(node.name)
    return {n for n in names if n.startswith("_") and not n.startswith("__")}


PYTEST_PRIVATE = _pytest_private_names()


def _private_use(module: str) -> set[str]:
    """pytest's private names ``module`` reads off objects other than its own ``self``, and
    ``_pytest`` imports."""
    tree = ast.parse(MODULES[module].read_text())
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and node.attr in PYTEST_PRIVATE \
                and not (isinstance(node.value, ast.Name) and node.value.id == "self"):
            found.add(node.attr)
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("_pytest"):
            found.add(node.module)
        elif isinstance(node, ast.Import) and any(a.name.startswith("_pytest") for a in node.names):
            found.add("_pytest")
    return found


def _private_users() -> dict[str, set[str]]:
    return {m: _private_use(m) for m in MODULES if _private_use(m)}


def test_pytest_private_api_stays_in_three_plugin_modules():
    # pytest's private attributes (item._fixtureinfo, item._request, the fixture manager)
    # change between pytest versions: the plugin reads them in few places, the rest never
    users = _private_users()
    # one known use outside: a Dask worker compiles the test module itself, with pytest's
    # assert rewriting so that a failed assert reads as under pytest (plain asserts without it)
    outside = {m: u for m, u in users.items() if not m.startswith(f"{NAME}.pytest_plugin.")}
    assert outside == {f"{NAME}.executors.remote": {"_pytest.assertion.rewrite"}}, outside
    assert len(users) - len(outside) <= 3, users


def test_the_private_api_rule_sees_a_use(tmp_path, monkeypatch):
    # negative control: reading item._fixtureinfo outside the three modules is caught
    assert {"_fixtureinfo", "_request", "_fixturemanager"} <= PYTEST_PRIVATE
    probe = f"{NAME}.campaign._probe_private"
    (tmp_path / "q.py").write_text("def f(item):\n    return item._fixtureinfo.argnames\n")
    monkeypatch.setitem(MODULES, probe, tmp_path / "q.py")
    assert _private_users()[probe] == {"_fixtureinfo"}
    with pytest.raises(AssertionError):
        test_pytest_private_api_stays_in_three_plugin_modules()

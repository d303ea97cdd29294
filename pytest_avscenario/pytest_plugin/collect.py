"""Collection: one ``@scenario`` test becomes one pytest item per concrete case.

:func:`plan_scenario` checks what only the pytest collection can tell (the marker's form,
stacked markers, the ``case`` fixture, fixtures a parameter would shadow, fixtures a remote
executor cannot send), then has :func:`pytest_avscenario.campaign.plan.build_plan` make the
frozen :class:`~pytest_avscenario.campaign.plan.ScenarioPlan` and the :class:`CaseSlot` of
every item; each slot becomes one item (``test_x[halton-007]``).
"""

from __future__ import annotations

import ast
import warnings
from pathlib import Path
from typing import Any

import pytest

from ..campaign.plan import (  # noqa: F401 - the plan's names, as the plugin's modules know them
    CaseSlot,
    ScenarioPlan,
    build_plan,
    call_text,
    likely_setting,
    sampled_slot,
)
from ..markers.spec import ScenarioSpec
from ..space import SpaceError
from .options import DeclarationError, Settings
from .stash import plans_key


def plan_scenario(metafunc: pytest.Metafunc, marker: pytest.Mark, settings: Settings,
                  db: Any) -> tuple[ScenarioPlan, list[CaseSlot]]:
    """The plan of ``metafunc``'s test and its items' slots; DeclarationError, SpaceError
    or ValueError say what is wrong with the declaration."""
    test = metafunc.definition.nodeid
    if len(marker.args) != 1 or not isinstance(marker.args[0], ScenarioSpec) or marker.kwargs:
        raise DeclarationError(
            "use the @scenario(...) decorator from pytest_avscenario, not a bare "
            "@pytest.mark.scenario"
        )
    spec: ScenarioSpec = marker.args[0]
    if spec.problem is not None:
        raise DeclarationError(spec.problem)
    stacked = len(list(metafunc.definition.iter_markers("scenario")))
    if stacked > 1:
        raise DeclarationError(
            f"{stacked} @scenario declarations apply to this test (stacked decorators, or one "
            "on its class or module); keep one: a test is one scenario (to run it with several "
            "samplers give sampler=[...])")
    if "case" not in metafunc.fixturenames:
        raise DeclarationError(
            "a @scenario test must request the `case` fixture (add `case` to its arguments) "
            "to read the concrete parameter values"
        )
    fm = metafunc.definition.session._fixturemanager
    config = metafunc.config
    return build_plan(
        test, spec, metafunc.function, settings, db,
        has_world="world" in metafunc.fixturenames,
        is_fixture=lambda name: bool(fm.getfixturedefs(name, metafunc.definition)),
        check_fixtures=None if settings.executor == "inprocess"
        else lambda: _check_remote_fixtures(metafunc, settings.executor),
        make_sampler=sampler_hook(config),
        warn=lambda message: warnings.warn(pytest.PytestWarning(message)))


def sampler_hook(config: pytest.Config) -> Any:
    """The plain callable a plan asks for a sampler of one's own: the conftests'
    ``pytest_avscenario_make_sampler``."""
    def make(**kwargs: Any) -> Any:
        return config.hook.pytest_avscenario_make_sampler(config=config, **kwargs)

    return make


def _check_remote_fixtures(metafunc: pytest.Metafunc, executor: str) -> None:
    fm = metafunc.definition.session._fixturemanager
    autouse = set(fm._getautousenames(metafunc.definition))
    own = set(metafunc.definition._fixtureinfo.argnames)
    # `request` is in every closure (our fixtures use it); refused only when the test asks
    others = sorted((set(metafunc.fixturenames) - {"case", "world", "avs_driver", "request"} - autouse)
                    | (own & {"request"}))
    if others:
        raise DeclarationError(
            f"under --avs-executor={executor} a scenario test gets only `case`, `world` and "
            f"`avs_driver` on the remote workers; it also requests {', '.join(others)} — run "
            "it with the in-process executor or drop them"
        )


def function_id(item: pytest.Item) -> str:
    nodeid = item.nodeid
    return nodeid[: nodeid.index("[")] if "[" in nodeid else nodeid


def plan_of(item: pytest.Item) -> ScenarioPlan:
    return item.config.stash[plans_key][function_id(item)]


def slot_of(item: pytest.Item) -> CaseSlot | None:
    """The item's slot, or None for an item that is not a scenario case."""
    slot = item.callspec.params.get("case") if hasattr(item, "callspec") else None
    return slot if isinstance(slot, CaseSlot) else None


# ------------------------------------------------------------------ errors at import time
_PACKAGE = Path(__file__).resolve().parent.parent


def _in_package(path: Any) -> bool:
    try:
        return Path(path).resolve().is_relative_to(_PACKAGE)
    except (TypeError, ValueError, OSError):
        return False


def _decorated_at(source: str, line: int) -> tuple[str, bool] | None:
    """The ``Class::function`` whose decorator list holds line ``line`` (1-based), and whether
    one of its decorators is ``scenario(...)`` or ``example(...)``; None if no decorator does."""
    try:
        tree = ast.parse(source)
    except (SyntaxError, ValueError):
        return None

    def ours(deco: ast.expr) -> bool:
        func = deco.func if isinstance(deco, ast.Call) else deco
        name = func.id if isinstance(func, ast.Name) else getattr(func, "attr", None)
        return name in ("scenario", "example")

    def visit(body: list[ast.stmt], prefix: str) -> tuple[str, bool] | None:
        for node in body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                name = f"{prefix}{node.name}"
                for deco in node.decorator_list:
                    if deco.lineno <= line <= (deco.end_lineno or deco.lineno):
                        return name, any(map(ours, node.decorator_list))
                if isinstance(node, ast.ClassDef):
                    found = visit(node.body, f"{name}::")
                    if found is not None:
                        return found
        return None

    return visit(tree.body, "")


def import_error_message(module: pytest.Module, excinfo: pytest.ExceptionInfo[BaseException]) -> str | None:
    """A one-paragraph collection error for an exception that a call into this package raised
    while ``module`` was imported — a bad monitor argument in ``@scenario(monitors=[...])``,
    say — naming the test whose decorator made the call; None for any other failure.

    The decorator's arguments run when the module is imported, before any test exists, so
    pytest would show the package's own frames and no test name. Also an exception raised by
    the call itself in the decorator of a ``@scenario``/``@example`` test
    (``scenario(**{1: 2})``).
    """
    entries = list(excinfo.traceback)
    here = [i for i, e in enumerate(entries) if Path(str(e.path)) == module.path]
    if not here:
        return None
    last = here[-1]
    callee = entries[last + 1:]
    line = entries[last].lineno + 1
    try:
        source = module.path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        source = ""
    decorated = _decorated_at(source, line)
    if callee and not _in_package(callee[0].path):
        return None
    if not callee and (decorated is None or not decorated[1]):
        return None
    test = None if decorated is None else decorated[0]
    exc = excinfo.value
    try:
        text = str(exc)
    except Exception:  # noqa: BLE001 - a message must not fail
        text = ""
    from ..monitors import MonitorError

    hint = ""
    if not isinstance(exc, (MonitorError, SpaceError, DeclarationError)):
        text = f"{type(exc).__name__}: {text}" if text else type(exc).__name__
        hint = "; --fulltrace shows the traceback"
    where = f"{module.path.name}:{line}"
    if test is None:
        return (f"{module.nodeid}: {text} (raised at {where} while the module was imported, so "
                f"none of its tests were collected{hint})")
    return (f"{module.nodeid}::{test}: {text} (raised by its decorator at {where} while the "
            f"module was imported, so none of the module's tests were collected{hint})")

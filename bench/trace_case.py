"""How often one scenario case's work comes back to a module it had left, at orchestration
depth.

Runs pytest in this process on one case (default: a failing vehicle-following case of the
example suite, which is simulated, minimized, judged by the reference driver, stored in the
replay database, drawn and reported) with a ``sys.setprofile`` hook installed for that item's
whole protocol (setup with its fixtures, call, teardown, and every report hook, the
controller's row included). The hook follows, on every Python call and return, the innermost
frame of this package whose stack holds at most ``--depth`` frames of this package (deeper
work counts as a stay in the frame that called it). A *stay* is a maximal run of events in one
module; a *return* is a stay in a module that had a stay before. It prints the modules in
order of first visit, the number of stays, the returns in all and per module, and the stays
themselves (``--show``). It also lists the modules whose code runs while the report renders
the case's counterexample card, and the package modules ``report/cards.py`` imports:

    PYTHONPATH=$PWD python bench/trace_case.py
    PYTHONPATH=$PWD python bench/trace_case.py 'example_tests/test_02_vehicle_following.py::test_vehicle_following[halton-010]' --depth 4

The case runs with ``--avs-seed=0``, a fresh replay database and report folder in a
temporary directory (nothing lands in the checkout), ``-p no:cacheprovider -p no:xdist``.
"""

from __future__ import annotations

import argparse
import collections
import json
import sys
import tempfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = "pytest_avscenario"
DEFAULT_CASE = "example_tests/test_02_vehicle_following.py::test_vehicle_following[halton-010]"


class ModuleTrace:
    """The ``sys.setprofile`` hook and what it saw."""

    def __init__(self, depth: int, on_return: bool = False):
        self.depth = depth
        self.on_return = on_return  # a return to the caller's module starts a stay too
        # frame -> (package frames on its stack, itself included; module of the innermost
        # package frame at or above it within the depth, or None)
        self.frames: dict[Any, tuple[int, str | None]] = {}
        self.stays: list[str] = []

    def _state(self, frame: Any) -> tuple[int, str | None]:
        if frame is None:
            return 0, None
        found = self.frames.get(frame)
        if found is None:  # a frame entered before tracing began
            depth, module = self._state(frame.f_back)
            name = frame.f_globals.get("__name__", "")
            if name == PACKAGE or name.startswith(PACKAGE + "."):
                depth += 1
                if depth <= self.depth:
                    module = name
            found = self.frames[frame] = (depth, module)
        return found

    def _at(self, module: str | None) -> None:
        if module is not None and (not self.stays or self.stays[-1] != module):
            self.stays.append(module)

    def __call__(self, frame: Any, event: str, arg: Any) -> None:
        if event == "call":
            depth, module = self._state(frame)
            if module is not None and module == frame.f_globals.get("__name__"):
                self._at(module)  # a frame of this package within the depth (not pytest's,
                # numpy's or pluggy's code called from one: that is a stay of the caller's)
        elif event == "return":
            self.frames.pop(frame, None)
            if self.on_return:
                self._at(self._state(frame.f_back)[1])

    def summary(self) -> dict[str, Any]:
        seen: set[str] = set()
        returns: collections.Counter[str] = collections.Counter()
        for module in self.stays:
            if module in seen:
                returns[module] += 1
            seen.add(module)
        order = list(dict.fromkeys(self.stays))
        return {"depth": self.depth, "counted": "calls and returns" if self.on_return else "calls",
                "modules": len(order), "stays": len(self.stays),
                "returns": sum(returns.values()), "returns_by_module": dict(returns.most_common()),
                "order": order}


class TracePlugin:
    """Installs the hook for the item ``nodeid``'s protocol only (the outermost wrapper of
    ``pytest_runtest_protocol``: every other plugin's part of it is inside)."""

    def __init__(self, nodeid: str, depth: int, on_return: bool = False):
        self.nodeid = nodeid
        self.trace = ModuleTrace(depth, on_return)
        self.ran = False

    def pytest_runtest_protocol(self, item: Any, nextitem: Any) -> Any:
        if item.nodeid != self.nodeid:
            return (yield)
        self.ran = True
        sys.setprofile(self.trace)
        try:
            return (yield)
        finally:
            sys.setprofile(None)


class CardTrace:
    """The modules of this package whose code runs while the report renders a counterexample
    card (``report.cards.render_card``, at the end of the session)."""

    def __init__(self) -> None:
        self.modules: set[str] = set()
        self.cards = 0

    def install(self) -> None:
        from pytest_avscenario.report import cards

        original = cards.render_card

        def hook(frame: Any, event: str, arg: Any) -> None:
            if event == "call":
                name = frame.f_globals.get("__name__", "")
                if name == PACKAGE or name.startswith(PACKAGE + "."):
                    self.modules.add(name)

        def traced(*args: Any, **kwargs: Any) -> Any:
            self.cards += 1
            sys.setprofile(hook)
            try:
                return original(*args, **kwargs)
            finally:
                sys.setprofile(None)

        cards.render_card = traced


def card_imports() -> list[str]:
    """The package modules ``report/cards.py`` imports (anywhere in its code)."""
    import ast

    path = ROOT / PACKAGE / "report" / "cards.py"
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level:
            base = ["report"][: 2 - node.level] if node.level <= 2 else []
            found.add(".".join([PACKAGE, *base, *([node.module] if node.module else [])]))
    return sorted(found)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("case", nargs="?", default=DEFAULT_CASE, help="the item's node id")
    parser.add_argument("--depth", type=int, default=3, help="package frames followed (3)")
    parser.add_argument("--show", action="store_true", help="print every stay")
    parser.add_argument("--out", help="also write the result (JSON) to this file")
    parser.add_argument("--returns-too", action="store_true",
                        help="a return from a call into the caller's module starts a stay too "
                             "(default: stays start where a call enters a module)")
    args = parser.parse_args()
    import pytest

    TracePlugin.pytest_runtest_protocol = pytest.hookimpl(wrapper=True, tryfirst=True)(
        TracePlugin.pytest_runtest_protocol)
    card = CardTrace()
    card.install()
    with tempfile.TemporaryDirectory(prefix="avs-trace-") as tmp:
        plugin = TracePlugin(args.case, args.depth, args.returns_too)
        status = pytest.main([str(ROOT / args.case.split("::")[0]) + "::" + args.case.split("::", 1)[1],
                              "--rootdir", str(ROOT), "-p", "no:cacheprovider", "-p", "no:xdist",
                              "-q", "--avs-seed=0", f"--avs-db={tmp}/db", f"--avs-report={tmp}/report"],
                             plugins=[plugin])
    if not plugin.ran:
        print(f"trace_case: {args.case} did not run (pytest status {status})", file=sys.stderr)
        return 2
    out = plugin.trace.summary()
    out["case"] = args.case
    out["pytest_status"] = int(status)
    out["card"] = {"cards_rendered": card.cards, "modules_run": sorted(card.modules),
                   "cards_py_imports": card_imports()}
    if args.show:
        out["stays_in_order"] = plugin.trace.stays
    print(json.dumps(out, indent=1))
    if args.out:
        Path(args.out).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""A guard against a CPython fault that turns a failing test into an INTERNALERROR.

On CPython before 3.13, :func:`ast.parse` keeps its recursion-depth counter in one
interpreter-wide state. When the garbage collector runs during a parse and finalizes an
object whose ``__del__`` raises, pytest's unraisable-exception hook formats that traceback at
once; on 3.11 :mod:`traceback` parses the failing line to place its carets, so a second
``ast.parse`` runs inside the first, and the outer one then fails with ``SystemError: AST
constructor recursion depth mismatch`` (python/cpython#106905). pytest parses the test's
source to show a failure, so the failure itself becomes an INTERNALERROR and the run ends
without its rows, JUnit file or report. Scenario runs make such garbage easily (a Dask
client, a stack's socket, a simulator closed by a collector).

:func:`guard_ast_parse` makes ``ast.parse`` hold the collector while it builds the tree. It
changes no result, only when cyclic garbage is collected.
"""

from __future__ import annotations

import ast
import functools
import gc
import sys
from typing import Any


def guard_ast_parse() -> None:
    """Install the guard once per process, on the interpreters that need it."""
    if sys.version_info >= (3, 13) or getattr(ast.parse, "avscenario_gc_guard", False):
        return
    parse = ast.parse

    @functools.wraps(parse)
    def parse_holding_gc(*args: Any, **kwargs: Any) -> Any:
        if not gc.isenabled():
            return parse(*args, **kwargs)
        gc.disable()
        try:
            return parse(*args, **kwargs)
        finally:
            gc.enable()

    parse_holding_gc.avscenario_gc_guard = True  # type: ignore[attr-defined]
    ast.parse = parse_holding_gc

"""JSON a user hands the plugin (the ``--avs-baseline`` summary, ``--avs-params``), read with
bounds, so that any text at all is either data of a known shape or one :class:`InputError`
that says what was wrong and where (``tests[3].violations.collision: ...``).

Python's ``json`` alone turns hostile text into exceptions a caller does not expect — a
5,000-digit integer (ValueError from the int-digit limit), ``[[[[...`` 100,000 deep
(RecursionError), ``1e400`` (silently ``inf``), ``Infinity`` and ``NaN`` (not JSON at all,
accepted) — so :func:`parse_json` refuses each of them by name, and :func:`read_json_file`
refuses what is not a regular file before opening it (a FIFO would block the run) and files
larger than any the plugin writes. :class:`Fields` checks the shape of the parsed data and
names the path of a bad field. Nothing here imports pytest.
"""

from __future__ import annotations

import json
import math
import os
import stat
from typing import Any, Callable

from .files import UnsafePath, read_regular

__all__ = ["InputError", "parse_json", "read_json_file", "Fields", "MAX_DEPTH", "MAX_INT_DIGITS"]

#: deeper than any file the plugin writes or reads (a summary is 6 levels deep)
MAX_DEPTH = 64
#: digits of a JSON integer: counts and seeds need at most 19 (2**63)
MAX_INT_DIGITS = 30
#: the largest summary.json a 100,000-case run writes is a few MB
MAX_FILE_BYTES = 256 * 1024 * 1024


class InputError(ValueError):
    """Input the plugin cannot use; the text says what and where (without the file's name,
    which the caller adds)."""


def _refuse_constant(name: str) -> Any:
    raise InputError(f"holds {name}, which is not JSON (JSON numbers are finite)")


def _parse_int(text: str) -> int:
    digits = len(text.lstrip("-"))
    if digits > MAX_INT_DIGITS:
        raise InputError(f"holds an integer of {digits} digits (at most {MAX_INT_DIGITS} are read)")
    return int(text)


def _parse_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise InputError(f"holds the number {text[:40]}, too large for a float")
    return value


def _depth(text: str) -> int:
    """The deepest bracket nesting of JSON ``text`` (brackets inside strings do not count);
    linear, and before parsing, so 100,000 levels never reach the parser's recursion."""
    depth = deepest = 0
    in_string = escaped = False
    for ch in text:
        if in_string:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_string = False
        elif ch == '"':
            in_string = True
        elif ch in "[{":
            depth += 1
            if depth > deepest:
                deepest = depth
                if deepest > MAX_DEPTH:
                    return deepest
        elif ch in "]}":
            depth -= 1
    return deepest


def parse_json(text: str, max_depth: int = MAX_DEPTH, finite: bool = True) -> Any:
    """JSON ``text`` as data; InputError says why it cannot be read. ``finite`` False keeps
    ``Infinity``, ``NaN`` and ``1e400`` as the floats they spell, for a schema (:class:`Fields`)
    to refuse naming their field."""
    if _depth(text) > max_depth:
        raise InputError(f"is nested more than {max_depth} levels deep")
    try:
        return json.loads(text, parse_constant=_refuse_constant if finite else float,
                          parse_int=_parse_int, parse_float=_parse_float if finite else float)
    except InputError:
        raise
    except json.JSONDecodeError as exc:
        raise InputError(f"is not valid JSON ({exc.msg} at line {exc.lineno} column {exc.colno})") from None
    except RecursionError:  # not reached after the depth check; kept so no input can escape
        raise InputError(f"is nested more than {max_depth} levels deep") from None
    except (ValueError, OverflowError, MemoryError) as exc:
        raise InputError(f"cannot be read as JSON ({type(exc).__name__}: {str(exc)[:120]})") from None


def read_json_file(path: str | os.PathLike, max_bytes: int = MAX_FILE_BYTES, finite: bool = True) -> Any:
    """The JSON data of the regular file ``path``; InputError (OSError reasons included) says
    why not, without naming the file."""
    try:
        info = os.stat(path)
    except OSError as exc:
        raise InputError(f"cannot be read: {exc.strerror or exc}") from None
    if not stat.S_ISREG(info.st_mode):
        kind = "a directory" if stat.S_ISDIR(info.st_mode) else "a FIFO" if stat.S_ISFIFO(info.st_mode) \
            else "a device or socket"
        raise InputError(f"is not a regular file (it is {kind})")
    if info.st_size > max_bytes:
        raise InputError(f"is {info.st_size} bytes, larger than any file this reads ({max_bytes})")
    try:
        # the package's one opener: non-blocking and fstat-checked, so a FIFO swapped in
        # after the stat does not block the run either (a link the user named is followed)
        raw = read_regular(path, max_bytes, follow=True)
    except UnsafePath:
        raise InputError("is not a regular file") from None
    except OSError as exc:
        raise InputError(f"cannot be read: {exc.strerror or exc}") from None
    if len(raw) > max_bytes:
        raise InputError(f"is larger than any file this reads ({max_bytes} bytes)")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise InputError("is not UTF-8 text") from None
    return parse_json(text, finite=finite)


class Fields:
    """Typed access to parsed JSON that names the path of a bad field:
    ``Fields(data).list("tests")[0].count("samples", at_most=...)``."""

    def __init__(self, data: Any, where: str = ""):
        self.data = data
        self.where = where

    def _at(self, key: Any) -> str:
        if isinstance(key, int):
            return f"{self.where}[{key}]"
        return f"{self.where}.{key}" if self.where else str(key)

    def fail(self, key: Any, why: str) -> InputError:
        return InputError(f"{self._at(key) if key is not None else self.where or 'the top level'}: {why}")

    def _get(self, key: str, optional: bool) -> Any:
        if not isinstance(self.data, dict):
            raise InputError(f"{self.where or 'the top level'}: is {_kind(self.data)}, not an object")
        if key not in self.data:
            if optional:
                return None
            raise self.fail(key, "is missing")
        return self.data[key]

    def obj(self, key: str, optional: bool = False) -> "Fields | None":
        value = self._get(key, optional)
        if value is None and optional:
            return None
        if not isinstance(value, dict):
            raise self.fail(key, f"is {_kind(value)}, not an object")
        return Fields(value, self._at(key))

    def list(self, key: str, optional: bool = False, max_len: int = 1_000_000) -> "list[Fields] | None":
        value = self._get(key, optional)
        if value is None and optional:
            return None
        if not isinstance(value, list):
            raise self.fail(key, f"is {_kind(value)}, not a list")
        if len(value) > max_len:
            raise self.fail(key, f"has {len(value)} entries, more than {max_len}")
        return [Fields(v, f"{self._at(key)}[{i}]") for i, v in enumerate(value)]

    def text(self, key: str, optional: bool = False, nullable: bool = False, max_len: int = 100_000) -> str | None:
        value = self._get(key, optional)
        if value is None and (optional or nullable):
            return None
        if not isinstance(value, str):
            raise self.fail(key, f"is {_kind(value)}, not text")
        if len(value) > max_len:
            raise self.fail(key, f"is {len(value)} characters long, more than {max_len}")
        return value

    def flag(self, key: str) -> bool:
        value = self._get(key, True)
        if value is None:
            return False
        if not isinstance(value, bool):
            raise self.fail(key, f"is {_kind(value)}, not true or false")
        return value

    def count(self, key: str, at_most: int | None = None, of: str = "") -> int:
        """A whole number ``0 <= value <= at_most`` (``of``: what ``at_most`` is, for the text)."""
        return check_count(self._get(key, False), lambda why: self.fail(key, why), at_most, of)

    def items(self) -> list[tuple[str, Any]]:
        if not isinstance(self.data, dict):
            raise InputError(f"{self.where}: is {_kind(self.data)}, not an object")
        return list(self.data.items())


def check_count(value: Any, fail: Callable[[str], InputError], at_most: int | None = None, of: str = "") -> int:
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or (isinstance(value, float) and not value.is_integer()):
        raise fail(f"is {_shown(value)}, not a whole number")
    value = int(value)
    if value < 0:
        raise fail(f"is {value}, negative")
    if at_most is not None and value > at_most:
        raise fail(f"is {value}, more than {of or at_most}")
    return value


def _kind(value: Any) -> str:
    return {dict: "an object", list: "a list", str: "text", bool: "true/false", type(None): "null",
            int: "a number", float: "a number"}.get(type(value), type(value).__name__)


def _shown(value: Any) -> str:
    text = json.dumps(value) if isinstance(value, (str, bool, type(None), int, float)) else _kind(value)
    return text if len(text) <= 40 else text[:37] + "..."


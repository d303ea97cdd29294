"""Floats and parameter values as JSON and text: one encoding for every file and channel.

JSON has no infinity (Python's ``json`` would write the non-standard ``Infinity``), CSV and
JUnit properties are strings. The error table, JUnit, the summary, the replay database, the
samplers' saved state and the xdist and Dask channels all write floats through these
functions, so ``+inf`` (e.g. TTC when nothing is on a collision course), ``-inf`` (an empty
``eventually`` window) and NaN are the strings ``"inf"``, ``"-inf"``, ``"nan"`` everywhere
and survive a round trip. Finite values are written so they parse back bit-identical.
"""

from __future__ import annotations

import math
import numbers
from typing import Any, Mapping

__all__ = ["identity_text", "rho_to_json", "rho_from_json", "rho_to_str", "rho_from_str", "jsonable", "fmt_rho",
           "fmt_value"]

_POS = ("inf", "+inf", "infinity", "+infinity")
_NEG = ("-inf", "-infinity")


def rho_to_json(x: float) -> float | str:
    """A JSON-safe value: finite floats as numbers, ``"inf"``/``"-inf"``/``"nan"`` as strings."""
    x = _as_float(x)
    return x if math.isfinite(x) else rho_to_str(x)


def rho_from_json(x: Any) -> float:
    """Inverse of :func:`rho_to_json` (also accepts numbers and the usual inf spellings)."""
    if isinstance(x, str):
        return rho_from_str(x)
    return _as_float(x)


def rho_to_str(x: float) -> str:
    """Text for CSV and JUnit properties: ``repr`` of finite floats (exact round trip),
    ``"inf"``, ``"-inf"`` or ``"nan"``."""
    x = _as_float(x)
    if math.isnan(x):
        return "nan"
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return repr(x)


def rho_from_str(s: str) -> float:
    """Inverse of :func:`rho_to_str`; raises ValueError for text that is not a number."""
    t = s.strip().lower()
    if t in _POS:
        return math.inf
    if t in _NEG:
        return -math.inf
    if t == "nan":
        return math.nan
    try:
        return float(t)
    except ValueError:
        raise ValueError(f"not a robustness value: {s!r} (expected a number, 'inf' or '-inf')") from None


def _as_float(x: Any) -> float:
    if isinstance(x, bool) or not isinstance(x, numbers.Real):
        raise TypeError(f"robustness must be a real number, got {type(x).__name__}: {x!r}")
    return float(x)


def jsonable(value: Any) -> Any:
    """Parameter values as JSON data: numpy scalars and arrays unwrapped, non-finite floats
    as strings, anything else (an enum, a custom object) as its ``repr`` — shown, not lost."""
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, int):
        return int(value)
    if isinstance(value, float):
        return value if math.isfinite(value) else rho_to_str(value)
    item = getattr(value, "item", None)
    if callable(item) and getattr(value, "shape", None) == ():  # numpy scalar / 0-d array
        return jsonable(item())
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)) or hasattr(value, "tolist"):
        seq = value.tolist() if hasattr(value, "tolist") else value
        return [jsonable(v) for v in seq]
    return repr(value)


# -- for people: the terminal's failure text and the card pages share these two ---------------

def fmt_rho(v: float | None) -> str:
    """A robustness value for people: always signed, since the sign is the verdict (``+0.500``,
    ``-1.234``, ``+inf``, ``-inf``; ``nan``); ``—`` for none."""
    if v is None:
        return "—"
    if not math.isfinite(v):
        return ("+" if v > 0 else "") + rho_to_str(v)
    return f"{v:+.3f}"


def fmt_value(v: Any) -> str:
    """A parameter (or drawn) value for people, as the Python literal one pastes into
    ``@example(...)``: floats to 6 significant digits, strings quoted (``'left'``: a string,
    not a name), anything else its ``repr``."""
    if isinstance(v, float):
        return f"{v:.6g}"
    return repr(v)


def identity_text(identity: Mapping[str, Any] | None, note: str = "") -> str:
    """One line for people: ``sb3:dqn.zip@highway-fast-v0 (sha256 3f2a9c1b7d04, from
    --avs-driver)``; ``note`` goes last in the parentheses."""
    if not identity:
        return "unknown"
    extra = [f"sha256 {identity['sha256']}"] if identity.get("sha256") else []
    if identity.get("kind") == "several":
        return "several: " + "; ".join(identity_text(d) for d in identity.get("drivers", ()))
    if identity.get("from"):
        extra.append(f"from {identity['from']}")
    inside = ", ".join(extra) + ("; " if extra and note else "") + note
    return str(identity.get("name")) + (f" ({inside})" if inside else "")

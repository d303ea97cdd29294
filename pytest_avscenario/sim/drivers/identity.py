"""Which driver is under test, as plain data: what the report records so two runs of two
different stacks are never compared unawares.

:func:`describe` turns anything :func:`~pytest_avscenario.sim.drivers.resolve` accepts into
an *identity*, a small JSON-safe dict:

* ``name`` — what a person reads: ``autopilot``, ``idm``, ``careful``,
  ``package.module:Name``, ``sb3:dqn.zip@highway-fast-v0``, or for an object the qualified
  name of its class (of the function, for a plain callable);
* ``kind`` — ``builtin``, ``import``, ``sb3``, ``highway_env_agent``, ``object``,
  ``function``, or a scheme's own (``osi``);
* ``file`` and ``sha256`` — for a driver that is a file (a saved model): its absolute path
  and the first 12 hex digits of the SHA-256 of its bytes, so a retrained model under the
  same name shows as another driver;
* anything else the driver says of itself (``env``, ``algorithm``, ``version``, ``repr``).

**The protocol.** A driver object (or a model inside a ``highway_env_agent``) may say who it
is: a method ``describe()`` returning a mapping with at least ``name``, and any of
``kind``, ``file``, ``sha256`` and further keys with text or number values. A stack out of
process (``osi:``) answers with its endpoint and whatever version its handshake gave. A
driver without ``describe()`` is named by its class; one that raises in ``describe()`` too
(the report must not fail for it), with the error in ``describe_error``.
"""

from __future__ import annotations

import inspect
import os
from typing import Any, Mapping

from ...codec import identity_text  # one line for people; lives where the header can read it cheaply
from .sb3 import SHA_DIGITS, file_sha256, parse

__all__ = ["describe", "file_sha256", "identity_text", "same_driver", "SHA_DIGITS"]

_BUILTIN_CLASSES = {
    "pytest_avscenario.sim.drivers.autopilot:Autopilot": "autopilot",
    "pytest_avscenario.sim.drivers.reference:CarefulDriver": "careful",
}


def describe(driver: Any) -> dict[str, Any]:
    """The identity of ``driver`` (see the module doc); never raises."""
    # the package's names, imported here: the package imports sb3, which must not import us
    from . import BUILTIN, IDMDriver, PolicyDriver, is_import_path

    if driver is None:
        return {"name": "autopilot", "kind": "builtin"}
    if isinstance(driver, str):
        text = driver.strip()
        if text in BUILTIN:
            return {"name": text, "kind": "builtin"}
        if text.startswith("sb3:"):
            return _sb3(text)
        if is_import_path(text):
            return {"name": text, "kind": "import"}
        # a scheme of its own (osi:ADDRESS, osi+spawn:COMMAND): the kind is the scheme's family
        scheme = text.partition(":")[0].partition("+")[0] if ":" in text else "name"
        return {"name": text, "kind": scheme}
    if isinstance(driver, IDMDriver):
        return {"name": "idm", "kind": "builtin"}
    if isinstance(driver, PolicyDriver):
        return describe(driver.target)
    own = _described(driver)
    if own is not None:
        return own
    cls = driver if inspect.isclass(driver) else type(driver)
    builtin = _BUILTIN_CLASSES.get(f"{cls.__module__}:{cls.__qualname__}")
    if builtin is not None:
        return {"name": builtin, "kind": "builtin"}
    if inspect.isfunction(driver) or inspect.ismethod(driver) or inspect.isclass(driver):
        return {"name": _qualified(driver), "kind": "function" if not inspect.isclass(driver) else "object"}
    out = {"name": _qualified(cls), "kind": "object"}
    if type(driver).__repr__ is not object.__repr__:  # a repr of its own says more than its class
        try:
            shown = repr(driver)
        except Exception:  # a broken __repr__ must not cost the report
            shown = ""
        if shown and len(shown) <= 200 and shown != out["name"]:
            out["repr"] = shown
    return out


def _qualified(obj: Any) -> str:
    module = getattr(obj, "__module__", None) or ""
    name = getattr(obj, "__qualname__", None) or getattr(obj, "__name__", None) or type(obj).__name__
    return f"{module}.{name}" if module and module != "builtins" else str(name)


def _described(driver: Any) -> dict[str, Any] | None:
    hook = getattr(driver, "describe", None)
    if not callable(hook) or inspect.isclass(driver):
        return None
    try:
        given = hook()
    except Exception as exc:  # the driver's own code: the report keeps its class name
        return {"name": _qualified(type(driver)), "kind": "object",
                "describe_error": f"{type(exc).__name__}: {exc}"}
    if not isinstance(given, Mapping) or not str(given.get("name") or "").strip():
        return {"name": _qualified(type(driver)), "kind": "object",
                "describe_error": f"describe() returned {given!r}, not a mapping with a 'name'"}
    out: dict[str, Any] = {"name": str(given["name"]).strip(), "kind": str(given.get("kind") or "object")}
    for key, value in given.items():
        if key in ("name", "kind") or value is None:
            continue
        out[str(key)] = value if isinstance(value, (bool, int, float, str)) else str(value)
    return out


def _sb3(text: str) -> dict[str, Any]:
    try:
        spec = parse(text)
    except ValueError:
        return {"name": text, "kind": "sb3"}
    path = os.path.abspath(os.path.expanduser(spec.path))
    algo = f"{spec.algorithm}:" if spec.algorithm else ""
    out: dict[str, Any] = {"name": f"sb3:{algo}{os.path.basename(path)}@{spec.env}", "kind": "sb3",
                           "file": path, "sha256": file_sha256(path), "env": spec.env}
    if spec.algorithm:
        out["algorithm"] = spec.algorithm
    return out


def same_driver(a: Mapping[str, Any] | None, b: Mapping[str, Any] | None) -> bool:
    """Whether two identities name one driver: the same name and kind, and the same file
    content where both hashed one (a retrained model under its old name is another driver)."""
    if not a or not b:
        return True  # unknown (a summary from before drivers were recorded): nothing to say
    if (a.get("name"), a.get("kind")) != (b.get("name"), b.get("kind")):
        return False
    if a.get("kind") == "several":
        return [ (d.get("name"), d.get("sha256")) for d in a.get("drivers", ())] == \
            [(d.get("name"), d.get("sha256")) for d in b.get("drivers", ())]
    return not (a.get("sha256") and b.get("sha256") and a["sha256"] != b["sha256"])

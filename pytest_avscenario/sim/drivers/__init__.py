"""Who drives the ego: turning a driver name or a user's policy object into one ``act`` call.

:func:`resolve` accepts

* ``"autopilot"`` — the built-in autopilot (``pytest_avscenario.sim.drivers.autopilot``,
  imported only when asked for);
* ``"idm"`` — highway-env's own ``IDMVehicle`` logic driving the ego: the world then builds
  the ego *as* an IDM vehicle following its route (the observation is not used), isolated from
  highway-env's mutable class constants;
* ``"careful"`` — the careful and competent human driver of UN R157 (:class:`CarefulDriver`,
  ``pytest_avscenario.sim.drivers.reference``): the reference a failure is judged against;
* ``"package.module:Name"`` — a class (instantiated without arguments) or object found there;
* ``"sb3:PATH@ENV"`` — a stable-baselines3 model saved at ``PATH``, trained on the highway-env
  environment ``ENV`` (default ``highway-fast-v0``), driven by :func:`highway_env_agent`
  (:mod:`.sb3`; needs the ``[sb3]`` extra);
* ``"osi:ADDRESS"`` / ``"osi+spawn:COMMAND"`` — a stack out of process speaking ASAM OSI over
  ZeroMQ (:class:`pytest_avscenario.stack.OSIStack`; needs the ``[osi]`` extra);
* a user object: anything with ``act(observation)``, an object with
  ``predict(observation)`` returning ``(action, state)``, or a plain callable
  ``policy(observation)``. Each gets the plugin's
  :class:`~pytest_avscenario.sim.observation.Observation` and answers
  ``(acceleration [m/s^2], steering [rad])`` — so a model trained on highway-env (whose
  ``predict`` expects highway-env's observation arrays) goes through
  :func:`highway_env_agent` instead;
* a driver with its own vehicle model, such as :func:`highway_env_agent`'s: an object with
  ``make_ego(world, position, heading, speed, *, lane_index, route, target_speed, name)``
  that returns the ego vehicle, which then drives itself.

Any driver may declare ``dt`` [s], the step it was made for: ``world.run()`` without ``dt=``
then steps at it (unless ``--avs-dt`` or ``@scenario(dt=...)`` says otherwise); a
:func:`highway_env_agent` declares its environment's ``1 / simulation_frequency``, a plain
callable nothing (0.1 s).

Any driver may have the per-case hook ``reset(world)`` (or ``reset()``): the world calls it
once per case, after every agent is placed and before the first step, so a driver object
reused across cases starts each one afresh, and a stack that needs more than its
observation keeps the world to call ``world.view()`` (every lane and every agent, read-only).

:func:`action_pair` checks what a driver returned; the world turns its ``ValueError`` into a
:class:`~pytest_avscenario.sim.SimError` naming the test and the agent.
"""

from __future__ import annotations

import difflib
import importlib
import inspect
import math
import pkgutil
import re
from typing import Any, Callable

from ..errors import SimError
from .reference import CarefulDriver, CarefulDriverOptions, closing_distance, stopping_distance

__all__ = ["resolve", "import_driver", "is_import_path", "SCHEMES", "declared_step", "action_pair", "IDMDriver", "PolicyDriver", "AUTOPILOT", "CAREFUL", "BUILTIN",
           "CarefulDriver", "CarefulDriverOptions", "stopping_distance", "closing_distance",
           "highway_env_agent"]

AUTOPILOT = "pytest_avscenario.sim.drivers.autopilot:Autopilot"
CAREFUL = "pytest_avscenario.sim.drivers.reference:CarefulDriver"

#: the built-in driver names :func:`resolve` accepts
BUILTIN = ("autopilot", "idm", "careful")
_PATHS = {"autopilot": AUTOPILOT, "careful": CAREFUL}


class IDMDriver:
    """Marker driver: the ego is highway-env's IDM vehicle itself (see module doc)."""

    name = "idm"

    def act(self, observation: Any) -> tuple[float, float]:  # pragma: no cover - never called
        raise RuntimeError("the 'idm' ego drives itself; act() is not used")

    def __repr__(self) -> str:
        return "IDMDriver()"


class PolicyDriver:
    """A user policy adapted to ``act(observation) -> raw action``.

    ``style`` is ``"act"``, ``"predict"`` or ``"callable"``; ``target`` the user's object.
    """

    def __init__(self, target: Any, style: str) -> None:
        self.target = target
        self.style = style
        self.name = getattr(target, "__name__", None) or type(target).__name__
        self._call: Callable[[Any], Any]
        if style == "act":
            self._call = target.act
        elif style == "callable":
            self._call = target
        else:
            predict = target.predict
            try:
                takes_det = "deterministic" in inspect.signature(predict).parameters
            except (TypeError, ValueError):
                takes_det = False
            if takes_det:
                self._call = lambda obs: _first(predict(obs, deterministic=True))
            else:
                self._call = lambda obs: _first(predict(obs))

    def act(self, observation: Any) -> Any:
        return self._call(observation)

    def reset(self, world: Any) -> None:
        """The user object's per-case hook, if it has one: ``reset(world)`` or ``reset()``."""
        hook = getattr(self.target, "reset", None)
        if not callable(hook):
            return
        try:
            inspect.signature(hook).bind(world)
        except TypeError:
            try:
                inspect.signature(hook).bind()
            except TypeError:
                pass  # neither fits: call it with the world and let the error say so
            else:
                hook()
                return
        except ValueError:  # no signature (a builtin): the documented form
            pass
        hook(world)

    def __repr__(self) -> str:
        return f"PolicyDriver({self.name}, {self.style})"


def highway_env_agent(model: Any, env: Any = "highway-fast-v0", config: dict | None = None) -> Any:
    """An agent trained on highway-env as the ego, driven exactly as its environment would.

    ``model`` is an object with stable-baselines3's ``predict(obs, deterministic=...)`` or a
    plain callable ``policy(obs) -> action``; ``env`` the highway-env id it was trained on (or
    that environment itself); ``config`` what was changed in that environment's default
    config. Use it as ``world.ego(..., driver=highway_env_agent(model))`` or as the value of
    the ``avs_driver`` fixture. See :mod:`.highway_agent`.
    """
    from .highway_agent import HighwayEnvAgent

    return HighwayEnvAgent(model, env=env, config=config)


def _first(out: Any) -> Any:
    # stable-baselines3 returns (action, recurrent_state).
    if isinstance(out, tuple) and len(out) == 2 and not _is_number(out[0]):
        return out[0]
    return out


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def resolve(driver: Any) -> Any:
    """The driver object for ``driver`` (name, import path or user policy); see module doc.

    Raises :class:`SimError` for an unknown name or an object that cannot drive.
    """
    if driver is None:
        driver = "autopilot"
    if isinstance(driver, str):
        name = driver.strip()
        if name == "idm":
            return IDMDriver()
        if name.startswith("sb3:"):
            from .sb3 import driver as sb3_driver

            return sb3_driver(name)
        if name.startswith(("osi:", "osi+spawn:")):
            from ...stack.client import OSIStack, parse_spec

            try:
                address, command = parse_spec(name)
            except ValueError as exc:
                raise SimError(str(exc)) from None
            return OSIStack(address, spawn=command)
        name = _PATHS.get(name, name)
        if ":" not in name:
            raise SimError(
                f"unknown driver {driver!r}: use 'autopilot', 'idm', 'careful', "
                "'package.module:Name', 'sb3:PATH@ENV', 'osi:ADDRESS', or pass a policy object")
        try:
            obj = import_driver(name, shown=driver)
        except ValueError as exc:
            raise SimError(str(exc)) from None
        if inspect.isclass(obj):
            obj = obj()
        return resolve(obj)
    if isinstance(driver, (IDMDriver, PolicyDriver)) or callable(getattr(driver, "make_ego", None)):
        return driver
    if callable(getattr(driver, "act", None)):
        return PolicyDriver(driver, "act")
    if callable(getattr(driver, "predict", None)):
        return PolicyDriver(driver, "predict")
    if callable(driver):
        return PolicyDriver(driver, "callable")
    raise SimError(
        f"cannot drive with {driver!r} ({type(driver).__name__}): a driver is 'autopilot', "
        "'idm', 'careful', a callable policy(observation), or an object with act() or predict()")


#: driver strings with a scheme of their own, not ``package.module:Name`` import paths
SCHEMES = ("sb3:", "osi:", "osi+spawn:")
_IMPORT_PATH = re.compile(r"[A-Za-z_]\w*(?:\.[A-Za-z_]\w*)*:[A-Za-z_]\w*(?:\.[A-Za-z_]\w*)*")


def is_import_path(text: str) -> bool:
    """``text`` names a driver as ``package.module:Name`` (not a built-in, not a scheme)."""
    text = text.strip()
    return not text.startswith(SCHEMES) and _IMPORT_PATH.fullmatch(text) is not None


def import_driver(text: str, shown: Any = None) -> Any:
    """The object ``package.module:Name`` names, checked to be able to drive (not called).

    ValueError says in one line what was wrong: the module not found (with close module
    names), importing it raised, the name missing (with close names), or the object is no
    driver (neither callable nor with ``act``/``predict``; a class that needs arguments).
    Configuration calls it for ``--avs-driver``, so a typo stops the run before any case.
    """
    shown = text.strip() if shown is None else shown
    text = text.strip()
    if _IMPORT_PATH.fullmatch(text) is None:
        raise ValueError(f"driver {shown!r} is not an import path: write 'package.module:Name' "
                         "(a module Python can import, then a class or object in it)")
    mod_name, _, attr = text.partition(":")
    try:
        module = importlib.import_module(mod_name)
    except ModuleNotFoundError as exc:
        missing = exc.name or mod_name
        if not (mod_name == missing or mod_name.startswith(missing + ".")):
            # the module exists but imports something that does not: its own error
            raise ValueError(f"driver {shown!r}: importing module {mod_name!r} failed: "
                             f"{type(exc).__name__}: {exc}") from None
        raise ValueError(f"driver {shown!r}: no module named {missing!r}"
                         f"{_suggest(missing, _module_names(missing))}; the module must be "
                         "importable when pytest starts (installed, or on sys.path: e.g. "
                         "`pythonpath = .` in the ini file)") from None
    except Exception as exc:  # the user's module raised while it was imported
        raise ValueError(f"driver {shown!r}: importing module {mod_name!r} failed: "
                         f"{type(exc).__name__}: {exc}") from None
    obj: Any = module
    for i, part in enumerate(attr.split(".")):
        if not hasattr(obj, part):
            where = mod_name if i == 0 else f"{mod_name}:{'.'.join(attr.split('.')[:i])}"
            names = [n for n in dir(obj) if not n.startswith("_")]
            raise ValueError(f"driver {shown!r}: {where!r} has no attribute {part!r}"
                             f"{_suggest(part, names)}") from None
        obj = getattr(obj, part)
    if isinstance(obj, str):
        if obj.strip() not in BUILTIN and not obj.strip().startswith(SCHEMES) and not is_import_path(obj):
            raise ValueError(f"driver {shown!r} names the text {obj!r}, which is no driver name")
        return obj
    if inspect.isclass(obj):
        # a class is always callable (it makes objects): what drives is what its objects have
        has = [m for m in ("act", "predict", "make_ego") if callable(getattr(obj, m, None))]
        if not has and not any("__call__" in vars(k) for k in obj.__mro__[:-1]):
            raise ValueError(f"driver {shown!r}: class {obj.__qualname__} has no act(observation) "
                             "or predict(observation) method and its objects are not callable, "
                             "so it cannot drive")
        try:
            inspect.signature(obj).bind()
        except TypeError as exc:
            raise ValueError(f"driver {shown!r}: class {obj.__qualname__} is made without "
                             f"arguments, but its constructor needs some ({exc}); name an "
                             "object made with them, or use an avs_driver fixture") from None
        except ValueError:
            pass  # no signature to read (a C type): trust it
        return obj
    if not (callable(obj) or any(callable(getattr(obj, m, None)) for m in ("act", "predict", "make_ego"))):
        raise ValueError(f"driver {shown!r}: {attr!r} is of type {type(obj).__name__}, not a driver: "
                         "give a class, a callable policy(observation), or an object with "
                         "act(observation) or predict(observation)")
    return obj


def _suggest(name: str, candidates: Any) -> str:
    close = difflib.get_close_matches(name, list(candidates), n=3, cutoff=0.8)
    return f" (did you mean {' or '.join(repr(c) for c in close)}?)" if close else ""


def _module_names(missing: str) -> list[str]:
    """Modules beside ``missing``: the top-level ones, or those of its parent package."""
    parent, _, _ = missing.rpartition(".")
    try:
        path = None if not parent else importlib.import_module(parent).__path__
        prefix = f"{parent}." if parent else ""
        return [prefix + m.name for m in pkgutil.iter_modules(path)]
    except Exception:  # a parent that is no package, an unreadable folder: no suggestion
        return []


def declared_step(driver: Any) -> Any:
    """The ``dt`` [s] a driver declares (see module doc), as given; None when it declares none.

    ``driver`` is resolved first (a name, ``sb3:...``, a user object); a user object's own
    ``dt`` counts, not only the adapter's.
    """
    drv = resolve(driver)
    declared = getattr(drv, "dt", None)
    if declared is None and isinstance(drv, PolicyDriver):
        declared = getattr(drv.target, "dt", None)
    return declared


def action_pair(raw: Any) -> tuple[float, float]:
    """``(acceleration, steering)`` as floats from a driver's answer; ``ValueError`` if malformed.

    Accepts a 2-sequence or an array of 2 numbers (any shape with 2 elements, e.g. ``(1, 2)``
    from a batched policy) and a mapping with ``acceleration`` and ``steering``. Text
    (``"1"``) and booleans are not numbers here: a policy returning them has a bug.
    """
    if type(raw) is tuple and len(raw) == 2 and type(raw[0]) is float and type(raw[1]) is float:
        a, d = raw  # the common answer, checked without numpy (the same checks as below)
        if math.isfinite(a) and math.isfinite(d) and abs(a) <= MAX_ACTION_MAGNITUDE \
                and abs(d) <= MAX_ACTION_MAGNITUDE:
            return a, d
    import numpy as np

    def not_number(v: Any) -> bool:
        return isinstance(v, (str, bytes, bool, np.bool_, np.str_, np.bytes_))

    if isinstance(raw, dict):
        try:
            vals = [raw["acceleration"], raw["steering"]]
        except KeyError as exc:
            raise ValueError(f"action dict lacks {exc.args[0]!r}: {raw!r}") from None
        if any(not_number(v) for v in vals):
            raise ValueError(f"expected two numbers, got {raw!r}")
    else:
        not_numbers = ValueError(
            f"expected (acceleration, steering) as two numbers, got {raw!r} (text, booleans "
            "and complex numbers are not accepted)")
        if isinstance(raw, (str, bytes)) or (isinstance(raw, (list, tuple)) and any(map(not_number, raw))):
            raise not_numbers  # checked before numpy, which would turn (True, 1.5) into floats
        try:
            arr = np.asarray(raw)
        except (TypeError, ValueError):
            arr = None
        if arr is not None and (arr.dtype.kind not in "iufO"
                                or (arr.dtype.kind == "O" and any(map(not_number, arr.reshape(-1))))):
            raise not_numbers
        try:
            arr = np.asarray(raw, dtype=float)
        except OverflowError:  # an integer beyond a float (10**400): a bad action, not a crash
            raise ValueError(f"expected (acceleration, steering) as two numbers, got {_short(raw)}: "
                             "an integer too large for a float") from None
        except (TypeError, ValueError):
            raise ValueError(
                f"expected (acceleration, steering), got {raw!r} ({type(raw).__name__})") from None
        if arr.size != 2:
            raise ValueError(
                f"expected (acceleration, steering): 2 numbers, got shape {arr.shape}: {raw!r}")
        vals = arr.reshape(2).tolist()
    try:
        a, d = float(vals[0]), float(vals[1])
    except OverflowError:
        raise ValueError(f"expected two numbers, got {_short(raw)}: an integer too large for a float") from None
    except (TypeError, ValueError):
        raise ValueError(f"expected two numbers, got {raw!r}") from None
    if not (math.isfinite(a) and math.isfinite(d)):
        raise ValueError(f"non-finite action (acceleration={a!r}, steering={d!r})")
    if abs(a) > MAX_ACTION_MAGNITUDE or abs(d) > MAX_ACTION_MAGNITUDE:
        # the world clamps an action to the vehicle's limits, which would hide a driver
        # answering 1e308 (a unit or scaling bug) as a hard brake; a saturating controller
        # stays far below this
        raise ValueError(f"absurd action (acceleration={a:g} m/s², steering={d:g} rad): beyond "
                         f"±{MAX_ACTION_MAGNITUDE:g}, no vehicle; a unit or scaling mistake?")
    return a, d


#: an action component beyond this (m/s² or rad) is a driver's bug, never clamped to the limits
MAX_ACTION_MAGNITUDE = 1e3


def _short(raw: Any) -> str:
    text = repr(raw)
    return text if len(text) <= 60 else text[:57] + "..."

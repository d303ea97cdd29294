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

import importlib
import inspect
import math
from typing import Any, Callable

from ..errors import SimError
from .reference import CarefulDriver, CarefulDriverOptions, closing_distance, stopping_distance

__all__ = ["resolve", "declared_step", "action_pair", "IDMDriver", "PolicyDriver", "AUTOPILOT", "CAREFUL", "BUILTIN",
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
        name = _PATHS.get(name, name)
        if ":" not in name:
            raise SimError(
                f"unknown driver {driver!r}: use 'autopilot', 'idm', 'careful', "
                "'package.module:Name', 'sb3:PATH@ENV', or pass a policy object")
        mod_name, _, attr = name.partition(":")
        try:
            obj = getattr(importlib.import_module(mod_name), attr)
        except (ImportError, AttributeError) as exc:
            raise SimError(f"driver {driver!r} cannot be imported ({exc}); "
                           "use driver='idm' or pass a policy object") from exc
        if inspect.isclass(obj):
            obj = obj()
        return resolve(obj) if not isinstance(obj, str) else resolve(obj)
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

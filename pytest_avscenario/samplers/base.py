"""The ask/tell protocol every sampler implements, and the registry that names them.

A sampler proposes points of ``[0, 1]^d`` (``ask_unit``) and may learn from the robustness
of each evaluated point (``tell_unit``). ``ask``/``tell`` are the same in parameter space.
Robustness is a float (the worst metric), a mapping ``{metric: rho}``, or ``None`` when the
case was invalid (the driver raised, a monitor gave NaN): an invalid case is never a pass.
Samplers are deterministic given their seed and the feedback they receive, and can save and
restore their state as plain JSON.
"""

from __future__ import annotations

import importlib
import math
from typing import Any, Callable, Mapping

import numpy as np

from ..space import FeatureSpace

Rho = float | Mapping[str, float] | None


class SamplerError(ValueError):
    """A sampler was asked for by an unknown name or given options it does not take."""


# name -> "module:ClassName" (imported lazily) or the class itself
_REGISTRY: dict[str, Any] = {
    "random": "pytest_avscenario.samplers.random:RandomSampler",
    "halton": "pytest_avscenario.samplers.halton:HaltonSampler",
}


def register(name: str, target: Any = None) -> Callable[[type], type] | type:
    """Register a sampler class under ``name`` (usable as a decorator)."""

    def deco(cls: type) -> type:
        _REGISTRY[name] = cls
        return cls

    return deco(target) if target is not None else deco


def available() -> list[str]:
    return sorted(_REGISTRY)


def sampler_class(name: str) -> type["Sampler"]:
    if not isinstance(name, str) or name not in _REGISTRY:
        raise SamplerError(f"unknown sampler {name!r}; available: {', '.join(available())}")
    target = _REGISTRY[name]
    if isinstance(target, str):
        mod, _, cls = target.partition(":")
        target = getattr(importlib.import_module(mod), cls)
        _REGISTRY[name] = target
    return target


def is_active(name: str) -> bool:
    return bool(sampler_class(name).active)


def make(name: str, space: FeatureSpace | Mapping[str, Any], seed: int | np.random.Generator = 0,
         **options: Any) -> "Sampler":
    """Make the sampler ``name`` over ``space`` (a FeatureSpace or the mapping given to @scenario)."""
    cls = sampler_class(name)
    return cls(FeatureSpace.coerce(space), seed=seed, **options)


def scalar_rho(rho: Rho) -> float | None:
    """The worst (smallest) robustness of a feedback value; None for an invalid case."""
    if rho is None:
        return None
    if isinstance(rho, Mapping):
        vals = [float(v) for v in rho.values()]
        if not vals:
            return None
        v = min(vals)
    else:
        v = float(rho)
    return None if math.isnan(v) else v


class Sampler:
    """Base class. Subclasses set ``name``/``active`` and implement ``ask_unit``."""

    name: str = "?"
    active: bool = False
    options: tuple[str, ...] = ()

    def __init__(self, space: FeatureSpace, seed: int | np.random.Generator = 0, **options: Any):
        unknown = set(options) - set(self.options)
        if unknown:
            raise SamplerError(
                f"sampler {self.name!r} does not take option(s) {sorted(unknown)}; "
                f"it takes: {list(self.options) or 'none'}"
            )
        self.space = FeatureSpace.coerce(space)
        self.seed = seed
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        self.n_asked = 0
        self.n_told = 0

    @property
    def d(self) -> int:
        return self.space.d

    # -- the protocol -------------------------------------------------------------------
    def ask_unit(self) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def tell_unit(self, u: np.ndarray, rho: Rho) -> None:
        self.n_told += 1

    def ask(self) -> dict[str, Any]:
        return self.space.from_unit(self.ask_unit())

    def tell(self, params: Mapping[str, Any], rho: Rho) -> None:
        self.tell_unit(self.space.to_unit(params), rho)

    def sample_unit(self, n: int) -> np.ndarray:
        """``n`` points at once (passive samplers override this with a vectorized draw)."""
        return np.array([self.ask_unit() for _ in range(n)]).reshape(n, self.d)

    # -- state --------------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        """JSON-able state; ``restore`` of it continues the same sequence."""
        return {"name": self.name, "n_asked": self.n_asked, "n_told": self.n_told,
                "rng": _rng_state(self.rng)}

    def restore(self, state: Mapping[str, Any]) -> None:
        self.n_asked = int(state["n_asked"])
        self.n_told = int(state["n_told"])
        self.rng.bit_generator.state = _rng_from_json(state["rng"])


def _rng_state(rng: np.random.Generator) -> dict[str, Any]:
    st = rng.bit_generator.state
    return _jsonable(st)


def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, np.ndarray):
        return {"__ndarray__": x.tolist(), "dtype": str(x.dtype)}
    if isinstance(x, (np.integer,)):
        return int(x)
    return x


def _rng_from_json(x: Any) -> Any:
    if isinstance(x, dict):
        if "__ndarray__" in x:
            return np.array(x["__ndarray__"], dtype=x["dtype"])
        return {k: _rng_from_json(v) for k, v in x.items()}
    return x

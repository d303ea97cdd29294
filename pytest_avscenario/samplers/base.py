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

from ..codec import rho_to_json
from ..space import FeatureSpace
from .errors import SamplerError

Rho = float | Mapping[str, float] | None

# name -> "module:ClassName" (imported lazily) or the class itself
_REGISTRY: dict[str, Any] = {
    "random": "pytest_avscenario.samplers.random:RandomSampler",
    "halton": "pytest_avscenario.samplers.halton:HaltonSampler",
    "mab": "pytest_avscenario.samplers.mab:MultiArmedBanditSampler",
    "ce": "pytest_avscenario.samplers.ce:CrossEntropySampler",
    "sa": "pytest_avscenario.samplers.sa:SimulatedAnnealingSampler",
    "bo": "pytest_avscenario.samplers.bo:BayesianOptimizationSampler",
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
    """The worst (smallest) robustness of a feedback value; None for an invalid case.

    Any NaN makes the whole case invalid (``min`` over a list holding NaN would otherwise
    depend on the order of the metrics). Infinite values are kept: a metric that holds
    trivially (TTC with no conflict) legitimately reports ``+inf``.
    """
    if rho is None:
        return None
    if type(rho) is float:  # the common case, without the Mapping ABC check
        return None if rho != rho else rho
    if isinstance(rho, Mapping):
        vals = [float(v) for v in rho.values()]
        if not vals or any(math.isnan(v) for v in vals):
            return None
        return min(vals)
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
        self._conv = _compile(self.space)
        self._rows_to_dicts = _dict_builder([c[0] for c in self._conv])
        dims = [c for c in self._conv if c[1] != 0]
        self._uni_idx = np.array([i for i, c in enumerate(dims) if c[1] == 1], dtype=int)
        self._uni_lo = np.array([c[2] for c in dims if c[1] == 1], dtype=float)
        self._uni_w = np.array([c[3] for c in dims if c[1] == 1], dtype=float)
        self._uni_hi = np.array([c[4].hi for c in dims if c[1] == 1], dtype=float)

    @property
    def d(self) -> int:
        return self.space.d

    # -- the protocol -------------------------------------------------------------------
    def ask_unit(self) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def tell_unit(self, u: np.ndarray, rho: Rho) -> None:
        self.n_told += 1

    def ask(self) -> dict[str, Any]:
        """The next case as ``{parameter: value}`` (constants included)."""
        return self._params(self.ask_unit())

    def tell(self, params: Mapping[str, Any], rho: Rho) -> None:
        """Feedback for an evaluated case: a float, ``{metric: float}``, or None if invalid."""
        if not self.active:
            # passive samplers learn nothing; skip the conversion (it is the whole cost)
            self.n_told += 1
            return
        self.tell_unit(self._unit(params), rho)

    # The plugin asks once per case, but the benchmark and users outside pytest call these
    # in tight loops: FeatureSpace.from_unit/to_unit cost more than a bandit step, so the
    # conversion is precompiled per parameter. It computes exactly what FeatureSpace does.
    def _params(self, u: Any) -> dict[str, Any]:
        it = iter(u.tolist() if isinstance(u, np.ndarray) else u)
        out: dict[str, Any] = {}
        for name, kind, a, w, dist in self._conv:
            if kind == 0:
                out[name] = a
                continue
            x = next(it)
            x = 0.0 if x < 0.0 else (1.0 if x > 1.0 else x)
            if kind == 1:
                v = a + x * w
                out[name] = v if v <= dist.hi else dist.hi  # lo + 1.0 * (hi - lo) may round past hi
            else:
                out[name] = dist.from_unit(x)
        return out

    def _params_many(self, U: np.ndarray) -> list[dict[str, Any]]:
        """``_params`` of every row of ``U`` at once (same values, fewer Python steps)."""
        U = np.asarray(U, dtype=float)
        U = (U.reshape(1, self.d) if U.ndim == 1 else U).clip(0.0, 1.0)
        n = U.shape[0]
        if not self._conv:
            return [{} for _ in range(n)]
        # every Uniform column in one affine step (the same float operations as _params)
        uni = iter(np.minimum(self._uni_lo + U[:, self._uni_idx] * self._uni_w, self._uni_hi).T.tolist())
        cols: list[list[Any]] = []
        j = 0
        for name, kind, a, w, dist in self._conv:
            if kind == 0:
                cols.append([a] * n)
                continue
            if kind == 1:
                cols.append(next(uni))
            else:
                cols.append([dist.from_unit(x) for x in U[:, j].tolist()])
            j += 1
        return self._rows_to_dicts(cols)

    def _unit(self, params: Mapping[str, Any]) -> list[float]:
        vals = []
        for name, kind, a, w, dist in self._conv:
            if kind == 0:
                continue
            x = (float(params[name]) - a) / w if kind == 1 else dist.to_unit(params[name])
            if not 0.0 <= x <= 1.0:
                if x != x:
                    raise SamplerError(f"told a case whose parameter {name!r} is NaN")
                # a value from outside the space counts at the nearest face, as from_unit
                # would have produced it (and bucket lookups rely on [0, 1])
                x = 0.0 if x < 0.0 else 1.0
            vals.append(x)
        return vals

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


# a float for strict JSON, encoded as everywhere else (±inf and NaN as strings)
json_float = rho_to_json


def _compile(space: FeatureSpace) -> list[tuple[str, int, Any, float, Any]]:
    """Per parameter: (name, kind 0=constant/1=uniform/2=other, offset, width, distribution)."""
    from ..space import Uniform

    conv: list[tuple[str, int, Any, float, Any]] = []
    for name, dist in space.parameters.items():
        if dist.kind == "constant":
            conv.append((name, 0, dist.nominal, 0.0, dist))
        elif type(dist) is Uniform:
            conv.append((name, 1, dist.lo, dist.hi - dist.lo, dist))
        else:
            conv.append((name, 2, 0.0, 0.0, dist))
    return conv


def _dict_builder(names: list[str]) -> Callable[[list[list[Any]]], list[dict[str, Any]]]:
    """A function turning per-parameter columns into one dict per row.

    Generated once per space (as namedtuple does) because a dict display is three times
    faster than ``dict(zip(names, row))``, and building the dicts was most of a Halton ask.
    Names enter the code only through ``repr``, so any string is safe."""
    if not names:
        return lambda cols: []
    keys = ", ".join(f"{n!r}: v{i}" for i, n in enumerate(names))
    args = ", ".join(f"v{i}" for i in range(len(names)))
    return eval(f"lambda cols: [{{{keys}}} for ({args},) in zip(*cols)]", {})  # noqa: S307


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


class ActiveSampler(Sampler):
    """Base of the samplers that learn from feedback.

    Every active sampler takes ``metrics=[names]`` (the monitor set's metrics, so feedback
    and the priority order can be checked against them) and ``priority=`` (metric names
    highest first, or ``(higher, lower)`` pairs), so the plugin can pass both uniformly.
    Feedback is reduced to the worst metric (``scalar_rho``) unless a sampler reads the
    mapping itself (``multi_objective = True``); with a priority order, to the worst of the
    top-ranked metrics, so a single-objective search goes for the failures that matter most.
    ``None`` (or any NaN) is an invalid case: counted in ``n_invalid`` and never treated as
    a pass.
    """

    active = True
    multi_objective = False  # True: _learn reads the metric mapping and the priority itself
    options: tuple[str, ...] = ("metrics", "priority")

    def __init__(self, space: FeatureSpace, seed: int | np.random.Generator = 0,
                 metrics: Any = None, priority: Any = None, **options: Any):
        super().__init__(space, seed=seed, **options)
        from .priority import PriorityOrder

        self.order = PriorityOrder.parse(priority, metrics)
        self.known_metrics = None if metrics is None else frozenset(self.order.metrics)
        self.multi = bool(self.order.edges)
        self.n_invalid = 0

    def _check_metrics(self, rho: Rho) -> None:
        if self.known_metrics is not None and isinstance(rho, Mapping):
            unknown = [k for k in rho if k not in self.known_metrics]
            if unknown:
                raise SamplerError(
                    f"feedback names unknown metric(s) {unknown}; declared metrics: "
                    f"{sorted(self.known_metrics)}"
                )

    def tell_unit(self, u: np.ndarray, rho: Rho) -> None:
        self.n_told += 1
        if self.known_metrics is not None:
            self._check_metrics(rho)
        r = scalar_rho(rho)
        if r is not None and self.multi and not self.multi_objective and isinstance(rho, Mapping):
            top = [v for m, v in rho.items() if self.order.level.get(m, 0) == 0]
            r = min(map(float, top)) if top else r
        if r is None:
            self.n_invalid += 1
        self._learn(u, r, rho)

    def _learn(self, u: Any, r: float | None, rho: Rho) -> None:  # pragma: no cover
        """Learn from one case: ``u`` its unit point (an array, or a list of floats when it
        came through ``tell``), ``r`` its scalar rho (None: invalid), ``rho`` as told."""
        raise NotImplementedError

    def state(self) -> dict[str, Any]:
        st = super().state()
        st["n_invalid"] = self.n_invalid
        return st

    def restore(self, state: Mapping[str, Any]) -> None:
        if state.get("name") != self.name:
            raise SamplerError(f"state of sampler {state.get('name')!r} given to {self.name!r}")
        super().restore(state)
        self.n_invalid = int(state.get("n_invalid", 0))


def check_int(value: Any, what: str, lo: int = 1) -> int:
    """An integer option >= lo, or a SamplerError saying what was wrong."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < lo:
        raise SamplerError(f"{what} must be an integer >= {lo}, got {value!r}")
    return int(value)


def check_float(value: Any, what: str, lo: float = 0.0, hi: float = math.inf,
                lo_open: bool = False, hi_open: bool = False) -> float:
    """A finite float option in [lo, hi] (ends optionally open), or a SamplerError."""
    ok = not isinstance(value, bool) and isinstance(value, (int, float, np.integer, np.floating))
    v = float(value) if ok else math.nan
    if ok and math.isfinite(v):
        ok = (v > lo if lo_open else v >= lo) and (v < hi if hi_open else v <= hi)
    else:
        ok = False
    if not ok:
        rng = f"{'(' if lo_open else '['}{lo}, {hi}{')' if hi_open else ']'}"
        raise SamplerError(f"{what} must be a number in {rng}, got {value!r}")
    return v

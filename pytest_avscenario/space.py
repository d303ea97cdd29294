"""Distributions over scenario parameters and the feature space they span.

A scenario declares each parameter as a distribution; a :class:`FeatureSpace` orders them
and maps every concrete case to and from the unit cube ``[0, 1]^d`` on which all samplers
work. Continuous parameters map affinely (or through the truncated normal CDF); integer and
categorical parameters are stratified, so a sampler's coordinate picks a value with
probability equal to its weight and a low-discrepancy sequence stratifies over the values too.
Constants take no coordinate. Nothing here imports anything heavier than numpy.
"""

from __future__ import annotations

import hashlib
import inspect
import json
import math
from dataclasses import dataclass
from statistics import NormalDist
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

__all__ = [
    "Distribution",
    "Uniform",
    "Normal",
    "IntRange",
    "Choice",
    "Constant",
    "FeatureSpace",
    "SpaceError",
]


class SpaceError(ValueError):
    """A distribution or feature space was declared wrongly (the message says how)."""


def _finite_number(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise SpaceError(f"{what} must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise SpaceError(f"{what} must be finite, got {value!r}")
    return value


def _within(value: Any, lo: float, hi: float) -> bool:
    try:
        v = float(value)
    except (TypeError, ValueError):
        return False
    return lo <= v <= hi


def _plain_signature(fn: Any) -> str:
    return ", ".join(
        p.name if p.default is inspect.Parameter.empty else f"{p.name}={p.default!r}"
        for p in inspect.signature(fn).parameters.values()
    )


class Distribution:
    """One parameter's distribution.

    ``kind`` is one of ``"continuous"``, ``"integer"``, ``"categorical"``, ``"constant"``.
    ``to_unit`` / ``from_unit`` map a value to and from the sampler's coordinate in [0, 1].
    """

    kind: str = "continuous"
    #: why the arguments were invalid (None when valid); see :meth:`check`
    error: str | None = None

    def __init__(self, *args: Any, **kwargs: Any):
        # Invalid arguments do not raise here: the declaration sits at module level above a
        # test, where a raise would become an import traceback without the test's name. The
        # feature space (and so the plugin, at collection) raises with the parameter's name.
        self._args = (args, kwargs)
        try:
            inspect.signature(self._setup).bind(*args, **kwargs)
        except TypeError as exc:
            self.error = f"{type(self).__name__}({_plain_signature(self._setup)}): {exc}"
            return
        try:
            self._setup(*args, **kwargs)
        except SpaceError as exc:
            self.error = str(exc)

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if "_setup" in cls.__dict__:
            # help(Uniform) and IDEs show the real arguments, not (*args, **kwargs)
            params = list(inspect.signature(cls._setup).parameters.values())
            cls.__signature__ = inspect.Signature(params[1:])

    def _setup(self, *args: Any, **kwargs: Any) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def check(self) -> None:
        """Raise :class:`SpaceError` if the distribution was declared with bad arguments."""
        if self.error is not None:
            raise SpaceError(self.error)

    @property
    def nominal(self) -> Any:  # pragma: no cover - every subclass defines it
        raise NotImplementedError

    @property
    def dims(self) -> int:
        return 0 if self.kind == "constant" else 1

    def from_unit(self, u: float) -> Any:  # pragma: no cover
        raise NotImplementedError

    def to_unit(self, value: Any) -> float:  # pragma: no cover
        raise NotImplementedError

    def contains(self, value: Any) -> bool:  # pragma: no cover
        raise NotImplementedError

    def describe(self) -> dict[str, Any]:  # pragma: no cover
        """A JSON-able description; two equal descriptions mean the same distribution."""
        raise NotImplementedError

    def __repr__(self) -> str:
        if self.error is not None:
            a, kw = self._args
            parts = [repr(x) for x in a] + [f"{k}={v!r}" for k, v in kw.items()]
            return f"{type(self).__name__}({', '.join(parts)})"
        args = ", ".join(f"{k}={v!r}" for k, v in self.describe().items() if k != "type")
        return f"{type(self).__name__}({args})"


class Uniform(Distribution):
    """Uniform on ``[lo, hi]``; ``nominal`` defaults to the midpoint."""

    kind = "continuous"

    def _setup(self, lo: float, hi: float, nominal: float | None = None) -> None:
        self.lo = _finite_number(lo, "Uniform lo")
        self.hi = _finite_number(hi, "Uniform hi")
        if not self.lo < self.hi:
            raise SpaceError(f"Uniform needs lo < hi, got lo={lo!r}, hi={hi!r}")
        if nominal is None:
            self._nominal = 0.5 * (self.lo + self.hi)
        else:
            self._nominal = _finite_number(nominal, "Uniform nominal")
            if not self.lo <= self._nominal <= self.hi:
                raise SpaceError(
                    f"Uniform nominal={nominal!r} lies outside [lo, hi] = [{lo!r}, {hi!r}]"
                )

    @property
    def nominal(self) -> float:
        return self._nominal

    def from_unit(self, u: float) -> float:
        return float(self.lo + float(u) * (self.hi - self.lo))

    def to_unit(self, value: Any) -> float:
        return float((float(value) - self.lo) / (self.hi - self.lo))

    def contains(self, value: Any) -> bool:
        return _within(value, self.lo, self.hi)

    def describe(self) -> dict[str, Any]:
        return {"type": "Uniform", "lo": self.lo, "hi": self.hi, "nominal": self._nominal}


class Normal(Distribution):
    """Normal(mean, sd) truncated to ``[lo, hi]``; the nominal value is the mean."""

    kind = "continuous"

    def _setup(self, mean: float, sd: float, lo: float, hi: float) -> None:
        self.mean = _finite_number(mean, "Normal mean")
        self.sd = _finite_number(sd, "Normal sd")
        self.lo = _finite_number(lo, "Normal lo")
        self.hi = _finite_number(hi, "Normal hi")
        if self.sd <= 0:
            raise SpaceError(f"Normal needs sd > 0, got sd={sd!r}")
        if not self.lo < self.hi:
            raise SpaceError(f"Normal needs lo < hi, got lo={lo!r}, hi={hi!r}")
        if not self.lo <= self.mean <= self.hi:
            raise SpaceError(f"Normal mean={mean!r} lies outside [lo, hi] = [{lo!r}, {hi!r}]")
        self._dist = NormalDist(self.mean, self.sd)
        self._clo = self._dist.cdf(self.lo)
        self._chi = self._dist.cdf(self.hi)
        if not self._chi - self._clo > 1e-12:
            raise SpaceError(f"Normal({mean}, {sd}) has no mass on [{lo}, {hi}]")

    @property
    def nominal(self) -> float:
        return self.mean

    def from_unit(self, u: float) -> float:
        p = self._clo + float(u) * (self._chi - self._clo)
        p = min(max(p, 1e-15), 1 - 1e-15)
        return float(min(max(self._dist.inv_cdf(p), self.lo), self.hi))

    def to_unit(self, value: Any) -> float:
        return float((self._dist.cdf(float(value)) - self._clo) / (self._chi - self._clo))

    def contains(self, value: Any) -> bool:
        return _within(value, self.lo, self.hi)

    def describe(self) -> dict[str, Any]:
        return {"type": "Normal", "mean": self.mean, "sd": self.sd, "lo": self.lo, "hi": self.hi}


class IntRange(Distribution):
    """Integers ``lo..hi`` inclusive, equally likely; nominal defaults to the middle value."""

    kind = "integer"

    def _setup(self, lo: int, hi: int, nominal: int | None = None) -> None:
        for name, v in (("lo", lo), ("hi", hi)):
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
                raise SpaceError(f"IntRange {name} must be an int, got {v!r}")
        self.lo, self.hi = int(lo), int(hi)
        if not self.lo < self.hi:
            raise SpaceError(f"IntRange needs lo < hi, got lo={lo!r}, hi={hi!r}")
        if nominal is None:
            self._nominal = (self.lo + self.hi) // 2
        else:
            if isinstance(nominal, bool) or not isinstance(nominal, (int, np.integer)):
                raise SpaceError(f"IntRange nominal must be an int, got {nominal!r}")
            if not self.lo <= nominal <= self.hi:
                raise SpaceError(f"IntRange nominal={nominal!r} lies outside [{lo}, {hi}]")
            self._nominal = int(nominal)

    @property
    def n_values(self) -> int:
        return self.hi - self.lo + 1

    @property
    def nominal(self) -> int:
        return self._nominal

    def from_unit(self, u: float) -> int:
        k = min(int(math.floor(float(u) * self.n_values)), self.n_values - 1)
        return self.lo + max(k, 0)

    def to_unit(self, value: Any) -> float:
        # the centre of the value's stratum, so from_unit(to_unit(v)) == v
        return (int(value) - self.lo + 0.5) / self.n_values

    def contains(self, value: Any) -> bool:
        if isinstance(value, bool):
            return False
        if isinstance(value, (float, np.floating)) and float(value).is_integer():
            value = int(value)
        return isinstance(value, (int, np.integer)) and self.lo <= value <= self.hi

    def describe(self) -> dict[str, Any]:
        return {"type": "IntRange", "lo": self.lo, "hi": self.hi, "nominal": self._nominal}


class Choice(Distribution):
    """One of ``options``; the first option is the nominal one. ``weights`` default to equal."""

    kind = "categorical"

    def _setup(self, options: Sequence[Any], weights: Sequence[float] | None = None) -> None:
        if isinstance(options, (str, bytes)) or not isinstance(options, Iterable):
            raise SpaceError(f"Choice options must be a list of values, got {options!r}")
        self.options = tuple(options)
        if not self.options:
            raise SpaceError("Choice needs at least one option, got an empty list")
        for o in self.options:
            if isinstance(o, float) and not math.isfinite(o):
                raise SpaceError(f"Choice option {o!r} is not finite; options must compare equal to themselves")
            try:
                json.dumps(o)
            except (TypeError, ValueError):
                raise SpaceError(
                    f"Choice option {o!r} is not a plain value (str, number, bool, None); "
                    "cases must be storable and replayable"
                ) from None
        if len(set(map(repr, self.options))) != len(self.options):
            raise SpaceError(f"Choice options must be distinct, got {list(self.options)!r}")
        if weights is None:
            w = np.full(len(self.options), 1.0 / len(self.options))
        else:
            if isinstance(weights, (str, bytes)) or not hasattr(weights, "__len__"):
                raise SpaceError(f"Choice weights must be a list of numbers, one per option, got {weights!r}")
            if len(weights) != len(self.options):
                raise SpaceError(
                    f"Choice has {len(self.options)} options but {len(weights)} weights"
                )
            w = np.array([_finite_number(x, "Choice weight") for x in weights], dtype=float)
            if (w < 0).any() or w.sum() <= 0:
                raise SpaceError(f"Choice weights must be >= 0 with a positive sum, got {weights!r}")
            w = w / w.sum()
        self.weights = tuple(float(x) for x in w)
        self._edges = np.concatenate([[0.0], np.cumsum(w)])
        self._edges[-1] = 1.0

    @property
    def n_values(self) -> int:
        return len(self.options)

    @property
    def nominal(self) -> Any:
        return self.options[0]

    def index(self, value: Any) -> int:
        for i, o in enumerate(self.options):
            if o == value and type(o) is type(value):
                return i
        for i, o in enumerate(self.options):
            if o == value:
                return i
        raise SpaceError(f"{value!r} is not one of the options {list(self.options)!r}")

    def from_unit(self, u: float) -> Any:
        k = int(np.searchsorted(self._edges, float(u), side="right")) - 1
        k = min(max(k, 0), len(self.options) - 1)
        # skip zero-weight strata at the boundary
        while self.weights[k] == 0.0 and k + 1 < len(self.options):
            k += 1
        return self.options[k]

    def to_unit(self, value: Any) -> float:
        k = self.index(value)
        return float(0.5 * (self._edges[k] + self._edges[k + 1]))

    def contains(self, value: Any) -> bool:
        try:
            self.index(value)
        except SpaceError:
            return False
        return True

    def describe(self) -> dict[str, Any]:
        return {"type": "Choice", "options": list(self.options), "weights": list(self.weights)}


class Constant(Distribution):
    """A fixed value; it takes no sampler coordinate."""

    kind = "constant"

    def _setup(self, value: Any) -> None:
        try:
            json.dumps(value)
        except (TypeError, ValueError):
            raise SpaceError(f"Constant value {value!r} is not a plain JSON value") from None
        if isinstance(value, float) and not math.isfinite(value):
            raise SpaceError(f"Constant value must be finite, got {value!r}")
        self.value = value

    @property
    def nominal(self) -> Any:
        return self.value

    def from_unit(self, u: float) -> Any:
        return self.value

    def to_unit(self, value: Any) -> float:
        return 0.5

    def contains(self, value: Any) -> bool:
        return value == self.value

    def describe(self) -> dict[str, Any]:
        return {"type": "Constant", "value": self.value}


def as_distribution(name: str, value: Any) -> Distribution:
    """A declared parameter as a distribution: plain values become :class:`Constant`."""
    if isinstance(value, Distribution):
        return value
    if isinstance(value, type) and issubclass(value, Distribution):
        raise SpaceError(f"parameter {name!r}: {value.__name__} must be called with its arguments")
    const = Constant(value)
    if const.error is not None:
        raise SpaceError(
            f"parameter {name!r}: {value!r} is neither a distribution "
            "(Uniform, Normal, IntRange, Choice, Constant) nor a plain constant"
        )
    return const


@dataclass(frozen=True)
class Dimension:
    """One sampler coordinate: which parameter, its kind and (if discrete) its value count."""

    name: str
    kind: str
    n_values: int | None


class FeatureSpace:
    """The ordered parameters of one scenario and their unit-cube mapping.

    ``dims`` lists the non-constant parameters in declaration order; a sampler point is a
    vector with one coordinate per dim.
    """

    def __init__(self, parameters: Mapping[str, Any]):
        self.parameters: dict[str, Distribution] = {}
        for k, v in parameters.items():
            dist = as_distribution(str(k), v)
            if dist.error is not None:
                raise SpaceError(f"parameter {k!r}: {dist.error}")
            self.parameters[str(k)] = dist
        self.dims: tuple[Dimension, ...] = tuple(
            Dimension(n, d.kind, getattr(d, "n_values", None))
            for n, d in self.parameters.items()
            if d.kind != "constant"
        )

    @classmethod
    def coerce(cls, space: "FeatureSpace | Mapping[str, Any]") -> "FeatureSpace":
        return space if isinstance(space, FeatureSpace) else cls(space)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.parameters)

    @property
    def d(self) -> int:
        return len(self.dims)

    @property
    def continuous(self) -> tuple[str, ...]:
        return tuple(dim.name for dim in self.dims if dim.kind == "continuous")

    def continuous_mask(self) -> np.ndarray:
        return np.array([dim.kind == "continuous" for dim in self.dims], dtype=bool)

    def nominal(self) -> dict[str, Any]:
        return {n: d.nominal for n, d in self.parameters.items()}

    def from_unit(self, u: Sequence[float] | np.ndarray) -> dict[str, Any]:
        u = np.asarray(u, dtype=float).reshape(-1)
        if u.shape[0] != self.d:
            raise SpaceError(f"expected a point with {self.d} coordinates, got {u.shape[0]}")
        u = np.clip(u, 0.0, 1.0)
        out: dict[str, Any] = {}
        i = 0
        for n, dist in self.parameters.items():
            if dist.kind == "constant":
                out[n] = dist.nominal
            else:
                out[n] = dist.from_unit(float(u[i]))
                i += 1
        return out

    def to_unit(self, params: Mapping[str, Any]) -> np.ndarray:
        return np.array(
            [self.parameters[dim.name].to_unit(params[dim.name]) for dim in self.dims], dtype=float
        )

    def validate(self, params: Mapping[str, Any]) -> None:
        """Raise SpaceError naming the first missing, unknown or out-of-range parameter."""
        unknown = set(params) - set(self.parameters)
        if unknown:
            raise SpaceError(f"unknown parameter(s) {sorted(unknown)}; declared: {list(self.names)}")
        for n, dist in self.parameters.items():
            if n not in params:
                if dist.kind == "constant":
                    continue
                raise SpaceError(f"parameter {n!r} is missing")
            if not dist.contains(params[n]):
                raise SpaceError(f"parameter {n!r}={params[n]!r} lies outside {dist!r}")

    def complete(self, params: Mapping[str, Any]) -> dict[str, Any]:
        """Fill missing constants, keeping declaration order."""
        return {n: params.get(n, d.nominal) for n, d in self.parameters.items()}

    def describe(self) -> dict[str, Any]:
        return {n: d.describe() for n, d in self.parameters.items()}

    @classmethod
    def from_description(cls, description: Mapping[str, Mapping[str, Any]]) -> "FeatureSpace":
        """Rebuild a space from :meth:`describe` output (plain JSON data; nothing executed)."""
        kinds = {"Uniform": Uniform, "Normal": Normal, "IntRange": IntRange, "Choice": Choice,
                 "Constant": Constant}
        params: dict[str, Distribution] = {}
        for name, desc in description.items():
            desc = dict(desc)
            kind = kinds.get(desc.pop("type", None))
            if kind is None:
                raise SpaceError(f"parameter {name!r}: unknown distribution in {desc!r}")
            params[name] = kind(**desc)
        return cls(params)

    def fingerprint(self) -> str:
        blob = json.dumps(self.describe(), sort_keys=True, default=repr).encode()
        return hashlib.sha256(blob).hexdigest()[:16]

    def __repr__(self) -> str:
        return f"FeatureSpace({', '.join(f'{n}={d!r}' for n, d in self.parameters.items())})"

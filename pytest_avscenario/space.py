"""Distributions over scenario parameters and the feature space they span.

A scenario declares each parameter as a distribution; a :class:`FeatureSpace` orders them
and maps every concrete case to and from the unit cube ``[0, 1]^d`` on which all samplers
work. Continuous parameters map affinely (or through the truncated normal CDF); integer and
categorical parameters are stratified, so a sampler's coordinate picks a value with
probability equal to its weight and a low-discrepancy sequence stratifies over the values too.
Constants take no coordinate. Nothing here imports anything heavier than numpy.
"""

from __future__ import annotations

import copy
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


#: IntRange bounds: beyond 2**53 a float coordinate cannot pick every integer
_INT_LIMIT = 2**53


def _show(value: Any, limit: int = 80) -> str:
    """``repr`` for a message: shortened, and safe for values whose repr fails (an int of
    more than 4300 digits) or is huge."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 200:
        return f"{'-' if value < 0 else ''}<an int of about {int(value.bit_length() * 0.30103) + 1} digits>"
    try:
        text = repr(value)
    except Exception:  # noqa: BLE001 - a message must not fail
        return f"<{type(value).__name__}>"
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _finite_number(value: Any, what: str) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise SpaceError(f"{what} must be a number, got {_show(value)}")
    try:
        number = float(value)
    except OverflowError:
        number = math.inf
    if not math.isfinite(number):
        raise SpaceError(f"{what} must be finite, got {_show(value)}")
    return number


def _numpy_plain(value: Any) -> Any:
    """``json.dumps``'s fallback: numpy scalars and arrays as the Python values they hold."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(type(value).__name__)


def _plain(value: Any, what: str) -> Any:
    """``value`` as the JSON data it is stored and replayed as (numpy scalars unwrapped,
    tuples as lists), or SpaceError: a case that cannot be stored cannot be replayed."""
    try:
        text = json.dumps(value, allow_nan=False, default=_numpy_plain)
        return json.loads(text)
    except (TypeError, ValueError, RecursionError):
        raise SpaceError(
            f"{what} {_show(value)} is not a plain value (str, finite number, bool, None, or a "
            "list/dict of them); cases must be storable and replayable"
        ) from None


def _key(value: Any) -> str | None:
    """A canonical text of a plain value (equal for equal JSON data), None if there is none."""
    try:
        return json.dumps(value, sort_keys=True, allow_nan=False, default=_numpy_plain)
    except (TypeError, ValueError, RecursionError):
        return None


def _sums_to_one(w: np.ndarray) -> bool:
    try:
        return math.fsum(w) == 1.0
    except OverflowError:  # 1e308 + 1e308
        return False


def _normalised(weights: Sequence[float]) -> np.ndarray:
    """Probabilities from non-negative weights with a positive sum, without overflow, and
    idempotent, so that a Choice rebuilt from its description has the same weights bit for
    bit: equal weights give exactly ``1/n`` each, and any other result sums to exactly 1
    (``math.fsum``), which is kept as it is when normalised again."""
    w = np.array(weights, dtype=float)
    n = len(w)
    if not (w == w[0]).all() and not _sums_to_one(w):
        with np.errstate(over="ignore"):
            total = float(w.sum())
        if math.isfinite(total):
            w = w / total
        if not _sums_to_one(w):
            w = w / w.max()  # no overflow when summing 1e308s
            w = w / math.fsum(w)
            k = int(np.argmax(w))
            for _ in range(64):  # move the largest weight by ulps until the sum is exactly 1
                total = math.fsum(w)
                if total == 1.0:
                    break
                w[k] = np.nextafter(w[k], -math.inf if total > 1.0 else math.inf)
    if (w == w[0]).all():
        return np.full(n, 1.0 / n)
    return w


def _within(value: Any, lo: float, hi: float) -> bool:
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
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
    unit: str | None = None
    #: why the arguments were invalid (None when valid); see :meth:`check`
    error: str | None = None

    def __init__(self, *args: Any, **kwargs: Any):
        # Invalid arguments do not raise here: the declaration sits at module level above a
        # test, where a raise would become an import traceback without the test's name. The
        # feature space (and so the plugin, at collection) raises with the parameter's name.
        self._args = (args, kwargs)
        name = type(self).__name__
        unit = kwargs.pop("unit", None)
        if unit is not None and not (isinstance(unit, str) and unit.strip() and len(unit) <= 20
                                     and unit.isprintable()):
            self.error = f"{name}: unit must be a short text such as 'm' or 'm/s^2', got {unit!r}"
            return
        #: the parameter's unit for reports (``"m"``, ``"m/s"``); None: not declared
        self.unit: str | None = unit.strip() if unit is not None else None
        if type(self)._setup is Distribution._setup:
            self.error = (f"{name} is {'the abstract base class' if type(self) is Distribution else 'a subclass of Distribution without _setup'}; "
                          "use one of Uniform, Normal, IntRange, Choice, Constant")
            return
        try:
            inspect.signature(self._setup).bind(*args, **kwargs)
        except TypeError as exc:
            self.error = f"{name}({_plain_signature(self._setup)}): {exc}"
            return
        try:
            self._setup(*args, **kwargs)
        except SpaceError as exc:
            self.error = str(exc)
        except Exception as exc:  # noqa: BLE001 - an odd argument must not become an import traceback
            self.error = f"{name}: bad arguments ({type(exc).__name__}: {exc})"

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if "_setup" in cls.__dict__:
            # help(Uniform) and IDEs show the real arguments, not (*args, **kwargs)
            params = list(inspect.signature(cls._setup).parameters.values())
            unit = inspect.Parameter("unit", inspect.Parameter.KEYWORD_ONLY, default=None)
            cls.__signature__ = inspect.Signature([*params[1:], unit])

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

    def _with_unit(self, description: dict[str, Any]) -> dict[str, Any]:
        if self.unit is not None:
            description["unit"] = self.unit
        return description

    def __repr__(self) -> str:
        if self.error is not None:
            a, kw = getattr(self, "_args", ((), {}))
            parts = [_show(x) for x in a] + [f"{k}={_show(v)}" for k, v in kw.items()]
            return f"{type(self).__name__}({', '.join(parts)})"
        args = ", ".join(f"{k}={_show(v)}" for k, v in self.describe().items() if k != "type")
        return f"{type(self).__name__}({args})"


class Uniform(Distribution):
    """Uniform on ``[lo, hi]``; ``nominal`` defaults to the midpoint."""

    kind = "continuous"

    def _setup(self, lo: float, hi: float, nominal: float | None = None) -> None:
        self.lo = _finite_number(lo, "Uniform lo")
        self.hi = _finite_number(hi, "Uniform hi")
        if not self.lo < self.hi:
            raise SpaceError(f"Uniform needs lo < hi, got lo={_show(lo)}, hi={_show(hi)}")
        if not math.isfinite(self.hi - self.lo):
            raise SpaceError(f"Uniform [{self.lo!r}, {self.hi!r}] is wider than the largest float; narrow it")
        if nominal is None:
            self._nominal = 0.5 * self.lo + 0.5 * self.hi
        else:
            self._nominal = _finite_number(nominal, "Uniform nominal")
            if not self.lo <= self._nominal <= self.hi:
                raise SpaceError(
                    f"Uniform nominal={_show(nominal)} lies outside [lo, hi] = [{_show(lo)}, {_show(hi)}]"
                )

    @property
    def nominal(self) -> float:
        return self._nominal

    def from_unit(self, u: float) -> float:
        # lo + 1.0 * (hi - lo) can round past hi (e.g. lo = -713.05, hi = -4e-121 gives 0.0)
        return float(min(self.lo + float(u) * (self.hi - self.lo), self.hi))

    def to_unit(self, value: Any) -> float:
        return float((float(value) - self.lo) / (self.hi - self.lo))

    def contains(self, value: Any) -> bool:
        return _within(value, self.lo, self.hi)

    def describe(self) -> dict[str, Any]:
        return self._with_unit({"type": "Uniform", "lo": self.lo, "hi": self.hi, "nominal": self._nominal})


class Normal(Distribution):
    """Normal(mean, sd) truncated to ``[lo, hi]``; the nominal value is the mean."""

    kind = "continuous"

    def _setup(self, mean: float, sd: float, lo: float, hi: float) -> None:
        self.mean = _finite_number(mean, "Normal mean")
        self.sd = _finite_number(sd, "Normal sd")
        self.lo = _finite_number(lo, "Normal lo")
        self.hi = _finite_number(hi, "Normal hi")
        if self.sd <= 0:
            raise SpaceError(f"Normal needs sd > 0, got sd={_show(sd)}")
        if not self.lo < self.hi:
            raise SpaceError(f"Normal needs lo < hi, got lo={_show(lo)}, hi={_show(hi)}")
        if not self.lo <= self.mean <= self.hi:
            raise SpaceError(f"Normal mean={_show(mean)} lies outside [lo, hi] = [{_show(lo)}, {_show(hi)}]")
        self._dist = NormalDist(self.mean, self.sd)
        self._clo = self._dist.cdf(self.lo)
        self._chi = self._dist.cdf(self.hi)
        if not self._chi - self._clo > 1e-12:
            raise SpaceError(f"Normal({self.mean!r}, {self.sd!r}) has no mass on [{self.lo!r}, {self.hi!r}]")

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
        return self._with_unit({"type": "Normal", "mean": self.mean, "sd": self.sd, "lo": self.lo, "hi": self.hi})


def _bounded_int(value: Any, what: str) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise SpaceError(f"{what} must be an int, got {_show(value)}")
    value = int(value)
    if abs(value) > _INT_LIMIT:
        raise SpaceError(
            f"{what} must lie within ±2**53 = ±{_INT_LIMIT} (a sampler's coordinate could not "
            f"pick every integer beyond it), got {_show(value)}; use Uniform for such a range")
    return value


class IntRange(Distribution):
    """Integers ``lo..hi`` inclusive, equally likely; nominal defaults to the middle value."""

    kind = "integer"

    def _setup(self, lo: int, hi: int, nominal: int | None = None) -> None:
        self.lo, self.hi = _bounded_int(lo, "IntRange lo"), _bounded_int(hi, "IntRange hi")
        if not self.lo < self.hi:
            raise SpaceError(f"IntRange needs lo < hi, got lo={_show(lo)}, hi={_show(hi)}")
        if nominal is None:
            self._nominal = (self.lo + self.hi) // 2
        else:
            nominal = _bounded_int(nominal, "IntRange nominal")
            if not self.lo <= nominal <= self.hi:
                raise SpaceError(f"IntRange nominal={nominal!r} lies outside [{self.lo}, {self.hi}]")
            self._nominal = nominal

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
        return self._with_unit({"type": "IntRange", "lo": self.lo, "hi": self.hi, "nominal": self._nominal})


class Choice(Distribution):
    """One of ``options``; the first option is the nominal one. ``weights`` default to equal."""

    kind = "categorical"

    def _setup(self, options: Sequence[Any], weights: Sequence[float] | None = None) -> None:
        if isinstance(options, (str, bytes, Mapping)) or not isinstance(options, Iterable):
            raise SpaceError(f"Choice options must be a list of values, got {_show(options)}")
        if isinstance(options, (set, frozenset)):
            raise SpaceError(
                f"Choice options must be a list, not a set: a set's order changes from run to "
                f"run, and so would the cases; got {_show(options)}")
        # stored as the JSON data a stored case replays as: numpy scalars unwrapped, tuples as lists
        self.options = tuple(_plain(o, "Choice option") for o in options)
        if not self.options:
            raise SpaceError("Choice needs at least one option, got an empty list")
        self._keys = {}
        for i, o in enumerate(self.options):
            if self._keys.setdefault(_key(o), i) != i:
                raise SpaceError(
                    f"Choice options must be distinct, got {_show(o)} twice in {_show(list(self.options))}")
        if weights is None:
            w = _normalised([1.0] * len(self.options))
        else:
            if isinstance(weights, (str, bytes, set, frozenset, Mapping)) or not hasattr(weights, "__len__") \
                    or not isinstance(weights, Iterable):
                raise SpaceError(f"Choice weights must be a list of numbers, one per option, got {_show(weights)}")
            if len(weights) != len(self.options):
                raise SpaceError(
                    f"Choice has {len(self.options)} options but {len(weights)} weights"
                )
            raw = [_finite_number(x, "Choice weight") for x in weights]
            if any(x < 0 for x in raw) or not any(x > 0 for x in raw):
                raise SpaceError(f"Choice weights must be >= 0 with a positive sum, got {_show(list(weights))}")
            w = _normalised(raw)
        self.weights = tuple(float(x) for x in w)
        self._edges = np.concatenate([[0.0], np.cumsum(w)])
        self._edges[-1] = 1.0

    @property
    def n_values(self) -> int:
        return len(self.options)

    @property
    def nominal(self) -> Any:
        return copy.deepcopy(self.options[0])

    def index(self, value: Any) -> int:
        k = self._keys.get(_key(value))
        if k is not None:
            return k
        for i, o in enumerate(self.options):
            if o == value and type(o) is type(value):
                return i
        for i, o in enumerate(self.options):
            if o == value:
                return i
        raise SpaceError(f"{_show(value)} is not one of the options {_show(list(self.options))}")

    def from_unit(self, u: float) -> Any:
        k = int(np.searchsorted(self._edges, float(u), side="right")) - 1
        k = min(max(k, 0), len(self.options) - 1)
        # skip zero-weight strata at the boundary
        while self.weights[k] == 0.0 and k + 1 < len(self.options):
            k += 1
        # a copy: a test that appends to a list option must not change the next case's
        return copy.deepcopy(self.options[k])

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
        return self._with_unit({"type": "Choice", "options": copy.deepcopy(list(self.options)), "weights": list(self.weights)})


class Constant(Distribution):
    """A fixed value; it takes no sampler coordinate. Write a constant whose name is close to a
    setting's (``sample``, ``seeds``) as ``Constant(...)``: a plain value there is refused as a
    likely misspelt setting."""

    kind = "constant"

    def _setup(self, value: Any) -> None:
        self.value = _plain(value, "Constant value")

    @property
    def nominal(self) -> Any:
        return copy.deepcopy(self.value)

    def from_unit(self, u: float) -> Any:
        return copy.deepcopy(self.value)

    def to_unit(self, value: Any) -> float:
        return 0.5

    def contains(self, value: Any) -> bool:
        key = _key(value)
        return (key is not None and key == _key(self.value)) or value == self.value

    def describe(self) -> dict[str, Any]:
        return self._with_unit({"type": "Constant", "value": copy.deepcopy(self.value)})


def as_distribution(name: str, value: Any) -> Distribution:
    """A declared parameter as a distribution: plain values become :class:`Constant`."""
    if isinstance(value, Distribution):
        return value
    if isinstance(value, type) and issubclass(value, Distribution):
        raise SpaceError(f"parameter {name!r}: {value.__name__} must be called with its arguments")
    const = Constant(value)
    if const.error is not None:
        raise SpaceError(
            f"parameter {name!r}: {_show(value)} is neither a distribution "
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

    def check_description(self) -> None:
        """Raise SpaceError naming the first parameter that its stored description (JSON, as
        the report and the replay database keep it) does not rebuild exactly."""
        for name, dist in self.parameters.items():
            try:
                desc = json.loads(json.dumps(dist.describe(), allow_nan=False))
                again = FeatureSpace.from_description({name: desc}).parameters[name].describe()
                same = _key(again) == _key(desc) and _key(desc) is not None
                why = "it comes back as a different distribution"
            except Exception as exc:  # noqa: BLE001 - any failure means: not storable
                same, why = False, f"{type(exc).__name__}: {exc}"
            if not same:
                raise SpaceError(
                    f"parameter {name!r}: a {type(dist).__name__} cannot be rebuilt from its "
                    f"description ({why}); the report and the replay database need that — use "
                    "Uniform, Normal, IntRange, Choice or Constant")

    def fingerprint(self) -> str:
        """Identifies the distributions (units left aside: they change no case)."""
        plain = {n: {k: v for k, v in d.items() if k != "unit"} for n, d in self.describe().items()}
        blob = json.dumps(plain, sort_keys=True, default=repr).encode()
        return hashlib.sha256(blob).hexdigest()[:16]

    def __repr__(self) -> str:
        return f"FeatureSpace({', '.join(f'{n}={d!r}' for n, d in self.parameters.items())})"

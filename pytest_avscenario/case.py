"""The concrete case a scenario test receives through the ``case`` fixture."""

from __future__ import annotations

import hashlib
from typing import Any, Iterator, Mapping

import numpy as np

#: attribute names of Case that a scenario parameter may not shadow
RESERVED = frozenset(
    {"params", "index", "seed", "rng", "sampler", "origin", "test", "get", "keys", "items", "values"}
)


class Case(Mapping[str, Any]):
    """One concrete point of a scenario's feature space, with its seed.

    Parameter values are readable as attributes (``case.gap``) and by key (``case["gap"]``).
    ``rng`` is a numpy Generator seeded from ``seed`` for randomness drawn during the run (it
    draws exactly what ``np.random.default_rng(seed)`` draws, and keeps a log of the draws for
    the report: :class:`RecordingGenerator`);
    ``origin`` says where the case came from: ``sampled``, ``example``, ``replay``, ``shrink``
    or ``pinned`` (``--avs-params``).
    """

    __slots__ = ("params", "index", "seed", "rng", "sampler", "origin", "test")

    def __init__(self, params: Mapping[str, Any], index: int, seed: int, sampler: str,
                 origin: str = "sampled", test: str = ""):
        self.params = dict(params)
        self.index = index
        self.seed = int(seed)
        self.rng = RecordingGenerator(self.seed)
        self.sampler = sampler
        self.origin = origin
        self.test = test

    def __getattr__(self, name: str) -> Any:
        try:
            return self.params[name]
        except KeyError:
            raise AttributeError(
                f"case has no parameter {name!r}; parameters: {list(self.params)}"
            ) from None

    def __getitem__(self, key: str) -> Any:
        return self.params[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self.params)

    def __len__(self) -> int:
        return len(self.params)

    def __repr__(self) -> str:
        vals = ", ".join(f"{k}={v!r}" for k, v in self.params.items())
        return f"Case({self.sampler}-{self.index}, seed={self.seed}: {vals})"


def stable_seed(*parts: Any) -> int:
    """A 63-bit seed from any printable parts, the same in every process (not ``hash()``)."""
    h = hashlib.sha256("\x1f".join(map(str, parts)).encode()).digest()
    return int.from_bytes(h[:8], "big") >> 1


#: draws kept in full per case; later ones are counted only
MAX_LOGGED_DRAWS = 100
#: values of one draw kept in full (a bigger array is logged by its shape and range)
MAX_LOGGED_VALUES = 6

# every public method of numpy's Generator that returns random values
_DRAWING = (
    "integers", "random", "choice", "bytes", "shuffle", "permutation", "permuted", "beta",
    "binomial", "chisquare", "dirichlet", "exponential", "f", "gamma", "geometric", "gumbel",
    "hypergeometric", "laplace", "logistic", "lognormal", "logseries", "multinomial",
    "multivariate_hypergeometric", "multivariate_normal", "negative_binomial",
    "noncentral_chisquare", "noncentral_f", "normal", "pareto", "poisson", "power",
    "rayleigh", "standard_cauchy", "standard_exponential", "standard_gamma", "standard_normal",
    "standard_t", "triangular", "uniform", "vonmises", "wald", "weibull", "zipf",
)


class RecordingGenerator(np.random.Generator):
    """``np.random.default_rng(seed)`` that logs what it is asked for, for the report.

    Same bit generator (PCG64) and same methods, so it draws bit-identical values; each call
    of a drawing method appends ``{"n", "call", "value", "t"}`` to :attr:`draws` (the first
    :data:`MAX_LOGGED_DRAWS` calls; :attr:`count` counts them all). ``call`` is the method
    with its arguments (``normal(0.0, 0.3)``), ``value`` the result (a number, a short list,
    or ``"array(shape) in [lo, hi]"``), ``t`` the simulation time when a world set
    :attr:`clock` (the world that uses the case's rng does). ``bit_generator`` draws made
    directly are not seen.
    """

    def __init__(self, seed: int):
        super().__init__(np.random.PCG64(seed))
        self.seed = seed
        self.draws: list[dict[str, Any]] = []
        self.count = 0
        self.clock: Any = None  # () -> seconds, set by the world running the case

    def __reduce__(self) -> Any:  # pickled (to a Dask worker) as what it is: a fresh log
        return (_revive_generator, (self.seed, self.bit_generator.state, self.count, self.draws))

    def log(self) -> dict[str, Any] | None:
        """The draws as JSON data ``{"count": N, "draws": [...]}``, or None when none."""
        if not self.count:
            return None
        return {"count": self.count, "draws": [dict(d) for d in self.draws]}


def _revive_generator(seed: int, state: dict[str, Any], count: int,
                      draws: list[dict[str, Any]]) -> RecordingGenerator:
    rng = RecordingGenerator(seed)
    rng.bit_generator.state = state
    rng.count, rng.draws = count, list(draws)
    return rng


def _short(value: Any) -> Any:
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value)
    if isinstance(value, bytes):
        return value.hex()
    arr = np.asarray(value) if value is not None else None
    if arr is None:
        return None
    if arr.size <= MAX_LOGGED_VALUES and arr.dtype.kind in "biuf":
        return arr.tolist()
    if arr.dtype.kind in "biuf" and arr.size:
        return f"array{tuple(arr.shape)} in [{arr.min():.6g}, {arr.max():.6g}]"
    return f"array{tuple(arr.shape)}"


def _argtext(value: Any) -> str:
    if isinstance(value, np.ndarray):
        return f"array{tuple(value.shape)}" if value.size > MAX_LOGGED_VALUES else repr(value.tolist())
    if isinstance(value, (list, tuple)) and len(value) > MAX_LOGGED_VALUES:
        return f"{type(value).__name__}[{len(value)}]"
    return repr(value)


def _recording(name: str) -> Any:
    method = getattr(np.random.Generator, name)

    def draw(self: RecordingGenerator, *args: Any, **kwargs: Any) -> Any:
        result = method(self, *args, **kwargs)
        self.count += 1
        if len(self.draws) < MAX_LOGGED_DRAWS:
            call = ", ".join([*map(_argtext, args), *(f"{k}={_argtext(v)}" for k, v in kwargs.items())])
            shown = args[0] if name in ("shuffle", "permuted") and args else result
            t = None
            if self.clock is not None:
                try:
                    t = round(float(self.clock()), 6)
                except Exception:
                    t = None
            self.draws.append({"n": self.count, "call": f"{name}({call})", "value": _short(shown), "t": t})
        return result

    draw.__name__ = draw.__qualname__ = name
    draw.__doc__ = method.__doc__
    return draw


for _name in _DRAWING:
    if hasattr(np.random.Generator, _name):
        setattr(RecordingGenerator, _name, _recording(_name))

"""Shrink a failing scenario toward the nominal one, under a hard simulation budget.

When a sampled case violates a monitor, the engineer wants the *least unusual* scenario
that still fails: every parameter as close to its nominal value as the failure allows, so
the report shows "fails once the gap drops below 17.3 m" rather than a random point deep
in the failing region. :func:`minimize` hands that search to Hypothesis's shrinker, with
two changes that make it fit simulations:

* **Encoding.** Hypothesis shrinks choices toward zero, so each parameter is re-expressed
  as a position k ∈ [0, K] on the straight path from its nominal value (k = 0) to the
  failing value (k = K). Shrinking k moves the scenario toward the nominal one and stops
  at the failure boundary. k is drawn as its binary digits, and a per-parameter "departs
  from nominal" flag is drawn last; Hypothesis's trivial-span pass walks the choices from
  the last to the first, so it first asks "does the failure survive with this parameter
  back at nominal?" (one simulation per parameter), then clears the most significant
  digit of every parameter, then the next — a breadth-first bisection that spends one
  simulation per digit and parameter. Drawing k as one integer instead lets Hypothesis's
  integer shrinker spend ~60 simulations on two parameters (linear probes, then
  galloping); the digit encoding gets both within 0.2 % of their boundaries in 20.
* **Budget.** Every simulation goes through a memo (the same candidate never costs twice)
  and a counter. The memo also keeps the best failing case (closest to nominal), so the
  result never depends on Hypothesis finishing: once a new candidate would need a
  simulation beyond the budget, Hypothesis is stopped and that best case returned.
  Candidates no closer to nominal than the best case, and candidates outside the space,
  are answered "passes" without a simulation.

Hypothesis is seeded with the failing case through an in-memory example database, as the
failing choice sequence under ``<key>.secondary`` (the corpus Hypothesis replays and then
shrinks); the explicit-example and primary-key routes are replayed but never shrunk. The
private Hypothesis details this needs (the byte format of a stored choice sequence, the
database-key attribute ``hypothesis.find`` sets too, and the order of the trivial-span
pass) live in :func:`_choices_bytes` and :func:`_run_hypothesis`; ``tests/test_shrink.py``
fails loudly when a new Hypothesis stops shrinking a seeded case or loses the bisection.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any, Callable, Mapping

from .space import FeatureSpace, SpaceError

__all__ = ["ShrinkResult", "ShrinkSeedingWarning", "minimize", "TESTED_HYPOTHESIS"]

#: Hypothesis versions tests/test_shrink.py passes with (6.130.0, 6.140.0, 6.150.0, 6.155.2;
#: 6.122 lacks choices_from_bytes and shrinks less efficiently, 6.100 lacks choices_to_bytes).
TESTED_HYPOTHESIS = ">=6.130,<7"


class ShrinkSeedingWarning(UserWarning):
    """Hypothesis did not replay the seeded failing case: the installed version stores or
    reuses examples differently, so no shrinking happened (the original case is kept)."""


@dataclass(frozen=True)
class ShrinkResult:
    """What one :func:`minimize` call did.

    ``candidates`` lists every *simulated* candidate in order with whether it still
    failed; memo hits, candidates outside the space and candidates refused after the
    budget ran out are not simulated and not listed. ``len(candidates) == sims``.
    """

    original: dict[str, Any]
    minimized: dict[str, Any]
    sims: int
    budget: int
    improved: bool
    exhausted: bool
    candidates: tuple[tuple[dict[str, Any], bool], ...]


class _Failing(Exception):
    """Raised inside the Hypothesis probe when a candidate still fails (Hypothesis's
    notion of an interesting example); never escapes :func:`minimize`."""


class _Stop(BaseException):
    """Ends the Hypothesis run early once nothing can change the result any more (budget
    spent, or ``still_fails`` raised). A BaseException, like KeyboardInterrupt, so
    Hypothesis lets it through instead of shrinking it as a new failure; the result is the
    oracle's best case, which Hypothesis's own progress is not needed for."""


# --------------------------------------------------------------------------- encoding


@dataclass(frozen=True)
class _Axis:
    """One encoded parameter: a straight path nominal → failing, addressed by k ∈ [0, K]."""

    name: str
    kind: str  # "continuous", "integer" or "categorical"
    nominal: Any
    failing: Any  # as a number of the axis's kind, for the path arithmetic
    bits: int  # binary digits of k; 0 for categorical (the flag alone encodes it)
    exact: Any = None  # the failing value exactly as given (k = K reproduces the original)

    @property
    def top(self) -> int:
        """K: the k of the failing value."""
        return (1 << self.bits) - 1

    def value(self, departs: bool, k: int) -> Any:
        if not departs or (self.kind != "categorical" and k == 0):
            return self.nominal
        if self.kind == "categorical" or k == self.top:
            # the failing value as given: no float round-off at the end of the path, and
            # the memo recognises the original case
            return self.exact
        if self.kind == "integer":
            span = self.failing - self.nominal
            if abs(span) <= self.top:
                # fewer distinct integers than steps: one step per integer, the rest of
                # the path sits on the failing value (memo hits, no simulations)
                if k >= abs(span):
                    return self.exact
                return self.nominal + int(math.copysign(k, span))
            return self.nominal + int(round(span * k / self.top))
        lo, hi = sorted((self.nominal, self.failing))
        x = self.nominal + (self.failing - self.nominal) * (k / self.top)
        return float(min(max(x, lo), hi))


def _axes(space: FeatureSpace, failing: Mapping[str, Any], resolution: int) -> list[_Axis]:
    """The parameters that depart from nominal in ``failing``, each as an :class:`_Axis`.

    Constants and parameters already at their nominal value are left out: there is
    nothing to shrink, and an unused choice would only cost the shrinker calls.
    """
    steps_bits = max(1, int(resolution).bit_length())  # 2**bits - 1 >= resolution
    axes = []
    for name, dist in space.parameters.items():
        if dist.kind == "constant":
            continue
        nominal, value = dist.nominal, failing[name]
        if dist.kind == "categorical":
            if dist.index(value) == dist.index(nominal):
                continue
            # Index 0 is the nominal option, 1 the failing one; the other options would
            # come after, but shrinking never raises a choice, so only the flag is drawn.
            axes.append(_Axis(name, "categorical", nominal, value, 0, value))
        elif dist.kind == "integer":
            if int(value) == nominal:
                continue
            bits = min(steps_bits, max(1, abs(int(value) - nominal).bit_length()))
            axes.append(_Axis(name, "integer", int(nominal), int(value), bits, value))
        else:
            if float(value) == float(nominal):
                continue
            axes.append(_Axis(name, "continuous", float(nominal), float(value), steps_bits, value))
    return axes


def _slots(axes: list[_Axis]) -> list[tuple[int, int]]:
    """Which (axis, digit) each boolean choice is, in the order the shrinker should *try*
    them: every axis's departure flag (digit -1), then the most significant digit of every
    axis, then the next, ... Axes with fewer digits join at their own most significant one.
    """
    order = [(i, -1) for i in range(len(axes))]
    depth = max((a.bits for a in axes), default=0)
    for level in range(depth):
        for i, a in enumerate(axes):
            if level < a.bits:
                order.append((i, a.bits - 1 - level))
    return order


def _decode(axes: list[_Axis], slots: list[tuple[int, int]], drawn: tuple[bool, ...],
            template: Mapping[str, Any]) -> dict[str, Any]:
    """Parameters for one drawn choice tuple (drawn in reverse slot order, see minimize)."""
    departs = [False] * len(axes)
    ks = [0] * len(axes)
    for (i, digit), bit in zip(reversed(slots), drawn):
        if bit:
            if digit < 0:
                departs[i] = True
            else:
                ks[i] |= 1 << digit
    params = dict(template)
    for i, a in enumerate(axes):
        params[a.name] = a.value(departs[i], ks[i])
    return params


def _choices_bytes(choices: list[bool]) -> bytes:
    """The bytes Hypothesis stores in its example database for a choice sequence.

    Private to Hypothesis (``hypothesis.database.choices_to_bytes`` in 6.1xx, called
    ``ir_to_bytes`` before); kept here alone so a format change breaks one function, and
    ``tests/test_shrink.py`` checks a seeded case still shrinks.
    """
    from hypothesis import database as hdb

    encode = getattr(hdb, "choices_to_bytes", None) or getattr(hdb, "ir_to_bytes", None)
    if encode is None:  # pragma: no cover - only on an untested Hypothesis
        raise ImportError(
            f"hypothesis {_hypothesis_version()} has no choices_to_bytes; pytest-avscenario's "
            f"shrinking is tested with hypothesis{TESTED_HYPOTHESIS}"
        )
    return encode(list(choices))


def _hypothesis_version() -> str:
    import hypothesis

    return hypothesis.__version__


# --------------------------------------------------------------------------- minimize


class _Budget:
    """The memoized, counted simulation oracle the Hypothesis probe consults.

    It also keeps the best failing case: the one closest to nominal, measured as the sum
    over parameters of the fraction of the nominal → failing path still travelled (a
    categorical parameter counts 1 while it departs). A candidate no closer than that
    cannot improve the result, so it is answered "passes" without a simulation: this is
    what keeps Hypothesis from spending budget on choice sequences that are smaller in its
    own (shortlex) order but further from nominal.
    """

    def __init__(self, space: FeatureSpace, still_fails: Callable[[dict[str, Any]], bool],
                 budget: int, original: dict[str, Any], axes: list[_Axis]):
        self.space = space
        self.still_fails = still_fails
        self.budget = budget
        self.axes = axes
        self.sims = 0
        self.exhausted = False
        self.error: Exception | None = None
        self.candidates: list[tuple[dict[str, Any], bool]] = []
        # the plugin replays the original once before shrinking; it is known to fail
        self.memo: dict[str, bool] = {_key(original): True}
        self.best = dict(original)
        self.best_departure = self.departure(original)

    def departure(self, params: Mapping[str, Any]) -> float:
        total = 0.0
        for a in self.axes:
            v = params[a.name]
            if a.kind == "categorical":
                total += 0.0 if v == a.nominal and type(v) is type(a.nominal) else 1.0
            else:
                total += abs(v - a.nominal) / abs(a.failing - a.nominal)
        return total

    def fails(self, params: dict[str, Any]) -> bool:
        key = _key(params)
        verdict = self.memo.get(key)
        if verdict is None:
            verdict = self._simulate(key, params)
        if verdict:
            d = self.departure(params)
            if d < self.best_departure:
                self.best, self.best_departure = dict(params), d
        return verdict

    def _simulate(self, key: str, params: dict[str, Any]) -> bool:
        try:
            self.space.validate(params)
        except SpaceError:
            self.memo[key] = False  # outside the space: not a failure, never simulated
            return False
        if self.departure(params) >= self.best_departure:
            return False  # cannot improve the result: not worth a simulation
        if self.sims >= self.budget:
            # The best case can no longer change: memo hits were judged when simulated.
            # Stopping Hypothesis here saves its remaining passes (~0.5 s of bookkeeping).
            self.exhausted = True
            raise _Stop
        self.sims += 1
        try:
            verdict = bool(self.still_fails(dict(params)))
        except Exception as exc:  # re-raised by minimize once Hypothesis has returned
            self.error = exc
            self.candidates.append((dict(params), False))
            raise _Stop from None
        self.memo[key] = verdict
        self.candidates.append((dict(params), verdict))
        return verdict


def _key(params: Mapping[str, Any]) -> str:
    # repr keeps 1 and 1.0 and True apart (a Choice may hold any of them); numpy scalars
    # count as the Python number they hold, so the original case is recognised
    def plain(v: Any) -> Any:
        return v.item() if hasattr(v, "item") and hasattr(v, "dtype") else v

    return repr(sorted((k, type(plain(v)).__name__, repr(plain(v))) for k, v in params.items()))


def minimize(
    space: FeatureSpace,
    failing: Mapping[str, Any],
    still_fails: Callable[[dict[str, Any]], bool],
    budget: int = 20,
    resolution: int = 1000,
    seed: int = 0,
) -> ShrinkResult:
    """Shrink ``failing`` toward ``space.nominal()`` while ``still_fails`` holds.

    ``still_fails(params)`` runs one simulation and returns True iff the candidate still
    fails the same way. It is called at most ``budget`` times, never with the original
    case (the caller has replayed it) nor with a candidate outside the space, and never
    twice with the same candidate. ``resolution`` is the number of steps along each
    parameter's nominal → failing path (rounded up to ``2**b - 1``; integer parameters
    use at most one step per integer). ``seed`` fixes Hypothesis's random choices, so the
    same inputs give the same shrink in every process.

    Raises :class:`~pytest_avscenario.space.SpaceError` if ``failing`` is not a case of
    ``space``; an exception raised by ``still_fails`` stops shrinking and is re-raised.
    """
    space = FeatureSpace.coerce(space)
    space.validate(failing)
    if int(budget) < 0:
        raise ValueError(f"shrink budget must be >= 0, got {budget!r}")
    if int(resolution) < 1:
        raise ValueError(f"shrink resolution must be >= 1, got {resolution!r}")
    budget = int(budget)
    original = space.complete(failing)
    axes = _axes(space, original, int(resolution))
    oracle = _Budget(space, still_fails, budget, original, axes)
    if budget == 0 or not axes:
        return _result(original, original, oracle)

    slots = _slots(axes)

    def probe(drawn: tuple[bool, ...]) -> None:
        if oracle.fails(_decode(axes, slots, drawn, original)):
            raise _Failing

    seen_seed = _run_hypothesis(probe, n_choices=len(slots), seed=seed)
    if oracle.error is not None:
        raise oracle.error
    if not seen_seed:
        warnings.warn(
            ShrinkSeedingWarning(
                f"hypothesis {_hypothesis_version()} did not replay the seeded failing case, "
                f"so it was not shrunk; shrinking is tested with hypothesis{TESTED_HYPOTHESIS}"
            ),
            stacklevel=2,
        )
        return _result(original, original, oracle)
    return _result(original, oracle.best, oracle)


def _run_hypothesis(probe: Callable[[tuple[bool, ...]], None], n_choices: int, seed: int) -> bool:
    """Let Hypothesis shrink the all-True choice tuple (= the failing case) under ``probe``.

    Returns whether Hypothesis replayed the seeded case at all (False means the seeding
    route no longer works on this Hypothesis version).
    """
    from hypothesis import HealthCheck, Phase, Verbosity, given
    from hypothesis import seed as hseed
    from hypothesis import settings
    from hypothesis import strategies as st
    from hypothesis.database import InMemoryExampleDatabase

    key = b"pytest-avscenario.shrink"
    seeded = [True] * n_choices
    db = InMemoryExampleDatabase()
    # The secondary corpus is what Hypothesis replays *and shrinks*; the primary key holds
    # already-minimal failures, which it replays without shrinking.
    db.save(key + b".secondary", _choices_bytes(seeded))
    replayed = [False]

    def test(drawn: tuple[bool, ...]) -> None:
        if all(drawn):
            replayed[0] = True
        probe(drawn)

    strategy = st.tuples(*[st.booleans()] * n_choices)
    wrapped = given(strategy)(test)
    # @seed fixes the shrinker's random choices (used once it stalls) but also switches the
    # database off; the @settings applied after it switches our in-memory one back on.
    wrapped = hseed(int(seed))(wrapped)
    wrapped = settings(
        database=db,
        phases=[Phase.reuse, Phase.shrink],
        max_examples=1,
        deadline=None,
        derandomize=False,  # derandomize=True forbids a database
        verbosity=Verbosity.quiet,
        suppress_health_check=list(HealthCheck),
        report_multiple_bugs=False,
        print_blob=False,
        backend="hypothesis",
    )(wrapped)
    # What hypothesis.find does too: a fixed key, honoured even under --hypothesis-seed
    # (which otherwise disables the database for tests without one).
    wrapped._hypothesis_internal_database_key = key  # type: ignore[attr-defined]
    try:
        wrapped()
    except (_Failing, _Stop):
        pass
    except BaseException as exc:
        # Hypothesis skips a test that ran no example (unittest.SkipTest, or pytest's skip
        # under its pytest plugin): the seed was not replayed; the caller warns.
        if replayed[0] or "skip" not in type(exc).__name__.lower():
            raise
    return replayed[0]


def _result(original: dict[str, Any], minimized: dict[str, Any], oracle: _Budget) -> ShrinkResult:
    return ShrinkResult(
        original=dict(original),
        minimized=dict(minimized),
        sims=oracle.sims,
        budget=oracle.budget,
        improved=_key(minimized) != _key(original),
        exhausted=oracle.exhausted,
        candidates=tuple((dict(p), v) for p, v in oracle.candidates),
    )

"""What ``@scenario`` and ``@example`` record on a test function (plain data only).

pytest is imported when ``scenario(...)`` is called, not when this module is.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, Mapping, Sequence

if TYPE_CHECKING:  # pragma: no cover
    import pytest

#: spec keywords of @scenario; every other keyword is a scenario parameter
SPEC_KEYWORDS = (
    "samples",
    "sampler",
    "seed",
    "monitors",
    "priority",
    "sampler_options",
    "shrink_budget",
    "shrink_max",
    "time_budget",
    "case_timeout",
    "accept",
    "reference_driver",
    "reference_max",
    "reference_margin",
    "unavoidable",
    "dt",
)

_UNSET: Any = object()


@dataclass(frozen=True)
class ScenarioSpec:
    """The raw declaration of one scenario test, exactly as written (validated at collection)."""

    parameters: Mapping[str, Any]
    samples: Any = None
    sampler: Any = None
    seed: Any = None
    monitors: Any = None
    priority: Any = None
    sampler_options: Any = None
    shrink_budget: Any = None
    shrink_max: Any = None
    time_budget: Any = None
    case_timeout: Any = None
    accept: Any = None
    reference_driver: Any = None
    reference_max: Any = None
    reference_margin: Any = None
    unavoidable: Any = None
    dt: Any = None
    #: keyword arguments given to @scenario explicitly (so "not given" differs from None)
    given: frozenset[str] = field(default_factory=frozenset)
    #: what was wrong with the call itself (positional arguments, a bare ``@scenario``), told
    #: at collection where the test can be named; None when the call was fine
    problem: str | None = None


def scenario(
    *args: Any,
    samples: int = _UNSET,
    sampler: str | Sequence[str] = _UNSET,
    seed: int | None = _UNSET,
    monitors: Sequence[Any] | None = _UNSET,
    priority: Sequence[Any] | None = _UNSET,
    sampler_options: Mapping[str, Any] | None = _UNSET,
    shrink_budget: int | None = _UNSET,
    shrink_max: int | None = _UNSET,
    time_budget: str | float | None = _UNSET,
    case_timeout: float | None = _UNSET,
    accept: Any = _UNSET,
    reference_driver: str | None = _UNSET,
    reference_max: int | None = _UNSET,
    reference_margin: Mapping[str, float] | None = _UNSET,
    unavoidable: str = _UNSET,
    dt: float | str = _UNSET,
    **parameters: Any,
) -> pytest.MarkDecorator:
    """Declare an abstract scenario on a test; returns a ``pytest.mark.scenario`` mark.

    Every keyword that is not one of the settings below is a scenario parameter: a
    distribution (``Uniform``, ``Normal``, ``IntRange``, ``Choice``, ``Constant``) or a plain
    constant. The test requests the ``case`` fixture to read the concrete values. A plain
    value under a name close to a setting's (``sample=100``, ``samplers=...``,
    ``case_time_out=...``; see :func:`~pytest_avscenario.pytest_plugin.collect.likely_setting`)
    is refused at collection as a likely misspelling: write ``Constant(...)`` for a constant
    parameter that really has such a name. Parameter names must be Python identifiers that are
    not keywords, ``__dunder__`` names or attributes of the case.

    :param samples: how many concrete cases to run (default 20; ``--avs-samples`` overrides).
    :param sampler: ``"halton"`` (default), ``"random"``, an active sampler (``"mab"``, ...), or
        a list of names to run the scenario once per sampler (``--avs-sampler`` overrides).
    :param seed: fixes this test's seed regardless of ``--avs-seed``.
    :param monitors: monitors judged on the recorded trajectory after the test body.
    :param priority: priority order between the monitors (names, highest first, or
        ``(higher, lower)`` edges), used by multi-objective samplers.
    :param sampler_options: keyword options for the sampler.
    :param shrink_budget: simulations allowed to minimize each failure (0 disables).
    :param shrink_max: minimize (and store) only the first N failures per sampler; the rest
        are reported as found (default: every failure).
    :param time_budget: wall-time cap for this test's campaign (``"30m"``, ``"90s"``, seconds).
    :param case_timeout: seconds one case may run before it is ended as an error.
    :param accept: when the campaign may ship (see :mod:`pytest_avscenario.acceptance`):
        ``"any"`` counterexample rejects it (default), metric names (only their violations
        reject it), ``"regressions"`` (only stored or pinned cases failing again), or
        ``rate(metric, at_most=..., confidence=...)`` bounds; a list combines them;
        ``"avoidable"`` counts only counterexamples the reference driver avoids.
    :param reference_driver: the driver each counterexample is simulated again with, to judge
        whether its violations were avoidable (default ``"careful"``, UN R157's careful and
        competent driver; ``"none"`` turns the check off).
    :param reference_max: judge only the first N counterexamples per sampler (default: all).
    :param reference_margin: ``{metric: margin}`` in each metric's unit: the band within which
        the reference's value toward the same agent decides nothing (avoidability unknown);
        default 0.2 m for a collision, 0 otherwise.
    :param unavoidable: ``"keep"`` (default) or ``"discard"``: an active sampler is told
        nothing of a case that starts RSS-unsafe or of a counterexample the reference driver
        cannot avoid either (it is still run and reported), so it does not converge on them.
    :param dt: the step [s] of ``world.run()`` calls that give no ``dt=``, or ``"auto"``
        (default): the step the ego's driver declares (a highway-env agent: its environment's
        ``1 / simulation_frequency``), else 0.1 s. Beats ``--avs-dt``; ``world.run(dt=...)``
        beats it.
    """
    given = {
        k
        for k, v in dict(
            samples=samples, sampler=sampler, seed=seed, monitors=monitors, priority=priority,
            sampler_options=sampler_options, shrink_budget=shrink_budget, shrink_max=shrink_max,
            time_budget=time_budget, case_timeout=case_timeout, accept=accept,
            reference_driver=reference_driver, reference_max=reference_max,
            reference_margin=reference_margin, unavoidable=unavoidable, dt=dt,
        ).items()
        if v is not _UNSET
    }
    values = {
        k: (None if v is _UNSET else v)
        for k, v in dict(
            samples=samples, sampler=sampler, seed=seed, monitors=monitors, priority=priority,
            sampler_options=sampler_options, shrink_budget=shrink_budget, shrink_max=shrink_max,
            time_budget=time_budget, case_timeout=case_timeout, accept=accept,
            reference_driver=reference_driver, reference_max=reference_max,
            reference_margin=reference_margin, unavoidable=unavoidable, dt=dt,
        ).items()
    }
    problem = None
    bare = len(args) == 1 and callable(args[0]) and not given and not parameters
    if bare:
        problem = ("@scenario is written without parentheses and declares nothing; write "
                   "@scenario(...) with the parameters, e.g. @scenario(gap=Uniform(10, 40))")
    elif args:
        problem = (f"@scenario takes keyword arguments only (parameter=distribution or "
                   f"setting=value), got {len(args)} positional argument(s); e.g. "
                   "@scenario(gap=Uniform(10, 40), samples=20)")
    spec = ScenarioSpec(parameters=dict(parameters), given=frozenset(given), problem=problem, **values)
    import pytest  # here, not at module level: importing the library loads no pytest

    mark = pytest.mark.scenario.with_args(spec)
    # bare @scenario: mark the function itself so that collection can name it (returning the
    # mark would replace the test by a MarkDecorator that pytest silently does not collect)
    return mark(args[0]) if bare else mark


def example(*args: Any, **params: Any) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Pin a concrete case of a scenario test; pinned examples run first and are never shrunk.

    Paste the line a minimized failure prints above the test to keep it as a regression::

        @example(gap=12.5, lead_speed=9.75, brake_at=2.0)
        @scenario(gap=Uniform(10, 40), ...)
        def test_follow(case, world): ...
    """

    def deco(fn: Callable[..., Any]) -> Callable[..., Any]:
        pins = list(getattr(fn, "_avs_examples", ()))
        # decorators apply bottom-up; keep the order in which they are written
        pins.insert(0, dict(params) if not args else BadExample(
            "@example takes the parameter values as keywords, e.g. @example(gap=12.5)"
            if not bare else "@example is written without parentheses; write @example(gap=12.5, ...)"))
        fn._avs_examples = pins  # type: ignore[attr-defined]
        return fn

    # a bare @example would otherwise replace the test by `deco`, which pytest does not collect
    bare = len(args) == 1 and callable(args[0]) and not params
    return deco(args[0]) if bare else deco


@dataclass(frozen=True)
class BadExample:
    """An ``@example`` written wrongly; collection reports ``problem`` naming the test."""

    problem: str

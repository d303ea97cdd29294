"""Acceptance criteria: when a scenario campaign may ship, for gating CI on it.

A campaign is one scenario test with one sampler. By default any counterexample rejects it
(falsification mode). ``@scenario(accept=...)``, ``--avs-accept`` or ini ``avs_accept`` say
otherwise, with any combination of:

* ``"any"`` — every counterexample rejects the campaign (the default);
* metric names, e.g. ``["collision", "school_bus"]`` — only counterexamples violating one of
  them reject it; every other one is an expected failure (still minimized, stored, reported);
* ``"regressions"`` — only a stored counterexample (replayed) or a pinned ``@example`` that
  fails again rejects it; new counterexamples are expected failures;
* ``"avoidable"`` — with the terms above (alone it means ``"any"``): a violated metric that
  the reference driver violates too (``CaseRow.avoidable[metric]`` is false) does not count,
  so a counterexample no careful driver survives is an expected failure; a metric whose
  avoidability is unknown still counts;
* :func:`rate` bounds, e.g. ``rate("collision", at_most=0.01, confidence=0.95)`` — judged on
  the whole campaign's sampled cases: the one-sided Clopper–Pearson upper bound of the
  violation rate must not exceed ``at_most`` (needs a passive sampler: an active one's cases
  are not a random sample, so their rate is biased);
* :func:`min_score`, e.g. ``min_score(0.8)`` — the campaign's driving score (the CARLA
  Leaderboard's: the mean over its judged cases of route completion × infraction penalties,
  :mod:`pytest_avscenario.monitors.score`) must be at least that; the cases need a road in
  their recording (every simulated one has it);
* and, with ``--avs-baseline PATH`` (an earlier run's ``summary.json``), a campaign whose
  violation rate of a metric is significantly higher than in the baseline (one-sided Fisher
  exact test at ``alpha``) is rejected.

On the command line and in the ini file the same terms are written as text, separated by
commas: ``any``, ``regressions``, a metric name, ``rate:collision<=1%@95%``, ``score>=0.8``.
Nothing here imports pytest; scipy is imported when a rate or a baseline is judged.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from typing import Any, Iterable, Mapping, Sequence

from .outcome import CaseRow

__all__ = ["Criteria", "RateBound", "rate", "ScoreBound", "min_score", "parse_accept", "Baseline", "load_baseline",
           "case_verdict", "campaign_verdict", "clopper_pearson_upper"]

KEYWORDS = ("any", "regressions", "avoidable")


@dataclass(frozen=True)
class RateBound:
    """The violation rate of ``metric`` is at most ``at_most`` with ``confidence``."""

    metric: str
    at_most: float
    confidence: float = 0.95

    def __post_init__(self) -> None:
        if not isinstance(self.metric, str) or not self.metric:
            raise ValueError(f"rate(): metric must be a metric name, got {self.metric!r}")
        for name, value, lo, hi in (("at_most", self.at_most, 0.0, 1.0), ("confidence", self.confidence, 0.5, 1.0)):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not (lo <= value < hi or (name == "at_most" and value == hi)):
                raise ValueError(f"rate(): {name} must be a number in [{lo}, {hi}{']' if name == 'at_most' else ')'}, got {value!r}")

    def text(self) -> str:
        return f"rate:{self.metric}<={_pct(self.at_most)}@{_pct(self.confidence)}"


def rate(metric: str, at_most: float, confidence: float = 0.95) -> RateBound:
    """An acceptance criterion: ``metric``'s violation rate ≤ ``at_most`` (a fraction, e.g.
    0.01) at one-sided ``confidence`` (Clopper–Pearson)."""
    return RateBound(metric, float(at_most), float(confidence))


@dataclass(frozen=True)
class ScoreBound:
    """The campaign's driving score is at least ``at_least`` (0..1)."""

    at_least: float

    def __post_init__(self) -> None:
        v = self.at_least
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0.0 <= v <= 1.0:
            raise ValueError(f"min_score(): the driving score bound must be a number in [0, 1], "
                             f"got {v!r}")

    def text(self) -> str:
        return f"score>={self.at_least:g}"


def min_score(at_least: float) -> ScoreBound:
    """An acceptance criterion: the campaign's driving score (CARLA Leaderboard: the mean of
    its cases' route completion × infraction penalties) is at least ``at_least`` (0..1)."""
    return ScoreBound(at_least)


_SCORE = re.compile(r"^score\s*>=\s*([0-9.eE+-]+%?)$")


@dataclass(frozen=True)
class Criteria:
    """A campaign's acceptance criteria, combined (each one can reject it)."""

    any: bool = True
    metrics: tuple[str, ...] = ()
    regressions: bool = False
    rates: tuple[RateBound, ...] = field(default=())
    avoidable: bool = False  # violations the reference driver commits too do not count
    score: ScoreBound | None = None  # the campaign's driving score bound

    def text(self) -> str:
        terms = (["any"] if self.any else []) + list(self.metrics) + \
            (["regressions"] if self.regressions else []) + [r.text() for r in self.rates] + \
            (["avoidable"] if self.avoidable else []) + \
            ([self.score.text()] if self.score is not None else [])
        return ",".join(terms)

    def to_json(self) -> dict[str, Any]:
        return {"any": self.any, "metrics": list(self.metrics), "regressions": self.regressions,
                "rates": [[r.metric, r.at_most, r.confidence] for r in self.rates],
                "avoidable": self.avoidable,
                "min_score": None if self.score is None else self.score.at_least}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> "Criteria":
        score = data.get("min_score")
        return cls(bool(data["any"]), tuple(data["metrics"]), bool(data["regressions"]),
                   tuple(RateBound(m, a, c) for m, a, c in data["rates"]),
                   bool(data.get("avoidable", False)),
                   None if score is None else ScoreBound(float(score)))

    def check(self, metrics: Sequence[str], active: bool) -> None:
        """ValueError when a criterion names an undeclared metric, or bounds the rate of an
        active sampler's campaign."""
        named = list(self.metrics) + [r.metric for r in self.rates]
        unknown = [m for m in named if m not in metrics]
        if unknown:
            known = ", ".join(metrics) if metrics else "none: declare monitors=[...]"
            raise ValueError(f"accept names metric {unknown[0]!r}, which the scenario does not "
                             f"monitor (its metrics: {known})")
        if self.rates and active:
            raise ValueError("accept= bounds a violation rate, but an active sampler's cases are "
                             "not a random sample (its rate is biased): use sampler='halton' or "
                             "'random' for that campaign")


_RATE = re.compile(r"^rate:\s*([^<\s]+)\s*<=\s*([0-9.eE+-]+%?)\s*(?:@\s*([0-9.eE+-]+%?))?$")


def _fraction(text: str) -> float:
    return float(text[:-1]) / 100.0 if text.endswith("%") else float(text)


def _pct(x: float) -> str:
    return f"{x * 100:g}%"


def parse_accept(value: Any) -> Criteria:
    """Criteria from ``accept=`` (a string, a :func:`rate`, or a list of them) or from the
    text of ``--avs-accept``; ValueError says what is wrong."""
    if isinstance(value, Criteria):
        return value
    if isinstance(value, str):
        terms: list[Any] = [t.strip() for t in value.split(",") if t.strip()]
    elif isinstance(value, (RateBound, ScoreBound)):
        terms = [value]
    elif isinstance(value, (list, tuple)):
        terms = list(value)
    else:
        raise ValueError(f"must be 'any', 'regressions', 'avoidable', metric names, rate(...) "
                         f"or min_score(...) bounds, got {value!r}")
    if not terms:
        raise ValueError(f"must name at least one criterion, got {value!r}")
    any_, regressions, avoidable, metrics, rates = False, False, False, [], []
    score: ScoreBound | None = None
    for term in terms:
        if isinstance(term, RateBound):
            rates.append(term)
        elif isinstance(term, ScoreBound) or (isinstance(term, str) and term.startswith("score")):
            if isinstance(term, str):
                m = _SCORE.match(term)
                if m is None:
                    raise ValueError(f"cannot read {term!r}: write score>=LIMIT, e.g. score>=0.8")
                term = ScoreBound(_fraction(m.group(1)))
            if score is not None and score != term:
                raise ValueError(f"two driving score bounds: {score.text()} and {term.text()}")
            score = term
        elif isinstance(term, str) and term.startswith("rate:"):
            m = _RATE.match(term)
            if m is None:
                raise ValueError(f"cannot read {term!r}: write rate:METRIC<=LIMIT[@CONFIDENCE], "
                                 "e.g. rate:collision<=1%@95%")
            rates.append(RateBound(m.group(1), _fraction(m.group(2)),
                                   _fraction(m.group(3)) if m.group(3) else 0.95))
        elif term == "any":
            any_ = True
        elif term == "regressions":
            regressions = True
        elif term == "avoidable":
            avoidable = True
        elif isinstance(term, str) and term.isidentifier():
            metrics.append(term)
        else:
            raise ValueError(f"unknown criterion {term!r}: use 'any', 'regressions', "
                             "'avoidable', a metric name, rate(...) or min_score(...)")
    if avoidable and not (any_ or metrics or regressions):
        if rates or score is not None:
            raise ValueError("'avoidable' qualifies 'any', 'regressions' or metric names; a rate "
                             "bound counts every violation: add 'any' or a metric name to it")
        any_ = True  # "avoidable" alone: every avoidable counterexample rejects
    return Criteria(any_, tuple(dict.fromkeys(metrics)), regressions, tuple(rates), avoidable,
                    score)


DEFAULT = Criteria()


def case_verdict(criteria: Criteria, row: CaseRow, violated: Iterable[str]) -> str | None:
    """Why this counterexample rejects its campaign, or None when the criteria accept it (an
    expected failure). ``violated``: its violated metrics (empty for a failed assertion)."""
    violated = list(violated)
    what = ", ".join(violated) or "the test's assertion"
    if criteria.avoidable and violated:
        known = row.avoidable or {}
        unavoidable = [m for m in violated if known.get(m) is False]
        violated = [m for m in violated if known.get(m) is not False]
        if not violated:
            return None  # the reference driver violates all of them too
        if unavoidable:
            what = f"{', '.join(violated)}; unavoidable: {', '.join(unavoidable)}"
    if criteria.any:
        return f"counterexample ({what})"
    hit = [m for m in violated if m in criteria.metrics]
    if hit:
        return f"counterexample violating {', '.join(hit)}"
    if criteria.regressions and row.origin in ("replay", "example"):
        return f"a {'stored counterexample' if row.origin == 'replay' else 'pinned @example'} fails again ({what})"
    return None


def accepted_reason(criteria: Criteria, violated: Iterable[str], row: CaseRow | None = None) -> str:
    """The xfail reason of an accepted counterexample."""
    violated = list(violated)
    known = (row.avoidable or {}) if row is not None else {}
    if criteria.avoidable and violated and all(known.get(m) is False for m in violated):
        return (f"violated {', '.join(violated)}, unavoidable: the reference driver violates "
                f"{'it' if len(violated) == 1 else 'them'} too; accepted by accept={criteria.text()}")
    return f"violated {', '.join(violated) or 'the assertion'}; accepted by accept={criteria.text()}"


def clopper_pearson_upper(k: int, n: int, confidence: float) -> float:
    """One-sided Clopper–Pearson upper bound of a binomial rate: k events in n trials."""
    if n <= 0:
        return 1.0
    if k >= n:
        return 1.0
    from scipy.stats import beta

    return float(beta.ppf(confidence, k + 1, n - k))


@dataclass(frozen=True)
class Baseline:
    """Per (test, sampler): sampled cases and violations per metric of an earlier run, and
    its failure modes (``summary.json``'s, as JSON data) where that run recorded them."""

    path: str
    campaigns: Mapping[tuple[str, str], tuple[int, Mapping[str, int]]]
    alpha: float = 0.05
    modes: Mapping[tuple[str, str], tuple[Mapping[str, Any], ...]] = field(default_factory=dict)
    #: the driver that run tested (its summary's "driver"), None when it recorded none
    driver: Mapping[str, Any] | None = None
    interrupted: bool = False  # the run stopped before all its cases ran (read with partial_ok)


#: the most sampled cases a campaign can have (``samples`` is refused above it at collection)
MAX_BASELINE_SAMPLES = 100_000


def load_baseline(path: str | os.PathLike, alpha: float = 0.05, partial_ok: bool = False) -> Baseline:
    """An earlier run's ``summary.json``; ValueError names the file, the field and what was
    wrong. Every count is checked (a whole number, ``0 <= violations <= samples``): a count the
    verdict cannot use must stop the run at start-up, never turn the gate off at its end.
    The summary of an interrupted run (``"interrupted": true``) is refused unless
    ``partial_ok``: its rates describe the cases that happened to finish."""
    from .inputs import Fields, InputError, read_json_file

    try:
        top = Fields(read_json_file(path, finite=False))  # a count of 1e400 is named by its field
        interrupted = top.flag("interrupted")
        campaigns: dict[tuple[str, str], tuple[int, dict[str, int]]] = {}
        modes: dict[tuple[str, str], tuple[dict[str, Any], ...]] = {}
        for t in top.list("tests") or ():
            key = (t.text("test"), t.text("sampler"))
            n = t.count("samples", at_most=MAX_BASELINE_SAMPLES)
            violations = t.obj("violations")
            counts = {metric: violations.count(metric, at_most=n, of=f"its {n} samples")
                      for metric, _ in violations.items()}
            if key in campaigns:
                raise t.fail("test", f"campaign {key[0]} [{key[1]}] is listed twice")
            campaigns[key] = (n, counts)
            listed = t.list("modes", optional=True)
            if listed is not None:  # written before failure modes existed: unknown, not "none"
                modes[key] = tuple(_mode_json(m, n) for m in listed)
    except InputError as exc:
        text = str(exc)
        if text.startswith("cannot be read: "):
            raise ValueError(f"cannot read {path}: {text[len('cannot be read: '):]}") from None
        if text.startswith("is not a regular file"):
            raise ValueError(f"{path} {text}") from None
        raise ValueError(f"{path} is not a pytest-avscenario summary.json: {text}") from None
    if interrupted and not partial_ok:
        raise ValueError(f"{path}: the summary of an interrupted run (\"interrupted\": true); its "
                         "rates count only the cases that finished. Use a finished run's summary, "
                         "or add --avs-baseline-partial to compare with it anyway")
    raw = top.data.get("driver") if isinstance(top.data, dict) else None
    driver = raw if isinstance(raw, dict) else None  # None: that run recorded no driver
    return Baseline(str(path), campaigns, alpha, modes, driver=driver, interrupted=interrupted)


def _mode_json(m: Any, n: int) -> dict[str, Any]:
    return {"id": m.text("id"), "key": m.text("key"),
            "metrics": [_text(x) for x in m.list("metrics")],
            "agent": m.text("agent", optional=True, nullable=True),
            "count": m.count("count", at_most=n, of=f"its campaign's {n} samples"),
            "rule": m.text("rule", optional=True) or ""}


def _text(f: Any) -> str:
    if not isinstance(f.data, str):
        raise f.fail(None, "is not text")
    return f.data


def campaign_verdict(criteria: Criteria, rows: Sequence[CaseRow], rejected_cases: Sequence[tuple[str, str]],
                     baseline: Baseline | None, test: str, sampler: str,
                     metrics: Sequence[str]) -> list[str]:
    """The reasons this campaign is rejected (empty: accepted).

    ``rows`` are its main-table rows; ``rejected_cases`` (item, why) its counterexamples that
    the criteria reject. Errors always reject: a case that could not be judged tells nothing.
    """
    reasons = []
    errors = [r for r in rows if r.verdict == "error"]
    if errors:
        reasons.append(f"{len(errors)} case{'s' if len(errors) > 1 else ''} could not be judged "
                       f"(errors; first: {_case_id(errors[0].item)})")
    if rejected_cases:
        item, why = rejected_cases[0]
        more = f" and {len(rejected_cases) - 1} more" if len(rejected_cases) > 1 else ""
        reasons.append(f"{why}: {_case_id(item)}{more}")
    sampled = [r for r in rows if r.origin == "sampled" and r.verdict != "error"]
    n = len(sampled)
    for bound in criteria.rates:
        k = sum(1 for r in sampled if _violates(r, bound.metric))
        upper = clopper_pearson_upper(k, n, bound.confidence)
        if upper > bound.at_most:
            reasons.append(f"{bound.metric} rate {k}/{n}: upper {_pct(bound.confidence)} bound "
                           f"{upper:.1%} > {bound.at_most:.1%}")
    if criteria.score is not None:
        from .monitors.score import campaign_score

        scores = [r.driving_score for r in rows if r.verdict != "error"]
        mean = campaign_score(scores)
        scored = sum(1 for x in scores if x is not None)
        if mean is None:
            reasons.append(f"no case has a driving score to hold to {criteria.score.text()} (its "
                           "recording has no road: simulate it with the world, or give the "
                           "trajectory meta['lanes'] and meta['ego_route'])")
        elif mean < criteria.score.at_least:
            reasons.append(f"driving score {mean:.3f} < {criteria.score.at_least:g} (mean of "
                           f"{scored} case{'s' if scored != 1 else ''})")
    if baseline is not None and (test, sampler) in baseline.campaigns and n:
        n0, before = baseline.campaigns[(test, sampler)]
        from scipy.stats import fisher_exact

        for metric in metrics:
            if metric not in before or n0 <= 0:
                continue
            k, k0 = sum(1 for r in sampled if _violates(r, metric)), before[metric]
            if k / n <= k0 / n0:
                continue
            p = float(fisher_exact([[k, n - k], [k0, n0 - k0]], alternative="greater")[1])
            if p < baseline.alpha:
                reasons.append(f"{metric} rate {k}/{n} ({k / n:.1%}) vs {k0}/{n0} ({k0 / n0:.1%}) "
                               f"in the baseline, p = {p:.2g}")
    return reasons


def _case_id(item: str) -> str:
    """``[halton-003]`` of ``path::test[halton-003]``: the line already names the test."""
    return item[item.index("["):] if "[" in item else item


def _violates(row: CaseRow, metric: str) -> bool:
    value = row.rho.get(metric)
    return value is not None and not math.isnan(value) and value < 0

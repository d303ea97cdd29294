"""The paper's results table, computed from the error table's rows.

After a falsification run an AV team wants one line per scenario test and sampler: how many
cases were sampled, how many violated each metric, how well the samples cover the continuous
parameter space (ε), how many counterexamples were found and minimized, and what the
simulations cost. :func:`summarize` computes those :class:`SummaryRow` s from plain row
dicts (see :mod:`.table`) and per-test declarations (:class:`TestInfo`);
:func:`format_table` renders the terminal section, :func:`suite_properties` the JUnit
suite-level properties, :func:`summary_to_json` the ``summary.json`` of the report
directory. Counting rules:

* ``samples`` and the per-metric violations count cases with origin ``"sampled"`` only (as
  in the paper), so replayed database entries and ``@example`` cases do not inflate them;
* ``counterexamples`` counts failing cases of every origin except shrink candidates;
* ``minimized`` counts counterexamples whose shrinking produced a failing candidate
  (a shrink row's ``item`` names the counterexample it shrinks) or whose row says
  ``"minimized"``;
* ``sim_time_s`` is all simulation time of the test and sampler, shrinking included;
* ε is :func:`.coverage.epsilon_coverage` over the sampled cases' continuous parameters in
  the unit cube, ``None`` (shown "—") without continuous parameters or samples;
* ``modes`` are the campaign's failure modes (:func:`.modes.failure_modes` over its
  counterexamples of every origin); the table shows how many.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any, Callable, Iterable, Mapping, Sequence

from .coverage import DEFAULT_TOL
from ..codec import rho_to_str
from ..outcome import CaseRow

__all__ = [
    "TestInfo",
    "SummaryRow",
    "summarize",
    "format_table",
    "format_pointer",
    "format_rejections",
    "short_names",
    "suite_properties",
    "summary_to_json",
    "metric_columns",
    "DASH",
]

DASH = "—"


@dataclass(frozen=True)
class TestInfo:
    """What the summary needs to know about one scenario test beyond its rows.

    ``metrics`` in declaration order (the table's column order); ``space`` is the test's
    :class:`~pytest_avscenario.space.FeatureSpace` or anything with ``continuous`` (names),
    ``continuous_mask()`` and ``to_unit(params)``; without it ε is "—".
    """

    __test__ = False  # not a pytest test class, despite its name

    metrics: tuple[str, ...] = ()
    space: Any = None
    samplers: tuple[str, ...] = ()  # in the order the test declares them
    #: the metrics in the order of the declared priority (``@scenario(priority=...)``;
    #: empty: the declaration order), which groups failure modes by the first one violated
    priority: tuple[str, ...] = ()


@dataclass(frozen=True)
class SummaryRow:
    """One line of the paper's table: one scenario test with one sampler."""

    __test__ = False

    test: str
    sampler: str
    metrics: tuple[str, ...]
    samples: int
    violations: dict[str, int]
    epsilon: float | None
    covering_radius: float | None
    fraction_within: float | None
    within_radius: float | None
    continuous: tuple[str, ...]
    counterexamples: int
    minimized: int
    errors: int
    cases: int
    shrink_sims: int
    sim_time_s: float
    failed_items: tuple[str, ...] = field(default=())
    #: why the campaign is rejected by its acceptance criteria (empty: accepted; None: the
    #: campaign was not judged)
    reasons: tuple[str, ...] | None = None
    #: counterexamples whose avoidability was judged, and those of them the reference driver
    #: could not avoid either (it violates every violated metric too, in the same conflict:
    #: the same other agent around the same time; judgements of the case as found)
    judged: int = 0
    unavoidable: int = 0
    #: the campaign's failure modes (:func:`.modes.failure_modes`), the largest first
    modes: tuple[Any, ...] = field(default=())
    #: the failure modes could not be computed (summary.json then says ``"modes": null``,
    #: "not recorded", so a comparison does not call every earlier mode gone)
    modes_failed: bool = False
    #: the campaign's driving score (the CARLA Leaderboard's: the mean of its cases' scores,
    #: 0..1) and how many cases had one; None when none had
    driving_score: float | None = None
    scored: int = 0
    #: violations per metric among all the campaign's cases (``violations`` counts sampled
    #: cases only, as the paper's table does): what a campaign of replays or pinned examples,
    #: which has no sampled case, shows per metric
    case_violations: dict[str, int] = field(default_factory=dict)

    @property
    def verdict(self) -> str | None:
        return None if self.reasons is None else "rejected" if self.reasons else "accepted"


def _unit_coordinate(dist: Any, value: Any) -> float:
    # a Uniform whose span is not a finite float (Uniform(-1e308, 1e308)) is refused at
    # collection, so to_unit's (x - lo) / (hi - lo) is finite here
    return float(dist.to_unit(value))


def _unit_points(rows: Sequence[CaseRow], space: Any):
    import numpy as np

    mask = np.asarray(space.continuous_mask(), dtype=bool)
    parameters = getattr(space, "parameters", None)
    dims = getattr(space, "dims", None)
    if isinstance(parameters, Mapping) and dims is not None:
        # plain floats per row, one array at the end: no numpy array per row (100,000 rows)
        to_unit = [(dim.name, parameters[dim.name]) for dim in dims]
        unit_row = lambda params: [_unit_coordinate(dist, params[name]) for name, dist in to_unit]  # noqa: E731
    else:
        unit_row = lambda params: list(np.asarray(space.to_unit(dict(params)), dtype=float))  # noqa: E731
    pts = []
    for r in rows:
        try:
            pts.append(unit_row(r.params))
        except (KeyError, ValueError, TypeError, ArithmeticError):
            # A row whose parameters do not fit the space (hand-written, or from an older
            # declaration) cannot be placed; it still counts as a sample, just not for ε.
            continue
    if not pts:
        return None
    u = np.array(pts, dtype=float).reshape(len(pts), -1)[:, mask]
    u = u[np.all(np.isfinite(u), axis=1)]
    if not len(u):
        return None
    return np.clip(u, 0.0, 1.0)


def summarize(
    rows: Iterable[CaseRow | Mapping[str, Any]],
    tests: Mapping[str, TestInfo] | None = None,
    *,
    tol: float = DEFAULT_TOL,
    within_radius: float | None = 0.1,
    cross_check: bool = True,
    verdicts: Mapping[tuple[str, str], Sequence[str]] | None = None,
    on_error: Callable[[str, str | None, Exception], None] | None = None,
    modes: bool = True,
    known_coverage: Callable[[str, str, list[CaseRow]], tuple | None] | None = None,
    known_modes: Callable[[str, str, list[CaseRow], tuple[str, ...]], tuple | None] | None = None,
) -> list[SummaryRow]:
    """Summary rows per (test, sampler), tests in the order of ``tests`` (collection order),
    then any others in order of first appearance; samplers in order of first appearance.

    ``rows`` may mix main-table and shrink rows. ``tol`` is ε's binary-search tolerance;
    ``within_radius`` the radius for the covered-fraction figure (None to skip);
    ``cross_check`` also computes the mesh covering radius; ``verdicts`` maps (test, sampler)
    to the reasons its campaign is rejected (see :mod:`pytest_avscenario.acceptance`).
    ``on_error(part, test, exception)``: when given, a coverage computation that raises is
    reported there and its figures are "—" (the other campaigns are still summarized);
    without it the exception propagates. ``modes``: group each campaign's counterexamples
    into failure modes (:mod:`.modes`; False leaves ``SummaryRow.modes`` empty).
    ``known_coverage(test, sampler, sampled rows)``: the campaign's :func:`campaign_coverage`
    when it was computed already from those rows (:mod:`.ahead`), else None;
    ``known_modes(test, sampler, main-table rows, metric order)`` the same for its failure
    modes.
    """
    from ..monitors.score import campaign_score

    tests = dict(tests or {})
    groups: dict[tuple[str, str], list[Mapping[str, Any]]] = {}
    for r in map(CaseRow.coerce, rows):
        groups.setdefault((r.test, r.sampler), []).append(r)
    order = {t: i for i, t in enumerate(tests)}
    def declared(test: str, sampler: str) -> int:
        samplers = tests[test].samplers if test in tests else ()
        return samplers.index(sampler) if sampler in samplers else len(samplers)

    keys = sorted(groups, key=lambda k: (order.get(k[0], len(order)), declared(*k)))
    # sorted() is stable: undeclared samplers keep their first-appearance order.

    out = []
    for test, sampler in keys:
        group = groups[(test, sampler)]
        info = tests.get(test, TestInfo())
        main = [r for r in group if r.origin != "shrink"]
        shrink = [r for r in group if r.origin == "shrink"]
        sampled = [r for r in main if r.origin == "sampled"]
        metrics = list(info.metrics)
        for r in group:  # metrics seen but not declared still get a column, after the declared
            for m in r.rho:
                if m not in metrics:
                    metrics.append(m)
        violations = {
            m: sum(1 for r in sampled if _violated(r.rho.get(m))) for m in metrics
        }
        case_violations = {
            m: sum(1 for r in main if _violated(r.rho.get(m))) for m in metrics
        }
        failing = [r for r in main if r.verdict == "fail"]
        failing_items = {r.item for r in failing}
        shrunk = {r.item for r in shrink if r.verdict == "fail"}
        shrunk |= {r.item for r in failing if r.minimized}
        space = info.space
        continuous = tuple(getattr(space, "continuous", ()) or ()) if space is not None else ()
        eps = cover = frac = None
        known = None if known_coverage is None else known_coverage(test, sampler, sampled)
        if known is not None:  # computed ahead, from these very rows (.ahead)
            eps, cover, frac = known
        else:
            try:
                eps, cover, frac = campaign_coverage(sampled, space, tol=tol, within_radius=within_radius,
                                                     cross_check=cross_check)
            except Exception as exc:  # e.g. scipy failing to load in a starved process
                if on_error is None:
                    raise
                on_error(f"the ε-coverage [{sampler}]", test, exc)
                eps = cover = frac = None
        found: tuple[Any, ...] = ()
        modes_failed = False
        priority = tuple(info.priority) or tuple(metrics)
        known_found = None if not (modes and failing) or known_modes is None or space is None else \
            known_modes(test, sampler, main, priority)
        if known_found is not None:  # made ahead, from these very rows (.ahead)
            found = known_found
        elif modes and failing:
            try:
                from .modes import failure_modes

                found = tuple(failure_modes(main, space, list(priority)))
            except Exception as exc:
                if on_error is None:
                    raise
                on_error(f"the failure modes [{sampler}]", test, exc)
                modes_failed = True
        out.append(
            SummaryRow(
                test=test,
                sampler=sampler,
                metrics=tuple(metrics),
                samples=len(sampled),
                violations=violations,
                epsilon=eps,
                covering_radius=cover,
                fraction_within=frac,
                within_radius=within_radius if frac is not None else None,
                continuous=continuous,
                counterexamples=len(failing),
                minimized=len(shrunk & failing_items),
                errors=sum(1 for r in main if r.verdict == "error"),
                cases=len(main),
                shrink_sims=len(shrink),
                sim_time_s=float(sum(r.sim_time_s for r in group)),
                failed_items=tuple(sorted(failing_items)),
                reasons=None if verdicts is None else tuple(verdicts.get((test, sampler), ())),
                judged=sum(1 for r in failing if r.avoidable),
                unavoidable=sum(1 for r in failing if r.unavoidable),
                modes=found,
                modes_failed=modes_failed,
                driving_score=campaign_score(r.driving_score for r in main),
                scored=sum(1 for r in main if r.driving_score is not None),
                case_violations=case_violations,
            )
        )
    return out


#: the most continuous parameters whose ε-coverage the summary computes (see summarize)
MAX_EPS_DIMENSIONS = 12


def campaign_coverage(
    sampled: Sequence[CaseRow], space: Any, *, tol: float = DEFAULT_TOL,
    within_radius: float | None = 0.1, cross_check: bool = True,
) -> tuple[float | None, float | None, float | None]:
    """(ε, covering radius, fraction within ``within_radius``) of one campaign's sampled
    cases in ``space``'s continuous parameters; None for what is not computed (see
    :func:`summarize`)."""
    from . import coverage

    continuous = tuple(getattr(space, "continuous", ()) or ()) if space is not None else ()
    eps = cover = frac = None
    # beyond MAX_EPS_DIMENSIONS continuous parameters the mesh ε-coverage probes cannot be
    # enumerated in reasonable time (seconds at 16, minutes at 20, 2^200 nodes at 200):
    # ε is "—" there, as for a space with no continuous parameter, not a failed report part
    if continuous and sampled and len(continuous) <= MAX_EPS_DIMENSIONS:
        pts = _unit_points(sampled, space)
        if pts is not None and pts.shape[1] > 0:
            eps = coverage.epsilon_coverage(pts, tol=tol)
            if cross_check:
                cover = coverage.covering_radius(pts, _summary_resolution(pts.shape[1]))
            if within_radius is not None:
                frac = coverage.fraction_within(pts, within_radius, n_probe=1 << 14)
    return eps, cover, frac


def _summary_resolution(d: int) -> int:
    # About 2^18 mesh nodes: a cross-check that costs well under a second per test even in
    # 6-D, where a finer mesh would dominate the end of the run.
    return max(2, int(math.floor((1 << 18) ** (1.0 / d) + 1e-9)))


def _violated(rho: float | None) -> bool:
    # NaN is not a violation verdict we can stand behind, so it does not count
    return rho is not None and not math.isnan(rho) and rho < 0


def metric_columns(summary: Sequence[SummaryRow]) -> list[str]:
    """All metrics in declaration order, tests in table order (first seen wins)."""
    cols: list[str] = []
    for s in summary:
        for m in s.metrics:
            if m not in cols:
                cols.append(m)
    return cols


def _fmt_eps(value: float | None) -> str:
    return DASH if value is None else f"{value:.3f}"


def _fmt_time(seconds: float) -> str:
    return f"{seconds:.1f}" if seconds < 1000 else f"{seconds:.0f}"


def _metric_title(name: str) -> str:
    # The paper's columns read "Progress, Distance, TTC, Lane": capitalize plain lower-case
    # names, keep anything the user spelled with capitals (TTC) as written.
    return name[:1].upper() + name[1:] if name.islower() and len(name) > 3 else (
        name.upper() if name.islower() else name
    )


def table_cells(summary: Sequence[SummaryRow]) -> tuple[list[str], list[list[str]]]:
    """Header and body cells of the paper's table (shared by terminal and HTML)."""
    metrics = metric_columns(summary)
    show_errors = any(s.errors for s in summary)
    header = ["test", "sampler", "samples", *(_metric_title(m) for m in metrics), "ε"]
    judged = any(s.verdict is not None for s in summary)
    show_unavoidable = any(s.judged for s in summary)
    show_score = any(s.driving_score is not None for s in summary)
    header += ["cex", "min"] + (["unavoid"] if show_unavoidable else []) + ["modes"] \
        + (["errors"] if show_errors else []) + (["score"] if show_score else []) + ["sim s"]
    header += ["verdict"] if judged else []
    body = []
    for s in summary:
        line = [s.test, s.sampler, str(s.samples)]
        # a campaign without sampled cases (replays of stored failures, pinned examples)
        # counts its violations among the cases it ran, so its row agrees with its "cex"
        counts = s.violations if s.samples or not s.case_violations else s.case_violations
        line += [str(counts[m]) if m in counts else DASH for m in metrics]
        line += [_fmt_eps(s.epsilon), str(s.counterexamples), str(s.minimized)]
        line += [str(s.unavoidable) if s.judged else DASH] if show_unavoidable else []
        line += [str(len(s.modes)) if s.modes else DASH]
        line += [str(s.errors)] if show_errors else []
        line += [DASH if s.driving_score is None else f"{s.driving_score:.2f}"] if show_score else []
        line += [_fmt_time(s.sim_time_s)]
        line += [{"rejected": "REJECTED", None: DASH}.get(s.verdict, s.verdict)] if judged else []
        body.append(line)
    return header, body


LEGEND = "ε: coverage of the continuous parameters (smaller: better) · cex: counterexamples · min: minimized"
#: added when a column "modes" is shown
LEGEND_MODES = " · modes: failure modes (kinds of counterexample, in the report)"
#: added when a column "score" is shown
LEGEND_SCORE = " · score: driving score (CARLA Leaderboard: route completion × infraction penalties, mean of the cases)"
#: added when a column "unavoid" is shown
LEGEND_UNAVOIDABLE = " · unavoid: counterexamples the reference driver fails too, in the same conflict"


def _legend(header: Sequence[str]) -> str:
    return LEGEND + (LEGEND_UNAVOIDABLE if "unavoid" in header else "") \
        + (LEGEND_MODES if "modes" in header else "") \
        + (LEGEND_SCORE if "score" in header else "")


def short_names(tests: Sequence[str]) -> dict[str, str]:
    """Test ids as short as they all stay unique: the function names, else ``module::function``,
    else the whole ids."""
    tests = list(dict.fromkeys(tests))
    for shorten in (lambda t: t.rpartition("::")[2], lambda t: t.rpartition("/")[2], lambda t: t):
        names = {t: shorten(t) for t in tests}
        if len(set(names.values())) == len(tests):
            return names
    return {t: t for t in tests}


def format_table(summary: Sequence[SummaryRow], width: int | None = None) -> str:
    """The terminal table: aligned columns, text left, numbers right; "—" where not
    applicable; columns that are "—" on every row left out; test ids as short as they stay
    unique; a one-line legend. When it is wider than ``width`` (the terminal's), each campaign
    takes two lines instead: its figures, then its violations per metric. Returns "" for an
    empty summary (the caller then prints nothing)."""
    if not summary:
        return ""
    header, body = table_cells(summary)
    names = short_names([s.test for s in summary])
    body = [[names[s.test], *line[1:]] for s, line in zip(summary, body)]
    keep = [i for i in range(len(header)) if i < 2 or any(line[i] != DASH for line in body)]
    header, body = [header[i] for i in keep], [[line[i] for i in keep] for line in body]
    widths = [max(len(r[i]) for r in [header, *body]) for i in range(len(header))]
    left = {0, 1} | ({len(header) - 1} if header[-1] == "verdict" else set())  # text columns

    def line(cells: Sequence[str], widths: Sequence[int]) -> str:
        parts = [c.ljust(w) if i in left else c.rjust(w) for i, (c, w) in enumerate(zip(cells, widths))]
        return "  ".join(parts).rstrip()

    rule = "  ".join("-" * w for w in widths)
    if width is None or len(rule) <= width:
        return "\n".join([line(header, widths), rule, *(line(r, widths) for r in body),
                          *_wrap(_legend(header), width)])
    # too wide: the figures on one line, the violations per metric on the next
    metrics = [h for h in header if h not in ("test", "sampler", "samples", "ε", "cex", "min",
                                              "unavoid", "modes", "errors", "score", "sim s",
                                              "verdict")]
    fixed = [i for i, h in enumerate(header) if h not in metrics]
    fheader = [header[i] for i in fixed]
    fbody = [[r[i] for i in fixed] for r in body]
    fwidths = [max(len(r[i]) for r in [fheader, *fbody]) for i in range(len(fheader))]
    over = sum(fwidths) + 2 * (len(fwidths) - 1) - width
    if over > 0:  # long test names: shortened in the middle, where ids differ least
        fwidths[0] = max(fwidths[0] - over, len(fheader[0]), MIN_NAME)
        fbody = [[ellipsize(r[0], fwidths[0]), *r[1:]] for r in fbody]
    left = {0, 1} | ({len(fheader) - 1} if fheader[-1] == "verdict" else set())
    out = [line(fheader, fwidths), "  ".join("-" * w for w in fwidths)]
    for s_row, r, full in zip(summary, fbody, body):
        out.append(line(r, fwidths))
        counts = [f"{h} {full[header.index(h)]}" for h in metrics
                  if full[header.index(h)] not in (DASH, "0")]
        among = "" if s_row.samples or not s_row.cases else f" (among its {s_row.cases} cases)"
        out += _wrap("violations: " + (", ".join(counts) or "none") + among, width, indent="    ")
    return "\n".join([*out, *_wrap(_legend(header), width)])


#: the fewest characters a shortened test name keeps in the terminal table
MIN_NAME = 16


def ellipsize(text: str, width: int) -> str:
    """``text`` cut to ``width`` characters with "…" in the middle (the start names the
    module, the end the function: both tell tests apart)."""
    if len(text) <= width:
        return text
    if width < 2:
        return text[:width]
    head = (width - 1 + 1) // 2
    tail = width - 1 - head
    return text[:head] + "…" + (text[-tail:] if tail else "")


def _wrap(text: str, width: int | None, indent: str = "") -> list[str]:
    """``text`` as lines of at most ``width`` characters (one line when ``width`` is None):
    whole " · "-separated items per line where they fit (an item is never split unless it is
    longer than a line by itself), continuation lines indented two more."""
    import textwrap

    if width is None:
        return [indent + text]
    width = max(width, 20)
    lines: list[str] = []
    for item in text.split(" · "):
        lead = indent if not lines else indent + "  "
        if lines and len(lines[-1]) + 3 + len(item) <= width:
            lines[-1] += " · " + item
        elif len(lead) + len(item) <= width:
            lines.append(lead + item)
        else:
            lines += textwrap.wrap(item, width=width, initial_indent=lead,
                                   subsequent_indent=indent + "  ", break_on_hyphens=False)
    return lines or [indent]


def format_rejections(summary: Sequence[SummaryRow]) -> list[str]:
    """One line per rejected campaign, saying why (for the terminal, after the table)."""
    names = short_names([s.test for s in summary])
    return [f"REJECTED {names[s.test]} [{s.sampler}]: {'; '.join(s.reasons)}" for s in summary if s.reasons]


def format_pointer(directory: Any) -> str:
    """The one line after the table that says where the full report is."""
    import os

    d = os.fspath(directory)
    return f"avscenario report: {os.path.join(d, 'index.html')} (error table: {os.path.join(d, 'errors.jsonl')})"


def _prop_value(value: Any) -> str:
    if value is None:
        return DASH
    if isinstance(value, float):
        return f"{value:.6g}" if math.isfinite(value) else rho_to_str(value)
    return str(value)


def suite_properties(
    summary: Sequence[SummaryRow],
    *,
    seed: Any = None,
    versions: Mapping[str, Any] | None = None,
) -> dict[str, str]:
    """The JUnit suite-level properties, as an ordered ``{name: value}`` of strings.

    ``avs.seed``, ``avs.version.<package>`` for each entry of ``versions`` (e.g.
    ``{"pytest-avscenario": "0.1.0", "highway-env": "1.12.1"}``), then per test and sampler
    ``avs.test[<test>][<sampler>].samples`` / ``.violations.<metric>`` / ``.epsilon`` /
    ``.counterexamples`` / ``.minimized`` / ``.modes`` (failure modes) / ``.driving_score``
    (when the cases had one) / ``.sim_time_s`` /
    ``.verdict`` (``accepted``, or
    ``rejected; <reason>; …``). Brackets delimit the ids because
    node ids themselves contain dots and colons.
    """
    props: dict[str, str] = {}
    if seed is not None:
        props["avs.seed"] = str(seed)
    for name, version in (versions or {}).items():
        props[f"avs.version.{name}"] = _prop_value(version)
    for s in summary:
        key = f"avs.test[{s.test}][{s.sampler}]"
        props[f"{key}.samples"] = str(s.samples)
        for m in s.metrics:
            props[f"{key}.violations.{m}"] = str(s.violations.get(m, 0))
        props[f"{key}.epsilon"] = _prop_value(s.epsilon)
        props[f"{key}.counterexamples"] = str(s.counterexamples)
        props[f"{key}.minimized"] = str(s.minimized)
        props[f"{key}.modes"] = str(len(s.modes))
        if s.judged:
            props[f"{key}.unavoidable"] = str(s.unavoidable)
        if s.driving_score is not None:
            props[f"{key}.driving_score"] = f"{s.driving_score:.6g}"
        props[f"{key}.sim_time_s"] = f"{s.sim_time_s:.3f}"
        if s.verdict is not None:
            props[f"{key}.verdict"] = s.verdict + "".join(f"; {r}" for r in s.reasons)
    return props


def summary_to_json(summary: Sequence[SummaryRow]) -> list[dict[str, Any]]:
    """JSON-safe dicts of the summary rows (for ``summary.json``)."""
    out = []
    for s in summary:
        d = asdict(s)
        for k in ("epsilon", "covering_radius", "fraction_within", "within_radius"):
            v = d[k]
            d[k] = None if v is None else float(v)
        d["metrics"] = list(s.metrics)
        d["continuous"] = list(s.continuous)
        d["failed_items"] = list(s.failed_items)
        d["reasons"] = None if s.reasons is None else list(s.reasons)
        d["verdict"] = s.verdict
        d["modes"] = None if s.modes_failed else [m.to_json() for m in s.modes]
        out.append(d)
    return out

"""Every setting of a scenario campaign: the option table, its parsers, and the frozen
:class:`Settings` of a session with where each value came from.

The pytest side (:mod:`pytest_avscenario.pytest_plugin.options`) reads the command line and the
ini file into :class:`Settings` (a bad value there is a ``pytest.UsageError``); a script makes
them with :func:`script_settings`. A scenario test's own values come from its ``@scenario``
marker: :meth:`Settings.for_test` gives a frozen :class:`TestSettings`, and a bad marker value
is a :class:`DeclarationError`, which collection turns into an error naming the test.

Precedence: a marker argument beats the command line, which beats the ini file, which beats
the default — except ``--avs-samples`` and ``--avs-sampler``, which exist to override every
test at once (their ini keys are defaults for tests whose marker does not say).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping

from ..markers.spec import ScenarioSpec

DEFAULT_SAMPLES = 20
DEFAULT_SAMPLER = "halton"
DEFAULT_SHRINK_BUDGET = 20
DEFAULT_REFERENCE = "careful"  # the reference driver of the avoidability check
DEFAULT_GIFS = 3
DEFAULT_CASE_PICTURES = 5
MAX_SAMPLES = 100_000
MAX_CASE_TIMEOUT_S = 86_400.0  # one day: beyond, a timer overflows and nobody means it
EXECUTORS = ("inprocess", "dask")


class DeclarationError(Exception):
    """A scenario test's declaration or setting is wrong; collection names the test."""


# --------------------------------------------------------------------------- parsers
# Each parser takes the raw value (a marker's Python value, or the text of an option or an
# ini line) and returns the clean value or raises ValueError saying what it expects.
def _integer(minimum: int, maximum: int | None = None) -> Callable[[Any], int]:
    def parse(raw: Any) -> int:
        try:
            if isinstance(raw, bool) or (isinstance(raw, float) and not raw.is_integer()):
                raise ValueError
            value = int(str(raw).strip()) if isinstance(raw, str) else int(raw)
        except (TypeError, ValueError, OverflowError):
            raise ValueError(f"must be an integer, got {_show(raw)}") from None
        if value < minimum:
            raise ValueError(f"must be >= {minimum}, got {_show(value)}")
        if maximum is not None and value > maximum:
            raise ValueError(f"must be at most {maximum}, got {_show(value)}")
        return value
    return parse


def _samples(raw: Any) -> int:
    value = _integer(1)(raw)
    if value > MAX_SAMPLES:
        raise ValueError(
            f"must be at most {MAX_SAMPLES} per test (got {_show(value)}): every case is a pytest "
            "item; for a long campaign give time_budget= (e.g. '30m') with a large count")
    return value


def parse_duration(raw: Any) -> float:
    """Seconds from ``90``, ``"90s"``, ``"30m"``, ``"1.5h"``; ValueError otherwise."""
    if isinstance(raw, bool):
        raise ValueError(raw)
    if isinstance(raw, (int, float)):
        seconds = float(raw)
    else:
        text = str(raw).strip().lower()
        unit = {"s": 1.0, "m": 60.0, "h": 3600.0}.get(text[-1:], None)
        seconds = float(text[:-1]) * unit if unit else float(text)
    if not math.isfinite(seconds) or seconds <= 0:
        raise ValueError(raw)
    return seconds


def _duration(what: str, maximum: float | None = None) -> Callable[[Any], float]:
    def parse(raw: Any) -> float:
        try:
            seconds = parse_duration(raw)
        except (TypeError, ValueError, OverflowError):
            raise ValueError(f"must be {what}, got {_show(raw)}") from None
        if maximum is not None and seconds > maximum:
            raise ValueError(f"must be at most {maximum:g} s (a day), got {_show(raw)}; "
                             "leave it unset for no limit")
        return seconds
    return parse


def _show(value: Any) -> str:
    from ..space import _show as show

    return show(value)


def _positive_seconds(raw: Any) -> float:
    try:
        value = float(raw)
    except (TypeError, ValueError):
        value = math.nan
    if isinstance(raw, bool) or not math.isfinite(value) or value <= 0:
        raise ValueError(f"must be a positive number of seconds, got {_show(raw)}")
    return value


def _spin(raw: Any) -> str | float:
    if str(raw).strip().lower() == "auto":
        return "auto"
    try:
        value = float(raw)
    except (TypeError, ValueError):
        value = math.nan
    if isinstance(raw, bool) or not math.isfinite(value) or not 0 <= value <= 1e6:
        raise ValueError(f"must be 'auto' or a number of microseconds from 0 to 1000000, "
                         f"got {_show(raw)}")
    return value


def _export(raw: Any) -> int | str:
    value = str(raw).strip().lower()
    if value in ("all", "none"):
        return value
    try:
        return _integer(0)(value)
    except ValueError:
        raise ValueError(f"must be a number N, 'all' or 'none', got {_show(raw)}") from None


def _one_of(what: str, *names: str) -> Callable[[Any], str]:
    def parse(raw: Any) -> str:
        value = str(raw).strip()
        if value not in names:
            raise ValueError(f"unknown {what} {value!r}; available: {', '.join(names)}")
        return value
    return parse


#: the built-in drivers' names (``sim.drivers.BUILTIN``, kept here so that loading the plugin
#: imports no simulator; tests/test_options.py checks the two agree)
BUILTIN_DRIVERS = ("autopilot", "idm", "careful")


def _driver(raw: Any) -> str:
    value = str(raw).strip()
    if value.startswith("sb3:"):
        from ..sim.drivers import sb3

        sb3.parse(value)  # the syntax here; the file and the environment in read_settings
        return value
    if value.startswith(("osi:", "osi+spawn:")):
        from ..stack.client import parse_spec

        parse_spec(value)  # the syntax here; whether pyzmq and osi3 are installed in read_settings
        return value
    if value not in BUILTIN_DRIVERS and ":" not in value:
        names = ", ".join(repr(n) for n in BUILTIN_DRIVERS)
        raise ValueError(f"unknown driver {value!r}; use {names}, 'package.module:Name', "
                         "'sb3:PATH@ENV', 'osi:ADDRESS' or 'osi+spawn:COMMAND'")
    return value


def _margins(raw: Any) -> dict[str, float]:
    """``{metric: margin}`` from a marker's mapping or ``"collision=0.3,distance=1"``: the
    band around zero within which the reference's value decides no avoidability judgement,
    in each metric's unit (see :mod:`pytest_avscenario.monitors.conflict`)."""
    if isinstance(raw, Mapping):
        pairs = list(raw.items())
    elif isinstance(raw, str):
        pairs = []
        for part in filter(None, (p.strip() for p in raw.split(","))):
            metric, eq, value = part.partition("=")
            if not eq or not metric.strip():
                raise ValueError(f"must be METRIC=MARGIN[,METRIC=MARGIN], got {_show(raw)}")
            pairs.append((metric.strip(), value.strip()))
    else:
        raise ValueError(f"must be a mapping {{metric: margin}} or 'METRIC=MARGIN,...', got {_show(raw)}")
    out = {}
    for metric, value in pairs:
        try:
            margin = float(value)
        except (TypeError, ValueError):
            margin = math.nan
        if isinstance(value, bool) or not math.isfinite(margin) or margin < 0:
            raise ValueError(f"margin of {metric!r} must be a number >= 0 in the metric's unit, "
                             f"got {_show(value)}")
        out[str(metric)] = margin
    return out


def _reference(raw: Any) -> str | None:
    """A built-in driver's name, or None for 'none' (no avoidability check)."""
    value = str(raw).strip() if isinstance(raw, str) or raw is None else raw
    if value is None or value == "none":
        return None
    if value not in BUILTIN_DRIVERS:
        names = ", ".join(repr(n) for n in BUILTIN_DRIVERS)
        raise ValueError(f"must be a built-in driver ({names}) or 'none', got {_show(raw)}")
    return value


MAX_DT_S = 10.0  # [s] a simulation step beyond this is a typo (ms for s), not a scenario


def _dt(raw: Any) -> float | None:
    """A simulation step [s], or None for 'auto' (the driver's own step, else 0.1 s)."""
    if isinstance(raw, str) and raw.strip().lower() == "auto":
        return None
    bad = ValueError(f"must be a step in seconds (0 < dt <= {MAX_DT_S:g}) or 'auto', "
                     f"got {_show(raw)}")
    if isinstance(raw, bool):
        raise bad
    try:
        value = float(raw.strip() if isinstance(raw, str) else raw)
    except (TypeError, ValueError):
        raise bad from None
    if not (math.isfinite(value) and 0 < value <= MAX_DT_S):
        raise bad
    return value


def _accept(raw: Any) -> Any:
    from ..acceptance import parse_accept

    return parse_accept(raw)


def _text(raw: Any) -> str:
    return str(raw).strip()


def _yes_no(raw: Any) -> bool:
    value = str(raw).strip().lower()
    if value in ("yes", "true", "1", "on"):
        return True
    if value in ("no", "false", "0", "off"):
        return False
    raise ValueError(f"must be yes or no, got {_show(raw)}")


def _sampler_names(raw: Any) -> tuple[str, ...]:
    from ..samplers import base

    if isinstance(raw, str):
        names = [n.strip() for n in raw.split(",") if n.strip()]
    elif isinstance(raw, (list, tuple)) and all(isinstance(n, str) for n in raw):
        names = list(raw)
    else:
        names = []
    if not names:
        raise ValueError(f"must be a name or a list of names, got {_show(raw)}")
    for n in names:
        if n not in base.available():
            raise ValueError(f"unknown sampler {n!r}; available: {', '.join(base.available())}")
    if len(set(names)) != len(names):
        raise ValueError(f"sampler list names a sampler twice: {names!r}")
    return tuple(names)


@dataclass(frozen=True)
class Option:
    """One ``--avs-…`` option with its ini key ``avs_…``."""

    name: str  # "shrink-budget": --avs-shrink-budget, ini avs_shrink_budget
    metavar: str
    help: str
    ini_help: str
    parse: Callable[[Any], Any]
    per_test: bool = False  # @scenario(<key>=...) may set it too
    cli_first: bool = False  # the command line overrides the marker
    ini: bool = True
    flag: bool = False  # a switch on the command line (no value); the ini key takes yes/no

    @property
    def key(self) -> str:
        return self.name.replace("-", "_")

    @property
    def dest(self) -> str:
        return f"avs_{self.key}"


OPTIONS = (
    Option("seed", "N|last",
           "seed for sampling and simulation; 'last' reuses the previous run's seed (default: "
           "a fresh seed, printed in the header)",
           "seed of the run (an integer); default: a fresh one each run", _text),
    Option("samples", "N",
           "override the number of cases of every scenario test (e.g. 5 for a smoke run)",
           "cases per scenario test when the marker does not say",
           _samples, per_test=True, cli_first=True),
    Option("sampler", "NAME[,NAME]",
           "override the sampler of every scenario test (halton, random, mab, ce, sa, bo)",
           "sampler for scenario tests whose marker does not name one",
           _sampler_names, per_test=True, cli_first=True),
    Option("driver", "NAME",
           "driver of the ego: 'autopilot' (default), 'idm', 'careful' (UN R157's careful and "
           "competent driver), 'package.module:Name', or 'sb3:PATH@ENV' (a stable-baselines3 "
           "model trained on the highway-env environment ENV, default highway-fast-v0; needs "
           "pytest-avscenario[sb3]), 'osi:ADDRESS' (a stack out of process at tcp://… or "
           "ipc://…) or 'osi+spawn:COMMAND' (started by the plugin; see docs/osi-protocol.md); "
           "a conftest `avs_driver` fixture overrides this",
           "driver of the ego (autopilot, idm, careful, package.module:Name, sb3:PATH@ENV, "
           "osi:ADDRESS or osi+spawn:COMMAND) when avs_driver is not overridden",
           _driver),
    Option("stack-timeout", "SECONDS",
           "seconds a stack out of process (--avs-driver osi:…) may take to answer one "
           "step before the case is an error (default 5)",
           "seconds an OSI stack may take to answer one step (default 5)",
           _positive_seconds),
    Option("stack-spin", "auto|MICROSECONDS",
           "how long each wait for a stack out of process's answer keeps the CPU (polling, "
           "yielding to other work) before it blocks, and so does a kit the plugin spawns "
           "waiting for the next request: 0 (default) blocks at once; 'auto' is 300 when this "
           "machine has at least two CPUs for each process running cases, else 0. Pays only "
           "where those CPUs are otherwise idle",
           "microseconds a wait for an OSI stack spins before it blocks (default 0; auto: 300 "
           "when there are two CPUs a process running cases, else 0)",
           _spin),
    Option("dt", "SECONDS|auto",
           "simulation step of world.run() calls that give no dt=: 'auto' (default) is the "
           "step the ego's driver declares (a highway-env agent or sb3:PATH@ENV: its "
           "environment's 1/simulation_frequency), else 0.1 s; a marker's dt= beats this, an "
           "explicit world.run(dt=...) beats both",
           "simulation step [s] of world.run() calls that give no dt= (auto: the driver's own "
           "step, else 0.1)",
           _dt, per_test=True),
    Option("report", "DIR",
           "write the scenario report under DIR (default avs-report; 'none' disables)",
           "directory of the scenario report (error table, summary, plots); 'none' disables",
           _text),
    Option("time-budget", "DURATION",
           "cap each scenario test's campaign per sampler (e.g. 30m, 90s, 1h); remaining "
           "cases are skipped",
           "wall-time cap per scenario test and sampler (e.g. 30m, 90s)",
           _duration("a positive duration like 30m, 90s, 1h or seconds"), per_test=True),
    Option("db", "PATH",
           "replay database of found counterexamples (default .avscenario at the rootdir; "
           "'none' disables)",
           "replay database directory (default .avscenario at the rootdir; 'none' disables)",
           _text),
    Option("shrink-budget", "N",
           "simulations allowed to minimize each failing case toward the nominal scenario "
           "(default 20; 0 disables)",
           "simulations allowed to minimize each failing case (0 disables)",
           _integer(0), per_test=True),
    Option("shrink-max", "N",
           "minimize (and store for replay) only the first N failures of each scenario test "
           "and sampler in each process (an xdist worker minimizes up to N); the rest are "
           "reported as found (default: every failure)",
           "failures per test and sampler that are minimized and stored (default: all)",
           _integer(0), per_test=True),
    Option("reference-driver", "NAME|none",
           "the reference driver each counterexample is simulated again with, to tell "
           "avoidable violations from unavoidable ones (default 'careful': UN R157's careful "
           "and competent driver; 'none' turns the check off)",
           "reference driver judging whether counterexamples were avoidable (careful, idm, "
           "autopilot or none)",
           _reference, per_test=True),
    Option("reference-max", "N",
           "judge the avoidability of only the first N counterexamples of each scenario test "
           "and sampler in each process — an xdist worker judges up to N of the cases it "
           "runs (one extra simulation each; default: all)",
           "counterexamples per test and sampler whose avoidability is judged (default: all)",
           _integer(0), per_test=True),
    Option("reference-margin", "METRIC=MARGIN[,...]",
           "the margin of the avoidability judgement per metric, in the metric's unit: the "
           "reference avoids a violation only with at least this much robustness toward the "
           "same agent (default collision=0.2 [m], others 0)",
           "avoidability margin per metric, e.g. collision=0.2,distance=0.5",
           _margins, per_test=True),
    Option("unavoidable", "keep|discard",
           "'discard': active samplers are told nothing of cases that start RSS-unsafe or of "
           "counterexamples the reference driver cannot avoid either, so they do not converge "
           "on them (the cases are still run and reported); default 'keep'",
           "keep or discard (for active samplers) cases that start RSS-unsafe or are unavoidable",
           _one_of("unavoidable", "keep", "discard"), per_test=True),
    Option("case-timeout", "SECONDS",
           "end a scenario case that runs longer than SECONDS (reported as an error with the "
           "time it ran)",
           "seconds one scenario case may run before it is ended as an error",
           _duration("a positive number of seconds (or 90s, 2m)", MAX_CASE_TIMEOUT_S), per_test=True),
    Option("executor", "NAME",
           "where scenario cases are simulated: 'inprocess' (default) or 'dask'",
           "where scenario cases are simulated: inprocess (default) or dask",
           _one_of("executor", *EXECUTORS)),
    Option("dask-address", "ADDRESS",
           "scheduler of an existing Dask cluster, e.g. tcp://host:8786 (default: start a "
           "LocalCluster with one worker per core)",
           "Dask scheduler address for --avs-executor=dask (default: a LocalCluster)", _text),
    Option("dask-workers", "N",
           "worker processes of the LocalCluster the plugin starts (default: one per core)",
           "worker processes of the LocalCluster started for --avs-executor=dask",
           _integer(1)),
    Option("dask-timeout", "SECONDS",
           "seconds to wait for the Dask scheduler before giving up (default 10)",
           "seconds to wait for the Dask scheduler", _positive_seconds),
    Option("dask-retries", "N",
           "how often a case whose worker died is resubmitted (default 2)",
           "resubmissions of a case whose Dask worker died", _integer(0)),
    Option("gifs", "N",
           "render a GIF of at most N counterexamples per test (default 3)",
           "GIFs rendered per scenario test for counterexamples (0: none)",
           _integer(0)),
    Option("case-pictures", "N",
           "draw the PNGs (time series, the first violation from above) of the minimized "
           "counterexamples and of at most N more per test and sampler (default 5; every "
           "counterexample still gets its card and its replay)",
           "counterexamples per test and sampler drawn as PNGs besides the minimized ones",
           _integer(0)),
    Option("export", "N|all|none",
           "write counterexamples as OpenSCENARIO (.xosc) + OpenDRIVE (.xodr) and an OSI "
           "trace beside their cards: the minimized ones and at most N more per test and "
           "sampler (default: every pictured one, --avs-case-pictures), 'all' or "
           "'none' (needs the [export] extra; the trace also [osi])",
           "counterexamples per test and sampler exported as OpenSCENARIO/OpenDRIVE/OSI "
           "besides the minimized ones (N, all or none)",
           _export),
    Option("accept", "CRITERIA",
           "when a scenario campaign is accepted: any (default: every counterexample rejects "
           "it), metric names (only their violations), regressions, rate:METRIC<=1%@95%; "
           "comma-separated terms combine",
           "acceptance criteria of scenario campaigns whose marker does not say (see --avs-accept)",
           _accept, per_test=True),
    Option("baseline", "PATH",
           "an earlier run's summary.json: a campaign whose violation rate of a metric is "
           "significantly higher (one-sided Fisher exact test, p < 0.05) is rejected",
           "summary.json of an earlier run to compare violation rates with", _text),
    Option("baseline-partial", "",
           "accept the --avs-baseline summary of an interrupted run (refused otherwise: its "
           "rates count only the cases that finished)",
           "accept an interrupted run's summary.json as the baseline (yes/no)", _yes_no,
           flag=True),
    Option("junit", "MODE",
           "per-case data in the --junitxml file: 'properties' (default: <properties> in each "
           "<testcase>, read by junitparser, GitLab, GitHub) or 'strict' (valid against the "
           "junit-10 schema of Jenkins' xUnit plugin: as suite properties avs.case[<id>].<name>)",
           "where per-case data goes in the JUnit file: properties (default) or strict",
           _one_of("JUnit mode", "properties", "strict")),
    Option("junit-accepted", "AS",
           "how a counterexample the acceptance criteria accept is reported to pytest and in "
           "the --junitxml file: xfail (default: <skipped type=\"pytest.xfail\">), skipped "
           "(a plain skip) or passed (a passing test case carrying the counterexample as "
           "properties avs.accepted and avs.verdict, so CI dashboards do not list it among "
           "skips)",
           "how accepted counterexamples are reported: xfail (default), skipped or passed",
           _one_of("accepted-counterexample outcome", "xfail", "skipped", "passed")),
    Option("params", "JSON",
           "run the selected scenario cases with these parameter values (a JSON object; "
           "missing parameters take their nominal value)", "", _text, ini=False),
)
_BY_KEY = {o.key: o for o in OPTIONS}

# --------------------------------------------------------------------------- values
@dataclass(frozen=True)
class Found:
    """A validated value and where it came from."""

    value: Any
    source: str  # "--avs-samples", "ini avs_samples", "@scenario(samples=...)"


def _validated(o: Option, raw: Any, source: str, error: type[Exception]) -> Found:
    try:
        return Found(o.parse(raw), source)
    except ValueError as exc:
        # parsers say "must be …" of the value, or a whole sentence ("unknown sampler …")
        text = f"{o.key} {exc}" if str(exc).startswith(("must", "list")) else str(exc)
        if error is DeclarationError:
            raise error(f"{text} (from {source})") from None
        raise error(f"{source}: {text}") from None


@dataclass(frozen=True)
class TestSettings:
    """The settings of one scenario test, after its marker had its say."""

    __test__ = False  # not a pytest test class, despite its name

    samples: int
    samplers: tuple[str, ...]
    shrink_budget: int
    shrink_max: int | None  # failures per sampler minimized and stored (None: all)
    time_budget_s: float | None
    case_timeout_s: float | None
    accept: Any  # acceptance.Criteria
    reference_driver: str | None  # None: no avoidability check
    reference_max: int | None  # counterexamples per sampler judged (None: all)
    unavoidable: str  # "keep" or "discard"
    dt: float | None = None  # [s] world.run()'s step when it gives none (None: the driver's)
    dt_from: str = ""  # where dt came from: "@scenario(dt=...)", "--avs-dt", "ini avs_dt"
    reference_margin: Mapping[str, float] | None = None  # metric -> margin (None: defaults)


@dataclass(frozen=True)
class Settings:
    """The session's settings: command line and ini, validated, each with its source."""

    seed: int
    driver: str
    report_dir: Path | None
    db_path: Path | None
    executor: str
    dask_address: str | None
    dask_workers: int | None
    dask_timeout_s: float | None
    dask_retries: int | None
    gifs: int
    case_pictures: int
    params: Mapping[str, Any] | None  # --avs-params, not yet completed against a space
    baseline: Any  # acceptance.Baseline of --avs-baseline, or None
    junit: str  # "properties" or "strict"
    junit_accepted: str  # "xfail", "skipped" or "passed"
    per_test: Mapping[str, Found]  # command line / ini values of the per-test settings
    command_line: Mapping[str, str]  # option key -> the text given on the command line
    #: --avs-export: N (the minimized counterexamples and N more per test and sampler),
    #: "all", "none"; None: not given (as the PNGs, when scenariogeneration is installed)
    export: int | str | None = None

    @property
    def pinned(self) -> bool:
        return self.params is not None

    def for_test(self, spec: ScenarioSpec) -> TestSettings:
        """This test's settings: marker > command line > ini > default (``samples`` and
        ``sampler``: command line > marker > ini > default). DeclarationError names the
        setting and the source of a bad marker value."""
        def pick(key: str) -> Any:
            o = _BY_KEY[key]
            outside = self.per_test.get(key)
            marker = None
            if key in spec.given and getattr(spec, key) is not None:
                marker = _validated(o, getattr(spec, key), f"@scenario({key}=...)", DeclarationError)
            if o.cli_first and outside is not None and outside.source.startswith("--"):
                return outside.value
            found = marker or outside
            return None if found is None else found.value

        samples = pick("samples")
        samplers = pick("sampler")
        budget = pick("shrink_budget")
        return TestSettings(
            samples=DEFAULT_SAMPLES if samples is None else samples,
            samplers=(DEFAULT_SAMPLER,) if samplers is None else samplers,
            shrink_budget=DEFAULT_SHRINK_BUDGET if budget is None else budget,
            shrink_max=pick("shrink_max"),
            time_budget_s=pick("time_budget"),
            case_timeout_s=pick("case_timeout"),
            accept=pick("accept") or _default_criteria(),
            reference_driver=self._reference_for(spec),
            reference_max=pick("reference_max"),
            unavoidable=pick("unavoidable") or "keep",
            reference_margin=pick("reference_margin"),
            **self._dt_for(spec),
        )

    def _dt_for(self, spec: ScenarioSpec) -> dict[str, Any]:
        # the value and its source: a warning about the step says where it was set
        found = self.per_test.get("dt")
        if "dt" in spec.given:
            found = _validated(_BY_KEY["dt"], spec.dt, "@scenario(dt=...)", DeclarationError)
        if found is None or found.value is None:
            return {"dt": None, "dt_from": ""}
        shown = {"@scenario(dt=...)": f"@scenario(dt={spec.dt!r})"}.get(found.source, found.source)
        return {"dt": found.value, "dt_from": shown}

    def _reference_for(self, spec: ScenarioSpec) -> str | None:
        # None is a value here ('none', or reference_driver=None: no check), so "not given"
        # is told apart by the marker's given keywords and the outside settings
        if "reference_driver" in spec.given:
            raw = spec.reference_driver
            return None if raw is None else _validated(
                _BY_KEY["reference_driver"], raw, "@scenario(reference_driver=...)", DeclarationError).value
        outside = self.per_test.get("reference_driver")
        return DEFAULT_REFERENCE if outside is None else outside.value


def _default_criteria() -> Any:
    from ..acceptance import DEFAULT

    return DEFAULT



def script_settings(seed: int = 0, *, driver: str = "autopilot", report_dir: Any = None,
                    db_path: Any = None, gifs: int = DEFAULT_GIFS,
                    case_pictures: int = DEFAULT_CASE_PICTURES, **options: Any) -> Settings:
    """The settings of a campaign run from a script: what ``pytest --avs-seed=SEED`` with no
    other option gives, with no report folder and no replay database unless named.
    ``options`` are the per-test settings by their key (``samples=5``, ``shrink_budget=0``,
    ``reference_driver="none"``), each validated as its option is (ValueError names it)."""
    per_test: dict[str, Found] = {}
    for key, raw in options.items():
        o = _BY_KEY.get(key)
        if o is None or not o.per_test:
            known = ", ".join(k for k, x in _BY_KEY.items() if x.per_test)
            raise ValueError(f"script_settings: {key!r} is not a per-test setting; use one of {known}")
        per_test[key] = _validated(o, raw, f"script_settings({key}=...)", ValueError)
    return Settings(
        seed=int(seed), driver=_driver(driver),
        report_dir=None if report_dir is None else Path(report_dir),
        db_path=None if db_path is None else Path(db_path),
        executor="inprocess", dask_address=None, dask_workers=None, dask_timeout_s=None,
        dask_retries=None, gifs=gifs, case_pictures=case_pictures, params=None, baseline=None,
        junit="properties", junit_accepted="xfail", per_test=per_test, command_line={})

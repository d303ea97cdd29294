"""Every setting of the plugin, read once, validated once, with where each value came from.

:func:`read_settings` builds the session's frozen :class:`Settings` in ``pytest_configure``
from the command line, the ini file and the defaults; a bad value from either source is a
``pytest.UsageError`` that names the option and where it came from (``--avs-dask-workers``,
``ini avs_dask_workers``), never an internal error later. A scenario test's own values
come from its ``@scenario`` marker: :meth:`Settings.for_test` gives a frozen
:class:`TestSettings`, and a bad marker value is a :class:`DeclarationError`, which
collection turns into an error naming the test.

Precedence: a marker argument beats the command line, which beats the ini file, which beats
the default — except ``--avs-samples`` and ``--avs-sampler``, which exist to override every
test at once (their ini keys are defaults for tests whose marker does not say).
"""

from __future__ import annotations

import math
import secrets
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping

import pytest

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


def _sb3_driver(found: Found, config: pytest.Config) -> str:
    """``--avs-driver sb3:...`` checked (installed, file, algorithm, environment), its path
    made absolute: relative to the working directory, or to the ini file for ``avs_driver``."""
    from ..sim.drivers import sb3

    base = (config.inipath.parent if found.source.startswith("ini") and config.inipath
            else config.invocation_params.dir)
    try:
        return sb3.check(found.value, base)
    except ValueError as exc:
        raise pytest.UsageError(f"{found.source}: {exc}") from None


def _imported_driver(found: Found | None) -> None:
    """``--avs-driver package.module:Name`` imported and checked now: a typo is one usage
    error before the run, not a traceback in every case. xdist workers import it too (they
    read the same options), which they would on their first case anyway."""
    if found is None or ":" not in str(found.value):
        return  # a built-in name: nothing to import (and the plugin's load stays light)
    from ..sim.drivers import import_driver, is_import_path

    if not is_import_path(found.value):
        return
    try:
        import_driver(found.value)
    except ValueError as exc:
        raise pytest.UsageError(f"{found.source}: {exc}") from None


def _osi_installed(found: Found) -> None:
    """``--avs-driver osi:...`` needs pyzmq and osi3: a usage error naming the extra if not."""
    import importlib.util

    for module, package in (("zmq", "pyzmq"), ("osi3", "osi-python")):
        if importlib.util.find_spec(module) is None:  # looked up, not imported: start-up stays fast
            raise pytest.UsageError(
                f"{found.source}: {found.value!r} needs {package} (pip install "
                "'pytest-avscenario[osi]')") from None


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


def add_options(parser: pytest.Parser) -> None:
    group = parser.getgroup("avscenario", "scenario-based AV testing (pytest-avscenario)")
    for o in OPTIONS:
        # argparse formats help with %: a literal % (as in "rate:METRIC<=1%@95%") is doubled
        if o.flag:
            group.addoption(f"--avs-{o.name}", dest=o.dest, action="store_const", const="yes",
                            default=None, help=o.help.replace("%", "%%"))
        else:
            group.addoption(f"--avs-{o.name}", dest=o.dest, metavar=o.metavar, default=None,
                            help=o.help.replace("%", "%%"))
        if o.ini:
            parser.addini(o.dest, o.ini_help, type="string", default=None)


# --------------------------------------------------------------------------- values
@dataclass(frozen=True)
class Found:
    """A validated value and where it came from."""

    value: Any
    source: str  # "--avs-samples", "ini avs_samples", "@scenario(samples=...)"


def _raw(config: pytest.Config, o: Option) -> tuple[Any, str] | None:
    """The command line's value of ``o``, else the ini file's, else None."""
    value = config.getoption(o.dest)
    if value not in (None, ""):
        return value, f"--avs-{o.name}"
    if o.ini:
        value = config.getini(o.dest)
        if value not in (None, ""):
            return value, f"ini {o.dest}"
    return None


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


def read_settings(config: pytest.Config) -> Settings:
    """The session's :class:`Settings`; ``pytest.UsageError`` names a bad option and its source."""
    found: dict[str, Found] = {}
    for o in OPTIONS:
        raw = _raw(config, o)
        if raw is not None and o.key != "seed":
            found[o.key] = _validated(o, raw[0], raw[1], pytest.UsageError)

    def value(key: str, default: Any = None) -> Any:
        f = found.get(key)
        return default if f is None else f.value

    executor = value("executor", "inprocess")
    address = value("dask_address")
    if executor == "dask" and address is None and getattr(config.option, "numprocesses", None) \
            and not hasattr(config, "workerinput"):
        raise pytest.UsageError(
            "--avs-executor=dask with pytest-xdist (-n) needs --avs-dask-address: otherwise "
            "every xdist worker would start a Dask cluster of its own")
    report = value("report", "avs-report")
    db = value("db")
    driver = value("driver", "autopilot")
    if driver.startswith("sb3:"):
        driver = _sb3_driver(found["driver"], config)
    if driver.startswith(("osi:", "osi+spawn:")):
        _osi_installed(found["driver"])
    if driver.startswith("osi:") and (executor == "dask" or (
            getattr(config.option, "numprocesses", None) and not hasattr(config, "workerinput"))):
        # one REP socket answers one case at a time: two processes' cases would interleave
        # in the stack's state, and it could not tell them apart
        raise pytest.UsageError(
            f"{found['driver'].source}: {driver!r} is one stack for one process, but "
            f"{'--avs-executor=dask' if executor == 'dask' else 'pytest-xdist (-n)'} runs cases "
            "in several: use 'osi+spawn:COMMAND' (a stack per process) or run them in one")
    if "stack_timeout" in found:
        from ..stack.client import configure

        configure(timeout_s=value("stack_timeout"))
    _imported_driver(found.get("driver"))
    return Settings(
        seed=_session_seed(config),
        driver=driver,
        report_dir=None if report.lower() == "none" else config.invocation_params.dir / report,
        db_path=(None if db is not None and db.lower() == "none" else
                 config.rootpath / ".avscenario" if db is None else config.invocation_params.dir / db),
        executor=executor,
        dask_address=address,
        dask_workers=value("dask_workers"),
        dask_timeout_s=value("dask_timeout"),
        dask_retries=value("dask_retries"),
        gifs=value("gifs", DEFAULT_GIFS),
        case_pictures=value("case_pictures", DEFAULT_CASE_PICTURES),
        params=_pinned_params(found.get("params")),
        baseline=_baseline(found.get("baseline"), config, value("baseline_partial", False)),
        junit=value("junit", "properties"),
        junit_accepted=value("junit_accepted", "xfail"),
        per_test={k: f for k, f in found.items() if _BY_KEY[k].per_test},
        command_line={k: str(config.getoption(o.dest)) for k, o in _BY_KEY.items()
                      if config.getoption(o.dest) not in (None, "")},
    )


def _default_criteria() -> Any:
    from ..acceptance import DEFAULT

    return DEFAULT


def _baseline(found: Found | None, config: pytest.Config, partial_ok: bool) -> Any:
    if found is None:
        return None
    from ..acceptance import load_baseline

    try:
        return load_baseline(config.invocation_params.dir / found.value, partial_ok=partial_ok)
    except ValueError as exc:
        raise pytest.UsageError(f"{found.source}: {exc}") from None


def _pinned_params(found: Found | None) -> Mapping[str, Any] | None:
    if found is None:
        return None
    from ..inputs import InputError, parse_json

    # the same bounded reader as the baseline's: 5,000 digits or 40,000 brackets are an
    # answer about the option, not a ValueError or RecursionError from inside json
    try:
        given = parse_json(found.value)
    except InputError as exc:
        raise pytest.UsageError(f"--avs-params: the value {exc}") from None
    if not isinstance(given, dict):
        raise pytest.UsageError("--avs-params must be a JSON object of parameter values")
    return given


def _session_seed(config: pytest.Config) -> int:
    workerinput = getattr(config, "workerinput", None)
    if workerinput is not None and "avs_seed" in workerinput:
        return int(workerinput["avs_seed"])  # the controller's seed: identical collections
    raw_found = _raw(config, _BY_KEY["seed"])
    cache = getattr(config, "cache", None)  # absent with -p no:cacheprovider
    if raw_found is None:
        seed = secrets.randbelow(2**31)
    elif str(raw_found[0]).strip() == "last":
        cached = cache.get("avscenario/seed", None) if cache is not None else None
        if cached is None:
            raise pytest.UsageError("--avs-seed=last: no previous run's seed is cached yet")
        seed = int(cached)
    else:
        raw, source = raw_found
        try:
            seed = int(str(raw).strip())
        except ValueError:
            raise pytest.UsageError(
                f"--avs-seed / avs_seed must be an integer or 'last', got {_show(raw)} (from {source})"
            ) from None
        if seed < 0:
            raise pytest.UsageError(f"--avs-seed / avs_seed must be >= 0, got {seed} (from {source})")
    if cache is not None and workerinput is None:
        cache.set("avscenario/seed", seed)
    return seed

"""The pytest plugin: options, the ``scenario`` marker, expansion into cases, judging.

Loaded through the ``pytest11`` entry point ``avscenario`` (``-p no:avscenario`` disables it).
Loading it imports only numpy and the plugin's light modules: highway-env, scipy, matplotlib
and the rest are imported when a scenario test is collected or run.

A test marked with ``@scenario`` becomes one item per concrete case (``test_x[halton-007]``).
Passive samplers fix every case at collection, identically on every machine for one seed;
active samplers are asked for item k's parameters when it runs and told its robustness when
it ends. After the body, the declared monitors judge the recorded trajectory; a violation
fails the item with every metric, the parameters and a command that re-runs just that case.
"""

from __future__ import annotations

import json
import math
import os
import secrets
import time
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import pytest

from .case import RESERVED, Case, stable_seed
from .markers.spec import ScenarioSpec
from .runner import CaseOutcome
from .space import FeatureSpace, SpaceError

DEFAULT_SAMPLES = 20
DEFAULT_SAMPLER = "halton"
MAX_SAMPLES = 100_000

plans_key = pytest.StashKey[dict[str, "ScenarioPlan"]]()
seed_key = pytest.StashKey[int]()
row_key = pytest.StashKey[dict]()
db_key = pytest.StashKey[Any]()
shrink_rows_key = pytest.StashKey[list]()
executor_key = pytest.StashKey[Any]()
pictures_key = pytest.StashKey[dict]()
session_key = pytest.StashKey["RunState"]()


# --------------------------------------------------------------------------- options
def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("avscenario", "scenario-based AV testing (pytest-avscenario)")

    def add(name: str, ini_help: str, ini_type: str = "string", **kw: Any) -> None:
        group.addoption(f"--avs-{name}", dest=f"avs_{name.replace('-', '_')}", **kw)
        parser.addini(f"avs_{name.replace('-', '_')}", ini_help, type=ini_type, default=None)

    add("seed", "seed of the run (an integer); default: a fresh one each run",
        metavar="N|last", default=None,
        help="seed for sampling and simulation; 'last' reuses the previous run's seed "
             "(default: a fresh seed, printed in the header)")
    add("samples", "cases per scenario test when the marker does not say",
        metavar="N", default=None, type=int,
        help="override the number of cases of every scenario test (e.g. 5 for a smoke run)")
    add("sampler", "sampler for scenario tests whose marker does not name one",
        metavar="NAME", default=None,
        help="override the sampler of every scenario test (halton, random, mab, ce, sa, bo)")
    add("driver", "built-in driver of the ego (autopilot or idm) when avs_driver is not overridden",
        metavar="NAME", default=None,
        help="built-in driver of the ego: 'autopilot' (default) or 'idm'; a conftest "
             "`avs_driver` fixture overrides this")
    add("report", "directory of the scenario report (error table, summary, plots); 'none' disables",
        metavar="DIR", default=None,
        help="write the scenario report under DIR (default avs-report; 'none' disables)")
    add("time-budget", "wall-time cap per scenario test and sampler (e.g. 30m, 90s)",
        metavar="DURATION", default=None,
        help="cap each scenario test's campaign per sampler (e.g. 30m, 90s, 1h); remaining "
             "cases are skipped")
    add("db", "replay database directory (default .avscenario at the rootdir; 'none' disables)",
        metavar="PATH", default=None,
        help="replay database of found counterexamples (default .avscenario at the rootdir; "
             "'none' disables)")
    add("shrink-budget", "simulations allowed to minimize each failing case (0 disables)",
        metavar="N", default=None, type=int,
        help="simulations allowed to minimize each failing case toward the nominal scenario "
             "(default 20; 0 disables)")
    add("executor", "where scenario cases are simulated: inprocess (default) or dask",
        metavar="NAME", default=None,
        help="where scenario cases are simulated: 'inprocess' (default) or 'dask'")
    add("dask-address", "Dask scheduler address for --avs-executor=dask (default: a LocalCluster)",
        metavar="ADDRESS", default=None,
        help="scheduler of an existing Dask cluster, e.g. tcp://host:8786 (default: start a "
             "LocalCluster with one worker per core)")
    add("gifs", "GIFs rendered per scenario test for minimized counterexamples (0: none)",
        metavar="N", default=None, type=int,
        help="render a GIF of at most N minimized counterexamples per test (default 3; every "
             "one gets a PNG of its worst moment)")
    add("case-timeout", "seconds one scenario case may run before it is ended as an error",
        metavar="SECONDS", default=None,
        help="end a scenario case that runs longer than SECONDS (reported as an error with "
             "the time it ran)")
    group.addoption(
        "--avs-params", dest="avs_params", metavar="JSON", default=None,
        help="run the selected scenario cases with these parameter values "
             "(a JSON object; missing parameters take their nominal value)",
    )


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "scenario(**parameters, samples=N, sampler='halton', seed=None, monitors=[...]): "
        "an abstract driving scenario expanded into N concrete cases (pytest-avscenario). "
        "Use the @scenario decorator from pytest_avscenario rather than the bare mark.",
    )
    config.stash[plans_key] = {}
    config.stash[seed_key] = _session_seed(config)
    _terminate_like_ctrl_c()
    config.stash[db_key] = _open_db(config)
    config.stash[session_key] = state = RunState(config)
    config.pluginmanager.register(state, "avscenario-run")
    if config.pluginmanager.hasplugin("xdist"):
        config.pluginmanager.register(_XdistHooks(), "avscenario-xdist")


def _session_seed(config: pytest.Config) -> int:
    workerinput = getattr(config, "workerinput", None)
    if workerinput is not None and "avs_seed" in workerinput:
        return int(workerinput["avs_seed"])  # the controller's seed: identical collections
    raw = config.getoption("avs_seed")
    if raw is None:
        raw = config.getini("avs_seed")
    if raw in (None, ""):
        seed = secrets.randbelow(2**31)
    elif str(raw).strip() == "last":
        cache = getattr(config, "cache", None)
        cached = cache.get("avscenario/seed", None) if cache is not None else None
        if cached is None:
            raise pytest.UsageError("--avs-seed=last: no previous run's seed is cached yet")
        seed = int(cached)
    else:
        try:
            seed = int(str(raw).strip())
        except ValueError:
            raise pytest.UsageError(
                f"--avs-seed / avs_seed must be an integer or 'last', got {raw!r}"
            ) from None
        if seed < 0:
            raise pytest.UsageError(f"--avs-seed / avs_seed must be >= 0, got {seed}")
    cache = getattr(config, "cache", None)  # absent with -p no:cacheprovider
    if cache is not None and workerinput is None:
        cache.set("avscenario/seed", seed)
    return seed


def _terminate_like_ctrl_c() -> None:
    """Let SIGTERM end a run the way Ctrl-C does: pytest then still finishes the session, so
    the error table is closed and the partial summary and index are written.

    Only when nobody installed a handler of their own, and only in the main thread."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return
    if signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL:
        return

    def terminate(signum: int, frame: Any) -> None:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)  # a second SIGTERM kills at once
        raise KeyboardInterrupt("SIGTERM")

    signal.signal(signal.SIGTERM, terminate)


def _open_db(config: pytest.Config) -> Any:
    """The replay database, or None. Workers get the controller's snapshot (same items)."""
    raw = config.getoption("avs_db") or config.getini("avs_db")
    if raw is not None and str(raw).lower() == "none":
        return None
    from .db import DatabaseError, ReplayDB

    path = config.rootpath / ".avscenario" if not raw else config.invocation_params.dir / str(raw)
    workerinput = getattr(config, "workerinput", None)
    try:
        if workerinput is not None and "avs_db" in workerinput:
            return ReplayDB.from_snapshot(path, workerinput["avs_db"])
        db = ReplayDB(path)
        db.entries()  # read once now, so unreadable files are reported once, before collection
    except DatabaseError as exc:
        raise pytest.UsageError(f"avscenario replay database (--avs-db): {exc}") from None
    for message in db.warnings:
        config.issue_config_time_warning(pytest.PytestWarning(f"avscenario replay database: {message}"), 2)
    return db


class _XdistHooks:
    """Registered only when pytest-xdist is installed: ship seed and database to the workers."""

    def pytest_configure_node(self, node: Any) -> None:
        node.workerinput["avs_seed"] = node.config.stash[seed_key]
        db = node.config.stash[db_key]
        if db is not None:
            node.workerinput["avs_db"] = db.snapshot()


def pytest_report_header(config: pytest.Config) -> str:
    seed = config.stash[seed_key]
    return f"avscenario: seed={seed} (replay with --avs-seed={seed})"


# --------------------------------------------------------------------------- expansion
@dataclass
class CaseSlot:
    """What collection fixes about one item: its index, origin and (if passive) its values."""

    sampler: str
    index: int
    seed: int
    origin: str = "sampled"
    params: dict[str, Any] | None = None  # None: asked from an active sampler at run time

    @property
    def id(self) -> str:
        return f"{self.sampler}-{self.index:03d}" if self.origin == "sampled" else f"{self.origin}-{self.index}"


@dataclass
class ScenarioPlan:
    """A scenario test's resolved declaration (one per test function)."""

    test: str
    space: FeatureSpace
    samplers: list[str]
    samples: int
    seed: int
    monitor_set: Any
    sampler_options: dict[str, Any]
    time_budget_s: float | None = None
    shrink_budget: int = 20
    replays: dict[int, Any] = field(default_factory=dict)  # replay index -> db entry
    gifs: int = 0  # GIFs rendered so far for this test
    case_timeout_s: float | None = None
    active: dict[str, Any] = field(default_factory=dict)  # sampler name -> live sampler
    started: dict[str, float] = field(default_factory=dict)  # sampler -> campaign start
    ran: dict[str, int] = field(default_factory=dict)  # sampler -> cases run

    @property
    def metrics(self) -> tuple[str, ...]:
        return tuple(self.monitor_set.names) if self.monitor_set is not None else ()

    def info(self) -> dict[str, Any]:
        """What the controller needs to summarize this test (plain JSON)."""
        return {"metrics": list(self.metrics), "space": self.space.describe()}

    def make_sampler(self, name: str) -> Any:
        from . import samplers

        opts = dict(self.sampler_options)
        if samplers.base.is_active(name) and self.monitor_set is not None:
            opts.setdefault("metrics", list(self.monitor_set.names))
            if self.monitor_set.priority_edges:
                opts.setdefault("priority", [list(e) for e in self.monitor_set.priority_edges])
        return samplers.make(name, self.space, seed=stable_seed(self.seed, name), **opts)


class DeclarationError(Exception):
    pass


def _fail_collection(test: str, message: str) -> None:
    raise pytest.Collector.CollectError(f"{test}: {message}")


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    marker = metafunc.definition.get_closest_marker("scenario")
    if marker is None:
        return
    test = metafunc.definition.nodeid
    try:
        plan, slots = _plan(metafunc, marker)
    except (DeclarationError, SpaceError, ValueError) as exc:
        _fail_collection(test, str(exc))
    metafunc.config.stash[plans_key][test] = plan
    metafunc.parametrize("case", slots, ids=[s.id for s in slots], indirect=True)


def _plan(metafunc: pytest.Metafunc, marker: pytest.Mark) -> tuple[ScenarioPlan, list[CaseSlot]]:
    config = metafunc.config
    test = metafunc.definition.nodeid
    if len(marker.args) != 1 or not isinstance(marker.args[0], ScenarioSpec) or marker.kwargs:
        raise DeclarationError(
            "use the @scenario(...) decorator from pytest_avscenario, not a bare "
            "@pytest.mark.scenario"
        )
    spec: ScenarioSpec = marker.args[0]
    if "case" not in metafunc.fixturenames:
        raise DeclarationError(
            "a @scenario test must request the `case` fixture (add `case` to its arguments) "
            "to read the concrete parameter values"
        )

    # parameters: their distributions, and names that would shadow something
    if not spec.parameters:
        raise DeclarationError("@scenario declares no parameters; give at least one, e.g. gap=Uniform(10, 40)")
    fm = metafunc.definition.session._fixturemanager
    for name in spec.parameters:
        if name in RESERVED:
            raise DeclarationError(
                f"parameter {name!r} clashes with the case attribute of the same name; rename it"
            )
        if fm.getfixturedefs(name, metafunc.definition):
            raise DeclarationError(
                f"parameter {name!r} clashes with the fixture {name!r}; rename the parameter "
                "(read values as case.<name>, fixtures stay available as arguments)"
            )
    space = FeatureSpace(spec.parameters)
    if _executor_name(config) != "inprocess":
        others = sorted(set(metafunc.fixturenames) - {"case", "world", "avs_driver", "request"}
                        - set(_autouse_names(metafunc)))
        if others:
            raise DeclarationError(
                f"under --avs-executor={_executor_name(config)} a scenario test gets only "
                f"`case`, `world` and `avs_driver` on the remote workers; it also requests "
                f"{', '.join(others)} — run it with the in-process executor or drop them"
            )

    samples = _setting_int(config, spec, "samples", DEFAULT_SAMPLES, minimum=1)
    if samples > MAX_SAMPLES:
        raise DeclarationError(
            f"samples must be at most {MAX_SAMPLES} per test (got {samples}): every case is a "
            "pytest item; for a long campaign give time_budget= (e.g. '30m') with a large count"
        )
    sampler_names = _samplers(config, spec)

    if spec.seed is not None:
        if isinstance(spec.seed, bool) or not isinstance(spec.seed, int) or spec.seed < 0:
            raise DeclarationError(f"seed must be a non-negative int, got {spec.seed!r}")
        seed = stable_seed("marker", spec.seed)
    else:
        seed = stable_seed(config.stash[seed_key], test)

    monitor_set = None
    if spec.monitors:
        from .monitors import MonitorSet

        try:
            monitor_set = MonitorSet(list(spec.monitors), priority=spec.priority)
        except ValueError as exc:
            raise DeclarationError(f"monitors: {exc}") from None
    elif spec.priority:
        raise DeclarationError("priority= is given but no monitors= to order")

    opts = spec.sampler_options or {}
    if not isinstance(opts, dict):
        raise DeclarationError(f"sampler_options must be a dict, got {opts!r}")
    plan = ScenarioPlan(test=test, space=space, samplers=sampler_names, samples=samples,
                        seed=seed, monitor_set=monitor_set, sampler_options=dict(opts),
                        time_budget_s=_time_budget(config, spec),
                        shrink_budget=_shrink_budget(config, spec),
                        case_timeout_s=_case_timeout(config, spec))

    pinned = _pinned_params(config, space)
    slots: list[CaseSlot] = []
    for k, pin in enumerate(getattr(metafunc.function, "_avs_examples", ())):
        params = space.complete(pin)
        try:
            space.validate(params)
        except SpaceError as exc:
            raise DeclarationError(f"@example #{k} ({_call_text('example', pin)}): {exc}") from None
        slots.append(CaseSlot("example", k, stable_seed(seed, "example", k), "example", params))
    db = config.stash[db_key]
    if db is not None and pinned is None:
        from .db import space_changes

        for entry in db.entries(test):
            if entry.fingerprint != space.fingerprint():
                changed = ", ".join(repr(n) for n in space_changes(entry.space, space)) or "its space"
                warnings.warn(pytest.PytestWarning(
                    f"{test}: stored counterexample {entry.path.name} skipped: parameter "
                    f"{changed} changed since it was found"))
                continue
            k = len(plan.replays)
            plan.replays[k] = entry
            slots.append(CaseSlot("replay", k, entry.seed, "replay", space.complete(entry.params)))
    from .samplers import SamplerError

    for name in sampler_names:
        try:
            sampler = plan.make_sampler(name)
        except SamplerError as exc:
            raise DeclarationError(str(exc)) from None
        if pinned is not None:
            values: list[dict[str, Any] | None] = [dict(pinned)] * samples
        elif sampler.active:
            values = [None] * samples
        else:
            pts = sampler.sample_unit(samples)
            values = [space.from_unit(p) for p in pts]
        for k, params in enumerate(values):
            slots.append(CaseSlot(name, k, stable_seed(seed, name, k),
                                  origin="sampled", params=params))
    return plan, slots


def _shrink_budget(config: pytest.Config, spec: ScenarioSpec) -> int:
    if "shrink_budget" in spec.given and spec.shrink_budget is not None:
        value, source = spec.shrink_budget, "@scenario(shrink_budget=...)"
    elif config.getoption("avs_shrink_budget") is not None:
        value, source = config.getoption("avs_shrink_budget"), "--avs-shrink-budget"
    elif config.getini("avs_shrink_budget") not in (None, ""):
        value, source = config.getini("avs_shrink_budget"), "ini avs_shrink_budget"
    else:
        return 20
    try:
        if isinstance(value, bool):
            raise ValueError
        value = int(value)
    except (TypeError, ValueError):
        raise DeclarationError(f"shrink_budget must be an integer, got {value!r} (from {source})") from None
    if value < 0:
        raise DeclarationError(f"shrink_budget must be >= 0, got {value} (from {source})")
    return value


def _call_text(name: str, params: Mapping[str, Any]) -> str:
    return f"@{name}(" + ", ".join(f"{k}={v!r}" for k, v in params.items()) + ")"


def _autouse_names(metafunc: pytest.Metafunc) -> list[str]:
    fm = metafunc.definition.session._fixturemanager
    return list(fm._getautousenames(metafunc.definition))


def _setting_int(config: pytest.Config, spec: ScenarioSpec, key: str, default: int,
                 minimum: int) -> int:
    cli = config.getoption(f"avs_{key}")
    if cli is not None:
        value, source = cli, f"--avs-{key}"
    elif key in spec.given:
        value, source = getattr(spec, key), f"@scenario({key}=...)"
    elif config.getini(f"avs_{key}") not in (None, ""):
        value, source = config.getini(f"avs_{key}"), f"ini avs_{key}"
    else:
        return default
    try:
        if isinstance(value, bool) or (isinstance(value, float) and not value.is_integer()):
            raise ValueError
        value = int(value)
    except (TypeError, ValueError):
        raise DeclarationError(f"{key} must be an integer, got {value!r} (from {source})") from None
    if value < minimum:
        raise DeclarationError(f"{key} must be >= {minimum}, got {value} (from {source})")
    return value


def parse_duration(value: Any) -> float:
    """Seconds from ``90``, ``"90s"``, ``"30m"``, ``"1.5h"``; ValueError otherwise."""
    if isinstance(value, bool):
        raise ValueError(value)
    if isinstance(value, (int, float)):
        seconds = float(value)
    else:
        text = str(value).strip().lower()
        unit = {"s": 1.0, "m": 60.0, "h": 3600.0}.get(text[-1:], None)
        seconds = float(text[:-1]) * unit if unit else float(text)
    if not math.isfinite(seconds) or seconds <= 0:
        raise ValueError(value)
    return seconds


def _case_timeout(config: pytest.Config, spec: ScenarioSpec) -> float | None:
    if "case_timeout" in spec.given and spec.case_timeout is not None:
        raw, source = spec.case_timeout, "@scenario(case_timeout=...)"
    elif config.getoption("avs_case_timeout"):
        raw, source = config.getoption("avs_case_timeout"), "--avs-case-timeout"
    elif config.getini("avs_case_timeout"):
        raw, source = config.getini("avs_case_timeout"), "ini avs_case_timeout"
    else:
        return None
    try:
        return parse_duration(raw)
    except (ValueError, TypeError):
        raise DeclarationError(
            f"case_timeout must be a positive number of seconds (or 90s, 2m), got {raw!r} "
            f"(from {source})"
        ) from None


def _time_budget(config: pytest.Config, spec: ScenarioSpec) -> float | None:
    if "time_budget" in spec.given and spec.time_budget is not None:
        raw, source = spec.time_budget, "@scenario(time_budget=...)"
    elif config.getoption("avs_time_budget"):
        raw, source = config.getoption("avs_time_budget"), "--avs-time-budget"
    elif config.getini("avs_time_budget"):
        raw, source = config.getini("avs_time_budget"), "ini avs_time_budget"
    else:
        return None
    try:
        return parse_duration(raw)
    except (ValueError, TypeError):
        raise DeclarationError(
            f"time_budget must be a positive duration like 30m, 90s, 1h or seconds, got {raw!r} "
            f"(from {source})"
        ) from None


def _samplers(config: pytest.Config, spec: ScenarioSpec) -> list[str]:
    from .samplers import base

    cli = config.getoption("avs_sampler")
    if cli:
        raw: Any = [s.strip() for s in cli.split(",") if s.strip()]
        source = "--avs-sampler"
    elif "sampler" in spec.given:
        raw, source = spec.sampler, "@scenario(sampler=...)"
    elif config.getini("avs_sampler"):
        raw, source = config.getini("avs_sampler"), "ini avs_sampler"
    else:
        raw, source = DEFAULT_SAMPLER, "default"
    names = [raw] if isinstance(raw, str) else list(raw) if isinstance(raw, (list, tuple)) else None
    if not names or not all(isinstance(n, str) for n in names):
        raise DeclarationError(f"sampler must be a name or a list of names, got {raw!r} (from {source})")
    for n in names:
        if n not in base.available():
            raise DeclarationError(
                f"unknown sampler {n!r} (from {source}); available: {', '.join(base.available())}"
            )
    if len(set(names)) != len(names):
        raise DeclarationError(f"sampler list names a sampler twice: {names!r}")
    return names


def _pinned_params(config: pytest.Config, space: FeatureSpace) -> dict[str, Any] | None:
    raw = config.getoption("avs_params")
    if not raw:
        return None
    try:
        given = json.loads(raw)
    except json.JSONDecodeError as exc:
        raise DeclarationError(f"--avs-params is not valid JSON: {exc}") from None
    if not isinstance(given, dict):
        raise DeclarationError("--avs-params must be a JSON object of parameter values")
    params = {**space.nominal(), **given}
    space.validate(params)
    return params


# --------------------------------------------------------------------------- fixtures
@pytest.fixture
def case(request: pytest.FixtureRequest) -> Case:
    """The concrete case of a ``@scenario`` test: ``case.<parameter>``, ``case.seed``, ``case.rng``."""
    slot: CaseSlot | None = getattr(request, "param", None)
    if not isinstance(slot, CaseSlot):
        raise pytest.UsageError(
            f"{request.node.nodeid}: the `case` fixture is only available to tests decorated "
            "with @scenario(...)"
        )
    plan = _plan_of(request.node)
    if plan.time_budget_s is not None:
        start = plan.started.setdefault(slot.sampler, time.monotonic())
        if time.monotonic() - start > plan.time_budget_s:
            pytest.skip(
                f"time budget of {plan.time_budget_s:g} s for {slot.sampler} spent after "
                f"{plan.ran.get(slot.sampler, 0)} cases"
            )
    params = slot.params
    if params is None:
        params = _active_sampler(plan, slot.sampler).ask()
    return Case(params, index=slot.index, seed=slot.seed, sampler=slot.sampler,
                origin=slot.origin if request.config.getoption("avs_params") is None else "pinned",
                test=request.node.nodeid)


@pytest.fixture
def avs_driver(request: pytest.FixtureRequest) -> Any:
    """The AV under test driving the ego: override this fixture in conftest.py with your stack.

    Return a callable ``policy(observation) -> (acceleration, steering)``, an object with
    ``act(observation)`` or ``predict(observation)``, or a built-in name (``"autopilot"``,
    ``"idm"``). The default is ``--avs-driver`` / ini ``avs_driver`` or ``"autopilot"``.
    """
    return _default_driver(request.config)


@pytest.fixture
def world(request: pytest.FixtureRequest, case: Case, avs_driver: Any) -> Any:
    """A fresh simulated world for this case, seeded from it, with ``avs_driver`` as the ego's."""
    return _make_world(case, avs_driver, request.node.nodeid)


def _make_world(case: Case, driver: Any, name: str) -> Any:
    from .sim import World

    return World(seed=case.seed, rng=case.rng, driver=driver, name=name)


def _plan_of(item: pytest.Item) -> ScenarioPlan:
    return item.config.stash[plans_key][_function_id(item)]


def _function_id(item: pytest.Item) -> str:
    nodeid = item.nodeid
    return nodeid[: nodeid.index("[")] if "[" in nodeid else nodeid


def _active_sampler(plan: ScenarioPlan, name: str) -> Any:
    if name not in plan.active:
        plan.active[name] = plan.make_sampler(name)
    return plan.active[name]


# --------------------------------------------------------------------------- running
@dataclass
class ShrinkReport:
    """What minimizing one failing case gave (for the message, the rows and the database)."""

    flaky: bool
    sims: int
    budget: int
    minimized: dict[str, Any] | None = None
    outcome: CaseOutcome | None = None  # the minimized case's outcome
    exhausted: bool = False
    rows: list[dict[str, Any]] = field(default_factory=list)


@pytest.hookimpl(tryfirst=True)
def pytest_pyfunc_call(pyfuncitem: pytest.Function) -> bool | None:
    if pyfuncitem.get_closest_marker("scenario") is None or "case" not in pyfuncitem.funcargs:
        return None
    item = pyfuncitem
    plan = _plan_of(item)
    case_obj: Case = item.funcargs["case"]
    slot: CaseSlot = item.callspec.params["case"]
    outcome = _executor(item.config).run(_job(item, plan, case_obj, fresh_world=False))
    if slot.params is None and case_obj.origin == "sampled":
        _active_sampler(plan, slot.sampler).tell(
            outcome.params,
            None if outcome.verdict == "error" else (dict(outcome.rho) or _body_rho(outcome)),
        )
    plan.ran[slot.sampler] = plan.ran.get(slot.sampler, 0) + 1

    shrink = None
    if outcome.failed and case_obj.origin == "sampled" and plan.shrink_budget > 0:
        shrink = _shrink(item, plan, case_obj, outcome)
    row = _row(item, case_obj, outcome)
    if shrink is not None and shrink.minimized is not None:
        row["minimized"] = shrink.minimized
        row["shrink_sims"] = shrink.sims
    item.stash[row_key] = row
    item.stash[shrink_rows_key] = shrink.rows if shrink is not None else []
    _record_properties(item, row, shrink)
    note = _update_db(item, plan, slot, case_obj, outcome, shrink)
    if outcome.failed:
        item.stash[pictures_key] = _render_case(item, plan, outcome, shrink)

    if outcome.verdict == "pass":
        return True
    message = failure_message(item, case_obj, outcome, shrink, note)
    if outcome.exc is not None and not isinstance(outcome.exc, _monitor_error()):
        # let pytest show the body's own traceback, with our summary as a report section
        item.add_report_section("call", "avscenario", message)
        raise outcome.exc
    pytest.fail(message, pytrace=False)


def _monitor_error() -> type:
    from .monitors import MonitorError

    return MonitorError


def _shrink(item: pytest.Function, plan: ScenarioPlan, case: Case, outcome: CaseOutcome) -> ShrinkReport:
    """Replay the failure once (flakiness), then minimize it toward the nominal scenario."""
    from .shrink import minimize

    report = ShrinkReport(flaky=False, sims=0, budget=plan.shrink_budget)
    outcomes: dict[str, CaseOutcome] = {}
    executor = _executor(item.config)

    progress = _progress_writer(item.config)

    def simulate(params: dict[str, Any]) -> CaseOutcome:
        candidate = Case(params, index=case.index, seed=case.seed, sampler=case.sampler,
                         origin="shrink", test=item.nodeid)
        result = executor.run(_job(item, plan, candidate, fresh_world=True))
        report.rows.append(_row(item, candidate, result))
        done = len(report.rows) - 1  # the first row is the flakiness replay
        if progress is not None and done > 0 and (done % progress.every == 0 or done == plan.shrink_budget):
            progress(f"shrinking {item.nodeid}: {done}/{plan.shrink_budget} simulations")
        return result

    signature = outcome.signature
    again = simulate(dict(case.params))
    if not (again.failed and again.signature == signature):
        report.flaky = True
        return report

    def still_fails(params: dict[str, Any]) -> bool:
        result = simulate(dict(params))
        outcomes[json.dumps(params, sort_keys=True, default=repr)] = result
        return result.failed and result.signature == signature

    result = minimize(plan.space, dict(case.params), still_fails, budget=plan.shrink_budget,
                      seed=case.seed % (2**32))
    report.sims = result.sims
    report.exhausted = result.exhausted
    report.minimized = dict(result.minimized)
    report.outcome = outcomes.get(json.dumps(result.minimized, sort_keys=True, default=repr), outcome)
    return report


def _progress_writer(config: pytest.Config) -> Any:
    """A function printing a live line in verbose runs (None when quiet or on an xdist worker)."""
    if config.get_verbosity() < 1 or hasattr(config, "workerinput"):
        return None
    reporter = config.pluginmanager.get_plugin("terminalreporter")
    capman = config.pluginmanager.get_plugin("capturemanager")
    if reporter is None or capman is None:
        return None

    def write(text: str) -> None:
        with capman.global_and_fixture_disabled():
            reporter.write_line(f"  avscenario: {text}")

    write.every = 1 if config.get_verbosity() >= 2 else 5  # type: ignore[attr-defined]
    return write


def _render_case(item: pytest.Function, plan: ScenarioPlan, outcome: CaseOutcome,
                 shrink: ShrinkReport | None) -> dict[str, str]:
    """PNG of the worst moment (and, within the per-test cap, a GIF) of a failing case.

    Drawn from the minimized case when there is one (that is the one an engineer studies),
    else from the case as found. Only in-process outcomes keep their world; nothing to draw
    for tests that return a Trajectory of their own.
    """
    state = item.config.stash[session_key]
    shown = shrink.outcome if shrink is not None and shrink.outcome is not None else outcome
    world = shown.world
    if state.directory is None or world is None or getattr(world, "trajectory", None) is None:
        return {}
    from .report.table import file_slug

    folder = state.directory / "cases"
    folder.mkdir(parents=True, exist_ok=True)
    base = folder / f"{file_slug(item.nodeid)}"
    pictures: dict[str, str] = {}
    traj = world.trajectory
    step = traj.n_steps - 1
    worst = min(shown.results.values(), key=lambda r: r.rho, default=None)
    if worst is not None and worst.t is not None:
        import numpy as np

        step = int(np.argmin(np.abs(traj.t - worst.t)))
    what = "minimized" if shown is not outcome else "as found"
    try:
        pictures[f"{item.name}: worst moment ({what})"] = world.render_png(f"{base}.png", step=step)
        cap = item.config.getoption("avs_gifs")
        cap = 3 if cap is None else cap
        done = plan.gifs
        if done < cap:
            pictures[f"{item.name}: the run ({what})"] = world.render_gif(f"{base}.gif", every=2)
            plan.gifs = done + 1
    except Exception as exc:  # a picture is a convenience: never fail the case over it
        warnings.warn(pytest.PytestWarning(f"{item.nodeid}: could not render the case: {exc}"))
    return pictures


def _executor_name(config: pytest.Config) -> str:
    return config.getoption("avs_executor") or config.getini("avs_executor") or "inprocess"


def _default_driver(config: pytest.Config) -> str:
    return config.getoption("avs_driver") or config.getini("avs_driver") or "autopilot"


def _executor(config: pytest.Config) -> Any:
    """The session's executor, made on first use (a Dask cluster only when a case runs)."""
    executor = config.stash.get(executor_key, None)
    if executor is None:
        from .executors import make_executor

        name = _executor_name(config)
        options = {}
        if name == "dask":
            options["address"] = config.getoption("avs_dask_address") or config.getini("avs_dask_address") or None
        try:
            executor = make_executor(name, **options)
        except ValueError as exc:
            raise pytest.UsageError(str(exc)) from None
        config.stash[executor_key] = executor
    return executor


def _job(item: pytest.Function, plan: ScenarioPlan, case: Case, fresh_world: bool,
         prefetch: bool = False) -> Any:
    """The executor's description of one case of ``item``'s test.

    With ``prefetch`` (before the item's fixtures exist) there are no fixture values, and the
    driver is known only when ``avs_driver`` is the plugin's own (then it is the built-in
    name); otherwise ``driver`` is None and the job cannot be started ahead.
    """
    from .executors import CaseJob

    argnames = tuple(item._fixtureinfo.argnames)
    if prefetch:
        fixtures: Mapping[str, Any] = {}
        defs = item._fixtureinfo.name2fixturedefs.get("avs_driver", ())
        overridden = bool(defs) and getattr(defs[-1].func, "__module__", None) != __name__
        driver = None if overridden else _default_driver(item.config)
    else:
        fixtures = item.funcargs
        driver = item.funcargs.get("avs_driver")
        if driver is None and "world" in argnames:
            driver = item._request.getfixturevalue("avs_driver")
    return CaseJob(
        nodeid=item.nodeid, module_path=str(item.path), rootdir=str(item.config.rootpath),
        function=item.originalname, func=item.obj, argnames=argnames, fixtures=fixtures,
        case=case, monitor_set=plan.monitor_set, driver=driver, fresh_world=fresh_world,
        timeout_s=plan.case_timeout_s, make_world=lambda c: _make_world(c, driver, item.nodeid),
    )


def _attach_to_html_report(report: pytest.TestReport, pictures: Mapping[str, str]) -> None:
    """Show a failing case's pictures in its pytest-html row (embedded, so the page travels)."""
    import base64

    from pytest_html import extras

    attached = list(getattr(report, "extras", []))
    for caption, path in pictures.items():
        try:
            data = base64.b64encode(open(path, "rb").read()).decode()
        except OSError:
            continue
        kind = "gif" if str(path).endswith(".gif") else "png"
        attached.append(extras.image(data, caption, mime_type=f"image/{kind}", extension=kind))
    report.extras = attached


def pytest_collection_finish(session: pytest.Session) -> None:
    """Hand a remote executor the passive cases ahead, so its workers stay busy."""
    config = session.config
    if _executor_name(config) == "inprocess" or hasattr(config, "workerinput"):
        return
    jobs = []
    for item in session.items:
        if not isinstance(item, pytest.Function) or item.get_closest_marker("scenario") is None:
            continue
        slot = item.callspec.params.get("case") if hasattr(item, "callspec") else None
        if not isinstance(slot, CaseSlot) or slot.params is None:
            continue
        case_obj = Case(slot.params, index=slot.index, seed=slot.seed, sampler=slot.sampler,
                        origin=slot.origin, test=item.nodeid)
        jobs.append(_job(item, _plan_of(item), case_obj, fresh_world=True, prefetch=True))
    if jobs:
        _executor(config).prefetch(jobs)


def _update_db(item: pytest.Item, plan: ScenarioPlan, slot: CaseSlot, case: Case,
               outcome: CaseOutcome, shrink: ShrinkReport | None) -> str | None:
    """Keep failures for the next run; forget replayed ones that pass now (fix confirmed)."""
    db = item.config.stash[db_key]
    if db is None:
        return None
    if case.origin == "replay":
        if outcome.verdict == "pass":
            db.delete(plan.replays[slot.index])
            return "fixed: this stored counterexample passes now and was removed from the database"
        return None
    if case.origin != "sampled" or not outcome.failed or (shrink is not None and shrink.flaky):
        return None
    minimized = shrink is not None and shrink.minimized is not None and shrink.minimized != case.params
    params = shrink.minimized if minimized else case.params
    rho = shrink.outcome.rho if minimized and shrink.outcome is not None else outcome.rho
    entry = db.save(plan.test, params, rho, case.seed, plan.space, minimized=minimized,
                    versions=_versions())
    return f"stored for replay in {entry.path}"


def _body_rho(outcome: CaseOutcome) -> float:
    # no monitors: a failing assertion is a violation, a pass is neutral
    return -1.0 if outcome.verdict == "fail" else 0.0


def _fmt_rho(v: float | None) -> str:
    if v is None:
        return "—"
    if math.isinf(v):
        return "+inf" if v > 0 else "-inf"
    return f"{v:+.3f}"


def _fmt_value(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    return repr(v)


def failure_message(item: pytest.Item, case: Case, outcome: CaseOutcome,
                    shrink: ShrinkReport | None = None, note: str | None = None) -> str:
    """The text a failing case shows: metrics, parameters (found and minimized), what to do."""
    lines = []
    if outcome.verdict == "fail" and outcome.violated:
        lines.append(f"scenario violated: {', '.join(outcome.violated)}")
    elif outcome.verdict == "fail":
        lines.append(f"scenario failed: {outcome.error}")
    else:
        lines.append(f"scenario case could not be judged: {outcome.error}")
    shrunk = shrink is not None and shrink.minimized is not None and shrink.outcome is not None
    if outcome.results:
        head = "  metric            rho" + ("   minimized" if shrunk else "") + "  threshold  verdict   worst (as found)"
        lines.append(head)
        for name, res in outcome.results.items():
            thr = "" if res.threshold is None else f"{res.threshold:g}"
            mid = f"  {_fmt_rho(shrink.outcome.rho.get(name)):>10}" if shrunk else ""
            verdict = "VIOLATED" if res.rho < 0 else "ok"
            lines.append(f"  {name:<12} {_fmt_rho(res.rho):>9}{mid}  {thr:>9}  {verdict:<8}  {res.detail}")
    if shrunk:
        nominal = _plan_of(item).space.nominal()
        lines.append("  parameter          found      minimized        nominal")
        for k, v in case.params.items():
            lines.append(f"  {k:<12} {_fmt_value(v):>11}  {_fmt_value(shrink.minimized[k]):>13}  "
                         f"{_fmt_value(nominal.get(k)):>13}")
        how = "budget spent" if shrink.exhausted else "done"
        lines.append(f"  shrinking: {shrink.sims} of {shrink.budget} simulations ({how})")
        lines.append(f"  pin it as a regression above the test: {_call_text('example', shrink.minimized)}")
    else:
        params = ", ".join(f"{k}={_fmt_value(v)}" for k, v in case.params.items())
        lines.append(f"  parameters: {params}")
        if shrink is not None and shrink.flaky:
            lines.append("  FLAKY: a replay of this case with the same seed did not fail the same way; "
                         "it was not shrunk (is the scene or the driver nondeterministic?)")
    lines.append(f"  case: {case.sampler} #{case.index}, origin {case.origin}, seed {case.seed}, "
                 f"simulated in {outcome.sim_time_s:.3f} s")
    if note:
        lines.append(f"  {note}")
    lines.append(f"  re-run only this case: {rerun_command(item, case)}")
    return "\n".join(lines)


def rerun_command(item: pytest.Item, case: Case) -> str:
    """A command that re-runs just this case, with the same values."""
    seed = item.config.stash[seed_key]
    cmd = f"pytest '{item.nodeid}' --avs-seed={seed}"
    plan = _plan_of(item)
    slot: CaseSlot = item.callspec.params["case"]
    if slot.params is None or item.config.getoption("avs_params"):
        # an active sampler's case depends on the cases before it: pin its values instead
        pinned = json.dumps({k: v for k, v in case.params.items() if k in plan.space.parameters})
        cmd += f" --avs-params '{pinned}'"
    for opt in ("avs_samples", "avs_sampler", "avs_driver"):
        val = item.config.getoption(opt)
        if val is not None:
            cmd += f" --{opt.replace('_', '-')}={val}"
    return cmd


def _row(item: pytest.Item, case: Case, outcome: CaseOutcome) -> dict[str, Any]:
    """The error-table row of one finished case (plain JSON-able data)."""
    from .report.table import row_to_json

    return row_to_json({
        "test": _function_id(item), "item": item.nodeid, "sampler": case.sampler,
        "index": case.index, "seed": case.seed, "origin": case.origin,
        "params": dict(case.params), "rho": dict(outcome.rho), "verdict": outcome.verdict,
        "sim_time_s": outcome.sim_time_s, "error": outcome.error,
    })


def _record_properties(item: pytest.Item, row: dict[str, Any], shrink: ShrinkReport | None) -> None:
    from .report.junit import case_properties
    from .report.table import row_from_json

    minimized = shrink.minimized if shrink is not None else None
    sims = shrink.sims if shrink is not None and shrink.minimized is not None else None
    # user_properties (not record_property) gives the same XML without xunit2's warning
    item.user_properties.extend(case_properties(row_from_json(row), minimized=minimized, shrink_sims=sims))
    if shrink is not None and shrink.flaky:
        item.user_properties.append(("avs.flaky", "true"))


# --------------------------------------------------------------------------- reporting
class RunState:
    """The controller's view of the run: the error table and what the summary needs."""

    def __init__(self, config: pytest.Config):
        self.config = config
        self.is_worker = hasattr(config, "workerinput")
        raw = config.getoption("avs_report") or config.getini("avs_report") or "avs-report"
        self.directory = None if str(raw).lower() == "none" else (
            config.invocation_params.dir / str(raw))
        self.table: Any = None
        self.rows: list[dict[str, Any]] = []
        self.tests: dict[str, dict[str, Any]] = {}
        self.summary_rows: list[Any] | None = None
        self.pictures: dict[str, dict[str, str]] = {}
        self.started = time.time()

    # -- hooks (this object is registered as a plugin for its config) ---------------------
    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        row = getattr(report, "avs_row", None)
        if row is not None and not self.is_worker:
            for shrink_row in getattr(report, "avs_shrink_rows", ()):
                self.add(shrink_row, report.avs_test)
            self.add(row, report.avs_test)
            pictures = getattr(report, "avs_pictures", None)
            if pictures:
                self.pictures.setdefault(row["test"], {}).update(pictures)

    @pytest.hookimpl(tryfirst=True)
    def pytest_sessionfinish(self, session: pytest.Session) -> None:
        # tryfirst: the suite properties must reach pytest's JUnit writer before it writes
        if self.is_worker or not self.rows:
            return
        from _pytest.junitxml import xml_key

        from .report.junit import add_suite_properties_to_logxml
        from .report.summary import suite_properties

        self.summary_rows = None
        if self.directory is not None and self.table is not None:
            from .report.build import finish_report

            try:
                self.table.close()  # every row is on disk; the report is built from the files
                self.summary_rows = finish_report(
                    self.directory, self.test_infos(), seed=self.config.stash[seed_key],
                    versions=_versions(), case_images=self.pictures)
            except OSError as exc:
                self.report_failed(exc)
        if self.summary_rows is None:
            self.summary_rows = self.summary()
        props = suite_properties(self.summary_rows, seed=self.config.stash[seed_key],
                                 versions=_versions())
        add_suite_properties_to_logxml(self.config.stash.get(xml_key, None), props)

    def pytest_terminal_summary(self, terminalreporter: Any) -> None:
        if self.is_worker or not self.rows:
            return
        from .report.summary import format_pointer, format_table

        summary = self.summary_rows if self.summary_rows is not None else self.summary()
        terminalreporter.write_sep("=", "avscenario")
        for line in format_table(summary).splitlines():
            terminalreporter.write_line(line)
        if self.directory is not None:
            terminalreporter.write_line(format_pointer(self.directory))

    # -- state ----------------------------------------------------------------------------
    def add(self, row: dict[str, Any], info: dict[str, Any]) -> None:
        self.tests.setdefault(row["test"], info)
        self.rows.append(row)
        if self.directory is None:
            return
        try:
            if self.table is None:
                from .report.table import ErrorTable, prepare_report_dir

                prepare_report_dir(self.directory)
                _remove_stale_pictures(self.directory / "cases", self.started)
                self.table = ErrorTable(self.directory)
            self.table.append(row)
        except OSError as exc:
            # the run goes on (verdicts, the replay database and the terminal summary do not
            # depend on the report); say once what was lost and where
            self.report_failed(exc)

    def report_failed(self, exc: OSError) -> None:
        directory, self.directory = self.directory, None
        if self.table is not None:
            try:
                self.table.close()
            except OSError:
                pass
        self.table = None
        self.config.issue_config_time_warning(pytest.PytestWarning(
            f"avscenario: cannot write the report under {directory} ({exc}); the rest of "
            "this run is reported in the terminal only"), 2)

    def close(self) -> None:
        if self.table is not None:
            self.table.close()

    def test_infos(self) -> dict[str, Any]:
        from .report.summary import TestInfo

        return {
            test: TestInfo(metrics=tuple(info["metrics"]),
                           space=FeatureSpace.from_description(info["space"]))
            for test, info in self.tests.items()
        }

    def summary(self) -> list[Any]:
        from .report.summary import summarize

        return summarize(self.rows, self.test_infos())


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Any:
    report = yield
    if call.when == "call" and row_key in item.stash:
        # extra report attributes travel to the xdist controller with the report
        report.avs_row = item.stash[row_key]
        report.avs_shrink_rows = item.stash.get(shrink_rows_key, [])
        report.avs_pictures = item.stash.get(pictures_key, {})
        if report.avs_pictures and item.config.pluginmanager.hasplugin("html"):
            _attach_to_html_report(report, report.avs_pictures)
        report.avs_test = _plan_of(item).info()
    return report


def _remove_stale_pictures(folder: Any, since: float) -> None:
    """Delete our case pictures left by earlier runs (workers may have drawn this run's already)."""
    if not folder.is_dir():
        return
    for f in folder.iterdir():
        if f.suffix in (".png", ".gif") and f.is_file() and f.stat().st_mtime < since - 1.0:
            f.unlink()


def _versions() -> dict[str, str]:
    from importlib.metadata import PackageNotFoundError, version

    out = {}
    for dist in ("pytest-avscenario", "highway-env"):
        try:
            out[dist] = version(dist)
        except PackageNotFoundError:
            out[dist] = "not installed"
    return out


def pytest_unconfigure(config: pytest.Config) -> None:
    executor = config.stash.get(executor_key, None)
    if executor is not None:
        executor.close()
    state = config.stash.get(session_key, None)
    if state is not None:
        state.close()

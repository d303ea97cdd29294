"""The plugin's options: the ``--avs-…`` command-line options and ``avs_…`` ini keys of the
option table (:mod:`pytest_avscenario.campaign.settings`), read once in ``pytest_configure``.

:func:`read_settings` builds the session's frozen :class:`Settings` from the command line, the
ini file and the defaults; a bad value from either source is a ``pytest.UsageError`` that
names the option and where it came from (``--avs-dask-workers``, ``ini avs_dask_workers``),
never an internal error later. What needs the pytest config to be checked (an sb3 model's
path relative to the ini file, xdist's ``-n``, the cached seed) is checked here.
"""

from __future__ import annotations

import secrets
import sys
from typing import Any, Mapping

import pytest

from ..campaign.settings import (  # noqa: F401 - the option table's names, read here and by users
    _BY_KEY,
    BUILTIN_DRIVERS,
    DEFAULT_CASE_PICTURES,
    DEFAULT_GIFS,
    DEFAULT_REFERENCE,
    DEFAULT_SAMPLER,
    DEFAULT_SAMPLES,
    DEFAULT_SHRINK_BUDGET,
    EXECUTORS,
    MAX_CASE_TIMEOUT_S,
    MAX_SAMPLES,
    OPTIONS,
    DeclarationError,
    Found,
    Option,
    Settings,
    TestSettings,
    _show,
    _validated,
    parse_duration,
)

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


def _export_installed(found: Found) -> None:
    import importlib.util

    if importlib.util.find_spec("scenariogeneration") is None:
        raise pytest.UsageError(f"{found.source}: exporting counterexamples needs "
                                "scenariogeneration: pip install 'pytest-avscenario[export]'")


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
    if "stack_timeout" in found or "stack_spin" in found \
            or "pytest_avscenario.stack.client" in sys.modules:
        # every run sets both (a second run in this process must not keep the first's)
        from ..stack.client import DEFAULT_TIMEOUT_S, configure

        spin = value("stack_spin", 0.0)
        configure(timeout_s=value("stack_timeout", DEFAULT_TIMEOUT_S),
                  spin_s=spin if spin == "auto" else spin * 1e-6)
    _imported_driver(found.get("driver"))
    if value("export") not in (None, "none"):
        _export_installed(found["export"])
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
        export=value("export"),
    )


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

"""Every setting of a scenario test, resolved once with one precedence, and validated.

Precedence: a marker argument beats the command line, which beats the ini file, which beats
the default — except ``--avs-samples`` and ``--avs-sampler``, which exist to override every
test at once. Each resolver names where a bad value came from (``--avs-…``, ``@scenario(…)``,
``ini avs_…``), and raises :class:`DeclarationError`, which collection turns into an error
naming the test.
"""

from __future__ import annotations

import json
import math
import secrets
from typing import Any

import pytest

from .markers.spec import ScenarioSpec
from .space import FeatureSpace

DEFAULT_SAMPLES = 20
DEFAULT_SAMPLER = "halton"
DEFAULT_SHRINK_BUDGET = 20
MAX_SAMPLES = 100_000
DEFAULT_GIFS = 3


class DeclarationError(Exception):
    pass


def session_seed(config: pytest.Config) -> int:
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


def open_db(config: pytest.Config) -> Any:
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


def lookup(config: pytest.Config, spec: ScenarioSpec, key: str,
           cli_overrides: bool = False) -> tuple[Any, str] | None:
    """The raw value of setting ``key`` and where it came from, by the documented precedence
    (marker > command line > ini), or None when nothing sets it. ``cli_overrides`` puts the
    command line first: for the options that exist to override every test at once."""
    option = key.replace("_", "-")
    marker = (getattr(spec, key), f"@scenario({key}=...)") \
        if key in spec.given and getattr(spec, key) is not None else None
    cli_value = config.getoption(f"avs_{key}")
    cli = (cli_value, f"--avs-{option}") if cli_value not in (None, "") else None
    ini_value = config.getini(f"avs_{key}")
    ini = (ini_value, f"ini avs_{key}") if ini_value not in (None, "") else None
    order = (cli, marker, ini) if cli_overrides else (marker, cli, ini)
    return next((found for found in order if found is not None), None)


def setting_int(config: pytest.Config, spec: ScenarioSpec, key: str, default: int,
                minimum: int, cli_overrides: bool = False) -> int:
    found = lookup(config, spec, key, cli_overrides)
    if found is None:
        return default
    value, source = found
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


def setting_duration(config: pytest.Config, spec: ScenarioSpec, key: str, what: str) -> float | None:
    found = lookup(config, spec, key)
    if found is None:
        return None
    raw, source = found
    try:
        return parse_duration(raw)
    except (ValueError, TypeError):
        raise DeclarationError(f"{key} must be {what}, got {raw!r} (from {source})") from None


def resolve_samples(config: pytest.Config, spec: ScenarioSpec) -> int:
    samples = setting_int(config, spec, "samples", DEFAULT_SAMPLES, minimum=1, cli_overrides=True)
    if samples > MAX_SAMPLES:
        raise DeclarationError(
            f"samples must be at most {MAX_SAMPLES} per test (got {samples}): every case is a "
            "pytest item; for a long campaign give time_budget= (e.g. '30m') with a large count"
        )
    return samples


def resolve_case_timeout(config: pytest.Config, spec: ScenarioSpec) -> float | None:
    return setting_duration(config, spec, "case_timeout",
                            "a positive number of seconds (or 90s, 2m)")


def resolve_time_budget(config: pytest.Config, spec: ScenarioSpec) -> float | None:
    return setting_duration(config, spec, "time_budget",
                            "a positive duration like 30m, 90s, 1h or seconds")


def resolve_shrink_budget(config: pytest.Config, spec: ScenarioSpec) -> int:
    return setting_int(config, spec, "shrink_budget", DEFAULT_SHRINK_BUDGET, minimum=0)


def resolve_shrink_max(config: pytest.Config, spec: ScenarioSpec) -> int | None:
    found = lookup(config, spec, "shrink_max")
    return None if found is None else setting_int(config, spec, "shrink_max", 0, minimum=0)


def resolve_samplers(config: pytest.Config, spec: ScenarioSpec) -> list[str]:
    from .samplers import base

    raw, source = lookup(config, spec, "sampler", cli_overrides=True) or (DEFAULT_SAMPLER, "default")
    if source == "--avs-sampler":
        raw = [name.strip() for name in raw.split(",") if name.strip()]
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


def pinned_params(config: pytest.Config, space: FeatureSpace) -> dict[str, Any] | None:
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


def executor_name(config: pytest.Config) -> str:
    return config.getoption("avs_executor") or config.getini("avs_executor") or "inprocess"


def dask_address(config: pytest.Config) -> str | None:
    return config.getoption("avs_dask_address") or config.getini("avs_dask_address") or None


def check_executor(config: pytest.Config) -> None:
    """Refuse, before anything runs, executor settings that cannot work together."""
    name = executor_name(config)
    if name not in ("inprocess", "dask"):
        raise pytest.UsageError(f"--avs-executor: unknown executor {name!r}; available: inprocess, dask")
    if name == "dask" and dask_address(config) is None and getattr(config.option, "numprocesses", None) \
            and not hasattr(config, "workerinput"):
        raise pytest.UsageError(
            "--avs-executor=dask with pytest-xdist (-n) needs --avs-dask-address: otherwise "
            "every xdist worker would start a Dask cluster of its own")


def gif_cap(config: pytest.Config) -> int:
    """GIFs to render per scenario test (``--avs-gifs`` / ini ``avs_gifs``, default 3)."""
    value = config.getoption("avs_gifs")
    if value is None and config.getini("avs_gifs") not in (None, ""):
        value = config.getini("avs_gifs")
    try:
        return max(0, int(value)) if value is not None else DEFAULT_GIFS
    except (TypeError, ValueError):
        raise pytest.UsageError(f"avs_gifs must be an integer, got {value!r}") from None


def default_driver(config: pytest.Config) -> str:
    return config.getoption("avs_driver") or config.getini("avs_driver") or "autopilot"

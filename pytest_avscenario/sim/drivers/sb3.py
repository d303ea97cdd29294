"""A stable-baselines3 model saved to a file, as the ego: the ``sb3:PATH[@ENV]`` driver.

``--avs-driver sb3:models/dqn.zip@highway-fast-v0`` (or ``world.ego(...,
driver="sb3:...")``) drives the ego with the model saved at ``PATH`` through
:class:`~.highway_agent.HighwayEnvAgent`, exactly as ``highway_env_agent(DQN.load(PATH),
env=ENV)`` does: ``ENV`` is the highway-env id the model was trained on, in its default
config (default ``highway-fast-v0``). The algorithm is read from the zip — stable-baselines3
stores the policy class, whose module names it (``stable_baselines3.dqn.policies`` → ``DQN``);
where that is ambiguous or a custom class, name it: ``sb3:PPO:PATH@ENV``. A model trained
with a changed config, or with an algorithm not listed in :data:`ALGORITHMS`, goes through
an ``avs_driver`` fixture with ``highway_env_agent(model, env=..., config=...)`` instead.

:func:`check` is what configuration runs (it imports neither torch nor stable-baselines3):
the file there and a model saved by stable-baselines3, the algorithm known, the environment
registered, the model's observation and action spaces those of the environment, and
stable-baselines3 installed; it answers the spec with an absolute path, so xdist workers and
Dask workers get the same file whatever their working directory. :func:`driver` makes the
agent; the model itself is loaded on first use in each process, from its path — never
pickled — and one agent is kept per process and file (loading costs torch's import, ~1-2 s).
"""

from __future__ import annotations

import functools
import hashlib
import importlib
import importlib.util
import json
import os
import re
import sys
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import SimError

__all__ = ["PREFIX", "DEFAULT_ENV", "ALGORITHMS", "SB3Spec", "SB3Model", "parse", "check", "driver"]

PREFIX = "sb3:"
DEFAULT_ENV = "highway-fast-v0"
INSTALL = 'pip install "pytest-avscenario[sb3]"'

#: the algorithms ``sb3:`` loads: name -> (package, class); sb3-contrib's need it installed
ALGORITHMS = {
    "A2C": ("stable_baselines3", "A2C"),
    "DDPG": ("stable_baselines3", "DDPG"),
    "DQN": ("stable_baselines3", "DQN"),
    "PPO": ("stable_baselines3", "PPO"),
    "SAC": ("stable_baselines3", "SAC"),
    "TD3": ("stable_baselines3", "TD3"),
    "ARS": ("sb3_contrib", "ARS"),
    "CROSSQ": ("sb3_contrib", "CrossQ"),
    "QRDQN": ("sb3_contrib", "QRDQN"),
    "TQC": ("sb3_contrib", "TQC"),
    "TRPO": ("sb3_contrib", "TRPO"),
}
# the policy class's module -> algorithm; stable_baselines3.common.policies (actor-critic) is
# shared by A2C, PPO and TRPO and told apart by their settings in the zip
_BY_POLICY_MODULE = {
    "stable_baselines3.dqn.policies": "DQN",
    "stable_baselines3.sac.policies": "SAC",
    "stable_baselines3.td3.policies": "TD3",  # DDPG's too; TD3.load predicts the same
    "sb3_contrib.ars.policies": "ARS",
    "sb3_contrib.crossq.policies": "CROSSQ",
    "sb3_contrib.qrdqn.policies": "QRDQN",
    "sb3_contrib.tqc.policies": "TQC",
}
_ALGO_PREFIX = re.compile(r"([A-Za-z][A-Za-z0-9_]+):(.+)", re.S)


@dataclass(frozen=True)
class SB3Spec:
    """A parsed ``sb3:[ALGO:]PATH[@ENV]``."""

    path: str
    env: str
    algorithm: str | None  # None: read from the zip

    def text(self) -> str:
        algo = f"{self.algorithm}:" if self.algorithm else ""
        return f"{PREFIX}{algo}{self.path}@{self.env}"


def is_sb3(value: Any) -> bool:
    return isinstance(value, str) and value.strip().startswith(PREFIX)


def parse(text: str) -> SB3Spec:
    """``sb3:[ALGO:]PATH[@ENV]`` split; ValueError saying the syntax when it is not that."""
    body = text.strip()[len(PREFIX):].strip()
    syntax = (f"write sb3:PATH (environment {DEFAULT_ENV}), sb3:PATH@ENV or sb3:ALGO:PATH@ENV, "
              "e.g. sb3:models/dqn.zip@highway-fast-v0")
    algorithm = None
    m = _ALGO_PREFIX.fullmatch(body)
    if m:  # a one-letter prefix is a drive letter (C:\...), not an algorithm
        name = m.group(1).upper()
        if name not in ALGORITHMS:
            raise ValueError(f"driver {text.strip()!r}: unknown algorithm {m.group(1)!r}; "
                             f"stable-baselines3's are {', '.join(sorted(ALGORITHMS))}; {syntax}")
        algorithm, body = name, m.group(2)
    path, env = body, DEFAULT_ENV
    head, at, tail = body.rpartition("@")
    if at and tail and not re.search(r"[/\\]", tail):  # an '@' in a folder name stays the path's
        path, env = head, tail.strip()
    path = path.strip()
    if not path:
        raise ValueError(f"driver {text.strip()!r} names no model file; {syntax}")
    return SB3Spec(path, env, algorithm)


def _installed(module: str) -> bool:
    # a None entry in sys.modules is Python's own "this import is blocked"
    if module in sys.modules:
        return sys.modules[module] is not None
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def check(text: str, base: os.PathLike | str) -> str:
    """The spec with an absolute path, once the model can drive; ValueError saying what is wrong.

    ``base`` is the folder a relative path is relative to. Reads the zip's ``data`` (JSON)
    only: no torch is imported here.
    """
    spec = parse(text)
    shown = text.strip()
    path = Path(base, os.path.expanduser(spec.path))
    path = Path(os.path.abspath(path))
    if not path.exists() and path.suffix != ".zip" and path.with_name(path.name + ".zip").is_file():
        path = path.with_name(path.name + ".zip")  # as stable-baselines3's load() finds it
    if not path.exists():
        raise ValueError(f"driver {shown!r}: no model file at {path} (read as model {spec.path!r}, "
                         f"environment {spec.env!r}{f', algorithm {spec.algorithm}' if spec.algorithm else ''})")
    if not path.is_file():
        raise ValueError(f"driver {shown!r}: {path} is not a file (give the .zip that "
                         "model.save() wrote)")
    data = _read_data(path, shown)
    algorithm = spec.algorithm or _algorithm_of(data, path, shown, spec.env)
    _check_env(spec.env, data, path, shown, algorithm)
    if not _installed("stable_baselines3"):
        raise ValueError(f"driver {shown!r} needs stable-baselines3, which is not installed: "
                         f"{INSTALL} (it brings torch)")
    package, _ = ALGORITHMS[algorithm]
    if not _installed(package):
        raise ValueError(f"driver {shown!r}: the model is a {algorithm}, which needs "
                         f"{package.replace('_', '-')}: pip install {package.replace('_', '-')}")
    return SB3Spec(str(path), spec.env, spec.algorithm).text()


def _read_data(path: Path, shown: str) -> dict:
    try:
        with zipfile.ZipFile(path) as z:
            names = set(z.namelist())
            if "data" not in names or "policy.pth" not in names:
                raise ValueError(f"driver {shown!r}: {path} is a zip but not a model saved by "
                                 "stable-baselines3 (no 'data' and 'policy.pth' in it)")
            data = json.loads(z.read("data"))
    except zipfile.BadZipFile:
        raise ValueError(f"driver {shown!r}: {path} is not a zip file; give the .zip that "
                         "stable-baselines3's model.save() wrote") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"driver {shown!r}: cannot read the model at {path}: "
                         f"{type(exc).__name__}: {exc}") from None
    if not isinstance(data, dict):
        raise ValueError(f"driver {shown!r}: {path}: its 'data' is not stable-baselines3's")
    return data


def fixture_hint(algorithm: str, path: Path | str, env_id: str, config: str | None = None) -> str:
    """How to run a model ``sb3:`` cannot: the ``avs_driver`` fixture, as one line of code."""
    cfg = f", config={config}" if config else ""
    given = ", giving the config it was trained with" if config else ""
    return (f"run it from an avs_driver fixture in conftest.py{given}: "
            f"return highway_env_agent({algorithm}.load({str(path)!r}), env={env_id!r}{cfg})")


def _algorithm_of(data: dict, path: Path, shown: str, env_id: str = DEFAULT_ENV) -> str:
    policy = data.get("policy_class")
    module = policy.get("__module__") if isinstance(policy, dict) else None
    if module in _BY_POLICY_MODULE:
        return _BY_POLICY_MODULE[module]
    if module == "stable_baselines3.common.policies":
        if "cg_max_steps" in data:
            return "TRPO"
        return "PPO" if "clip_range" in data else "A2C"
    raise ValueError(f"driver {shown!r}: cannot tell the algorithm of {path} (its policy class "
                     f"comes from {module!r}); name it: sb3:ALGO:PATH@ENV with ALGO one of "
                     f"{', '.join(sorted(ALGORITHMS))}; for another algorithm, "
                     + fixture_hint("MyAlgo", path, env_id))


def _check_env(env_id: str, data: dict, path: Path, shown: str, algorithm: str = "DQN") -> None:
    """The environment is registered and its spaces are the ones the model was trained on."""
    try:
        import gymnasium
        import highway_env  # noqa: F401  (registers the environment ids)
    except ImportError as exc:  # pragma: no cover - core dependencies
        raise ValueError(f"driver {shown!r}: cannot import highway-env ({exc})") from None
    try:
        gymnasium.spec(env_id)
    except gymnasium.error.Error:
        ids = sorted(k for k, s in gymnasium.registry.items()
                     if str(getattr(s, "entry_point", "")).startswith("highway_env"))
        raise ValueError(f"driver {shown!r}: unknown environment {env_id!r}; highway-env's "
                         f"are {', '.join(ids)}") from None
    try:
        env = gymnasium.make(env_id)
    except Exception as exc:
        raise ValueError(f"driver {shown!r}: making {env_id!r} failed: "
                         f"{type(exc).__name__}: {exc}") from None
    try:
        obs_space, act_space = env.observation_space, env.action_space
        config = dict(env.unwrapped.config)
    finally:
        env.close()
    from .highway_agent import _check_config

    try:  # what highway_env_agent refuses (images, other action types), said now
        _check_config(config, f"driver {shown!r}", "", "")
    except SimError as exc:
        raise ValueError(f"{exc} — the environment {env_id!r} in its default config") from None
    # sb3: knows an environment only in its default config; a model trained on a changed one
    # (another observation, continuous actions) runs through the fixture, which takes config=
    want = _shape(data.get("observation_space"))
    if want is not None and tuple(obs_space.shape or ()) != want:
        raise ValueError(
            f"driver {shown!r}: the model at {path} takes observations of shape {want}, but "
            f"{env_id!r} in its default config gives {tuple(obs_space.shape)}; give the "
            "environment it was trained on (sb3:PATH@ENV), or, for a changed config, "
            + fixture_hint(algorithm, path, env_id, "{'observation': {...}}"))
    model_act = data.get("action_space")
    if isinstance(model_act, dict):
        kind = str(model_act.get(":type:", ""))
        n = model_act.get("n")
        env_kind = type(act_space).__name__
        if "Discrete" in kind and env_kind == "Discrete" and n is not None \
                and str(n) != str(int(act_space.n)):
            raise ValueError(f"driver {shown!r}: the model at {path} chooses among {n} actions, "
                             f"{env_id!r} has {int(act_space.n)}; "
                             + fixture_hint(algorithm, path, env_id, "{'action': {...}}"))
        if ("Discrete" in kind) != (env_kind == "Discrete") and kind:
            continuous = "Discrete" not in kind
            raise ValueError(
                f"driver {shown!r}: the model at {path} was trained with "
                f"{kind.split('.')[-1].rstrip(chr(39) + '>')} actions, {env_id!r} in its "
                f"default config has {env_kind} actions; sb3: runs an environment in its "
                "default config only, so "
                + fixture_hint(algorithm, path, env_id,
                               "{'action': {'type': 'ContinuousAction'}}" if continuous
                               else "{'action': {...}}"))


def _shape(space: Any) -> tuple | None:
    shape = space.get("_shape") if isinstance(space, dict) else None
    if isinstance(shape, list) and all(isinstance(s, int) for s in shape):
        return tuple(shape)
    return None


class SB3Model:
    """A stable-baselines3 model loaded from ``path`` on first use in each process.

    Pickles as its path (xdist workers, Dask): the loaded network stays in the process
    that loaded it.
    """

    def __init__(self, path: str, algorithm: str | None = None) -> None:
        self.path = path
        self.algorithm = algorithm
        self.__name__ = f"{PREFIX}{os.path.basename(path)}"
        self._model: Any = None

    def describe(self) -> dict:
        """The model file and its content hash (:mod:`.identity`), without loading it."""
        out = {"name": self.__name__, "kind": "sb3", "file": self.path, "sha256": file_sha256(self.path)}
        if self.algorithm:
            out["algorithm"] = self.algorithm
        return out

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["_model"] = None
        return state

    def load(self) -> Any:
        if self._model is not None:
            return self._model
        shown = f"{PREFIX}{self.path}"
        if not _installed("stable_baselines3"):
            raise SimError(f"driver {shown!r} needs stable-baselines3, which is not installed "
                           f"here: {INSTALL}")
        algorithm = self.algorithm
        if algorithm is None:
            algorithm = _algorithm_of(_read_data(Path(self.path), shown), Path(self.path), shown)
        package, name = ALGORITHMS[algorithm]
        try:
            cls = getattr(importlib.import_module(package), name)
            self._model = cls.load(self.path, device="cpu")
        except Exception as exc:
            raise SimError(f"driver {shown!r}: loading the {algorithm} model failed: "
                           f"{type(exc).__name__}: {exc}") from exc
        return self._model

    def predict(self, observation: Any, deterministic: bool = True) -> Any:
        return self.load().predict(observation, deterministic=deterministic)


SHA_DIGITS = 12  # hex digits of the SHA-256 kept: enough to tell two model files apart


def file_sha256(path: str | os.PathLike) -> str | None:
    """The first :data:`SHA_DIGITS` hex digits of the SHA-256 of the file, None if unreadable."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return _sha(os.path.abspath(path), st.st_mtime_ns, st.st_size)


@functools.lru_cache(maxsize=32)
def _sha(path: str, mtime_ns: int, size: int) -> str | None:
    # keyed by mtime and size too: a model rewritten during a session is hashed again
    digest = hashlib.sha256()
    try:
        with open(path, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                digest.update(block)
    except OSError:
        return None
    return digest.hexdigest()[:SHA_DIGITS]


@functools.lru_cache(maxsize=8)
def _agent(text: str, mtime_ns: int, size: int) -> Any:
    from .highway_agent import HighwayEnvAgent

    spec = parse(text)
    return HighwayEnvAgent(SB3Model(spec.path, spec.algorithm), env=spec.env)


def driver(text: str) -> Any:
    """The agent for ``sb3:[ALGO:]PATH[@ENV]``: one per process and file (a rewritten file is
    loaded again). A relative path is relative to the working directory."""
    try:
        spec = parse(text)
    except ValueError as exc:
        raise SimError(str(exc)) from None
    path = os.path.abspath(os.path.expanduser(spec.path))
    try:
        st = os.stat(path)
    except OSError:
        raise SimError(f"driver {text.strip()!r}: no model file at {path}") from None
    return _agent(SB3Spec(path, spec.env, spec.algorithm).text(), st.st_mtime_ns, st.st_size)

"""What one simulated case gives: its outcome, and the error-table row it becomes.

:class:`CaseOutcome` is what running a case produced (the verdict, every ρ, the body's
exception, and — in the process that ran it — the world and its trajectory). It is the same
type in this process and on a Dask worker: pickled, it leaves the world and trajectory
behind and carries its exception as data, re-created on the other side with the same type
name, text and last frame, so :attr:`CaseOutcome.signature` matches across processes.

:class:`CaseRow` is one finished case as the reports see it — frozen, plain data — with one
JSON codec (:meth:`CaseRow.to_json` / :meth:`CaseRow.from_json`; floats through
:mod:`.codec`, so ±inf and NaN are written one way). The error table, JUnit, the summary and
the xdist channel all carry this row.
"""

from __future__ import annotations

import math
import os
import pickle
import sys
import traceback
from dataclasses import dataclass, field, fields
from typing import Any, Mapping

from .codec import jsonable, rho_from_json, rho_to_json
from .frozen import CompactMapping

__all__ = ["CaseOutcome", "CaseRow", "ORIGINS", "VERDICTS", "all_unavoidable", "violations_of"]

ORIGINS = ("sampled", "replay", "example", "pinned", "shrink")
VERDICTS = ("pass", "fail", "error")


@dataclass
class CaseOutcome:
    """What one run of a case produced.

    ``verdict`` is ``"pass"``, ``"fail"`` (a monitor violated or the body's assertion failed)
    or ``"error"`` (the case could not be judged: an exception, no trajectory, NaN, or a
    worker that could not run it). ``signature`` identifies *which* failure it is, so
    shrinking keeps to the same bug: the sorted violated metrics, or the exception type and
    the line it came from.
    """

    params: dict[str, Any]
    verdict: str
    rho: dict[str, float] = field(default_factory=dict)
    results: dict[str, Any] = field(default_factory=dict)
    violated: list[str] = field(default_factory=list)
    exc: BaseException | None = None
    error: str | None = None
    sim_time_s: float = 0.0
    trajectory: Any = None  # in the process that ran it only
    world: Any = None  # the World that ran (in-process only), for rendering pictures
    worker_pid: int = 0  # the process that simulated it (0: this one)
    drawn: dict[str, Any] | None = None  # the case.rng draws (RecordingGenerator.log())
    #: violated metric -> (time [s], agent) of its first violation (monitors.first_violation)
    first: dict[str, Any] = field(default_factory=dict)
    #: the run's driving score (``DrivingScore.to_json()``); None without a road to score on
    score: dict[str, Any] | None = None
    #: the ego and another agent both RSS-unsafe at t = 0 (``campaign.pipeline.starts_unsafe``),
    #: judged where the trajectory was recorded when a campaign discards unfair cases;
    #: None: not judged here (the trajectory, if any, answers)
    start_unsafe: bool | None = None

    @property
    def signature(self) -> tuple[Any, ...]:
        if self.exc is not None:
            tb = traceback.extract_tb(self.exc.__traceback__)
            where = (tb[-1].filename, tb[-1].lineno) if tb else ("?", 0)
            return ("exception", type(self.exc).__name__, *where)
        return ("monitors", *sorted(self.violated))

    @property
    def failed(self) -> bool:
        return self.verdict == "fail"

    @property
    def worst_rho(self) -> float | None:
        vals = [v for v in self.rho.values() if not math.isnan(v)]
        return min(vals) if vals else None

    # -- crossing a process boundary (Dask) ---------------------------------------------
    def __getstate__(self) -> dict[str, Any]:
        state = {f.name: getattr(self, f.name) for f in fields(self)}
        # a counterexample keeps its recording (~40 kB): who entered an unsafe state first
        # and the crash partner are judged from it where the campaign runs, as in process
        state.update(trajectory=self.trajectory if self.verdict == "fail" else None, world=None,
                     exc=_pack_exception(self.exc), worker_pid=self.worker_pid or os.getpid())
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        state = dict(state)
        state["exc"] = _revive_exception(state["exc"])
        self.__dict__.update(state)


def _pack_exception(exc: BaseException | None) -> dict[str, Any] | None:
    """An exception as picklable data: itself when it pickles both ways, else its type's
    name and text; its traceback through tblib (the last frame makes the signature)."""
    if exc is None:
        return None
    cls = type(exc)
    packed: dict[str, Any] = {"type": (cls.__module__, cls.__qualname__), "text": str(exc),
                              "kind": "fail" if isinstance(exc, AssertionError) else "error",
                              "pickle": None, "tb": None}
    try:
        data = pickle.dumps(exc)
        pickle.loads(data)  # some exceptions pickle but do not unpickle (required args)
        packed["pickle"] = data
    except Exception:
        pass
    try:
        from tblib import Traceback

        packed["tb"] = Traceback(exc.__traceback__).to_dict()
    except Exception:
        pass
    return packed


def _revive_exception(packed: Mapping[str, Any] | None) -> BaseException | None:
    if packed is None:
        return None
    exc: BaseException | None = None
    if packed["pickle"] is not None:
        try:
            exc = pickle.loads(packed["pickle"])
        except Exception:  # the class is not importable here: fall back to a stand-in
            exc = None
    if exc is None:
        module, name = packed["type"]
        base = AssertionError if packed["kind"] == "fail" else Exception
        # same __name__ as the remote class, so CaseOutcome.signature matches across retries
        stand_in = type(name.rpartition(".")[2], (base,), {"__module__": module,
                                                          "__doc__": "re-created from a worker"})
        exc = stand_in(packed["text"])
    if packed["tb"] is not None:
        try:
            from tblib import Traceback

            exc = exc.with_traceback(Traceback.from_dict(packed["tb"]).as_traceback())
        except Exception:  # a traceback we cannot rebuild must not hide the failure itself
            pass
    return exc


@dataclass(frozen=True, slots=True)
class CaseRow:
    """One finished case in the error table (plain data).

    ``test`` is the function's node id, ``item`` the case's; ``origin`` one of
    :data:`ORIGINS`, ``verdict`` one of :data:`VERDICTS`; ``rho`` maps each metric to its
    robustness (±inf allowed, None for a metric not evaluated); ``minimized`` and
    ``shrink_sims`` are set on a counterexample that was minimized, ``flaky`` on one that did
    not fail again when replayed with its seed.
    """

    test: str
    item: str
    sampler: str
    index: int
    seed: int | None
    origin: str
    params: Mapping[str, Any]
    rho: Mapping[str, float | None]
    verdict: str
    sim_time_s: float = 0.0
    error: str | None = None
    minimized: Mapping[str, Any] | None = None
    shrink_sims: int | None = None
    flaky: bool = False  # a replay with the same seed did not fail the same way
    #: violated metric -> whether the reference driver avoids it (True: avoidable; False: it
    #: violates it too; None: unknown — the reference run failed); None: not judged
    avoidable: Mapping[str, bool | None] | None = None
    #: violated metric -> the conflict the judgement is about and what the reference did in
    #: it: {"agent": the other agent, "t": first violation [s], "until": end of the window [s],
    #: "rho": the reference's value toward that agent, "why": text}; None: not judged
    conflicts: Mapping[str, Mapping[str, Any]] | None = None
    #: the minimized case's own first violations (as ``violations``) and its own judgement
    #: against the reference driver (as ``avoidable`` and ``conflicts``), when it was judged
    minimized_violations: Mapping[str, Mapping[str, Any]] | None = None
    minimized_avoidable: Mapping[str, bool | None] | None = None
    minimized_conflicts: Mapping[str, Mapping[str, Any]] | None = None
    #: the minimized case's own robustness per metric (as ``rho``, which is the case as
    #: found's); None when the case was not minimized
    minimized_rho: Mapping[str, float | None] | None = None
    #: the agent that entered an RSS-unsafe state first by its own responsibility, and when
    #: ({"agent": name or "both", "t": seconds}); None: not judged or nobody did
    unsafe_first: Mapping[str, Any] | None = None
    #: per violated metric, where it was violated: {"t": seconds of the first violation (or
    #: of the deciding moment when the monitor cannot tell), "agent": the agent involved,
    #: "threshold": the bound, "worst_t": seconds of the worst value (the moment the
    #: monitor's own text names, e.g. the minimum TTC)}; None for a case that violated
    #: nothing or was not simulated
    violations: Mapping[str, Mapping[str, Any]] | None = None
    #: what the run drew from ``case.rng``: {"count": N, "draws": [{"n", "call", "value",
    #: "t"}, ...]} (the first draws in full); None when it drew nothing
    drawn: Mapping[str, Any] | None = None
    #: the driver under test that drove the ego ({"name", "kind", "file", "sha256", "from",
    #: ...}: :mod:`pytest_avscenario.sim.drivers.identity`); None for a test without one
    driver: Mapping[str, Any] | None = None
    #: the CARLA Leaderboard's driving score of the run ({"score", "route_completion",
    #: "penalty", "infractions": [{"kind", "factor", "t", "agent"}, ...]}, all 0..1):
    #: :mod:`pytest_avscenario.monitors.score`; None when the recording has no road
    score: Mapping[str, Any] | None = None
    #: the case exported for other simulators (``--avs-export``): {"xosc", "xodr", "osi": file
    #: name beside the card, "trajectories": {agent: why it follows its recorded trajectory},
    #: "errors": {part: why it was not written}}; None: not exported
    exports: Mapping[str, Any] | None = None

    def __post_init__(self) -> None:
        if self.origin not in ORIGINS:
            raise ValueError(f"row origin must be one of {ORIGINS}, got {self.origin!r}")
        if self.verdict not in VERDICTS:
            raise ValueError(f"row verdict must be one of {VERDICTS}, got {self.verdict!r}")
        if not isinstance(self.params, Mapping) or not isinstance(self.rho, Mapping):
            raise ValueError("row 'params' and 'rho' must be mappings {name: value}")
        # read-only: a row is shared by the table, JUnit and the summary
        object.__setattr__(self, "params", CompactMapping.of(self.params))
        object.__setattr__(self, "rho", CompactMapping.of(self.rho))

    def to_json(self) -> dict[str, Any]:
        """The row as JSON data (one line of errors.jsonl, or what crosses the xdist channel)."""
        out: dict[str, Any] = {
            "test": self.test, "item": self.item, "sampler": self.sampler, "index": self.index,
            "seed": self.seed, "origin": self.origin, "params": jsonable(dict(self.params)),
            "rho": {k: None if v is None else rho_to_json(v) for k, v in self.rho.items()},
            "verdict": self.verdict, "sim_time_s": self.sim_time_s, "error": self.error,
        }
        if self.minimized is not None:
            out["minimized"] = jsonable(dict(self.minimized))
        if self.shrink_sims is not None:
            out["shrink_sims"] = self.shrink_sims
        if self.flaky:
            out["flaky"] = True
        if self.avoidable is not None:
            out["avoidable"] = dict(self.avoidable)
        if self.unsafe_first is not None:
            out["unsafe_first"] = dict(self.unsafe_first)
        for key in ("conflicts", "minimized_violations", "minimized_conflicts"):
            value = getattr(self, key)
            if value is not None:
                out[key] = {k: jsonable(dict(v)) for k, v in value.items()}
        if self.minimized_avoidable is not None:
            out["minimized_avoidable"] = dict(self.minimized_avoidable)
        if self.minimized_rho is not None:
            out["minimized_rho"] = {k: None if v is None else rho_to_json(v)
                                    for k, v in self.minimized_rho.items()}
        if self.violations is not None:
            out["violations"] = {k: jsonable(dict(v)) for k, v in self.violations.items()}
        if self.drawn is not None:
            out["drawn"] = jsonable(dict(self.drawn))
        if self.driver is not None:
            out["driver"] = jsonable(dict(self.driver))
        if self.score is not None:
            out["score"] = jsonable(dict(self.score))
        if self.exports is not None:
            out["exports"] = jsonable(dict(self.exports))
        return out

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> "CaseRow":
        """Inverse of :meth:`to_json`; also takes a hand-written row (rho as floats, ``item``,
        ``seed``, ``sim_time_s`` and ``error`` optional). ValueError names a missing or bad key."""
        missing = [k for k in ("test", "sampler", "index", "origin", "params", "rho", "verdict")
                   if k not in data]
        if missing:
            raise ValueError(f"error-table row lacks {missing}; got keys {sorted(data)}")
        rho = data["rho"]
        if not isinstance(rho, Mapping):
            raise ValueError("row 'params' and 'rho' must be mappings {name: value}")
        # the run holds every row to its end: the strings most rows repeat are kept once
        return cls(
            test=sys.intern(str(data["test"])), item=str(data.get("item") or data["test"]),
            sampler=sys.intern(str(data["sampler"])), index=int(data["index"]),
            seed=None if data.get("seed") is None else int(data["seed"]),
            origin=data["origin"], params=data["params"],
            rho={str(k): None if v is None or v == "" else rho_from_json(v) for k, v in rho.items()},
            verdict=data["verdict"], sim_time_s=float(data.get("sim_time_s") or 0.0),
            error=None if data.get("error") is None else str(data["error"]),
            minimized=data.get("minimized"),
            shrink_sims=None if data.get("shrink_sims") is None else int(data["shrink_sims"]),
            flaky=bool(data.get("flaky", False)),
            avoidable=_avoidable(data.get("avoidable")),
            unsafe_first=data.get("unsafe_first") if isinstance(data.get("unsafe_first"), Mapping) else None,
            # absent in rows written before judgements were per conflict
            conflicts=_violations(data.get("conflicts")),
            minimized_violations=_violations(data.get("minimized_violations")),
            minimized_avoidable=_avoidable(data.get("minimized_avoidable")),
            minimized_conflicts=_violations(data.get("minimized_conflicts")),
            minimized_rho=_rho_map(data.get("minimized_rho")),
            violations=_violations(data.get("violations")),
            drawn=data.get("drawn") if isinstance(data.get("drawn"), Mapping) else None,
            driver=dict(data["driver"]) if isinstance(data.get("driver"), Mapping) else None,
            score=dict(data["score"]) if isinstance(data.get("score"), Mapping) else None,
            exports=dict(data["exports"]) if isinstance(data.get("exports"), Mapping) else None,
        )

    @property
    def driving_score(self) -> float | None:
        """The run's driving score (0..1), None when it has none."""
        return None if self.score is None else float(self.score["score"])

    @property
    def unavoidable(self) -> bool:
        """A counterexample judged against the reference driver, every violated metric of
        which the reference violates too (no driver of its standard avoids it)."""
        return all_unavoidable(self.avoidable)

    @classmethod
    def coerce(cls, row: "CaseRow | Mapping[str, Any]") -> "CaseRow":
        """``row`` itself, or a row read from JSON data or written by hand."""
        return row if isinstance(row, CaseRow) else cls.from_json(row)


def _avoidable(data: Any) -> dict[str, bool | None] | None:
    if not isinstance(data, Mapping):
        return None
    return {str(k): v if isinstance(v, bool) else None for k, v in data.items()}


def _rho_map(data: Any) -> dict[str, float | None] | None:
    if not isinstance(data, Mapping):
        return None
    return {str(k): None if v is None or v == "" else rho_from_json(v) for k, v in data.items()}


def _violations(data: Any) -> dict[str, dict[str, Any]] | None:
    if not isinstance(data, Mapping):
        return None
    return {str(k): dict(v) for k, v in data.items() if isinstance(v, Mapping)}


def violations_of(results: Mapping[str, Any],
                  first: Mapping[str, Any] | None = None) -> dict[str, dict[str, Any]] | None:
    """The ``violations`` of a row from a case's monitor results (violated metrics only);
    ``first``: {metric: (t, agent)} of the first violation, where known (else the result's
    deciding moment); ``worst_t``: the result's deciding moment (its worst value), which its
    text names."""
    out = {}
    for name, res in results.items():
        rho = getattr(res, "rho", None)
        if rho is None or not rho < 0:
            continue
        worst = getattr(res, "t", None)
        t, agent = (first or {}).get(name) or (worst, getattr(res, "agent", None))
        out[name] = {"t": None if t is None else float(t), "agent": agent,
                     "threshold": getattr(res, "threshold", None)}
        if worst is not None:
            out[name]["worst_t"] = float(worst)
    return out or None


def all_unavoidable(avoidable: Mapping[str, bool | None] | None) -> bool:
    """Every judged metric is unavoidable (False), and there is at least one."""
    return bool(avoidable) and all(v is False for v in avoidable.values())


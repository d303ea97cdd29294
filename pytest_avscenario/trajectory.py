"""The recorded trajectory of one simulated case: the contract between the simulator and
the monitors. The simulator (:mod:`pytest_avscenario.sim`) writes it; monitors read it and
nothing else, so neither knows the other.

Plain numpy arrays stacked as ``(agents, steps)`` so monitors vectorize over both. Agent 0
is always the ego. An agent that is not in the scene at a step (spawned later, removed after
the ego passed) has ``present`` False there and NaN kinematics. Build one from a simulator
run, or by hand from plain arrays with :meth:`Trajectory.from_arrays` (that is how monitors
are used and tested without a simulator). Saved as ``.npz`` without pickles.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

__all__ = ["Trajectory", "AgentView"]

_KINEMATICS = ("x", "y", "vx", "vy", "speed", "heading", "lane_offset")
_PER_STEP = _KINEMATICS + ("lane", "crashed", "present", "on_road")


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Per-agent, per-step recording of one run.

    Shapes: ``t`` is ``(T,)`` [s]; every per-step array is ``(A, T)``; ``length``/``width``
    are ``(A,)`` [m]. Positions [m] are world coordinates of the agent's centre; velocities
    [m/s]; heading [rad] counter-clockwise from +x; ``lane`` the id of the lane the agent
    follows (``""`` when none); ``lane_offset`` [m] its signed lateral offset from that
    lane's centre line (NaN when none); ``crashed`` whether it has collided (sticky);
    ``on_road`` whether its centre lies on some lane. ``signals`` holds extra named per-step
    arrays of shape ``(T,)`` (e.g. ``"bus.stop_arm"``); ``meta`` plain JSON data about the run.
    """

    t: np.ndarray
    names: tuple[str, ...]
    kinds: tuple[str, ...]
    length: np.ndarray
    width: np.ndarray
    x: np.ndarray
    y: np.ndarray
    vx: np.ndarray
    vy: np.ndarray
    speed: np.ndarray
    heading: np.ndarray
    lane: np.ndarray
    lane_offset: np.ndarray
    crashed: np.ndarray
    present: np.ndarray
    on_road: np.ndarray
    signals: Mapping[str, np.ndarray] = field(default_factory=dict)
    meta: Mapping[str, Any] = field(default_factory=dict)

    # -- construction ---------------------------------------------------------------------
    @classmethod
    def from_arrays(
        cls,
        t: Sequence[float] | np.ndarray,
        agents: Mapping[str, Mapping[str, Any]],
        signals: Mapping[str, Sequence[float]] | None = None,
        meta: Mapping[str, Any] | None = None,
    ) -> "Trajectory":
        """Build a trajectory from plain per-agent arrays.

        ``agents`` maps a name to a dict with ``x``, ``y`` (required, length T) and optional
        ``vx``, ``vy`` (default: finite differences of x, y), ``speed``, ``heading``
        (default: from the velocity), ``length`` (5.0), ``width`` (2.0), ``kind``
        (``"ego"`` for the first agent, else ``"car"``), ``lane`` (``""``), ``lane_offset``
        (NaN), ``crashed`` (False), ``present`` (True), ``on_road`` (True).
        The first agent is the ego.
        """
        t = np.asarray(t, dtype=float).reshape(-1)
        T = t.shape[0]
        if not agents:
            raise ValueError("a trajectory needs at least one agent (the ego)")
        names, kinds, length, width = [], [], [], []
        cols: dict[str, list[np.ndarray]] = {k: [] for k in _PER_STEP}
        for i, (name, a) in enumerate(agents.items()):
            names.append(str(name))
            kinds.append(str(a.get("kind", "ego" if i == 0 else "car")))
            length.append(float(a.get("length", 5.0)))
            width.append(float(a.get("width", 2.0)))
            x = _col(a["x"], T, name, "x")
            y = _col(a["y"], T, name, "y")
            if "vx" in a:
                vx = _col(a["vx"], T, name, "vx")
            else:
                vx = np.gradient(x, t) if T > 1 else np.zeros(T)
            if "vy" in a:
                vy = _col(a["vy"], T, name, "vy")
            else:
                vy = np.gradient(y, t) if T > 1 else np.zeros(T)
            speed = _col(a["speed"], T, name, "speed") if "speed" in a else np.hypot(vx, vy)
            heading = (
                _col(a["heading"], T, name, "heading") if "heading" in a else np.arctan2(vy, vx)
            )
            lane = a.get("lane", "")
            lane = np.full(T, lane, dtype=object) if isinstance(lane, str) else np.asarray(lane, dtype=object)
            lane_offset = _col(a.get("lane_offset", np.nan), T, name, "lane_offset")
            crashed = np.broadcast_to(np.asarray(a.get("crashed", False), dtype=bool), (T,))
            present = np.broadcast_to(np.asarray(a.get("present", True), dtype=bool), (T,))
            on_road = np.broadcast_to(np.asarray(a.get("on_road", True), dtype=bool), (T,))
            for k, v in zip(
                _PER_STEP,
                (x, y, vx, vy, speed, heading, lane_offset, lane, crashed, present, on_road),
            ):
                cols[k].append(v)
        arrays = {k: np.stack(v) for k, v in cols.items()}
        arrays["lane"] = arrays["lane"].astype(str)
        sig = {k: np.asarray(v, dtype=float).reshape(T) for k, v in (signals or {}).items()}
        return cls(
            t=t, names=tuple(names), kinds=tuple(kinds),
            length=np.asarray(length, dtype=float), width=np.asarray(width, dtype=float),
            signals=sig, meta=dict(meta or {}), **arrays,
        )

    # -- views ----------------------------------------------------------------------------
    @property
    def n_agents(self) -> int:
        return len(self.names)

    @property
    def n_steps(self) -> int:
        return int(self.t.shape[0])

    @property
    def dt(self) -> float:
        return float(self.t[1] - self.t[0]) if self.n_steps > 1 else float(self.meta.get("dt", 0.0))

    @property
    def positions(self) -> np.ndarray:
        """``(A, T, 2)`` centre positions [m]."""
        return np.stack([self.x, self.y], axis=-1)

    @property
    def velocities(self) -> np.ndarray:
        """``(A, T, 2)`` velocities [m/s]."""
        return np.stack([self.vx, self.vy], axis=-1)

    @property
    def ego(self) -> "AgentView":
        return AgentView(self, 0)

    def agent(self, name_or_index: str | int) -> "AgentView":
        if isinstance(name_or_index, str):
            try:
                return AgentView(self, self.names.index(name_or_index))
            except ValueError:
                raise KeyError(f"no agent {name_or_index!r}; agents: {list(self.names)}") from None
        return AgentView(self, int(name_or_index))

    def footprints(self, step: int) -> list[Any]:
        """Shapely polygons of every present agent's footprint at ``step`` (None if absent)."""
        from shapely.geometry import Polygon

        out = []
        for a in range(self.n_agents):
            if not self.present[a, step]:
                out.append(None)
                continue
            c, s = np.cos(self.heading[a, step]), np.sin(self.heading[a, step])
            hl, hw = self.length[a] / 2, self.width[a] / 2
            corners = np.array([[hl, hw], [hl, -hw], [-hl, -hw], [-hl, hw]])
            rot = np.array([[c, -s], [s, c]])
            pts = corners @ rot.T + np.array([self.x[a, step], self.y[a, step]])
            out.append(Polygon(pts))
        return out

    def prefix(self, steps: int) -> "Trajectory":
        """The first ``steps`` steps of the recording (signals cut alike; meta kept)."""
        from dataclasses import replace

        k = max(1, min(int(steps), self.n_steps))
        cut = {f: getattr(self, f)[:, :k] for f in _PER_STEP}
        sig = {n: np.asarray(v)[:k] for n, v in self.signals.items()}
        return replace(self, t=self.t[:k], signals=sig, **cut)

    # -- persistence ------------------------------------------------------------------------
    def _arrays(self) -> dict[str, np.ndarray]:
        arrays = {k: getattr(self, k) for k in _PER_STEP}
        arrays["lane"] = np.asarray(self.lane, dtype=str)
        arrays.update(t=self.t, length=self.length, width=self.width,
                      names=np.asarray(self.names, dtype=str),
                      kinds=np.asarray(self.kinds, dtype=str))
        for k, v in self.signals.items():
            arrays[f"signal:{k}"] = np.asarray(v)
        return arrays

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write an ``.npz`` (no pickles) atomically."""
        path = os.fspath(path)
        buf = io.BytesIO()
        arrays = self._arrays()
        arrays["meta"] = np.asarray(json.dumps(dict(self.meta), default=str))
        np.savez_compressed(buf, **arrays)
        from .files import atomic_write_bytes

        atomic_write_bytes(path, buf.getvalue(), durable=False)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> "Trajectory":
        with np.load(os.fspath(path), allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
        signals = {k[len("signal:"):]: v for k, v in data.items() if k.startswith("signal:")}
        return cls(
            t=data["t"], names=tuple(str(n) for n in data["names"]),
            kinds=tuple(str(k) for k in data["kinds"]),
            length=data["length"], width=data["width"],
            signals=signals, meta=json.loads(str(data["meta"])),
            **{k: data[k] for k in _PER_STEP},
        )

    def digest(self) -> str:
        """SHA-256 over every array's bytes: equal digests mean bit-identical runs."""
        h = hashlib.sha256()
        for k, v in sorted(self._arrays().items()):
            h.update(k.encode())
            h.update(np.ascontiguousarray(v).tobytes() if v.dtype != object else repr(v.tolist()).encode())
        return h.hexdigest()


@dataclass(frozen=True)
class AgentView:
    """One agent's rows of a trajectory (arrays of shape ``(T,)``)."""

    trajectory: Trajectory
    index: int

    @property
    def name(self) -> str:
        return self.trajectory.names[self.index]

    @property
    def kind(self) -> str:
        return self.trajectory.kinds[self.index]

    def __getattr__(self, key: str) -> Any:
        if key in _PER_STEP:
            return getattr(self.trajectory, key)[self.index]
        if key in ("length", "width"):
            return float(getattr(self.trajectory, key)[self.index])
        raise AttributeError(key)

    @property
    def position(self) -> np.ndarray:
        return self.trajectory.positions[self.index]


def _col(v: Any, T: int, agent: str, key: str) -> np.ndarray:
    arr = np.asarray(v, dtype=float)
    if arr.ndim == 0:
        return np.full(T, float(arr))
    arr = arr.reshape(-1)
    if arr.shape[0] != T:
        raise ValueError(f"agent {agent!r}: {key} has {arr.shape[0]} values but t has {T}")
    return arr

"""The plugin's side of ``avs-osi/1``: a driver whose decisions come from a stack in another process.

:class:`OSIStack` is an ordinary driver (``world.ego(..., driver=OSIStack("tcp://…"))``,
``--avs-driver osi:ADDRESS``, ``--avs-driver osi+spawn:COMMAND``) with its own vehicle
(:mod:`.vehicle`): at the start of each case it sends a ``Reset`` (the handshake: versions,
step, ids, the ego's route) and waits for ``Ready``; every step it sends the world as an
OSI ``SensorView`` and waits for the stack's ``MotionRequest`` (a desired state or a
desired trajectory, followed by the ego's controller) or ``TrafficUpdate`` (the stack moved its vehicle itself; checked against
:class:`Limits`). Every wait has a timeout. A REQ socket that timed out is closed and a
fresh one opened for the next request ("lazy pirate"), never reused: its state machine
would refuse to send again. A stack the plugin spawned is watched while it is awaited, so a
crash is an error at once (not a timeout later), and it is started again for the next case.

Sockets and spawned processes are kept per address and per command for the whole process
(one stack per pytest process or xdist worker), and stopped when the process exits.
Errors are :class:`~pytest_avscenario.sim.SimError` naming the test, the ego, the step and
the time, and what was wrong; the case is an error and every other case still runs.
"""

from __future__ import annotations

import atexit
import math
import os
import shlex
import shutil
import signal
import subprocess
import tempfile
import time
from dataclasses import dataclass
from typing import Any

from . import frame, wire, zmtp
from ..sim.errors import SimError

__all__ = ["OSIStack", "Limits", "configure", "parse_spec", "DEFAULT_TIMEOUT_S", "stop_all"]

DEFAULT_TIMEOUT_S = 5.0  # [s] per exchange; --avs-stack-timeout sets it (see configure)
STARTUP_TIMEOUT_S = 60.0  # [s] for a spawned stack's first answer (its imports)
_POLL_S = 0.05  # [s] how often a spawned stack's process is checked while it is awaited

#: [s] how long a wait for the next message spins before it blocks under ``--avs-stack-spin
#: auto`` when the machine has a CPU to spare for it (see :func:`auto_spin_s`)
AUTO_SPIN_S = 300e-6

# the process's settings: timeout [s]; spin [s] (0: block at once, the default; None:
# "auto", decided at the first exchange)
_settings: dict[str, Any] = {"timeout_s": DEFAULT_TIMEOUT_S, "spin_s": 0.0}


def configure(timeout_s: float | None = None, spin_s: float | str | None = None) -> None:
    """Set the process-wide default per-exchange timeout [s] (the plugin's
    ``--avs-stack-timeout``; an ``OSIStack(timeout_s=...)`` given one keeps its own) and the
    spin before each blocking wait [s] (``--avs-stack-spin``; ``"auto"``: :func:`auto_spin_s`,
    decided at the first exchange)."""
    if timeout_s is not None:
        _settings["timeout_s"] = float(timeout_s)
    if spin_s is not None:
        _settings["spin_s"] = None if spin_s == "auto" else float(spin_s)


def auto_spin_s(processes: int | None = None) -> float:
    """The spin of ``--avs-stack-spin auto``: :data:`AUTO_SPIN_S` when the CPUs this process
    may run on are at least twice the processes that run cases at once (each with a stack
    beside it, each side spinning while the other works), else 0 — a spinning process would
    take the CPU its own stack or another worker needs. ``processes``: by default the
    pytest-xdist workers of this run (``PYTEST_XDIST_WORKER_COUNT``), else 1."""
    if processes is None:
        try:
            processes = max(1, int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1")))
        except ValueError:
            processes = 1
    try:
        cpus = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cpus = os.cpu_count() or 1
    return AUTO_SPIN_S if cpus >= 2 * processes else 0.0


def spin_s() -> float:
    """[s] this process's spin before each blocking wait for a stack's answer."""
    value = _settings["spin_s"]
    if value is None:
        value = _settings["spin_s"] = auto_spin_s()
    return value


def settings_for(processes: int | None) -> dict[str, float]:
    """This process's stack settings for :func:`configure` in another process that runs its
    cases (a Dask worker), one of ``processes`` running cases at once on its machine (None:
    not known, e.g. a remote cluster: ``auto`` does not spin there)."""
    value = _settings["spin_s"]
    if value is None:
        value = 0.0 if processes is None else auto_spin_s(processes)
    return {"timeout_s": _settings["timeout_s"], "spin_s": value}


@dataclass(frozen=True)
class Limits:
    """What a ``TrafficUpdate`` may do to the ego in one step before it is refused as
    physically impossible: speed [m/s], the speed change per second [m/s^2], the yaw rate
    [rad/s], and how far [m] the position may land beyond the distance its speeds allow."""

    max_speed_mps: float = 70.0
    max_acceleration_mps2: float = 15.0
    max_yaw_rate_rps: float = 3.0
    jump_tolerance_m: float = 0.05


def parse_spec(spec: str) -> tuple[str | None, str | None]:
    """``(address, command)`` of a driver spec ``osi:ADDRESS`` or ``osi+spawn:COMMAND``;
    ``ValueError`` saying what is expected otherwise."""
    text = spec.strip()
    if text.startswith("osi+spawn:"):
        command = text[len("osi+spawn:"):].strip()
        if not command:
            raise ValueError(f"{spec!r}: give the command that starts the stack after 'osi+spawn:'")
        check_command(command)
        return None, command
    if text.startswith("osi:"):
        address = text[len("osi:"):].strip()
        check_address(address)
        return address, None
    raise ValueError(f"{spec!r} is not 'osi:ADDRESS' nor 'osi+spawn:COMMAND'")


def check_address(address: str) -> None:
    if not (address.startswith("tcp://") or address.startswith("ipc://")):
        raise ValueError(f"OSI stack address {address!r}: use tcp://HOST:PORT or ipc://PATH")
    if address.startswith("tcp://") and ":" not in address[len("tcp://"):]:
        raise ValueError(f"OSI stack address {address!r} has no port (tcp://127.0.0.1:5555)")


def check_command(command: str) -> None:
    """``ValueError`` when ``osi+spawn:``'s command cannot be started: its quoting does not
    close, or its program is neither on ``PATH`` nor an executable file (found at start-up,
    not once per case)."""
    try:
        args = shlex.split(command)
    except ValueError as exc:
        raise ValueError(f"stack command {command!r}: {exc}") from None
    if not args:
        raise ValueError("give the command that starts the stack after 'osi+spawn:'")
    program = args[0]
    if os.sep in program:
        if not (os.path.isfile(program) and os.access(program, os.X_OK)):
            raise ValueError(f"stack command {command!r}: {program!r} is not an executable file")
    elif shutil.which(program) is None:
        raise ValueError(f"stack command {command!r}: no program {program!r} on PATH")


class _Timeout(Exception):
    pass


class _Gone(Exception):
    pass


_RETRY_S = 0.01  # [s] between attempts to connect to a stack that does not listen yet


class _Channel:
    """One REQ connection to a stack, replaced after every timeout (lazy pirate).

    ZeroMQ's REQ is spoken directly on the socket (:mod:`.zmtp`): libzmq would hand each
    message to an I/O thread and back on both sides, ~6 thread wake-ups a step instead of 2
    (bench/README.md). Like a libzmq REQ, it connects to a stack that does not listen yet by
    trying again until the request's deadline."""

    def __init__(self, address: str) -> None:
        self.address = address
        self.req: zmtp.Requester | None = None

    def request(self, frames: list[bytes], timeout_s: float, alive: Any = None) -> list[bytes]:
        """The answer's frames; :class:`_Timeout` at ``timeout_s`` [s], :class:`_Gone` when
        ``alive()`` says why the stack is gone or the stack closed the connection."""
        deadline = time.monotonic() + timeout_s
        if self.req is not None and not self.req.usable():
            self.drop()  # closed by the stack since the last answer: connect afresh
        if self.req is not None:
            try:
                self.req.send(frames)
            except (zmtp.Closed, OSError):  # the stack went away since: start afresh
                self.drop()
        if self.req is None:
            self._connect(deadline, alive)
            self.req.send(frames)
        while True:
            now = time.monotonic()
            if now >= deadline:
                self.drop()
                raise _Timeout()
            try:
                return self.req.receive(min(deadline, now + _POLL_S) if alive is not None else deadline)
            except TimeoutError:
                pass
            except zmtp.ZMTPError:
                self.drop()
                raise
            except (zmtp.Closed, OSError):
                self.drop()
                self._gone(deadline, alive, "the stack closed the connection")
            if alive is not None:
                why = alive()
                if why:
                    self.drop()
                    raise _Gone(why)

    def _connect(self, deadline: float, alive: Any) -> None:
        req = zmtp.Requester(self.address, spin_s=spin_s())
        next_check = time.monotonic() + _POLL_S
        while not req.connect(deadline):
            now = time.monotonic()
            if now >= deadline:
                raise _Timeout()
            if alive is not None and now >= next_check:
                why = alive()
                if why:
                    raise _Gone(why)
                next_check = now + _POLL_S
            time.sleep(min(_RETRY_S, max(0.0, deadline - now)))
        self.req = req

    @staticmethod
    def _gone(deadline: float, alive: Any, what: str) -> None:
        """The peer closed the connection: a spawned stack's exit is awaited (briefly) so
        that the error names its exit code and output."""
        if alive is not None:
            until = min(deadline, time.monotonic() + 1.0)
            while time.monotonic() < until:
                why = alive()
                if why:
                    raise _Gone(why)
                time.sleep(0.005)
        raise _Gone(what)

    def drop(self) -> None:
        if self.req is not None:
            self.req.close()
            self.req = None


class _Spawned:
    """A stack process this process started: its command, address and log."""

    def __init__(self, command: str) -> None:
        self.command = command
        self.proc: subprocess.Popen | None = None
        self.address = ""
        self.log_path = ""
        self.starts = 0

    def ensure(self) -> tuple[str, bool]:
        """The address of a running process (started now if none runs); True when fresh."""
        if self.proc is not None and self.proc.poll() is None:
            return self.address, False
        self.starts += 1
        folder = tempfile.gettempdir()
        self.address = f"ipc://{folder}/avs-osi-{os.getpid()}-{id(self):x}-{self.starts}.sock"
        self.log_path = f"{folder}/avs-osi-{os.getpid()}-{id(self):x}-{self.starts}.log"
        args = shlex.split(self.command.replace("{address}", self.address))
        env = dict(os.environ, AVS_OSI_ADDRESS=self.address)
        env[wire.SPIN_ENV] = f"{spin_s() * 1e6:g}"
        with open(self.log_path, "wb") as log:
            try:
                self.proc = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=log,
                                             stderr=subprocess.STDOUT, env=env,
                                             start_new_session=True)
            except OSError as exc:
                raise SimError(f"cannot start the OSI stack {self.command!r}: {exc}") from None
        return self.address, True

    def alive(self) -> str | None:
        """None while the process runs, else what became of it (exit code, last output)."""
        if self.proc is None or self.proc.poll() is None:
            return None
        return f"the stack process exited with code {self.proc.returncode}{self.tail()}"

    def tail(self, n: int = 800) -> str:
        try:
            with open(self.log_path, "rb") as f:
                text = f.read()[-n:].decode(errors="replace").strip()
        except OSError:
            return ""
        return f"; its last output:\n{text}" if text else ""

    def stop(self) -> None:
        proc, self.proc = self.proc, None
        if proc is None or proc.poll() is not None:
            return
        try:
            os.killpg(proc.pid, signal.SIGTERM)  # its own session: the command and its children
            proc.wait(timeout=3)
        except (ProcessLookupError, PermissionError):
            pass
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=3)


_CHANNELS: dict[str, _Channel] = {}
_SPAWNED: dict[str, _Spawned] = {}


def stop_all() -> None:
    """Close every socket and stop every stack process this process started."""
    for ch in _CHANNELS.values():
        ch.drop()
    _CHANNELS.clear()
    stop_processes()
    _SPAWNED.clear()


def stop_processes() -> None:
    """Stop every stack process this process started (their sockets untouched: safe from
    another thread, e.g. on the way out of a process whose main thread is stuck)."""
    for sp in list(_SPAWNED.values()):
        sp.stop()


# three ways a spawned stack is stopped: the plugin's pytest_unconfigure (the run is over),
# this (any interpreter exit, an unhandled exception's included), and the plugin's own hard
# exits (stopping.py: a case that would not stop, a second SIGTERM) calling stop_processes
atexit.register(stop_all)


class OSIStack:
    """A stack out of process as the ego's driver, over ZeroMQ at ``address`` (``tcp://…``,
    ``ipc://…``), or started by this process with ``spawn="command {address}"``.

    ``timeout_s`` [s] bounds every exchange (default ``--avs-stack-timeout``, 5 s); a
    spawned stack has ``startup_timeout_s`` for its first answer. ``limits`` bound what a
    ``TrafficUpdate`` may do in one step.
    """

    name = "osi"
    dt = None  # the stack takes the world's step; the handshake tells it and it may refuse

    def __init__(self, address: str | None = None, *, spawn: str | None = None,
                 timeout_s: float | None = None, startup_timeout_s: float = STARTUP_TIMEOUT_S,
                 limits: Limits = Limits()) -> None:
        if (address is None) == (spawn is None):
            raise SimError("OSIStack: give an address (tcp://… or ipc://…) or spawn='COMMAND'")
        try:
            if address is not None:
                check_address(address)
            else:
                check_command(spawn)
        except ValueError as exc:
            raise SimError(f"OSIStack: {exc}") from None
        self.address = address
        self.spawn = spawn
        self.timeout_s = timeout_s
        self.startup_timeout_s = float(startup_timeout_s)
        self.limits = limits
        self._world: Any = None
        self._views: Any = None  # frame.SensorViews of the case

    def __repr__(self) -> str:
        return f"OSIStack({self.address!r})" if self.spawn is None else f"OSIStack(spawn={self.spawn!r})"

    def describe(self) -> dict:
        """Who drives, for the report (:mod:`pytest_avscenario.sim.drivers.identity`): named as
        ``--avs-driver`` would name this stack, so both ways of plugging it in read alike."""
        if self.spawn is None:
            return {"name": f"osi:{self.address}", "kind": "osi", "address": self.address}
        return {"name": f"osi+spawn:{self.spawn}", "kind": "osi", "command": self.spawn}

    # -- the driver protocol ------------------------------------------------------------------
    def make_ego(self, world: Any, position: Any, heading: float, speed: float, **_: Any) -> Any:
        from .vehicle import make_stack_ego

        return make_stack_ego(world, position, heading, speed)

    def reset(self, world: Any) -> None:
        """The handshake of one case: ``Reset`` out, ``Ready`` back (see docs/osi-protocol.md)."""
        self._world = world
        agents = world.agents
        if len(agents) > frame.MAX_AGENTS:
            raise SimError(f"{len(agents)} agents: the OSI ids of agents stop at {frame.MAX_AGENTS}",
                           test=world.name)
        ids = {a: i + 1 for i, a in enumerate(agents)}  # stable for the case (frame doc)
        view = world.view()
        self._views = frame.SensorViews(frame.lane_ground_truth(view), ids)
        ego = agents[0]
        lane_ids = {lane.id: frame.LANE_ID0 + i for i, lane in enumerate(view.lanes)}
        marks: dict[str, list] = {}
        for m in view.stop_marks:
            marks.setdefault(m.lane, []).append([m.s, m.kind])
        hello = {
            "protocol": wire.PROTOCOL.decode(), "revision": wire.REVISION,
            "osi_version": ".".join(map(str, wire.osi_version())),
            "case": world.name, "seed": world.seed, "dt": world.dt,
            "host_vehicle_id": 1,
            "agents": [{"id": i + 1, "name": a.name, "kind": a.kind,
                        "length": float(a.LENGTH), "width": float(a.WIDTH)}
                       for i, a in enumerate(agents)],
            "lanes": [{"id": lane_ids[l.id], "name": l.id, "width": l.width,
                       "speed_limit": l.speed_limit, "kind": l.kind,
                       "stop_marks": marks.get(l.id, [])} for l in view.lanes],
            "traffic_lights": _lights_hello(world, lane_ids),
            "ego": {"route": [lane_ids[l.id] for l in ego.plan], "route_index": ego.route_index,
                    "target_speed": ego.target_speed_request, "goal": ego.goal,
                    "sensor_range": world.sensor_range},
        }
        kind, body = self._ask(wire.pack(wire.RESET, hello), (wire.READY, wire.ERROR),
                               "the Reset of this case", ego, reset=True)
        if kind == wire.ERROR:
            self._fail(f"the stack refused the Reset: {body.decode(errors='replace')}", ego)
        ready = self._checked(lambda: wire.json_body(body, "Ready"), ego, "its Ready")
        self._check_ready(ready, ego)

    def _check_ready(self, ready: dict, ego: Any) -> None:
        w = self._world
        problems = []
        if ready.get("protocol") != wire.PROTOCOL.decode() or ready.get("revision") != wire.REVISION:
            problems.append(f"it speaks {ready.get('protocol')!r} revision {ready.get('revision')!r}, "
                            f"the plugin {wire.PROTOCOL.decode()!r} revision {wire.REVISION}")
        theirs = str(ready.get("osi_version", ""))
        if theirs.split(".")[0] != str(wire.osi_version()[0]):
            problems.append(f"its OSI version is {theirs!r}, the plugin's "
                            f"{'.'.join(map(str, wire.osi_version()))} (the major versions must agree)")
        dt = ready.get("dt")
        if not isinstance(dt, (int, float)) or abs(float(dt) - w.dt) > 1e-12:
            problems.append(f"it runs at dt={dt!r} s, the world steps at {w.dt!r} s (set --avs-dt "
                            "or @scenario(dt=...) to the stack's step)")
        if ready.get("host_vehicle_id") != 1:
            problems.append(f"it drives host vehicle {ready.get('host_vehicle_id')!r}, the ego is 1")
        if problems:
            self._fail("handshake failed: " + "; ".join(problems), ego)

    def exchange(self, ego: Any) -> tuple[str, tuple]:
        """One step: the SensorView out, the answer back, checked. ``("action", (a, delta))``
        for a MotionRequest, ``("state", (x, y, heading, speed))`` for a TrafficUpdate."""
        w = self._world
        if w is None:
            raise SimError(f"{self!r} was not reset before its first step (the world calls "
                           "reset(world) before the run)", agent=getattr(ego, "name", ""))
        t_ns = wire.ns(w.t)
        msg = self._views.build(w, t_ns)
        kind, body = self._ask(wire.pack(wire.SENSOR_VIEW, msg), wire.ANSWERS,
                               "the SensorView", ego)
        if kind == wire.ERROR:
            self._fail(f"the stack answered Error: {body.decode(errors='replace')}", ego)
        if kind == wire.MOTION_REQUEST:
            M = frame._osi()["motionrequest"]
            mr = self._checked(lambda: wire.parse(M.MotionRequest, body, "MotionRequest"), ego, "its answer")
            self._check_timestamp(mr, t_ns, "MotionRequest", ego)
            if mr.motion_request_type == M.MotionRequest.MOTION_REQUEST_TYPE_TRAJECTORY:
                a, d = self._checked(lambda: frame.trajectory_to_action(
                    mr.desired_trajectory, t_ns, float(ego.position[0]), float(ego.position[1]),
                    float(ego.heading), float(ego.speed), float(ego.LENGTH), w.dt),
                    ego, "its MotionRequest's desired_trajectory")
                return "action", (a, d)
            if mr.motion_request_type != M.MotionRequest.MOTION_REQUEST_TYPE_DESIRED_STATE \
                    or not mr.HasField("desired_state"):
                names = dict(M.MotionRequest.MotionRequestType.items())
                kind_name = next((k for k, v in names.items() if v == mr.motion_request_type),
                                 str(mr.motion_request_type))
                self._fail(f"MotionRequest of type {kind_name} has no desired_state (a desired "
                           "trajectory needs motion_request_type MOTION_REQUEST_TYPE_TRAJECTORY)", ego)
            a, d = self._checked(lambda: frame.motion_to_action(
                mr.desired_state, t_ns, float(ego.heading), float(ego.speed), float(ego.LENGTH),
                w.dt), ego, "its MotionRequest")
            return "action", (a, d)
        T = frame._osi()["trafficupdate"]
        tu = self._checked(lambda: wire.parse(T.TrafficUpdate, body, "TrafficUpdate"), ego, "its answer")
        self._check_timestamp(tu, t_ns, "TrafficUpdate", ego)
        mine = [mo for mo in tu.update if mo.id.value == 1]
        if len(mine) != 1:
            self._fail(f"TrafficUpdate must update the host vehicle (id 1) once; it updates "
                       f"ids {[mo.id.value for mo in tu.update]}", ego)
        return "state", self._plausible(frame.object_state(mine[0]), ego)

    # -- checks ---------------------------------------------------------------------------------
    def _plausible(self, st: dict, ego: Any) -> tuple[float, float, float, float]:
        w, lim = self._world, self.limits
        x, y, h, v = st["x"], st["y"], st["heading"], st["speed"]
        if not all(math.isfinite(q) for q in (x, y, h, v)):
            self._fail(f"TrafficUpdate has a non-finite state (x={x!r}, y={y!r}, yaw={h!r}, "
                       f"speed={v!r})", ego)
        dt = w.dt
        x0, y0, h0, v0 = float(ego.position[0]), float(ego.position[1]), float(ego.heading), float(ego.speed)
        problems = []
        if abs(v) > lim.max_speed_mps:
            problems.append(f"speed {v:.2f} m/s exceeds {lim.max_speed_mps:g} m/s")
        if abs(v - v0) / dt > lim.max_acceleration_mps2:
            problems.append(f"acceleration {(v - v0) / dt:.1f} m/s^2 exceeds "
                            f"{lim.max_acceleration_mps2:g} m/s^2")
        turn = math.atan2(math.sin(h - h0), math.cos(h - h0))
        if abs(turn) / dt > lim.max_yaw_rate_rps:
            problems.append(f"yaw rate {turn / dt:.2f} rad/s exceeds {lim.max_yaw_rate_rps:g} rad/s")
        jump = math.hypot(x - x0, y - y0)
        reach = max(abs(v0), abs(v)) * dt + lim.jump_tolerance_m
        if jump > reach:
            problems.append(f"it moved {jump:.2f} m in {dt:g} s (at most {reach:.2f} m at its "
                            f"speeds): a teleport")
        if problems:
            self._fail(f"TrafficUpdate is physically impossible: {'; '.join(problems)} "
                       f"(from ({x0:.2f}, {y0:.2f}) m at {v0:.2f} m/s to ({x:.2f}, {y:.2f}) m)", ego)
        return x, y, h, v

    def _check_timestamp(self, msg: Any, t_ns: int, what: str, ego: Any) -> None:
        got = wire.timestamp_ns(msg.timestamp) if msg.HasField("timestamp") else None
        if got != t_ns:
            shown = "none" if got is None else f"{got} ns ({got * 1e-9:.3f} s)"
            self._fail(f"{what} carries the wrong timestamp: {shown}, the request's is "
                       f"{t_ns} ns ({t_ns * 1e-9:.3f} s)", ego)

    def _checked(self, call: Any, ego: Any, what: str) -> Any:
        try:
            return call()
        except (wire.ProtocolError, ValueError) as exc:
            self._fail(f"{what}: {exc}", ego)

    # -- the exchange ---------------------------------------------------------------------------
    def _where(self) -> str:
        return self.address if self.spawn is None else f"{self.spawn!r} at {self.address}"

    def _fail(self, what: str, ego: Any) -> None:
        w = self._world
        step = int(round(w.t / w.dt)) if w is not None and w.dt > 0 else 0
        when = f"step {step} (t={w.t:.2f} s)" if w is not None else "reset"
        raise SimError(f"OSI stack {self._where()}, {when}: {what}",
                       test=getattr(w, "name", ""), agent=getattr(ego, "name", ""))

    def _ask(self, frames: list[bytes], expected: tuple, what: str, ego: Any,
             reset: bool = False) -> tuple[bytes, bytes]:
        timeout = self.timeout_s if self.timeout_s is not None else _settings["timeout_s"]
        alive = None
        if self.spawn is not None:
            sp = _SPAWNED.get(self.spawn)
            if sp is None:
                sp = _SPAWNED[self.spawn] = _Spawned(self.spawn)
            if reset:
                self.address, fresh = sp.ensure()
                if fresh:
                    timeout = max(timeout, self.startup_timeout_s)
            alive = sp.alive
        ch = _CHANNELS.get(self.address)
        if ch is None:
            ch = _CHANNELS[self.address] = _Channel(self.address)
        try:
            answer = ch.request(frames, timeout, alive)
        except _Timeout:
            again = "the socket was closed and reopened for the next case"
            if self.spawn is not None:
                # a stack that missed its deadline is presumed hung: a fresh one takes the next case
                _SPAWNED[self.spawn].stop()
                again = "the stack process was stopped and is started again for the next case"
            self._fail(f"no answer to {what} within {timeout:g} s (--avs-stack-timeout); {again}", ego)
        except _Gone as exc:
            again = "a new connection is opened for the next request"
            if self.spawn is not None:
                _SPAWNED[self.spawn].stop()  # alive but no longer answering: presumed broken
                again = "it is started again for the next case"
            self._fail(f"{exc} while it was answering {what}; {again}", ego)
        except zmtp.ZMTPError as exc:
            self._fail(f"while sending {what}: the peer at {self.address} breaks ZeroMQ's "
                       f"REQ/REP: {exc}", ego)
        try:
            return wire.unpack(answer, expected)
        except wire.ProtocolError as exc:
            self._fail(f"answer to {what}: {exc}", ego)
        raise AssertionError("unreachable")


def _lights_hello(world: Any, lane_ids: dict[str, int]) -> list[dict]:
    """The traffic lights' static facts for the Reset: OSI id, signal id and stop positions
    ``[lane OSI id, s [m]]`` (their state comes with every SensorView)."""
    lights = world.traffic_lights
    if lights is None:
        return []
    return [{"id": osi_id, "signal": sid,
             "stops": [[lane_ids[p.lane], p.s] for p in lights.lights[sid].stops
                       if p.lane in lane_ids]}
            for sid, osi_id in frame.light_ids(lights).items()]

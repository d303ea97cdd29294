"""ZeroMQ's REQ and REP sockets spoken directly on a plain socket (ZMTP 3.1, NULL mechanism).

avs-osi/1 is ZeroMQ request/reply on the wire (docs/osi-protocol.md), and a stack written
with libzmq or any ZeroMQ binding keeps speaking it. This module is the same wire without
libzmq's machinery on the plugin's side and in the Python kit: libzmq hands every message
from the application thread to an I/O thread of its own and back, so one lockstep round trip
wakes a thread ~6 times (each an inter-processor interrupt when the threads sit on different
CPUs) and costs ~90 µs of CPU on a small virtual machine; a process that reads and writes
its own socket wakes the other once each way (bench/README.md, "Stacks out of process").

What is spoken, from the ZMTP 3.1 specification (rfc.zeromq.org/spec/37): the 64-byte
greeting (signature, version 3.1, mechanism ``NULL``), a ``READY`` command carrying the
``Socket-Type`` (``REQ`` here, ``REP`` expected back, or the reverse), then frames of one
flags byte (MORE, LONG, COMMAND) and a 1- or 8-byte length. A REQ puts an empty delimiter
frame before its message; a REP sends back everything up to that delimiter before its
answer. ``PING`` is answered with ``PONG`` (a peer that asks for heartbeats); other commands
are ignored. Security mechanisms other than ``NULL`` are refused, as avs-osi/1 uses none.
"""

from __future__ import annotations

import errno
import os
import select
import socket
import struct
import time
from typing import Any

__all__ = ["Requester", "Replier", "ZMTPError", "Closed", "open_address"]

_SIGNATURE = b"\xff" + b"\x00" * 8 + b"\x7f"
GREETING = _SIGNATURE + b"\x03\x01" + b"NULL".ljust(20, b"\x00") + b"\x00" + b"\x00" * 31
_MORE, _LONG, _COMMAND = 1, 2, 4
_LONG_SIZE = struct.Struct(">Q")
_PEERS = {b"REQ": (b"REP", b"ROUTER"), b"REP": (b"REQ", b"DEALER")}  # who may talk to whom
_CHUNK = 1 << 16
#: the largest message read [bytes]: a SensorView of a whole town map is a few MB; a length
#: beyond this is refused before any of it is buffered (a stack's bug, or no ZeroMQ peer)
MAX_MESSAGE_BYTES = 64 << 20


class ZMTPError(Exception):
    """The peer broke ZMTP (or is no ZeroMQ peer at all); the text says what arrived."""


class Closed(ConnectionError):
    """The peer closed the connection."""


def _command(name: bytes, body: bytes = b"") -> bytes:
    data = bytes([len(name)]) + name + body
    if len(data) > 255:
        return bytes([_COMMAND | _LONG]) + _LONG_SIZE.pack(len(data)) + data
    return bytes([_COMMAND, len(data)]) + data


def _ready(socket_type: bytes) -> bytes:
    props = b""
    for name, value in ((b"Socket-Type", socket_type), (b"Identity", b"")):
        props += bytes([len(name)]) + name + struct.pack(">I", len(value)) + value
    return _command(b"READY", props)


def _properties(data: bytes) -> dict[bytes, bytes]:
    props, i = {}, 0
    while i < len(data):
        n = data[i]
        name = data[i + 1:i + 1 + n]
        i += 1 + n
        if i + 4 > len(data):
            raise ZMTPError(f"a READY property {name!r} without its length")
        (size,) = struct.unpack_from(">I", data, i)
        props[name.lower()] = data[i + 4:i + 4 + size]
        i += 4 + size
    return props


# the header of a short frame of n bytes, without and with MORE
_SHORT = (tuple(bytes([0, n]) for n in range(256)), tuple(bytes([_MORE, n]) for n in range(256)))
_DELIMITER = b"\x01\x00"  # a REQ's envelope: one empty frame, MORE


def frames_bytes(frames: list[bytes], more_after: bool = False, prefix: bytes = b"") -> bytes:
    """The bytes of one multipart message (``frames`` in order, MORE on all but the last;
    on the last too when ``more_after``: an envelope that a message follows), after
    ``prefix`` (bytes already framed: an envelope)."""
    parts = [prefix]
    append = parts.append
    more = _SHORT[_MORE]
    last = len(frames) - 1
    for i, f in enumerate(frames):
        n = len(f)
        if i == last and not more_after:
            append(_SHORT[0][n] if n < 256 else b"\x02" + _LONG_SIZE.pack(n))
        else:
            append(more[n] if n < 256 else b"\x03" + _LONG_SIZE.pack(n))
        append(f)
    return b"".join(parts)


def _ipc_path(address: str) -> str:
    path = address[len("ipc://"):]
    return "\0" + path[1:] if path.startswith("@") else path  # "@name": Linux's abstract namespace


def open_address(address: str, timeout_s: float | None = None) -> socket.socket:
    """A connected stream socket to ``tcp://HOST:PORT`` or ``ipc://PATH`` (not yet greeted),
    blocking; ``OSError`` when nobody listens there (yet), ``TimeoutError`` when a tcp
    connection is not made within ``timeout_s`` [s]."""
    if address.startswith("ipc://"):
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            s.connect(_ipc_path(address))
        except OSError:
            s.close()
            raise
        return s
    host, port = _host_port(address)
    s = socket.create_connection((host, port), timeout=timeout_s)
    s.settimeout(None)
    s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)  # lockstep: never wait for more
    return s


def _host_port(address: str) -> tuple[str, int]:
    rest = address[len("tcp://"):]
    host, _, port = rest.rpartition(":")
    if ";" in host:  # libzmq's "source;destination" form: the destination
        host = host.split(";")[-1]
    return host.strip("[]"), int(port)


def _spin(poll: Any, until: float) -> None:
    """Wait for input without giving the CPU up: ``poll(0)`` until it reports something or
    the monotonic clock passes ``until``, yielding to any other runnable thread between looks
    (so a process that shares this CPU runs at once). Then the caller's blocking wait returns
    at once or waits as usual.

    Why: on a machine whose idle CPUs halt (a virtual machine's vCPU given back to its host), a
    process that blocks resumes slowly and cold; in lockstep each side blocks once a step.
    A bounded spin keeps the CPU while the answer is due (bench/README.md)."""
    now, yield_ = time.monotonic, os.sched_yield
    while now() < until:
        if poll(0):
            return
        yield_()


class _Connection:
    """One greeted ZMTP connection: whole messages in, whole messages out."""

    def __init__(self, sock: socket.socket, socket_type: bytes) -> None:
        self.sock = sock
        self.fd = sock.fileno()
        self.type = socket_type
        # what was received and not yet consumed from ``pos``: the bytes of one ``recv`` as
        # they came (a message that arrived whole is cut out of them without a copy more),
        # a bytearray while a message longer than one read is gathered
        self.buf: bytes | bytearray = b""
        self.pos = 0
        self.greeted = False
        self.peer_type = b""
        self.local = sock.family == socket.AF_UNIX  # ipc://
        self.spin_s = 0.0  # [s] how long a wait with a deadline spins before it blocks (_spin)
        self._poll = select.poll()
        self._poll.register(self.fd, select.POLLIN)

    def close(self) -> None:
        try:
            self.sock.close()
        except OSError:
            pass

    # -- raw bytes ------------------------------------------------------------------------------
    def _fill(self, deadline: float | None) -> None:
        """Append what the peer sent to the buffer, waiting until ``deadline`` (monotonic [s];
        None: a plain read, for a caller that polled already or may block until the rest of a
        message it has begun arrives). ``TimeoutError`` when nothing came, :class:`Closed` on
        EOF."""
        if deadline is not None:
            if self.spin_s:
                _spin(self._poll.poll, min(deadline, time.monotonic() + self.spin_s))
            while True:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError()
                if self._poll.poll(max(1, int(left * 1000 + 0.999))):
                    break
        try:
            data = self.sock.recv(_CHUNK)
        except BlockingIOError:
            raise TimeoutError() from None
        except (ConnectionResetError, BrokenPipeError) as exc:
            raise Closed(str(exc)) from None
        if not data:
            raise Closed("the peer closed the connection")
        buf, pos = self.buf, self.pos
        if pos >= len(buf):
            self.buf, self.pos = data, 0
            return
        if type(buf) is bytes:
            buf = bytearray(memoryview(buf)[pos:])
        elif pos:
            del buf[:pos]
        buf += data
        self.buf, self.pos = buf, 0

    def _take(self, n: int, deadline: float | None) -> bytes:
        while len(self.buf) - self.pos < n:
            self._fill(deadline)
        out = bytes(self.buf[self.pos:self.pos + n])
        self.pos += n
        return out

    def send(self, data: bytes) -> None:
        try:
            self.sock.sendall(data)
        except (BrokenPipeError, ConnectionResetError) as exc:
            raise Closed(str(exc)) from None

    # -- the handshake --------------------------------------------------------------------------
    def greet(self, deadline: float) -> None:
        """Greeting and READY both ways; :class:`ZMTPError` if the peer is not a ZeroMQ
        peer of a matching type."""
        self.send(GREETING + _ready(self.type))
        theirs = self._take(11, deadline)
        if theirs[0] != 0xFF or not theirs[9] & 1:
            raise ZMTPError(f"not a ZeroMQ 3.x peer (its first bytes: {theirs!r})")
        if theirs[10] < 3:
            raise ZMTPError(f"the peer speaks ZMTP {theirs[10]}.x; 3.0 or later is needed")
        rest = self._take(64 - 11, deadline)
        mechanism = rest[1:21].rstrip(b"\x00")
        if mechanism != b"NULL":
            raise ZMTPError(f"the peer asks for the {mechanism.decode(errors='replace')} security "
                            "mechanism; avs-osi/1 uses NULL")
        flags, body = self._frame(deadline)
        if not flags & _COMMAND or not body.startswith(b"\x05READY"):
            raise ZMTPError(f"expected the peer's READY command, got {body[:24]!r}")
        self.peer_type = _properties(body[6:]).get(b"socket-type", b"")
        if self.peer_type not in _PEERS[self.type]:
            raise ZMTPError(f"a {self.type.decode()} socket cannot talk to a "
                            f"{self.peer_type.decode(errors='replace') or 'nameless'} socket")
        self.greeted = True

    # -- frames and messages --------------------------------------------------------------------
    def _frame(self, deadline: float | None) -> tuple[int, bytes]:
        buf, pos = self.buf, self.pos
        if len(buf) - pos >= 2:  # the common case: a short frame already here
            flags = buf[pos]
            if not flags & _LONG:
                n = buf[pos + 1]
                if len(buf) - pos - 2 >= n:
                    self.pos = pos + 2 + n
                    return flags, bytes(buf[pos + 2:pos + 2 + n])
        flags = self._take(1, deadline)[0]
        if flags & ~(_MORE | _LONG | _COMMAND):
            raise ZMTPError(f"a frame with flags {flags:#04x}: not ZMTP 3")
        if flags & _LONG:
            (n,) = _LONG_SIZE.unpack(self._take(8, deadline))
            if n > MAX_MESSAGE_BYTES:
                raise ZMTPError(f"a frame of {n:,} bytes, more than the {MAX_MESSAGE_BYTES:,} "
                                "bytes a message may have")
        else:
            n = self._take(1, deadline)[0]
        return flags, self._take(n, deadline)

    def message(self, deadline: float | None) -> list[bytes]:
        """The next whole multipart message; commands in between are handled here.
        ``TimeoutError`` at ``deadline`` when it is not whole by then (what came of it stays
        buffered: a later call goes on)."""
        while True:
            if self.pos < len(self.buf):  # nothing to parse while nothing is buffered
                frames = self._parse()
                if frames is not None:
                    return frames
            self._fill(deadline)

    def _parse(self) -> list[bytes] | None:
        """The buffered message's frames when it is whole (consumed), else None (nothing
        consumed but the commands before it, which are handled)."""
        buf, pos = self.buf, self.pos
        if type(buf) is not bytes:
            return self._parse_gathered()
        end = len(buf)
        frames: list[bytes] = []
        append = frames.append
        while True:  # the common case: data frames in the bytes of one read
            if end - pos < 2:
                return None
            flags = buf[pos]
            if flags <= _MORE:
                start = pos + 2
                pos = start + buf[pos + 1]
            elif flags <= _MORE | _LONG and end - pos >= 9:
                start = pos + 9
                pos = start + _LONG_SIZE.unpack_from(buf, pos + 1)[0]
                if pos - start > MAX_MESSAGE_BYTES:
                    return self._parse_gathered()  # which says why it is refused
            else:
                return self._parse_gathered()  # a command, a cut header, a broken frame
            if pos > end:
                return None
            append(buf[start:pos])
            if not flags & _MORE:
                self.pos = pos
                return frames

    def _parse_gathered(self) -> list[bytes] | None:
        """:meth:`_parse` for any frame, in bytes or in a bytearray being gathered."""
        buf, pos = self.buf, self.pos
        end = len(buf)
        src = buf if type(buf) is bytes else memoryview(buf)  # a bytearray: copy once, below
        try:
            frames: list[bytes] = []
            size = 0
            while True:
                if end - pos < 2:
                    return None
                flags = buf[pos]
                if flags & ~(_MORE | _LONG | _COMMAND):
                    raise ZMTPError(f"a frame with flags {flags:#04x}: not ZMTP 3")
                if flags & _LONG:
                    if end - pos < 9:
                        return None
                    (n,) = _LONG_SIZE.unpack_from(buf, pos + 1)
                    start = pos + 9
                else:
                    n = buf[pos + 1]
                    start = pos + 2
                if size + n > MAX_MESSAGE_BYTES:  # refused before any of it is gathered
                    if n > MAX_MESSAGE_BYTES:
                        raise ZMTPError(f"a frame of {n:,} bytes, more than the "
                                        f"{MAX_MESSAGE_BYTES:,} bytes a message may have")
                    raise ZMTPError(f"a message of more than {MAX_MESSAGE_BYTES:,} bytes")
                pos = start + n
                if pos > end:
                    return None
                body = src[start:pos] if src is buf else bytes(src[start:pos])
                if flags & _COMMAND:
                    if frames:
                        raise ZMTPError("a command inside a multipart message")
                    self.pos = pos  # handled once, whatever follows
                    self._on_command(body)
                    continue
                frames.append(body)
                size += n
                if not flags & _MORE:
                    self.pos = pos
                    return frames
        finally:
            if src is not buf:
                src.release()

    def _on_command(self, body: bytes) -> None:
        n = body[0] if body else 0
        name = body[1:1 + n]
        if name == b"PING":  # PING: TTL (2 bytes), context; PONG echoes the context
            self.send(_command(b"PONG", body[1 + n + 2:]))


class Requester:
    """A REQ socket's side of one connection to a REP at ``address``.

    :meth:`request` sends one message and returns the answer's frames (without the REQ
    envelope). :meth:`connect`, :meth:`send` and :meth:`receive` are its steps for callers
    that check something between waits (the plugin watches a spawned stack's process)."""

    def __init__(self, address: str, spin_s: float = 0.0) -> None:
        self.address = address
        self.spin_s = spin_s  # [s] each wait for an answer spins this long before it blocks
        self.conn: _Connection | None = None

    def connect(self, deadline: float) -> bool:
        """Connect and greet; False while nobody listens at the address yet (try again)."""
        try:
            sock = open_address(self.address, max(0.01, deadline - time.monotonic()))
        except (FileNotFoundError, ConnectionRefusedError, TimeoutError):
            return False
        except OSError as exc:
            if exc.errno in (errno.ENOENT, errno.ECONNREFUSED, errno.EAGAIN):
                return False
            raise
        conn = _Connection(sock, b"REQ")
        try:
            conn.greet(deadline)
        except Closed:
            conn.close()
            raise ZMTPError("the peer closed the connection during ZeroMQ's handshake (is it "
                            "a REP socket?)") from None
        except BaseException:
            conn.close()
            raise
        conn.spin_s = self.spin_s
        self.conn = conn
        return True

    def usable(self) -> bool:
        """False when the peer closed the connection while no answer was owed (a stack
        restarted, or one that drops peers silent past its heartbeat timeout: its PINGs are
        answered only while an answer is awaited); what it sent meanwhile is handled.

        Over ``ipc://`` it is not looked at (a system call a step saved): sending to a Unix
        socket whose peer closed fails at once (EPIPE), and the caller connects afresh then;
        over tcp the first send to a closed peer succeeds, so it is asked before."""
        conn = self.conn
        if conn is None:
            return False
        if conn.local:
            return True
        try:
            while conn._poll.poll(0):
                conn._fill(None)
                while len(conn.buf) > conn.pos:
                    flags, body = conn._frame(None)
                    if not flags & _COMMAND:
                        raise ZMTPError("a message that no request asked for")
                    conn._on_command(body)
        except (Closed, OSError):
            return False
        return True

    def send(self, frames: list[bytes]) -> None:
        self.conn.send(frames_bytes(frames, prefix=_DELIMITER))  # the empty delimiter, then the message

    def receive(self, deadline: float) -> list[bytes]:
        """The answer's frames; ``TimeoutError`` at ``deadline`` (the connection is kept: a
        later call picks the answer up), :class:`Closed` if the peer went away."""
        frames = self.conn.message(deadline)
        if not frames or frames[0] != b"":
            raise ZMTPError(f"an answer without the REQ envelope: {[f[:24] for f in frames[:3]]}")
        return frames[1:]

    def close(self) -> None:
        if self.conn is not None:
            self.conn.close()
            self.conn = None


class Replier:
    """A REP socket bound at ``address``: any number of REQ peers, one request answered at
    a time, each answer to the peer that asked. ``ipc://`` paths are replaced if a file is
    in the way, as libzmq does."""

    def __init__(self, address: str, handshake_timeout_s: float = 5.0, spin_s: float = 0.0) -> None:
        self.address = address
        self.handshake_timeout_s = handshake_timeout_s
        self.spin_s = spin_s  # [s] each wait for a request spins this long before it blocks
        if address.startswith("ipc://"):
            path = _ipc_path(address)
            if not path.startswith("\0"):
                try:
                    os.unlink(path)
                except FileNotFoundError:
                    pass
            self.listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            self.listener.bind(path)
            self.path: str | None = path
        elif address.startswith("tcp://"):
            host, port = _host_port(address)
            family = socket.AF_INET6 if ":" in host else socket.AF_INET
            self.listener = socket.socket(family, socket.SOCK_STREAM)
            self.listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            self.listener.bind(("" if host == "*" else host, port))
            self.path = None
        else:
            raise ValueError(f"address {address!r}: use tcp://HOST:PORT or ipc://PATH")
        self.listener.listen(16)
        self._listen_fd = self.listener.fileno()
        self.poller = select.poll()
        self.poller.register(self._listen_fd, select.POLLIN)
        self.conns: dict[int, _Connection] = {}
        self.last: _Connection | None = None  # where the request being answered came from
        self.envelope = b""

    def receive(self, timeout_s: float | None = None) -> list[bytes] | None:
        """The next request's frames (envelope removed), or None after ``timeout_s`` [s]
        (None: wait for ever). Peers that connect are greeted, peers that leave dropped."""
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        for conn in list(self.conns.values()):
            if len(conn.buf) > conn.pos:  # a request read along with an earlier message
                got = self._message(conn)
                if got is not None:
                    return got
        poll, listen_fd = self.poller.poll, self._listen_fd
        if self.spin_s:
            until = time.monotonic() + self.spin_s
            _spin(poll, until if deadline is None else min(deadline, until))
        while True:
            ms = -1 if deadline is None else max(0, int((deadline - time.monotonic()) * 1000 + 0.999))
            events = poll(ms)
            if not events:
                if deadline is not None and time.monotonic() >= deadline:
                    return None
                continue
            for fd, _ in events:
                if fd == listen_fd:
                    conn = self._accept()
                    if conn is not None and len(conn.buf) > conn.pos:  # sent with its READY
                        got = self._message(conn)
                        if got is not None:
                            return got
                    continue
                conn = self.conns.get(fd)
                if conn is None:
                    continue
                try:
                    conn._fill(None)
                except TimeoutError:
                    continue
                except (Closed, OSError):
                    self._drop(conn)
                    continue
                got = self._message(conn)
                if got is not None:
                    return got

    def _message(self, conn: _Connection) -> list[bytes] | None:
        try:
            frames = conn.message(None)
        except TimeoutError:
            return None  # not whole yet
        except (Closed, ZMTPError, OSError):
            self._drop(conn)
            return None
        if frames[0] == b"":  # a REQ peer's envelope: the delimiter alone
            self.last, self.envelope = conn, _DELIMITER
            del frames[0]
            return frames
        try:
            cut = frames.index(b"")
        except ValueError:
            self._drop(conn)  # a REQ always sends the delimiter: a peer that does not is broken
            return None
        self.last = conn
        self.envelope = frames_bytes(frames[:cut + 1], more_after=True)
        return frames[cut + 1:]

    def send(self, frames: list[bytes]) -> None:
        """The answer to the last request (dropped if its peer has left, as ZeroMQ does)."""
        conn, self.last = self.last, None
        if conn is None or conn.fd not in self.conns:
            return
        try:
            conn.send(frames_bytes(frames, prefix=self.envelope))
        except (Closed, OSError):
            self._drop(conn)

    def _accept(self) -> _Connection | None:
        try:
            sock, _ = self.listener.accept()
        except OSError:
            return None
        if sock.family != socket.AF_UNIX:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        conn = _Connection(sock, b"REP")
        try:
            conn.greet(time.monotonic() + self.handshake_timeout_s)
        except (ZMTPError, Closed, TimeoutError, OSError):
            conn.close()
            return None
        self.conns[conn.fd] = conn
        self.poller.register(conn.fd, select.POLLIN)
        return conn

    def _drop(self, conn: _Connection) -> None:
        if self.conns.pop(conn.fd, None) is not None:
            self.poller.unregister(conn.fd)
        if self.last is conn:
            self.last = None
        conn.close()

    def close(self) -> None:
        for conn in list(self.conns.values()):
            self._drop(conn)
        self.listener.close()
        if self.path is not None and not self.path.startswith("\0"):
            try:
                os.unlink(self.path)
            except OSError:
                pass

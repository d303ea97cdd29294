"""The wire format of ``avs-osi/1``: what travels between the plugin and a stack, and nothing else.

Every message is one ZeroMQ multipart message of three frames ``[PROTOCOL, kind, body]``:
``PROTOCOL`` is ``b"avs-osi/1"``, ``kind`` the ASCII name of what the body holds and ``body``
either a serialized ASAM OSI message (``SensorView``, ``TrafficUpdate``, ``MotionRequest``)
or UTF-8 JSON (``Reset``, ``Ready``) or UTF-8 text (``Error``). The plugin's socket is a
REQ, the stack's a REP: one request, one answer, in lockstep. docs/osi-protocol.md is the
specification; this module is its one implementation on the Python side (the plugin's
client and the stack kit both use it), so the two cannot drift apart.

Timestamps are integers of nanoseconds on the wire (OSI's ``Timestamp``: ``seconds`` and
``nanos``); :func:`ns` and :func:`timestamp_ns` convert.
"""

from __future__ import annotations

import json
import math
from typing import Any

__all__ = ["PROTOCOL", "REVISION", "ProtocolError", "ns", "timestamp_ns", "set_timestamp",
           "pack", "unpack", "osi_version", "OSI_VERSION"]

PROTOCOL = b"avs-osi/1"
REVISION = 2  # the protocol's own revision, checked in the handshake (2: lanes in the first
#              SensorView after a Reset only)
#: the environment variable in which ``osi+spawn:`` hands the stack it starts the plugin's
#: spin [µs] (``--avs-stack-spin``): the kit spins as long waiting for each request; any
#: other stack may ignore it (docs/osi-protocol.md, "Waiting")
SPIN_ENV = "AVS_OSI_SPIN_US"

#: message kinds (the second frame)
RESET, READY, SENSOR_VIEW, TRAFFIC_UPDATE, MOTION_REQUEST, ERROR = (
    b"Reset", b"Ready", b"SensorView", b"TrafficUpdate", b"MotionRequest", b"Error")
ANSWERS = (TRAFFIC_UPDATE, MOTION_REQUEST, ERROR)


class ProtocolError(ValueError):
    """A message that breaks the protocol; the text says which rule and what arrived."""


def ns(t: float) -> int:
    """Nanoseconds of a simulation time ``t`` [s] (rounded to the nearest)."""
    return int(round(float(t) * 1e9))


def timestamp_ns(ts: Any) -> int:
    """Nanoseconds of an ``osi3.Timestamp``."""
    return int(ts.seconds) * 1_000_000_000 + int(ts.nanos)


def set_timestamp(ts: Any, t_ns: int) -> None:
    """Fill an ``osi3.Timestamp`` from nanoseconds (``nanos`` always in [0, 1e9))."""
    ts.seconds, ts.nanos = divmod(int(t_ns), 1_000_000_000)


def osi_version() -> tuple[int, int, int]:
    """The OSI interface version of the installed ``osi3`` package, as (major, minor, patch)."""
    from osi3 import osi_version_pb2

    v = osi_version_pb2.DESCRIPTOR.GetOptions().Extensions[osi_version_pb2.current_interface_version]
    return int(v.version_major), int(v.version_minor), int(v.version_patch)


OSI_VERSION = None  # filled on first use by :func:`set_version`


def set_version(msg_version: Any) -> None:
    """Fill an ``osi3.InterfaceVersion`` with the installed OSI version."""
    global OSI_VERSION
    if OSI_VERSION is None:
        OSI_VERSION = osi_version()
    msg_version.version_major, msg_version.version_minor, msg_version.version_patch = OSI_VERSION


def pack(kind: bytes, body: Any) -> list[bytes]:
    """The three frames of one message; ``body`` is bytes, a dict (JSON) or text."""
    if isinstance(body, dict):
        body = json.dumps(_plain(body), sort_keys=True, default=str, allow_nan=False).encode()
    elif isinstance(body, str):
        body = body.encode()
    return [PROTOCOL, kind, body]


def _plain(value: Any) -> Any:
    """``value`` with every non-finite float made ``null``: strict JSON parsers (a C++ or
    Rust stack's) refuse ``NaN`` and ``Infinity``."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def unpack(frames: list[bytes], expected: tuple[bytes, ...]) -> tuple[bytes, bytes]:
    """``(kind, body)`` of a received message; :class:`ProtocolError` says what is wrong."""
    if len(frames) != 3:
        shown = [bytes(f[:24]) for f in frames[:4]]
        raise ProtocolError(f"expected 3 frames [b'avs-osi/1', kind, body], got {len(frames)}: {shown}")
    proto, kind, body = frames
    if type(body) is not bytes or type(kind) is not bytes or type(proto) is not bytes:
        proto, kind, body = bytes(proto), bytes(kind), bytes(body)  # e.g. pyzmq's Frames
    if proto != PROTOCOL:
        raise ProtocolError(f"first frame must be {PROTOCOL!r}, got {proto[:40]!r}")
    if kind not in expected:
        raise ProtocolError(f"wrong message type {kind[:40]!r}; expected "
                            f"{' or '.join(k.decode() for k in expected)}")
    return kind, body


def json_body(body: bytes, what: str) -> dict:
    """The JSON object of a ``Reset``/``Ready`` body; :class:`ProtocolError` when it is none."""
    try:
        value = json.loads(body.decode())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ProtocolError(f"{what} body is not UTF-8 JSON ({exc}): {body[:60]!r}") from None
    if not isinstance(value, dict):
        raise ProtocolError(f"{what} body must be a JSON object, got {body[:60]!r}")
    return value


def parse(cls: Any, body: bytes, what: str) -> Any:
    """An OSI message of class ``cls`` from ``body``; :class:`ProtocolError` if it does not parse."""
    msg = cls()
    try:
        msg.ParseFromString(body)
    except Exception as exc:
        from google.protobuf.message import DecodeError

        if not isinstance(exc, (DecodeError, RuntimeError, ValueError)):
            raise
        raise ProtocolError(f"{what}: unparseable bytes ({type(exc).__name__}: {exc}; "
                            f"{len(body)} bytes starting {body[:16]!r})") from None
    return msg

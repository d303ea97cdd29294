"""ZeroMQ's REQ/REP spoken directly on a socket (pytest_avscenario.stack.zmtp) talks to libzmq.

The plugin's client and the Python kit speak ZMTP themselves; a stack written with libzmq
(any binding) must not notice. Each test pairs one side of :mod:`~pytest_avscenario.stack.zmtp`
with a pyzmq (libzmq) socket on the other side, over ``ipc://`` and ``tcp://``.
"""

from __future__ import annotations

import socket
import threading
import time

import pytest

zmq = pytest.importorskip("zmq")

from pytest_avscenario.stack import zmtp  # noqa: E402

SIZES = (0, 1, 255, 256, 1000, 300_000)  # short and long frames, empty ones, a big one


def _free_tcp() -> str:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp://127.0.0.1:{s.getsockname()[1]}"


@pytest.fixture(params=["ipc", "tcp"])
def address(request, tmp_path):
    return f"ipc://{tmp_path}/s.sock" if request.param == "ipc" else _free_tcp()


def _echo_rep(address: str, stop: threading.Event, delay_s: float = 0.0, **options) -> threading.Thread:
    """A libzmq REP answering every request with its frames reversed."""
    ctx = zmq.Context.instance()
    sock = ctx.socket(zmq.REP)
    for name, value in options.items():
        sock.setsockopt(getattr(zmq, name), value)
    sock.bind(address)

    def run() -> None:
        try:
            while not stop.is_set():
                if sock.poll(50):
                    frames = sock.recv_multipart()
                    time.sleep(delay_s)
                    sock.send_multipart(frames[::-1])
        finally:
            sock.close(linger=0)

    t = threading.Thread(target=run, daemon=True)
    t.start()
    return t


def _connected(address: str) -> zmtp.Requester:
    req = zmtp.Requester(address)
    deadline = time.monotonic() + 5
    while not req.connect(deadline):
        time.sleep(0.01)
    return req


def test_a_requester_talks_to_a_libzmq_rep(address):
    stop = threading.Event()
    _echo_rep(address, stop)
    req = _connected(address)
    try:
        for n in SIZES:
            frames = [b"avs-osi/1", b"SensorView", bytes(range(256)) * (n // 256) + b"x" * (n % 256)]
            req.send(frames)
            assert req.receive(time.monotonic() + 5) == frames[::-1]
    finally:
        req.close()
        stop.set()


def test_a_requester_finds_nobody_then_connects_once_the_rep_binds(tmp_path):
    address = f"ipc://{tmp_path}/late.sock"
    req = zmtp.Requester(address)
    assert req.connect(time.monotonic() + 1) is False
    stop = threading.Event()
    _echo_rep(address, stop)
    try:
        assert req.connect(time.monotonic() + 5) is True
        req.send([b"a", b"b"])
        assert req.receive(time.monotonic() + 5) == [b"b", b"a"]
    finally:
        req.close()
        stop.set()


def test_a_late_answer_times_out_and_is_picked_up_by_the_next_wait(address):
    stop = threading.Event()
    _echo_rep(address, stop, delay_s=0.3)
    req = _connected(address)
    try:
        req.send([b"slow", b"answer"])
        with pytest.raises(TimeoutError):
            req.receive(time.monotonic() + 0.05)
        assert req.receive(time.monotonic() + 5) == [b"answer", b"slow"]
    finally:
        req.close()
        stop.set()


def test_heartbeats_of_a_libzmq_peer_are_answered_while_the_answer_is_awaited(tmp_path):
    # the REP pings every 20 ms and drops a connection silent for 100 ms; its answer takes
    # 400 ms: only a requester that answers PING with PONG keeps the connection
    address = f"ipc://{tmp_path}/hb.sock"
    stop = threading.Event()
    _echo_rep(address, stop, delay_s=0.4, HEARTBEAT_IVL=20, HEARTBEAT_TIMEOUT=100, HEARTBEAT_TTL=200)
    req = _connected(address)
    try:
        req.send([b"x", b"y"])
        assert req.receive(time.monotonic() + 5) == [b"y", b"x"]
    finally:
        req.close()
        stop.set()


def test_a_connection_the_rep_dropped_between_requests_is_noticed_before_the_next_one(address):
    # idle between cases, the requester answers no PING: the REP drops it after 100 ms
    from pytest_avscenario.stack import client

    stop = threading.Event()
    _echo_rep(address, stop, HEARTBEAT_IVL=20, HEARTBEAT_TIMEOUT=100, HEARTBEAT_TTL=200)
    channel = client._Channel(address)
    try:
        assert channel.request([b"a", b"b"], 5.0) == [b"b", b"a"]
        time.sleep(0.5)
        assert channel.request([b"c", b"d"], 5.0) == [b"d", b"c"]
    finally:
        channel.drop()
        stop.set()


def test_a_replier_answers_libzmq_reqs_each_its_own(address):
    rep = zmtp.Replier(address)
    ctx = zmq.Context.instance()
    a, b = ctx.socket(zmq.REQ), ctx.socket(zmq.REQ)
    for s in (a, b):
        s.setsockopt(zmq.LINGER, 0)
        s.setsockopt(zmq.RCVTIMEO, 5000)
        s.connect(address)
    try:
        for n in SIZES:
            body = b"z" * n
            a.send_multipart([b"a", body])
            b.send_multipart([b"b", body])
            for _ in range(2):  # whichever comes first, each answer goes to its asker
                frames = rep.receive(5.0)
                rep.send([frames[0] + b"!", frames[1]])
            assert a.recv_multipart() == [b"a!", body]
            assert b.recv_multipart() == [b"b!", body]
    finally:
        a.close(linger=0)
        b.close(linger=0)
        rep.close()


def test_a_replier_drops_the_answer_of_a_peer_that_left_and_serves_the_next(tmp_path):
    address = f"ipc://{tmp_path}/s.sock"
    rep = zmtp.Replier(address)
    ctx = zmq.Context.instance()
    gone = ctx.socket(zmq.REQ)
    gone.connect(address)
    gone.send_multipart([b"first"])
    assert rep.receive(5.0) == [b"first"]
    gone.close(linger=0)  # a requester that timed out: closed before its answer
    time.sleep(0.05)
    rep.send([b"too late"])
    fresh = ctx.socket(zmq.REQ)
    fresh.setsockopt(zmq.RCVTIMEO, 5000)
    fresh.connect(address)
    try:
        fresh.send_multipart([b"second"])
        assert rep.receive(5.0) == [b"second"]
        rep.send([b"answer"])
        assert fresh.recv_multipart() == [b"answer"]
        assert rep.receive(0.05) is None  # nothing else pending
    finally:
        fresh.close(linger=0)
        rep.close()


def test_what_is_not_a_zeromq_peer_is_refused_on_both_sides(tmp_path):
    address = f"ipc://{tmp_path}/s.sock"
    rep = zmtp.Replier(address, handshake_timeout_s=1.0)
    junk = socket.socket(socket.AF_UNIX)
    junk.connect(f"{tmp_path}/s.sock")
    junk.sendall(b"GET / HTTP/1.1\r\n\r\n" + b"\x00" * 64)
    assert rep.receive(0.3) is None  # refused, and the REP still serves
    ctx = zmq.Context.instance()
    ok = ctx.socket(zmq.REQ)
    ok.setsockopt(zmq.RCVTIMEO, 5000)
    ok.connect(address)
    ok.send_multipart([b"hello"])
    assert rep.receive(5.0) == [b"hello"]
    rep.send([b"world"])
    assert ok.recv_multipart() == [b"world"]
    ok.close(linger=0)
    junk.close()
    rep.close()

    # a REQ that reaches something speaking another protocol says so
    server = socket.socket(socket.AF_UNIX)
    server.bind(f"{tmp_path}/http.sock")
    server.listen(1)

    def http() -> None:
        conn, _ = server.accept()
        conn.sendall(b"HTTP/1.1 400 Bad Request\r\n\r\n" + b" " * 80)
        time.sleep(0.5)
        conn.close()

    threading.Thread(target=http, daemon=True).start()
    req = zmtp.Requester(f"ipc://{tmp_path}/http.sock")
    with pytest.raises(zmtp.ZMTPError, match="not a ZeroMQ 3.x peer"):
        req.connect(time.monotonic() + 2)
    server.close()


def test_a_requester_refuses_a_peer_of_the_wrong_socket_type(tmp_path):
    address = f"ipc://{tmp_path}/pub.sock"
    pub = zmq.Context.instance().socket(zmq.PUB)
    pub.bind(address)
    try:
        with pytest.raises(zmtp.ZMTPError, match="REQ socket cannot talk to a PUB|is it a REP socket"):
            zmtp.Requester(address).connect(time.monotonic() + 2)
    finally:
        pub.close(linger=0)


def test_a_stack_that_hangs_up_on_a_request_is_an_error_at_once_not_a_timeout(tmp_path):
    from pytest_avscenario.sim import SimError, World
    from pytest_avscenario.stack import OSIStack, client

    address = f"ipc://{tmp_path}/rude.sock"
    rep = zmtp.Replier(address)

    def hang_up() -> None:
        rep.receive(10.0)  # the Reset arrives; no answer, the connection closed
        rep.close()

    threading.Thread(target=hang_up, daemon=True).start()
    w = World(seed=1, driver=OSIStack(address, timeout_s=30), name="t::rude")
    road = w.straight_road(lanes=1, length=200)
    w.ego(road.lane(0), s=10.0, speed=10.0)
    try:  # said at once, not as "no answer within 30 s"
        with pytest.raises(SimError, match="closed the connection while it was answering the Reset"):
            w.run(seconds=1)
    finally:
        client.stop_all()


def _raw_req(path: str) -> socket.socket:
    """A socket that has greeted a Replier as a REQ, by hand: the test writes its frames."""
    raw = socket.socket(socket.AF_UNIX)
    raw.connect(path)
    raw.sendall(zmtp.GREETING + zmtp._ready(b"REQ"))
    return raw


def test_a_request_that_arrives_in_pieces_is_whole_when_it_is_answered(tmp_path):
    # a message cut anywhere (mid header, mid length, mid body; a long frame among short
    # ones; a PING before it) is gathered across reads and answered once, whole
    address = f"ipc://{tmp_path}/s.sock"
    rep = zmtp.Replier(address)
    raw = _raw_req(f"{tmp_path}/s.sock")
    try:
        body = bytes(range(256)) * 3
        ping = bytes([zmtp._COMMAND, 7]) + b"\x04PING\x00\x0a"
        wire_bytes = ping + zmtp.frames_bytes([b"avs", b"", body], prefix=zmtp._DELIMITER)
        got: list = []
        t = threading.Thread(target=lambda: got.append(rep.receive(5.0)))
        t.start()
        for i in range(0, len(wire_bytes), 5):
            raw.sendall(wire_bytes[i:i + 5])
            time.sleep(0.001)
        t.join(5)
        assert got == [[b"avs", b"", body]]
        rep.send([b"ok"])
        answer = b""
        while not answer.endswith(b"ok"):
            answer += raw.recv(4096)
        # after the REP's greeting: the PING's one PONG, then the answer behind its envelope
        pong = bytes([zmtp._COMMAND, 5]) + b"\x04PONG"
        assert answer.count(pong) == 1
        assert answer.endswith(pong + zmtp._DELIMITER + b"\x00\x02ok")
    finally:
        raw.close()
        rep.close()


def test_a_command_inside_a_multipart_message_drops_the_peer(tmp_path):
    # ZMTP 3.1: commands come between messages, never between the frames of one
    address = f"ipc://{tmp_path}/s.sock"
    rep = zmtp.Replier(address)
    raw = _raw_req(f"{tmp_path}/s.sock")
    try:
        raw.sendall(zmtp._DELIMITER + bytes([zmtp._MORE, 1]) + b"a"
                    + bytes([zmtp._COMMAND, 5]) + b"\x04PING" + bytes([0, 1]) + b"b")
        assert rep.receive(0.5) is None
        assert not rep.conns  # dropped, as a broken peer
    finally:
        raw.close()
        rep.close()

"""Stacks out of process (avs-osi/1): what the wire costs per step and per case.

Run ``python bench/bench_stack.py`` (``--repeats N``, default 15; ``--steps N`` round trips
per transport, default 2000). Three measurements, each over ``ipc://`` and ``tcp://``
(loopback) against a server in its own process:

1. Wire alone: a REQ/REP round trip of three frames the size of a following case's
   SensorView (~1 kB), answered at once by a pyzmq echo server.
2. Protocol step: one full step of the protocol without the simulation — the plugin builds
   the SensorView of a following scene, the kit (``python -m pytest_avscenario.stack``)
   turns it into the Observation, asks the autopilot and answers a MotionRequest, the plugin
   decodes it into (acceleration, steering). Against the same autopilot call in process.
3. Per case: the vehicle-following case of example_tests/test_02 (nominal parameters, 12 s
   at 0.1 s = 120 steps, the lead's wobble included) with the autopilot in process and
   served through the kit; wall time per case, median over repeats after a warm-up.

Machines are shared and noisy (2 cores here, the stack process competing with pytest's):
compare ratios measured within one run.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = __file__.rsplit("/bench/", 1)[0]
sys.path.insert(0, ROOT)
sys.path.insert(0, f"{ROOT}/example_tests")

import zmq  # noqa: E402

from pytest_avscenario.sim import World  # noqa: E402
from pytest_avscenario.stack import OSIStack, client, frame, wire  # noqa: E402

ECHO = """
import sys, zmq
s = zmq.Context.instance().socket(zmq.REP); s.bind(sys.argv[1])
while True:
    s.send_multipart(s.recv_multipart())
"""


def _start(args: list[str]) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=ROOT)
    return subprocess.Popen([sys.executable, *args], env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)


def _addresses(tag: str) -> dict[str, str]:
    folder = tempfile.mkdtemp(prefix="avs-bench-")
    with __import__("socket").socket() as s:  # a free loopback port
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    return {"ipc": f"ipc://{folder}/{tag}.sock", "tcp": f"tcp://127.0.0.1:{port}"}


def following(driver):
    import subscenarios as sub

    w = World(seed=7, driver=driver, name="bench::following")
    road = w.straight_road(lanes=1, length=400)
    w.ego(road.lane(0), s=20.0, speed=12.0)
    w.car(road.lane(0), s=50.0, speed=10.0, behavior=sub.wobble(sub.slow_down(3.0, 2.5, 5.0), sd=0.3))
    return w


def bench_wire(steps: int) -> None:
    print("1. wire alone: REQ/REP round trip of 3 frames (~1 kB body) to a pyzmq echo process")
    body = b"x" * 1000
    for kind, address in _addresses("echo").items():
        proc = _start(["-c", ECHO, address])
        try:
            sock = zmq.Context.instance().socket(zmq.REQ)
            sock.connect(address)
            for _ in range(200):
                sock.send_multipart([wire.PROTOCOL, b"SensorView", body]); sock.recv_multipart()
            t0 = time.perf_counter()
            for _ in range(steps):
                sock.send_multipart([wire.PROTOCOL, b"SensorView", body]); sock.recv_multipart()
            us = (time.perf_counter() - t0) / steps * 1e6
            sock.close(linger=0)
        finally:
            proc.kill(); proc.wait()
        print(f"   {kind}: {us:6.1f} µs per round trip")


def bench_step(steps: int) -> None:
    print("2. one protocol step (SensorView out, kit + autopilot, MotionRequest back, decoded)")
    from osi3 import osi_motionrequest_pb2 as M

    w = following("autopilot")
    w.run(seconds=0.1)  # agents in running order, observation state as in a run
    ego = w.agents[0]
    obs = w.observe(ego)
    from pytest_avscenario.sim.drivers import resolve

    auto = resolve("autopilot")
    t0 = time.perf_counter()
    for _ in range(steps):
        auto.act(w.observe(ego))
    here = (time.perf_counter() - t0) / steps * 1e6
    print(f"   in process: observe + autopilot: {here:6.1f} µs per step")
    ids = {a: i + 1 for i, a in enumerate(w.agents)}
    static = frame.lane_ground_truth(w.view())

    for kind, address in _addresses("kit").items():
        proc = _start(["-m", "pytest_avscenario.stack", address])
        try:
            sock = zmq.Context.instance().socket(zmq.REQ)
            sock.connect(address)
            ego_plan = [frame.LANE_ID0 + w.lane_index.code[l.index] for l in ego.plan]
            hello = {"protocol": "avs-osi/1", "revision": 1, "dt": w.dt, "host_vehicle_id": 1,
                     "agents": [{"id": i + 1, "name": a.name, "kind": a.kind} for i, a in enumerate(w.agents)],
                     "lanes": [{"id": frame.LANE_ID0 + i, "width": l.width, "speed_limit": l.speed_limit}
                               for i, l in enumerate(w.view().lanes)],
                     "ego": {"route": ego_plan, "route_index": ego.route_index}}
            sock.send_multipart(wire.pack(wire.RESET, hello)); sock.recv_multipart()
            times = {"build": 0.0, "round trip": 0.0, "decode": 0.0}
            for i in range(steps + 100):
                a = time.perf_counter()
                msg = frame.sensor_view(w, wire.ns(w.t), static, ids)
                b = time.perf_counter()
                sock.send_multipart(wire.pack(wire.SENSOR_VIEW, msg))
                kind_, body = wire.unpack(sock.recv_multipart(), wire.ANSWERS)
                c = time.perf_counter()
                mr = M.MotionRequest(); mr.ParseFromString(body)
                frame.motion_to_action(mr.desired_state, wire.ns(w.t), ego.heading, ego.speed, 5.0, w.dt)
                d = time.perf_counter()
                if i >= 100:
                    times["build"] += b - a; times["round trip"] += c - b; times["decode"] += d - c
            sock.close(linger=0)
        finally:
            proc.kill(); proc.wait()
        total = sum(times.values()) / steps * 1e6
        parts = ", ".join(f"{k} {v / steps * 1e6:.1f}" for k, v in times.items())
        print(f"   {kind}: {total:6.1f} µs per step ({parts}; the round trip includes the kit's "
              f"Observation and the autopilot, {here:.1f} µs in process)")


def bench_case(repeats: int) -> None:
    print(f"3. per case: the following case, 120 steps, median of {repeats}")

    def ticks(pid: int) -> float:
        # [s] user + system CPU of a process (the stack's), from /proc
        fields = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")

    def timed(make_driver, pid: int | None = None) -> tuple[float, float]:
        out = []
        cpu = 0.0
        for i in range(repeats + 2):
            w = following(make_driver())
            t0, c0 = time.perf_counter(), time.process_time()
            k0 = ticks(pid) if pid else 0.0
            w.run(seconds=12)
            if i >= 2:
                out.append(time.perf_counter() - t0)
                cpu += time.process_time() - c0 + ((ticks(pid) - k0) if pid else 0.0)
        return statistics.median(out), cpu / repeats

    here, here_cpu = timed(lambda: "autopilot")
    print(f"   in process: {here * 1e3:6.1f} ms per case (CPU {here_cpu * 1e3:.1f} ms)")
    for kind, address in _addresses("case").items():
        proc = _start(["-m", "pytest_avscenario.stack.autopilot", address])
        try:
            there, there_cpu = timed(lambda: OSIStack(address, timeout_s=60), proc.pid)
        finally:
            proc.kill(); proc.wait(); client.stop_all()
        print(f"   served over {kind}: {there * 1e3:6.1f} ms per case, {there / here:.2f}x in process, "
              f"{(there - here) / 120 * 1e6:.0f} µs per step more; CPU of both processes "
              f"{there_cpu * 1e3:.1f} ms, {there_cpu / here_cpu:.2f}x, "
              f"{(there_cpu - here_cpu) / 120 * 1e6:.0f} µs per step more")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--repeats", type=int, default=15)
    p.add_argument("--steps", type=int, default=2000)
    args = p.parse_args()
    bench_wire(args.steps)
    bench_step(args.steps // 4)
    bench_case(args.repeats)


if __name__ == "__main__":
    main()

"""Instructions per protocol step (avs-osi/1), counted by valgrind: a measure the machine's load does not move.

Run ``python bench/stack_instructions.py`` (``--calls N``, default 2000; ``--pieces``, default
``kit plugin zmtp``; ``--tree PATH``: measure the project checked out at PATH, e.g. a
worktree of an older commit, with this script). Each piece runs twice under ``valgrind --tool=callgrind`` in a process of
its own, with 0 and with N calls after the same set-up and warm-up; the difference over N is
the instructions of one call (user space: Python, protobuf, the C library; not the kernel's):

* ``kit``: the kit's answer to one SensorView of the following scene (``kit.handle``: parse,
  Observation, autopilot, MotionRequest), as in section 3 of ``bench_stack.py``;
* ``plugin``: the plugin's ``OSIStack.exchange`` with its channel answering at once (the
  SensorView written, the message packed, the answer unpacked, parsed, checked and turned
  into (acceleration, steering)), without the wire;
* ``zmtp``: a request framed, sent and parsed by a ``zmtp.Replier``, its answer framed, sent
  and parsed by the ``zmtp.Requester`` (both sides, one process, one socket pair).

The three sum to the user-space instructions of one step over ipc on both sides. Wall and CPU
times of a step in lockstep run ~3x their hot-loop figures on this machine (bench/README.md);
instructions are what the code's changes move, measured the same under any load.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import threading
import time

ROOT = os.environ.get("AVS_TREE") or __file__.rsplit("/bench/", 1)[0]


def kit_session(w):
    """The scene ``w``'s ego served by the kit's autopilot, reset as the plugin resets a stack:
    (ego, OSI ids of the agents, the lanes' ground truth, the kit's session). Shared with
    ``bench_stack.py``'s section 3 (this script imports the modules of the tree it measures)."""
    from pytest_avscenario.stack import frame, kit, wire

    ego = w.agents[0]
    ids = {a: i + 1 for i, a in enumerate(w.agents)}
    view = w.view()
    hello = {"protocol": wire.PROTOCOL.decode(), "revision": wire.REVISION, "dt": w.dt,
             "host_vehicle_id": 1,
             "agents": [{"id": i + 1, "name": a.name, "kind": a.kind} for i, a in enumerate(w.agents)],
             "lanes": [{"id": frame.LANE_ID0 + i, "width": l.width, "speed_limit": l.speed_limit}
                       for i, l in enumerate(view.lanes)],
             "ego": {"route": [frame.LANE_ID0 + w.lane_index.code[l.index] for l in ego.plan],
                     "route_index": ego.route_index}}
    _, session = kit.handle(wire.pack(wire.RESET, hello), None, "autopilot")
    return ego, ids, frame.lane_ground_truth(view), session


def piece(what: str):
    """The call to count, after its set-up."""
    sys.path.insert(0, ROOT)
    sys.path.insert(0, f"{ROOT}/bench")
    sys.path.insert(0, f"{ROOT}/example_tests")
    import bench_stack as B
    from pytest_avscenario.stack import OSIStack, client, frame, kit, wire, zmtp

    w = B.following("autopilot")
    w.run(seconds=0.1)
    ego, ids, static, session = kit_session(w)
    views = frame.SensorViews(static, ids)
    t_ns = wire.ns(w.t)
    first = views.build(w, t_ns)
    kit.handle(wire.pack(wire.SENSOR_VIEW, first), session, "autopilot")
    request = wire.pack(wire.SENSOR_VIEW, views.build(w, t_ns))
    answer = kit.handle(request, session, "autopilot")[0]
    if what == "kit":
        return lambda: kit.handle(request, session, "autopilot")
    if what == "plugin":
        address = "ipc://" + tempfile.gettempdir() + "/avs-instructions-none.sock"

        class AtOnce:
            """A channel whose stack answers at once: the Reset's Ready, then the answer above."""

            def request(self, frames, timeout_s, alive=None):
                if frames[1] == wire.RESET:
                    return kit.handle(frames, None, "autopilot")[0]
                return answer

            def drop(self) -> None:
                pass

        client._CHANNELS[address] = AtOnce()
        stack = OSIStack(address, timeout_s=60)
        stack.reset(w)
        return lambda: stack.exchange(ego)
    if what == "zmtp":
        address = "ipc://" + tempfile.mkdtemp(prefix="avs-instructions-") + "/z.sock"
        rep, req = zmtp.Replier(address), zmtp.Requester(address)
        t = threading.Thread(target=lambda: req.connect(time.monotonic() + 600))
        t.start()
        while t.is_alive():
            rep.receive(0.01)  # greets the requester
        mr = wire.pack(wire.MOTION_REQUEST, answer[2])

        def cycle() -> None:
            req.usable()
            req.send(request)
            rep.receive(600.0)
            rep.send(mr)
            req.receive(time.monotonic() + 600)

        return cycle
    raise SystemExit(f"unknown piece {what!r}: kit, plugin or zmtp")


def count(what: str, calls: int, tree: str) -> int:
    """Instructions valgrind collected for the whole process with ``calls`` calls."""
    out = tempfile.mktemp(prefix="avs-callgrind-")
    env = dict(os.environ, PYTHONPATH=tree, AVS_TREE=tree)
    run = subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}",
                          sys.executable, __file__, "--run", what, str(calls)],
                         env=env, capture_output=True, text=True)
    try:
        os.unlink(out)
    except OSError:
        pass
    got = re.search(r"Collected : (\d+)", run.stderr)
    if got is None:
        raise SystemExit(f"valgrind said:\n{run.stderr[-2000:]}")
    return int(got.group(1))


def main() -> None:
    if len(sys.argv) == 4 and sys.argv[1] == "--run":
        call = piece(sys.argv[2])
        for _ in range(20):
            call()
        for _ in range(int(sys.argv[3])):
            call()
        return
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--calls", type=int, default=2000)
    p.add_argument("--pieces", default="kit plugin zmtp")
    p.add_argument("--tree", default=ROOT)
    args = p.parse_args()
    tree = os.path.abspath(args.tree)
    print(f"instructions of one call, {tree}")
    total = 0
    for what in args.pieces.split():
        n = (count(what, args.calls, tree) - count(what, 0, tree)) / args.calls
        total += n
        print(f"   {what}: {n:,.0f} instructions a call")
    print(f"   together: {total:,.0f} instructions a step")


if __name__ == "__main__":
    main()

"""Simulator cost: our World against raw highway-env, lane tracking against the full scan.

Run ``python bench/bench_sim.py`` (``--repeats N``, default 25). CPU time per case is
``time.process_time`` around building the world, placing agents, running and recording (the
Trajectory included), median over repeats after a warm-up. Machines are shared and noisy:
compare ratios measured within one run, not absolute numbers across runs.

1. Vehicle following (ego + braking lead, one lane, 10 s at 0.1 s): ours with the "idm" ego,
   with a trivial policy (observation built each step) and with the autopilot, against raw
   highway-env stepping two ``IDMVehicle``s with ``road.act(); road.step(dt)``.
2. Lane lookup on a 2-car intersection case: our tracking against highway-env's
   ``get_closest_lane_index`` (every lane, every agent, every step) in the same world.
3. Per-case cost of each road type, and growth with 2, 5, 10, 20 agents.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from typing import Callable

import numpy as np

sys.path.insert(0, __file__.rsplit("/bench/", 1)[0])

from pytest_avscenario.sim import World  # noqa: E402
from pytest_avscenario.sim import behaviors as b  # noqa: E402


def cpu_ms(fn: Callable[[], object], repeats: int) -> float:
    fn()  # warm-up: imports, caches
    times = []
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        times.append(time.process_time() - t0)
    return 1e3 * statistics.median(times)


# -- 1. following ------------------------------------------------------------------------------------


def raw_following() -> None:
    from highway_env.road.lane import StraightLane
    from highway_env.road.road import Road, RoadNetwork
    from highway_env.vehicle.behavior import IDMVehicle

    net = RoadNetwork()
    net.add_lane("a", "b", StraightLane([0.0, 0.0], [400.0, 0.0]))
    road = Road(net, np_random=np.random.default_rng(0))
    road.vehicles.append(IDMVehicle.make_on_lane(road, ("a", "b", 0), 0.0, 12.0))
    road.vehicles.append(IDMVehicle.make_on_lane(road, ("a", "b", 0), 30.0, 10.0))
    for _ in range(100):
        road.act()
        road.step(0.1)


def our_following(driver) -> Callable[[], object]:
    def run():
        w = World(seed=1, driver=driver)
        road = w.straight_road(lanes=1, length=400)
        w.ego(road.lane(0), s=0.0, speed=12.0)
        w.car(road.lane(0), s=30.0, speed=10.0, behavior=b.brake_at(3.0, decel=6.0))
        return w.run(10.0)
    return run


def hold_speed(obs):
    return 0.0, 0.0


# -- 2. lane lookup ----------------------------------------------------------------------------------


def intersection_world() -> World:
    w = World(seed=1, driver="idm")
    w.intersection()
    return w


def intersection_2car() -> object:
    w = World(seed=1, driver="idm")
    inter = w.intersection()
    w.ego(inter.stop_line("south").before(30), speed=8.0, route=inter.route("south", "left"))
    w.car(inter.stop_line("north").before(30), speed=8.0, behavior=b.turn("straight", stop=False))
    return w.run(10.0)


class FullScan:
    """Replace lane tracking with highway-env's default lookup (scan every lane) while active."""

    def __enter__(self):
        from pytest_avscenario.sim import roads

        self.roads = roads
        self.track = roads.LaneIndex.track

        def track(index, agent):
            index.progress(agent)  # route progress stays identical
            net = agent.world._road.network
            li = net.get_closest_lane_index(agent.position, agent.heading)
            agent.lane_index = li
            agent.lane = net.get_lane(li)
            agent.lane_r = agent.lane.local_coordinates(agent.position)[1]
            agent.is_on_road = agent.lane.on_lane(agent.position)

        roads.LaneIndex.track = track
        return self

    def __exit__(self, *exc):
        self.roads.LaneIndex.track = self.track


# -- 3. road types and scaling ----------------------------------------------------------------------


def two_way_case() -> object:
    w = World(seed=1, driver="idm")
    road = w.two_way_road()
    w.ego(road.lane(0), s=0.0, speed=10.0)
    w.car(road.lane(0, "backward"), s=150.0, speed=10.0, behavior=b.encroach(1.0, at=2.0))
    w.parked_car(road.parking_lane, s=60.0)
    return w.run(10.0)


def scaled(n_agents: int) -> Callable[[], object]:
    def run():
        w = World(seed=1, driver="idm")
        road = w.straight_road(lanes=3, length=1000)
        w.ego(road.lane(1), s=0.0, speed=10.0)
        for k in range(n_agents - 1):
            w.car(road.lane(k % 3), s=20.0 + 15.0 * k, speed=8.0 + (k % 4))
        return w.run(10.0)
    return run


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=25)
    args = ap.parse_args()
    n = args.repeats
    print(f"python {sys.version.split()[0]}, numpy {np.__version__}, median of {n} (CPU ms per case)\n")

    raw = cpu_ms(raw_following, n)
    idm = cpu_ms(our_following("idm"), n)
    policy = cpu_ms(our_following(hold_speed), n)
    rows = [("raw highway-env (2 IDMVehicles, road.act/step, no recording)", raw),
            ("World, ego driver 'idm' (+ recording)", idm),
            ("World, ego driver = trivial policy (observation each step)", policy)]
    try:
        from pytest_avscenario.sim.drivers.autopilot import Autopilot  # noqa: F401

        rows.append(("World, ego driver 'autopilot'", cpu_ms(our_following("autopilot"), n)))
    except ImportError:
        pass
    print("## Vehicle following, 10 s at 0.1 s\n")
    print("| run | CPU ms / case | ratio to raw |\n|---|---:|---:|")
    for name, ms in rows:
        print(f"| {name} | {ms:.2f} | {ms / raw:.2f} |")

    tracked = cpu_ms(intersection_2car, n)
    with FullScan():
        scan = cpu_ms(intersection_2car, n)
    print("\n## Lane lookup, 2-car intersection case (ego 'idm' turning left, 10 s)\n")
    print("| lookup | CPU ms / case |\n|---|---:|")
    n_lanes = len(intersection_world().__dict__["_index"].order)
    print(f"| highway-env get_closest_lane_index (all {n_lanes} lanes, every step) | {scan:.2f} |")
    print(f"| our tracking (current lane, then its neighbours/successors) | {tracked:.2f} |")
    print(f"\nspeed-up {scan / tracked:.2f}x")

    print("\n## Per road type (ego 'idm', 10 s)\n")
    print("| case | CPU ms / case |\n|---|---:|")
    print(f"| straight, following (2 agents) | {idm:.2f} |")
    print(f"| two-way, encroaching car + parked car (3 agents) | {cpu_ms(two_way_case, n):.2f} |")
    print(f"| intersection, ego left + crossing car (2 agents) | {tracked:.2f} |")

    print("\n## Growth with agents (3-lane straight road, 10 s)\n")
    print("| agents | CPU ms / case | per agent |\n|---:|---:|---:|")
    for k in (2, 5, 10, 20):
        ms = cpu_ms(scaled(k), max(5, n // 2))
        print(f"| {k} | {ms:.2f} | {ms / k:.2f} |")


if __name__ == "__main__":
    main()

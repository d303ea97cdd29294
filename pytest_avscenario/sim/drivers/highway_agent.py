"""An agent trained on highway-env as the ego, driven exactly as its own environment drives it.

``highway_env_agent(model, env="highway-fast-v0", config=None)`` (in
:mod:`pytest_avscenario.sim.drivers`) makes the environment the agent was trained in —
``gymnasium.make(env, config=config)``, so its default config merged with ``config`` — and
takes from it everything that decides what the agent sees and does: the observation type,
the action type, ``policy_frequency`` and ``simulation_frequency``. Per case:

* the ego is built as the vehicle class that action type controls (``MDPVehicle`` for
  ``DiscreteMetaAction``, ``Vehicle`` for ``ContinuousAction``/``DiscreteAction``), with the
  world's lane tracking mixed in, as the ``"idm"`` driver builds an ``IDMVehicle``; a
  controlled vehicle follows the world's route and starts with ``world.ego(target_speed=)``
  or its speed as its target (``MDPVehicle`` snaps it to the action type's target speeds,
  as highway-env builds its ego); it gets fresh highway-env observation and action objects,
  so nothing carries over between cases;
* every policy period — ``int(simulation_frequency // policy_frequency)`` highway-env steps,
  as in its ``step`` — the ego is observed by highway-env's observation object, the model
  answers, and highway-env's action object applies the answer; between decisions the
  vehicle's own controllers run every world step, as in highway-env's ``_simulate``. The
  agent declares ``dt = 1 / simulation_frequency``, the step ``world.run()`` takes when the
  test sets none, so the steps are highway-env's own. Another step still runs, with one
  ``AgentStepWarning`` per test: a ``dt`` that divides the policy period
  keeps the decision times and runs the controllers at the world's rate; one that does not
  decides at the nearest multiple of it.
* the scenario's ego speeds (``world.ego(speed=, target_speed=)``) outside what the action
  type holds (``DiscreteMetaAction``'s target speeds, ``ContinuousAction``'s
  ``speed_range``) get one ``AgentSpeedWarning`` per test: the agent starts
  in a state it never met in training.

Frames. The world's frame is highway-env's mirrored: a point ``(x, y)`` with heading ``h``
in the world is ``(x, -y)`` with heading ``-h`` in highway-env; lane numbers are the same
(0 = leftmost, so ``LANE_LEFT`` goes toward lane 0 in both), lateral offsets and steering
angles change sign. highway-env's dynamics and controllers are symmetric under this
mirror, so the ego moves in the world's frame, and the agent always sees highway-env's:
observations are computed by highway-env's own observation class on a mirrored copy of the
scene (every lane of the world's road network mirrored, every agent on the road copied with
``y``, heading and steering negated and its lane found as highway-env finds it), and the
steering of a continuous action is negated on its way to the world's ego.

Kinematics' normalisation ranges are those of the agent's environment (highway-env fixes them
at its first observation, from its own road: ``y`` within ±4 m × its ``lanes_count``),
not recomputed from the world's road. The world's other agents are the scenario's (driven by
its behaviours), not highway-env's ``IDMVehicle`` traffic. As everywhere in the world,
braking stops the ego at 0 m/s unless ``world.ego(..., allow_reverse=True)``.
"""

from __future__ import annotations

import copy
import functools
import inspect
import math
import traceback
from typing import Any

import numpy as np

from ..errors import AgentSpeedWarning, AgentStepWarning, DriverError, SimError

__all__ = ["HighwayEnvAgent"]

OBSERVATIONS = ("Kinematics", "OccupancyGrid", "TimeToCollision", "LidarObservation")
ACTIONS = ("DiscreteMetaAction", "ContinuousAction", "DiscreteAction")


class HighwayEnvAgent:
    """A model trained on a highway-env environment, driving the world's ego (see module doc).

    ``dt`` [s] is the environment's step, ``1 / simulation_frequency``: the world runs at it
    unless the test says otherwise, which reproduces highway-env's stepping exactly. The ego
    keeps its ``decisions``: a list of ``(t [s], action)``.
    """

    def __init__(self, model: Any, env: Any = "highway-fast-v0", config: dict | None = None) -> None:
        predict = getattr(model, "predict", None)
        if callable(predict):
            self._style = "predict"
            try:
                self._takes_det = "deterministic" in inspect.signature(predict).parameters
            except (TypeError, ValueError):
                self._takes_det = False
        elif callable(model):
            self._style = "callable"
            self._takes_det = False
        else:
            raise SimError(f"highway_env_agent(model={model!r}): need an object with "
                           "predict(obs, deterministic=...) (a stable-baselines3 model) or a "
                           "callable policy(obs) -> action")
        if not (isinstance(env, str) and env.strip()) and not hasattr(env, "unwrapped"):
            raise SimError(f"highway_env_agent(env={env!r}): give a highway-env id such as "
                           "'highway-fast-v0', or the environment itself")
        if config is not None and not isinstance(config, dict):
            raise SimError(f"highway_env_agent(config={config!r}): give a dict of the settings "
                           "changed from the environment's defaults, or None")
        self.model = model
        self.env_id = env.strip() if isinstance(env, str) else _env_id(env)
        self.config = dict(config or {})
        if not isinstance(env, str):
            # the environment as configured, its changes under ours
            self.config = {**dict(env.unwrapped.config), **self.config}
        self._env: Any = None  # made on first use; never pickled

    def __repr__(self) -> str:
        name = getattr(self.model, "__name__", None) or type(self.model).__name__
        return f"highway_env_agent({name}, env={self.env_id!r})"

    def describe(self) -> dict:
        """Who drives (:mod:`.identity`): the agent, its environment, and what its model says
        of itself (an ``sb3:`` model: its file and the file's hash)."""
        out = {"name": repr(self), "kind": "highway_env_agent", "env": self.env_id,
               "model": type(self.model).__qualname__}
        own = getattr(self.model, "describe", None)
        if callable(own):
            out.update({k: v for k, v in own().items() if k not in ("name", "kind")})
        return out

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["_env"] = None
        return state

    # -- the environment ---------------------------------------------------------------------------
    def environment(self, test: str = "", agent: str = "") -> Any:
        """The agent's highway-env environment (unwrapped), made on first use."""
        if self._env is not None:
            return self._env
        what = f"highway_env_agent(env={self.env_id!r})"
        try:
            import gymnasium
            import highway_env  # noqa: F401  (registers the environment ids)
        except ImportError as exc:
            raise SimError(f"{what}: cannot import gymnasium/highway-env ({exc})",
                           test=test, agent=agent) from exc
        try:
            spec = gymnasium.spec(self.env_id)
        except gymnasium.error.Error as exc:
            raise SimError(f"{what}: {exc}; use an id highway-env registers, e.g. "
                           "'highway-fast-v0' or 'highway-v0'", test=test, agent=agent) from None
        # check the merged config before making the environment: making it resets it, which
        # fails on some settings with highway-env's own, less helpful errors
        try:
            entry = spec.entry_point
            env_cls = (gymnasium.envs.registration.load_env_creator(entry)
                       if isinstance(entry, str) else entry)
            cfg = env_cls.default_config()
        except Exception:
            raise SimError(f"{what}: not a highway-env environment (no default_config)",
                           test=test, agent=agent) from None
        cfg.update((spec.kwargs or {}).get("config") or {})
        cfg.update(self.config)
        _check_config(cfg, what, test, agent)
        try:
            env = gymnasium.make(self.env_id, config=self.config).unwrapped
        except Exception as exc:
            raise SimError(f"{what}: making the environment with config={self.config!r} failed: "
                           f"{type(exc).__name__}: {exc}", test=test, agent=agent) from exc
        self._env = env
        return env

    @property
    def dt(self) -> float:
        """[s] highway-env's simulation step of the agent's environment."""
        return 1.0 / float(self.environment().config["simulation_frequency"])

    @property
    def policy_period(self) -> float:
        """[s] time between two decisions, as highway-env's ``step``."""
        cfg = self.environment().config
        sim = float(cfg["simulation_frequency"])
        return int(sim // float(cfg["policy_frequency"])) / sim

    # -- the driver protocol -------------------------------------------------------------------------
    def make_ego(self, world: Any, position: Any, heading: float, speed: float, *,
                 lane_index: tuple, route: list, target_speed: float | None, name: str) -> Any:
        """The ego: the vehicle class of the environment's action type, on the world's road."""
        env = self.environment(world.name, name)
        factory = env.action_type.vehicle_class
        if isinstance(factory, functools.partial):
            base, kwargs = factory.func, dict(factory.keywords)
        else:
            base, kwargs = factory, {}
        from highway_env.vehicle.controller import ControlledVehicle

        cls = _ego_class(world, base)
        if issubclass(base, ControlledVehicle):
            ego = cls(None, position, heading, speed, target_lane_index=lane_index,
                      target_speed=target_speed, route=list(route), **kwargs)
        else:
            ego = cls(None, position, heading, speed, **kwargs)
        ego.session = _Session(self, env, world, ego)
        ego.decisions = []
        self._check_speeds(world, ego, speed, target_speed)
        return ego

    def _check_speeds(self, world: Any, ego: Any, speed: float, target_speed: float | None) -> None:
        """Warn (once per test) when the scenario's ego speeds are ones the action type cannot
        hold: the agent then starts in a state it never met in training (an ego placed at
        5.6 m/s under DiscreteMetaAction's 20/25/30 m/s is at ~22 m/s a second later)."""
        from highway_env.envs.common.action import ContinuousAction, DiscreteMetaAction

        at = ego.session.action_type
        asked = [("speed", float(speed))]
        if target_speed is not None:
            asked.append(("target_speed", float(target_speed)))
        if isinstance(at, DiscreteMetaAction):
            targets = np.asarray(at.target_speeds, dtype=float)
            lo, hi = float(targets.min()), float(targets.max())
            holds = f"its target speeds are {', '.join(f'{v:g}' for v in targets)} m/s"
            after = (f", so the ego (highway-env's MDPVehicle) heads for "
                     f"{float(ego.target_speed):g} m/s from the start")
            name = "DiscreteMetaAction"
        elif isinstance(at, ContinuousAction):  # DiscreteAction too
            rng = at.speed_range or (ego.MIN_SPEED, ego.MAX_SPEED)
            lo, hi = float(min(rng)), float(max(rng))
            holds = f"its speed_range is [{lo:g}, {hi:g}] m/s"
            after = ""
            name = type(at).__name__
        else:  # pragma: no cover - _check_config admits no other action type
            return
        tol = 1e-6
        off = [(k, v) for k, v in asked if not lo - tol <= v <= hi + tol]
        if not off:
            return
        given = ", ".join(f"{k}={v:g} m/s" for k, v in off)
        world.warn(AgentSpeedWarning(
            f"{world.name}: the scenario places the ego at {given}, outside what "
            f"{self!r}'s {name} can hold: {holds}{after}; the agent starts where it never was "
            f"in training — place the ego within [{lo:g}, {hi:g}] m/s, or test an agent "
            "trained for these speeds"), "agent-speed")

    def reset(self, world: Any) -> None:
        """Per case, before the run: decision timing from the world's ``dt``, the mirrored road."""
        ego = world.agents[0]
        session = getattr(ego, "session", None)
        if isinstance(session, _Session) and session.agent is self:
            session.start(world)

    def predict(self, obs: Any) -> Any:
        """The model's answer to a highway-env observation."""
        if self._style == "callable":
            return self.model(obs)
        out = (self.model.predict(obs, deterministic=True) if self._takes_det
               else self.model.predict(obs))
        if isinstance(out, tuple) and len(out) == 2:
            out = out[0]  # stable-baselines3: (action, recurrent state)
        return out


def _check_config(cfg: dict, what: str, test: str, agent: str) -> None:
    """Refuse what the adapter cannot run, naming the setting."""
    if not isinstance(cfg.get("observation"), dict) or not isinstance(cfg.get("action"), dict):
        raise SimError(f"{what}: config['observation'] and config['action'] must be dicts "
                       "with a 'type'", test=test, agent=agent)
    obs = cfg["observation"].get("type")
    act = cfg["action"].get("type")
    if obs == "GrayscaleObservation":
        raise SimError(f"{what}: observation type {obs!r} is an image of highway-env's "
                       "renderer, which the world does not draw; train or run with one of "
                       f"{', '.join(OBSERVATIONS)} "
                       "(config={'observation': {'type': 'Kinematics'}})", test=test, agent=agent)
    if obs not in OBSERVATIONS:
        raise SimError(f"{what}: observation type {obs!r} is not supported; use one of "
                       f"{', '.join(OBSERVATIONS)} (config={{'observation': {{'type': ...}}}})",
                       test=test, agent=agent)
    if act not in ACTIONS:
        raise SimError(f"{what}: action type {act!r} is not supported (one ego, one agent); "
                       f"use one of {', '.join(ACTIONS)} (config={{'action': {{'type': ...}}}})",
                       test=test, agent=agent)
    if cfg["action"].get("dynamical"):
        raise SimError(f"{what}: config['action']['dynamical']=True (highway-env's "
                       "BicycleVehicle) is not supported; use the kinematic model "
                       "(dynamical=False)", test=test, agent=agent)
    if obs == "TimeToCollision" and act != "DiscreteMetaAction":
        raise SimError(f"{what}: the TimeToCollision observation needs the "
                       f"DiscreteMetaAction's target speeds; the action type is {act!r}",
                       test=test, agent=agent)
    for key in ("simulation_frequency", "policy_frequency"):
        f = cfg.get(key)
        if not (isinstance(f, (int, float)) and math.isfinite(f) and f > 0):
            raise SimError(f"{what}: config[{key!r}]={f!r}: need a frequency > 0 [Hz]",
                           test=test, agent=agent)
    if cfg["simulation_frequency"] < cfg["policy_frequency"]:
        raise SimError(f"{what}: simulation_frequency {cfg['simulation_frequency']} Hz is "
                       f"below policy_frequency {cfg['policy_frequency']} Hz", test=test,
                       agent=agent)


def _env_id(env: Any) -> str:
    spec = getattr(env, "spec", None) or getattr(env.unwrapped, "spec", None)
    if spec is None:
        raise SimError(f"highway_env_agent(env={env!r}): the environment has no registered id; "
                       "give its id, e.g. env='highway-fast-v0'")
    return str(spec.id)


# -- the ego ---------------------------------------------------------------------------------------

_EGO_CLASSES: dict[type, type] = {}


def _ego_class(world: Any, base: type) -> type:
    """``base`` (a highway-env vehicle class) as a world agent that decides by its model."""
    cls = _EGO_CLASSES.get(base)
    if cls is None:
        cls = type(f"HighwayEnv{base.__name__}Ego", (_PolicyEgo, world.agent_class(base)), {})
        _EGO_CLASSES[base] = cls
    return cls


class _PolicyEgo:
    """The ego's ``act``: a decision every policy period, the vehicle's controllers every step."""

    session: Any = None

    def act(self, action: Any = None) -> None:
        if action is not None:  # from highway-env's action object
            super().act(action)  # type: ignore[misc]
            return
        session = self.session
        if session is not None:
            session.tick(self)
        super().act()  # type: ignore[misc]  (highway-env's road.act() call)


class _MirroredControls:
    """What a continuous action type acts on: the world's ego, steering sign flipped."""

    def __init__(self, ego: Any) -> None:
        object.__setattr__(self, "_ego", ego)

    def act(self, action: dict) -> None:
        a = dict(action)
        a["steering"] = -a["steering"]
        self._ego.act(a)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._ego, name)

    def __setattr__(self, name: str, value: Any) -> None:  # e.g. speed_range -> MIN/MAX_SPEED
        setattr(self._ego, name, value)


class _Session:
    """One ego's run: highway-env's observation and action objects, timing, the mirror."""

    def __init__(self, agent: HighwayEnvAgent, env: Any, world: Any, ego: Any) -> None:
        from highway_env.envs.common.action import ContinuousAction, action_factory
        from highway_env.envs.common.observation import KinematicObservation, observation_factory

        self.agent = agent
        self.env = env
        self.world = world
        cfg = env.config
        self.obs_type = observation_factory(env, cfg["observation"])
        if isinstance(self.obs_type, KinematicObservation) and not self.obs_type.features_range:
            # the training environment's ranges, fixed at its first observation
            fr = getattr(env.observation_type, "features_range", None)
            if fr:
                self.obs_type.features_range = copy.deepcopy(fr)
        self.action_type = action_factory(env, cfg["action"])
        self.action_type.controlled_vehicle = (
            _MirroredControls(ego) if isinstance(self.action_type, ContinuousAction) else ego)
        self.every = 0
        self.k = 0
        self.mirror: _Mirror | None = None
        self.rng = np.random.default_rng([world.seed, 0x6877])

    def start(self, world: Any) -> None:
        period = self.agent.policy_period
        own = self.agent.dt
        dt = float(world.dt)
        every = int(round(period / dt))
        divides = every >= 1 and abs(every * dt - period) <= 1e-9 * max(period, 1.0)
        every = max(every, 1)
        # Another step than the environment's still runs (a scenario may need its own), but
        # the ego then moves as it never did in training: say so, once per test.
        if not divides or abs(dt - own) > 1e-9 * max(own, 1.0):
            world.warn(AgentStepWarning(self.step_text(world, dt, every, divides)),
                       "agent-step")
        self.every = every
        self.k = 0
        self.mirror = _Mirror(world.engine_road.network)

    def step_text(self, world: Any, dt: float, every: int, divides: bool) -> str:
        cfg = self.env.config
        sim, pol = cfg["simulation_frequency"], cfg["policy_frequency"]
        own = self.agent.dt
        period = self.agent.policy_period
        source = world.dt_from
        head = (f"{world.name}: {self.agent!r} runs at dt={dt:g} s ({source}), not at "
                f"its environment's step {own:g} s (simulation_frequency {sim:g} Hz)")
        if divides:
            what = (f"it still decides every {period:g} s (policy_frequency {pol:g} Hz), but "
                    "highway-env's controllers run at the world's step, so the ego does not "
                    "move as in its environment")
        else:
            what = (f"{dt:g} s does not divide its policy period {period:g} s (policy_frequency "
                    f"{pol:g} Hz), so it decides every {every * dt:g} s instead")
        # where the step was set is where it is changed back
        if source.startswith("world.run("):
            how = "world.run() without dt="
        elif source.startswith("@scenario("):
            how = "drop dt= from @scenario, or dt='auto'"
        elif source.startswith("--"):
            how = "--avs-dt auto"
        else:
            how = f"{source} = auto, or --avs-dt auto"
        return (f"{head}: {what}; to reproduce highway-env, leave the step to the driver "
                f"({how}) or give dt={own:g}")

    def tick(self, ego: Any) -> None:
        if self.mirror is None:
            self.start(self.world)
        k = self.k
        self.k += 1
        if k % self.every or ego.crashed:
            return
        world = self.world
        obs = self.observe(ego)
        try:
            raw = self.agent.predict(obs)
        except Exception as exc:  # the model is user code: report, never swallow
            raise DriverError(
                f"driver {self.agent!r} raised {type(exc).__name__}: {exc} at t={world.t:.2f} s",
                test=world.name, agent=ego.name, driver_traceback=traceback.format_exc()) from exc
        action = self.check(raw, ego)
        ego.decisions.append((float(world.t), action))
        self.action_type.act(action)

    def observe(self, ego: Any) -> Any:
        env = self.env
        road, me = self.mirror.scene(self.world.engine_road, ego)
        env.road = road
        env.controlled_vehicles = [me]
        env.np_random = self.rng
        self.obs_type.observer_vehicle = me
        try:
            return self.obs_type.observe()
        finally:  # keep no scene alive in the shared environment
            env.road = None
            env.controlled_vehicles = []
            self.obs_type.observer_vehicle = None

    def check(self, raw: Any, ego: Any) -> Any:
        """The model's answer as the action type takes it; SimError if it is none."""
        from highway_env.envs.common.action import DiscreteAction, DiscreteMetaAction

        at = self.action_type
        world = self.world

        def bad(expected: str) -> SimError:
            return SimError(f"driver {self.agent!r} returned a bad action at t={world.t:.2f} s: "
                            f"{raw!r}; expected {expected}", test=world.name, agent=ego.name)

        if isinstance(at, (DiscreteMetaAction, DiscreteAction)):
            n = int(at.space().n)
            names = (", ".join(f"{i}={v}" for i, v in at.actions.items())
                     if isinstance(at, DiscreteMetaAction) else f"{n} actions")
            expected = f"an action index 0..{n - 1} ({names})"
            try:
                arr = np.asarray(raw, dtype=float)
            except (TypeError, ValueError):
                raise bad(expected) from None
            if arr.size != 1 or not math.isfinite(float(arr.reshape(-1)[0])):
                raise bad(expected)
            v = float(arr.reshape(-1)[0])
            if v != int(v) or not 0 <= int(v) < n:
                raise bad(expected)
            return int(v)
        size = int(at.size)
        expected = f"{size} number{'s' if size > 1 else ''} in [-1, 1] (ContinuousAction)"
        try:
            arr = np.asarray(raw)
        except (TypeError, ValueError):
            raise bad(expected) from None
        # the model's own dtype (float32 for stable-baselines3), as highway-env would get it
        if arr.dtype.kind not in "fiu" or arr.size != size or not np.all(np.isfinite(arr)):
            raise bad(expected)
        return arr.reshape(-1)


# -- highway-env's frame -----------------------------------------------------------------------------


def _lane_base() -> type:
    from highway_env.road.lane import AbstractLane

    return AbstractLane


class _Mirror:
    """The world's road network and agents mirrored into highway-env's frame (y -> -y).

    The network is mirrored once per case (every lane wrapped, same node names and lane
    numbers); the agents are copied at each observation. Negation is exact in floating
    point, so highway-env's computations on the copy are the mirror images of what they
    would give on the world's scene.
    """

    def __init__(self, network: Any) -> None:
        from highway_env.road.road import RoadNetwork

        self.network = RoadNetwork()
        lane_cls = _mirrored_lane_class()
        for frm, tos in network.graph.items():
            for to, lanes in tos.items():
                for lane in lanes:
                    self.network.add_lane(frm, to, lane_cls(lane))

    def scene(self, world_road: Any, ego: Any) -> tuple[Any, Any]:
        from highway_env.road.road import Road

        road = Road(network=self.network, vehicles=[], road_objects=[],
                    np_random=np.random.default_rng(0), record_history=False)
        me = None
        for v in world_road.vehicles:
            c = self._copy(v, road)
            road.vehicles.append(c)
            if v is ego:
                me = c
        road.objects = [self._copy(o, road) for o in world_road.objects]
        return road, me

    def _copy(self, v: Any, road: Any) -> Any:
        c = copy.copy(v)
        c.position = np.array([v.position[0], -v.position[1]], dtype=float)
        c.heading = -v.heading
        c.road = road
        if getattr(v, "impact", None) is not None:
            c.impact = np.array([v.impact[0], -v.impact[1]], dtype=float)
        action = getattr(v, "action", None)
        if isinstance(action, dict) and "steering" in action:
            c.action = {**action, "steering": -action["steering"]}
        # the lane as highway-env finds it for its own vehicles after every step
        c.lane_index = self.network.get_closest_lane_index(c.position, c.heading)
        c.lane = self.network.get_lane(c.lane_index)
        return c


@functools.lru_cache(maxsize=1)
def _mirrored_lane_class() -> type:
    base = _lane_base()

    class MirroredLane(base):  # type: ignore[misc, valid-type]
        """A world lane seen in highway-env's frame: ``(x, y) -> (x, -y)``, ``r -> -r``."""

        def __init__(self, lane: Any) -> None:
            self.lane = lane
            self.length = float(lane.length)
            self.width = float(lane.width_at(0.0))
            lt = getattr(lane, "line_types", None)
            self.line_types = [lt[1], lt[0]] if lt else None
            self.forbidden = getattr(lane, "forbidden", False)
            self.speed_limit = getattr(lane, "speed_limit", None)
            self.priority = getattr(lane, "priority", 0)

        def position(self, longitudinal: float, lateral: float) -> np.ndarray:
            p = self.lane.position(longitudinal, -lateral)
            return np.array([p[0], -p[1]], dtype=float)

        def local_coordinates(self, position: Any) -> tuple[float, float]:
            s, r = self.lane.local_coordinates(np.array([position[0], -position[1]], dtype=float))
            return s, -r

        def heading_at(self, longitudinal: float) -> float:
            return -self.lane.heading_at(longitudinal)

        def width_at(self, longitudinal: float) -> float:
            return self.lane.width_at(longitudinal)

        def to_config(self) -> dict:  # pragma: no cover - never serialised
            raise NotImplementedError("a mirrored view of a world lane")

    return MirroredLane

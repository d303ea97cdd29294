"""What a remote worker does with one case, and the plain data that crosses the wire.

A cluster worker knows nothing of pytest's session: it gets the path of the test module, the
test function's name and one pickled *test spec* (argument names, monitor set, ego driver),
plus the case's own fields (parameters, index, seed, sampler, origin, item id). It imports
the module the way pytest's default ``prepend`` import mode does (the first directory above
the package goes first on ``sys.path``; asserts rewritten so messages read as in a local
run), builds the :class:`~pytest_avscenario.case.Case` and a fresh
:class:`~pytest_avscenario.sim.World`, and calls :func:`~pytest_avscenario.runner.run_case`.

What comes back is the :class:`~pytest_avscenario.outcome.CaseOutcome` itself, the same type
as in-process: pickled, it leaves its world and trajectory behind (the plugin does not need
them and they are the bulk of the bytes) and carries the body's exception as data, so the
client re-creates an exception whose type, text and last frame (``CaseOutcome.signature``)
match the remote one.

This module imports neither pytest's session machinery nor Dask: any executor that can call
a function on another process can use it.
"""

from __future__ import annotations

import ast
import hashlib
import importlib
import importlib.util
import os
import pickle
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..case import Case
from ..outcome import CaseOutcome
from ..runner import run_case

#: fixtures a scenario body can receive away from pytest
REMOTE_FIXTURES = frozenset({"case", "world", "avs_driver"})


@dataclass
class TestSpec:
    """Everything about one scenario test that is the same for all of its cases."""

    __test__ = False  # not a pytest test class, despite the name

    module_path: str
    rootdir: str
    function: str
    argnames: tuple[str, ...]
    monitor_set: Any
    driver: Any
    dt: float | None = None  # [s] the world's step setting (None: the driver's own step)
    dt_from: str = ""
    # a stack out of process's settings (stack.client.settings_for), when this run uses one
    stack: dict | None = None


@dataclass
class CaseFields:
    """The per-case part of a remote job (plain values)."""

    nodeid: str
    params: dict[str, Any]
    index: int
    seed: int
    sampler: str
    origin: str
    test: str
    timeout_s: float | None = None  # wall-time limit of the body (the job's timeout_s)
    judge_start: bool = False  # fill the outcome's start_unsafe (CaseJob.judge_start)


# --------------------------------------------------------------------------- client side
def pack_spec(spec: TestSpec) -> bytes:
    """The spec as bytes, pickled with cloudpickle.

    Functions and classes of importable modules (the test module, the team's stack) go by
    reference and are looked up again on the worker, after :func:`run_remote` has imported the
    test module. A driver defined in a ``conftest.py`` goes by value: conftest modules are not
    importable by name outside pytest.
    """
    import cloudpickle

    by_value = []
    for obj in (spec.driver, type(spec.driver)):
        mod = sys.modules.get(getattr(obj, "__module__", None) or "")
        is_conftest = mod is not None and mod.__name__.rpartition(".")[2] == "conftest"
        if is_conftest and mod not in by_value:
            by_value.append(mod)
    for mod in by_value:
        cloudpickle.register_pickle_by_value(mod)
    try:
        return cloudpickle.dumps(spec)
    finally:
        for mod in by_value:
            cloudpickle.unregister_pickle_by_value(mod)


# --------------------------------------------------------------------------- worker side
# Per worker process: specs already unpickled (by digest) and the stamp of each test module
# imported, so a module edited between runs against a long-lived cluster is imported anew.
_SPECS: dict[str, tuple[Any, TestSpec, Any]] = {}
_MODULE_STAMPS: dict[str, tuple[int, int]] = {}


def spec_digest(spec_bytes: bytes) -> str:
    return hashlib.sha256(spec_bytes).hexdigest()[:20]


def run_remote(spec_bytes: bytes, digest: str, module_path: str, rootdir: str,
               fields: CaseFields) -> CaseOutcome:
    """Run one case on this process and return what crosses the wire back.

    Never raises for anything the case or the test module does: those come back as the
    outcome's error (``infra_error`` when the case could not even start).
    """
    try:
        module = import_test_module(module_path, rootdir)
        spec, func = _load_spec(spec_bytes, digest, module)
    except BaseException as exc:  # noqa: BLE001 - report anything, even SystemExit, as data
        return CaseOutcome(params=dict(fields.params), verdict="error", worker_pid=os.getpid(),
                           error=(f"could not load {fields.nodeid} on the worker (pid "
                                  f"{os.getpid()}): {type(exc).__name__}: {exc}"))
    unknown = [a for a in spec.argnames if a not in REMOTE_FIXTURES]
    if unknown:
        return CaseOutcome(params=dict(fields.params), verdict="error", worker_pid=os.getpid(),
                           error=(f"{fields.nodeid} requests {', '.join(unknown)}: only "
                                  "case, world and avs_driver exist on a remote worker"))
    if spec.stack:
        from ..stack.client import configure

        configure(**spec.stack)  # --avs-stack-timeout and --avs-stack-spin, as on the client
    case = Case(fields.params, index=fields.index, seed=fields.seed, sampler=fields.sampler,
                origin=fields.origin, test=fields.test)
    driver, nodeid = spec.driver, fields.nodeid

    def make_world(c: Case) -> Any:
        from ..sim import World

        return World(seed=c.seed, rng=c.rng, driver=driver, name=nodeid, dt=spec.dt,
                     dt_from=spec.dt_from)

    fixtures = {"avs_driver": driver} if "avs_driver" in spec.argnames else {}
    body = func if fields.timeout_s is None else _bounded(func, float(fields.timeout_s))
    outcome = run_case(body, spec.argnames, fixtures, case, spec.monitor_set, make_world)
    outcome.worker_pid = os.getpid()
    if fields.judge_start and outcome.trajectory is not None:
        from ..monitors.rss import starts_unsafe

        outcome.start_unsafe = starts_unsafe(outcome.trajectory)
    return outcome  # pickles without its world, and its trajectory unless it failed


def run_remote_many(spec_bytes: bytes, digest: str, module_path: str, rootdir: str,
                    fields: list[CaseFields]) -> list[CaseOutcome]:
    """:func:`run_remote` for several cases of one test, in order (one task, one round trip)."""
    return [run_remote(spec_bytes, digest, module_path, rootdir, f) for f in fields]


def _bounded(func: Any, seconds: float) -> Any:
    """``func`` ended by the runner's ``CaseTimeout`` after ``seconds``, in any thread.

    Dask runs tasks in worker threads, where the runner's SIGALRM limit cannot work; a timer
    thread raises the exception asynchronously in the case's thread instead (it lands at the
    next Python bytecode: code stuck inside one C call is bounded only by the client's
    deadline, see ``DaskExecutor``). The exception then reads as a local timeout does.
    """
    import ctypes
    import threading

    try:
        from ..runner import CaseTimeout
    except ImportError:  # a runner without time limits: nothing to match
        return func
    message = f"the case ran longer than its time limit of {seconds:g} s"

    class Expired(CaseTimeout):
        # the C API raises a class without arguments: carry the message as the default
        def __init__(self, *args: Any) -> None:
            super().__init__(*(args or (message,)))

    def call(**kwargs: Any) -> Any:
        target = ctypes.c_ulong(threading.get_ident())
        timer = threading.Timer(seconds, ctypes.pythonapi.PyThreadState_SetAsyncExc,
                                (target, ctypes.py_object(Expired)))
        timer.daemon = True
        timer.start()
        try:
            return func(**kwargs)
        except Expired as exc:
            # a plain CaseTimeout with the same traceback: it pickles, and its type name
            # (CaseOutcome.signature) is the one a local run gives
            raise CaseTimeout(message).with_traceback(exc.__traceback__) from None
        finally:
            timer.cancel()
            # the timer may have fired after func returned but before cancel: clear it
            ctypes.pythonapi.PyThreadState_SetAsyncExc(target, None)

    return call


def warm_up() -> int:
    """Import what every case needs (highway-env alone takes ~0.7 s) with a tiny scene.

    Run once per worker when the executor starts, so the first real case on each worker
    reports its own simulation time, not the imports'.
    """
    from ..monitors import MonitorSet, distance
    from ..sim import World

    world = World(seed=0, driver="autopilot", name="avscenario warm-up")
    road = world.straight_road(lanes=1, length=100)
    world.ego(road.lane(0), s=0.0, speed=10.0)
    world.car(road.lane(0), s=30.0, speed=10.0)
    world.run(seconds=0.3)
    MonitorSet([distance(5.0)]).evaluate(world.trajectory)
    return os.getpid()


def _load_spec(spec_bytes: bytes, digest: str, module: Any) -> tuple[TestSpec, Any]:
    cached = _SPECS.get(digest)
    if cached is not None and cached[0] is module:  # same bytes, same import of the module
        return cached[1], cached[2]
    import cloudpickle

    spec: TestSpec = cloudpickle.loads(spec_bytes)
    func = _function(spec, module)
    _SPECS[digest] = (module, spec, func)
    return spec, func


def _function(spec: TestSpec, module: Any) -> Any:
    try:
        return getattr(module, spec.function)
    except AttributeError:
        raise LookupError(
            f"{spec.module_path} has no module-level function {spec.function!r} (scenario "
            "tests inside classes are not supported by remote executors)"
        ) from None


def module_name_for(path: Path) -> tuple[Path, str]:
    """(directory to put on sys.path, dotted module name), as pytest's ``prepend`` mode.

    The name is the file's stem, prefixed with every enclosing directory that is a package
    (has ``__init__.py``); the directory above the outermost package is the import base.
    """
    parts = [path.stem]
    base = path.parent
    while (base / "__init__.py").is_file():
        parts.append(base.name)
        base = base.parent
    return base, ".".join(reversed(parts))


def import_test_module(module_path: str, rootdir: str) -> Any:
    """Import the test module at ``module_path`` like pytest would, or reuse it if unchanged."""
    path = Path(module_path).resolve()
    base, name = module_name_for(path)
    if str(base) not in sys.path:
        sys.path.insert(0, str(base))
    if rootdir and rootdir not in sys.path:
        sys.path.append(rootdir)  # helpers next to the rootdir, as conftest there would allow
    st = path.stat()
    stamp = (st.st_mtime_ns, st.st_size)
    mod = sys.modules.get(name)
    if mod is not None and _MODULE_STAMPS.get(name) == stamp and \
            Path(getattr(mod, "__file__", "") or "").resolve() == path:
        return mod
    if "." in name:  # the enclosing packages, imported normally
        importlib.import_module(name.rpartition(".")[0])
    source = path.read_bytes()
    spec = importlib.util.spec_from_file_location(name, str(path))
    mod = importlib.util.module_from_spec(spec)
    code = _compile_rewritten(source, str(path))
    sys.modules[name] = mod
    try:
        exec(code, mod.__dict__)
    except BaseException:
        sys.modules.pop(name, None)
        raise
    _MODULE_STAMPS[name] = stamp
    return mod


def _compile_rewritten(source: bytes, filename: str) -> Any:
    """The module's code with pytest's assert rewriting, so failures read as in pytest."""
    tree = ast.parse(source, filename=filename)
    try:
        from _pytest.assertion.rewrite import rewrite_asserts

        rewrite_asserts(tree, source, filename)
    except Exception:  # a pytest without this private helper: plain asserts still fail
        tree = ast.parse(source, filename=filename)
    return compile(tree, filename, "exec", dont_inherit=True)

"""Import highway-env's simulation core without its gym environments.

``highway_env/__init__.py`` registers every gym environment, which imports gymnasium, pygame,
matplotlib and pandas: about 0.7 s on a quiet machine, before the first case of every fresh
process (a pytest run, an xdist worker, a Dask worker). The scene code needs none of that —
only roads, lanes, vehicles and utils, which import in ~25 ms.

:func:`load_core` imports those modules under a temporary, unexecuted package object, then
takes the package out of ``sys.modules`` again and leaves a one-shot import hook: if anybody
later imports ``highway_env`` itself (to ``gym.make`` an environment, say), the real package
``__init__`` runs as usual, and the submodules loaded before are attached to it, so both see
the very same classes. Nothing of highway-env's behaviour changes; only when it is paid for.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
from typing import Any

PACKAGE = "highway_env"
CORE = (
    "highway_env.utils",
    "highway_env.road.lane",
    "highway_env.road.road",
    "highway_env.vehicle.kinematics",
    "highway_env.vehicle.controller",
    "highway_env.vehicle.behavior",
    "highway_env.vehicle.objects",
)


def load_core() -> None:
    """Make highway-env's road and vehicle modules importable at their light cost."""
    if PACKAGE in sys.modules or all(name in sys.modules for name in CORE):
        return
    spec = importlib.util.find_spec(PACKAGE)
    if spec is None:
        raise ImportError("highway-env is not installed: pip install highway-env")
    stub = importlib.util.module_from_spec(spec)  # the package object, its __init__ not run
    sys.modules[PACKAGE] = stub
    try:
        for name in CORE:
            importlib.import_module(name)
    except Exception:
        # a highway-env whose core needs its __init__ after all: forget the partial import
        # and let the ordinary, complete import happen
        for name in [n for n in sys.modules if n == PACKAGE or n.startswith(PACKAGE + ".")]:
            del sys.modules[name]
        importlib.import_module(PACKAGE)
        return
    finally:
        if sys.modules.get(PACKAGE) is stub:
            del sys.modules[PACKAGE]
    if not any(isinstance(f, _CompletePackage) for f in sys.meta_path):
        sys.meta_path.insert(0, _CompletePackage())


class _CompletePackage(importlib.abc.MetaPathFinder):
    """On the first real ``import highway_env``: run its ``__init__`` with the submodules
    loaded by :func:`load_core` already attached, then step aside."""

    def find_spec(self, fullname: str, path: Any = None, target: Any = None) -> Any:
        if fullname != PACKAGE:
            return None
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(PACKAGE)
        if spec is None or spec.loader is None:
            return spec
        spec.loader = _AttachingLoader(spec.loader)
        return spec


class _AttachingLoader(importlib.abc.Loader):
    def __init__(self, loader: Any) -> None:
        self.loader = loader

    def create_module(self, spec: Any) -> Any:
        return self.loader.create_module(spec)

    def exec_module(self, module: Any) -> None:
        # what the import system would have done had the package been imported first
        for name, sub in list(sys.modules.items()):
            if name.startswith(PACKAGE + ".") and name.count(".") == 1 and sub is not None:
                setattr(module, name.rpartition(".")[2], sub)
        self.loader.exec_module(module)

"""Stacks out of process: the ego driven by an AV stack in another process over ASAM OSI + ZeroMQ.

The plugin's side is :class:`OSIStack` (``--avs-driver osi:ADDRESS``,
``--avs-driver osi+spawn:COMMAND``, ``world.ego(..., driver=OSIStack(address))``); a Python
stack's side is :func:`serve`. The protocol, ``avs-osi/1``, is written down in
docs/osi-protocol.md; :mod:`.wire` is its one Python implementation and :mod:`.frame`
the one place where the world's frame and ids become OSI's. Needs ``pyzmq`` and
``osi-python`` (``pip install pytest-avscenario[osi]``); nothing here is imported when the
plugin loads.
"""

from __future__ import annotations

from typing import Any

__all__ = ["OSIStack", "Limits", "serve"]


def __getattr__(name: str) -> Any:
    # lazily: the client needs pyzmq and osi3, the kit also the simulator
    if name in ("OSIStack", "Limits"):
        from . import client

        return getattr(client, name)
    if name == "serve":
        from .kit import serve

        return serve
    raise AttributeError(name)

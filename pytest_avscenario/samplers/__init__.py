"""Samplers: where the next concrete case comes from.

Every sampler works on the unit cube of a :class:`~pytest_avscenario.space.FeatureSpace`
behind one small ask/tell protocol (see :mod:`.base`). Passive samplers (``random``,
``halton``) ignore feedback and can produce a whole batch up front; active samplers learn
from the robustness values they are told. The public entry point, usable outside pytest::

    from pytest_avscenario import samplers, Uniform
    s = samplers.make("halton", {"gap": Uniform(10, 40)}, seed=0)
    params = s.ask()            # {"gap": 25.0}
    s.tell(params, rho)         # rho: float, or {metric: float}, or None for an invalid case

Sampler modules are imported only when a sampler of theirs is made, so the plugin never
pays for scipy unless a Halton (or other scipy-backed) sampler is used.
"""

from .base import Sampler, SamplerError, available, make, register

__all__ = ["Sampler", "SamplerError", "available", "make", "register"]

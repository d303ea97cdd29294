"""Samplers: where the next concrete case comes from.

Every sampler works on the unit cube of a :class:`~pytest_avscenario.space.FeatureSpace`
behind one small ask/tell protocol (see :mod:`.base`). Passive samplers (``random``,
``halton``) ignore feedback and can produce a whole batch up front; active samplers learn
from the robustness values they are told. The public entry point, usable outside pytest::

    from pytest_avscenario import samplers, Uniform
    s = samplers.make("mab", {"gap": Uniform(10, 40)}, seed=0)
    params = s.ask()            # {"gap": 31.7}
    s.tell(params, rho)         # rho: float, or {metric: float}, or None for an invalid case
    blob = s.state()            # plain JSON; samplers.make(...).restore(blob) continues

=========  ==================================================================================
``random`` uniform, seeded numpy Generator
``halton`` low-discrepancy (unscrambled like the paper; ``scramble``, ``skip``)
``mab``    UCB1 bandit per dimension over buckets, near-miss rewards, multi-objective patterns
           under a priority order (``buckets``, ``exploration``, ``near_miss``, ``jitter``)
``ce``     cross-entropy over per-dimension bucket distributions, elite quantile of rho
           (``buckets``, ``elite``, ``smoothing``, ``batch``, ``floor``)
``sa``     simulated annealing, Metropolis acceptance, shrinking Gaussian proposal, restarts
           (``step``, ``min_step``, ``shrink``, ``temperature``, ``cooling``, ``restart``,
           ``jump``)
``bo``     Gaussian-process Bayesian optimization, EI or LCB (``kernel``, ``acquisition``,
           ``kappa``, ``xi``, ``init``, ``corners``, ``starts``, ``candidates``,
           ``max_points``); starts from corners of the box
=========  ==================================================================================

Active samplers also take ``metrics=[names]`` and ``priority=`` (names highest first, or
``(higher, lower)`` pairs); an unknown option, a bad value, a priority naming an unknown
metric or containing a cycle raise :class:`SamplerError`. Every sampler is deterministic
given its seed and the feedback it receives.

Sampler modules are imported only when a sampler of theirs is made, so the plugin never
pays for scipy unless a scrambled Halton or a ``bo`` sampler is used.
"""

from .base import Sampler, SamplerError, available, make, register

__all__ = ["Sampler", "SamplerError", "available", "make", "register"]

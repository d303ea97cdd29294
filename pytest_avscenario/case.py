"""The concrete case a scenario test receives through the ``case`` fixture."""

from __future__ import annotations

import hashlib
from typing import Any, Iterator, Mapping

import numpy as np

#: attribute names of Case that a scenario parameter may not shadow
RESERVED = frozenset(
    {"params", "index", "seed", "rng", "sampler", "origin", "test", "get", "keys", "items", "values"}
)


class Case(Mapping[str, Any]):
    """One concrete point of a scenario's feature space, with its seed.

    Parameter values are readable as attributes (``case.gap``) and by key (``case["gap"]``).
    ``rng`` is a numpy Generator seeded from ``seed`` for randomness drawn during the run;
    ``origin`` says where the case came from: ``sampled``, ``example``, ``replay``, ``shrink``
    or ``pinned`` (``--avs-params``).
    """

    __slots__ = ("params", "index", "seed", "rng", "sampler", "origin", "test")

    def __init__(self, params: Mapping[str, Any], index: int, seed: int, sampler: str,
                 origin: str = "sampled", test: str = ""):
        self.params = dict(params)
        self.index = index
        self.seed = int(seed)
        self.rng = np.random.default_rng(self.seed)
        self.sampler = sampler
        self.origin = origin
        self.test = test

    def __getattr__(self, name: str) -> Any:
        try:
            return self.params[name]
        except KeyError:
            raise AttributeError(
                f"case has no parameter {name!r}; parameters: {list(self.params)}"
            ) from None

    def __getitem__(self, key: str) -> Any:
        return self.params[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self.params)

    def __len__(self) -> int:
        return len(self.params)

    def __repr__(self) -> str:
        vals = ", ".join(f"{k}={v!r}" for k, v in self.params.items())
        return f"Case({self.sampler}-{self.index}, seed={self.seed}: {vals})"


def stable_seed(*parts: Any) -> int:
    """A 63-bit seed from any printable parts, the same in every process (not ``hash()``)."""
    h = hashlib.sha256("\x1f".join(map(str, parts)).encode()).digest()
    return int.from_bytes(h[:8], "big") >> 1

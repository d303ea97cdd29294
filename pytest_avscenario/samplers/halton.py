"""Halton low-discrepancy sampling, the paper's coverage sampler.

Unscrambled by default so runs compare with the paper and with VerifAI's Halton sampler:
point ``i`` has coordinate ``j`` equal to the radical inverse of ``i`` in the ``j``-th prime
base, computed here with numpy (so collecting a Halton test does not pay for importing
scipy.stats). ``scramble=True`` gives scipy.stats.qmc's randomized (seeded) sequence. The
unscrambled sequence starts at the origin, a degenerate corner case; like VerifAI we skip it
(``skip``, default 1). Integer and categorical dimensions take their coordinate of the same
Halton point, which stratifies them over their values. Points are made in blocks (256
points, doubling up to ``_BLOCK``), converted to parameter dicts together, and handed out
one by one: a numpy (or scipy) call per point cost ten times more than everything else in
a sample.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from .base import Sampler, SamplerError

_BLOCK = 4096


def first_primes(n: int) -> list[int]:
    primes: list[int] = []
    k = 2
    while len(primes) < n:
        if all(k % p for p in primes if p * p <= k):
            primes.append(k)
        k += 1
    return primes


def radical_inverse(indices: np.ndarray, base: int) -> np.ndarray:
    """Van der Corput radical inverse of non-negative integer ``indices`` in ``base``.

    All digits are taken at once (a digit loop with a numpy call per step cost ~1 µs per
    point); the sum runs digit by digit with scales 1/base, 1/base², … obtained by repeated
    division, so the values are the same floats the digit loop gave."""
    i = np.asarray(indices, dtype=np.int64)
    out = np.zeros(i.shape, dtype=float)
    top = int(i.max()) if i.size else 0
    if top <= 0:
        return out
    n_digits = 1
    while base**n_digits <= top:
        n_digits += 1
    powers = base ** np.arange(n_digits, dtype=np.int64)
    digits = (i[..., None] // powers) % base
    scale = 1.0 / base
    for k in range(n_digits):
        out += digits[..., k] * scale
        scale /= base
    return out


def halton_points(start: int, n: int, d: int) -> np.ndarray:
    """Rows ``start .. start+n-1`` of the unscrambled ``d``-dimensional Halton sequence."""
    idx = np.arange(start, start + n, dtype=np.int64)
    return np.stack([radical_inverse(idx, b) for b in first_primes(d)], axis=1) if d else np.zeros((n, 0))


class HaltonSampler(Sampler):
    name = "halton"
    active = False
    options = ("scramble", "skip")

    def __init__(self, space, seed=0, scramble: bool = False, skip: int = 1, **options: Any):
        super().__init__(space, seed=seed, **options)
        if isinstance(skip, bool) or not isinstance(skip, int) or skip < 0:
            raise SamplerError(f"halton skip must be an int >= 0, got {skip!r}")
        self.scramble = bool(scramble)
        self.skip = skip
        # the scramble comes from an integer drawn once, so restore rebuilds the same engine
        # even when the caller passed a Generator (which has moved on since)
        self._engine_seed = int(self.rng.integers(2**63)) if self.scramble else 0
        self._buf: list[list[float]] = []  # the current block, reversed, as plain floats
        self._pbuf: list[dict[str, Any]] = []  # and as parameter dicts
        self._blk = 128
        self._engine = self._make_engine() if self.scramble else None

    def _make_engine(self) -> Any:
        from scipy.stats import qmc

        engine = qmc.Halton(d=max(self.d, 1), scramble=True,
                            seed=np.random.default_rng(self._engine_seed))
        engine.fast_forward(self.skip + self.n_asked)
        return engine

    def _block(self, start: int, n: int) -> np.ndarray:
        if self._engine is not None:
            return self._engine.random(n)[:, : self.d]
        return halton_points(start, n, self.d)

    def _fill(self) -> None:
        # blocks double from 256 up to _BLOCK points: a short campaign pays for a few hundred
        # points, a long one amortizes numpy's per-call overhead over thousands
        self._blk = min(_BLOCK, 2 * self._blk)
        blk = self._block(self.skip + self.n_asked, self._blk)[::-1]
        self._buf = blk.tolist()
        self._pbuf = self._params_many(blk)  # the same points as parameter dicts

    def ask_unit(self) -> np.ndarray:
        if not self._buf:
            self._fill()
        self.n_asked += 1
        self._pbuf.pop()
        return np.array(self._buf.pop(), dtype=float)

    def ask(self) -> dict[str, Any]:
        if not self._buf:
            self._fill()
        self.n_asked += 1
        self._buf.pop()
        return self._pbuf.pop()

    def sample_unit(self, n: int) -> np.ndarray:
        take = min(n, len(self._buf))
        head = [self._buf.pop() for _ in range(take)]
        del self._pbuf[len(self._buf):]
        self.n_asked += take
        rest = self._block(self.skip + self.n_asked, n - take)
        self.n_asked += n - take
        if not take:
            return rest
        return np.concatenate([np.array(head, dtype=float).reshape(take, self.d), rest])

    def state(self) -> dict[str, Any]:
        st = super().state()
        st.update(scramble=self.scramble, skip=self.skip, engine_seed=self._engine_seed)
        return st

    def restore(self, state: Mapping[str, Any]) -> None:
        super().restore(state)
        self._engine_seed = int(state.get("engine_seed", self._engine_seed))
        self._buf, self._pbuf = [], []
        if self.scramble:
            # a scrambled engine's permutations come from the seed: rebuild, then fast-forward
            self._engine = self._make_engine()

"""The Bayesian-optimization sampler (``bo``): a Gaussian process on rho, minimized actively.

The first ``init`` cases are an initial design: ``corners`` of them (default 3 of 5) are
corners of the box, spread out (see :mod:`.design`: failures of driving scenarios gather
where parameters are extreme, which a uniform draw almost never reaches), the rest uniform
random. After that, a Gaussian process with a Matérn-5/2 (or RBF) kernel and one length
scale per dimension is fitted to the standardized rho values, and the next case maximizes
the acquisition — expected improvement below the best rho so far, or the lower confidence
bound ``mu - kappa * sigma``. The acquisition is screened on random and near-best
candidates, then polished from the ``starts`` best of them with TNC (all starts in one
call: the objective is their sum, which is separable).

Bounded cost, whatever the number of cases told: the GP is fitted to at most ``max_points``
of them — all while there are that few, then a tenth chosen to cover the space (greedy
maximin, in the GP's length scales) and, in equal parts, the best and the most recent of the
rest, so the model stays sharp where the search is and still knows roughly where it has
been. (A third for coverage found the ball of bench_bo.py later at tight caps: spread-out
high rho flattened the standardized model near the minimum.) Its
hyperparameters (maximizing the log marginal likelihood with scipy's bounded truncated
Newton and analytic gradients, warm-started from the previous fit) are re-optimized, and the
space-filling part chosen again, whenever the cases told have grown by a tenth since the
last time (at least one case, at most ``_REFIT_MAX``); every other ask costs one Cholesky
factorization of at most ``max_points`` cases and a screening of ``candidates`` points.

Cases asked but not told yet count at the posterior mean ("kriging believer"), so a batch of
asks spreads out instead of repeating one point. A told case is matched to its ask through
the parameters the ask produced, so integer and categorical parameters (whose told value
maps back to the centre of its stratum, not to the asked point) match too. Invalid cases
are kept at the median rho: no evidence, but not proposed again.
"""

from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from .base import ActiveSampler, Rho, SamplerError, check_float, check_int, json_float

_SQRT5 = math.sqrt(5.0)
# Bounded truncated Newton: its C core calls no BLAS, where L-BFGS-B's Fortran core did and
# ran 8x slower per sample on a loaded 2-core machine (BLAS threads spinning).
_METHOD = "TNC"
# hyperparameters are re-optimized once the cases told grow by a tenth (at least 1, at most
# _REFIT_MAX cases): every case early, where the length scales still move, and a bounded
# share of the asks later, where the fitting subset changes slowly
_REFIT_SHARE = 10
_REFIT_MAX = 50
_FILL_SHARE = 0.1  # of the fitting subset, chosen to cover the space (the rest: best, latest)


def _inv_from_cholesky(L: np.ndarray) -> np.ndarray:
    """K^-1 from its Cholesky factor.

    Written with numpy's own LAPACK and einsum on purpose: on a loaded 2-core machine the
    multi-threaded BLAS-3 paths (scipy.linalg.cho_solve, matmul of a candidate batch) were
    measured 30-60x slower than these (threads spinning against the simulations)."""
    Li = np.linalg.inv(L)
    return np.einsum("ki,kj->ij", Li, Li)


def _sq_dist(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Squared distances between the rows of A (m, d) and B (n, d), one dimension at a time
    (no (m, n, d) temporary: d is small and m * n is the size that matters)."""
    r2 = np.zeros((A.shape[0], B.shape[0]))
    for k in range(A.shape[1]):
        t = A[:, k, None] - B[None, :, k]
        r2 += t * t
    return r2


class GaussianProcess:
    """A zero-mean GP with an ARD Matérn-5/2 or RBF kernel on standardized targets.

    ``theta`` = log length scales (d), log signal variance, log noise variance.
    """

    def __init__(self, kernel: str = "matern", d: int = 1):
        self.kernel = kernel
        self.d = d
        self.theta = np.concatenate([np.full(d, math.log(0.3)), [0.0, math.log(1e-4)]])
        self.n_fits = 0
        self.bounds = [(math.log(0.01), math.log(10.0))] * d + [
            (math.log(0.01), math.log(100.0)), (math.log(1e-8), math.log(0.1))]

    # -- kernel -------------------------------------------------------------------------
    def _k(self, D2: np.ndarray, s2: float) -> tuple[np.ndarray, np.ndarray]:
        """Kernel values and the factor f with dk/dlog(l_k) = f * D2_k (and dk/dx = -f*diff/l^2).

        ``D2`` holds the squared scaled differences per dimension (..., d) or, with one
        dimension fewer, their sum r^2."""
        r2 = D2.sum(-1) if D2.ndim == 3 else D2
        if self.kernel == "rbf":
            k = s2 * np.exp(-0.5 * r2)
            return k, k
        r = np.sqrt(r2)
        e = np.exp(-_SQRT5 * r)
        k = s2 * (1.0 + _SQRT5 * r + (5.0 / 3.0) * r2) * e
        return k, s2 * (5.0 / 3.0) * (1.0 + _SQRT5 * r) * e

    def nll(self, theta: np.ndarray, X: np.ndarray, y: np.ndarray,
            S: np.ndarray | None = None) -> tuple[float, np.ndarray]:
        """Negative log marginal likelihood and its gradient in theta (``S``: the unscaled
        squared differences of X, (n, n, d), when the caller has them already)."""
        d = self.d
        ell = np.exp(theta[:d])
        s2, sn2 = math.exp(theta[d]), math.exp(theta[d + 1])
        if S is None:
            S = (X[:, None, :] - X[None, :, :]) ** 2
        D2 = S / (ell * ell)
        K0, f = self._k(D2, s2)
        n = len(y)
        K = K0 + (sn2 + 1e-10) * np.eye(n)
        try:
            L = np.linalg.cholesky(K)
        except np.linalg.LinAlgError:
            return 1e25, np.zeros_like(theta)
        Kinv = _inv_from_cholesky(L)
        alpha = Kinv @ y
        nll = 0.5 * y @ alpha + np.log(np.diag(L)).sum() + 0.5 * n * math.log(2 * math.pi)
        W = Kinv - np.outer(alpha, alpha)
        grad = np.empty_like(theta)
        fW = f * W
        grad[:d] = 0.5 * np.einsum("ij,ijk->k", fW, D2)
        grad[d] = 0.5 * (W * K0).sum()
        grad[d + 1] = 0.5 * sn2 * np.trace(W)
        return float(nll), grad

    def fit(self, X: np.ndarray, y: np.ndarray, optimize: bool = True) -> None:
        from scipy.optimize import minimize

        if optimize and len(y) >= 2:
            # warm start from the last fit; every 10th fit also from the default, so one
            # bad early optimum cannot stick
            starts = [self.theta]
            self.n_fits += 1
            if self.n_fits % 10 == 1:
                starts.append(GaussianProcess(self.kernel, self.d).theta)
            S = (X[:, None, :] - X[None, :, :]) ** 2
            best = None
            for t0 in starts:
                res = minimize(self.nll, t0, args=(X, y, S), jac=True, method=_METHOD,
                               bounds=self.bounds, options={"maxfun": 60})
                if best is None or res.fun < best.fun:
                    best = res
            if np.all(np.isfinite(best.x)):
                self.theta = np.asarray(best.x, dtype=float)
        d = self.d
        self.ell = np.exp(self.theta[:d])
        self.s2 = math.exp(self.theta[d])
        self.X = X
        self._Xs = X / self.ell
        noise = math.exp(self.theta[d + 1]) + 1e-10
        K = self._k(_sq_dist(self._Xs, self._Xs), self.s2)[0] + noise * np.eye(len(y))
        self._Kinv = _inv_from_cholesky(np.linalg.cholesky(K))
        self.alpha = self._Kinv @ y

    def predict(self, Z: np.ndarray, grad: bool = False):
        """Posterior mean and standard deviation at Z (m, d); with gradients if asked."""
        if not grad:
            ks, f = self._k(_sq_dist(Z / self.ell, self._Xs), self.s2)
        else:
            diff = (Z[:, None, :] - self.X[None, :, :]) / self.ell  # (m, n, d)
            ks, f = self._k(diff * diff, self.s2)
        mu = ks @ self.alpha
        v = np.einsum("mn,nk->mk", ks, self._Kinv)  # (m, n); see _inv_from_cholesky
        var = np.maximum(self.s2 - (v * ks).sum(1), 1e-12)
        sd = np.sqrt(var)
        if not grad:
            return mu, sd
        dks = -f[:, :, None] * diff / self.ell  # dk*/dz, (m, n, d)
        dmu = np.einsum("mnd,n->md", dks, self.alpha)
        dsd = -np.einsum("mnd,mn->md", dks, v) / sd[:, None]
        return mu, sd, dmu, dsd


class BayesianOptimizationSampler(ActiveSampler):
    """GP Bayesian optimization of rho.

    Options: ``kernel`` ("matern" or "rbf"), ``acquisition`` ("ei" or "lcb"), ``kappa``
    (LCB weight, default 2), ``xi`` (EI margin in standardized units, default 0.01),
    ``init`` (initial cases before the GP proposes, default 5), ``corners`` (how many of
    them are corners of the box, the first asks, default 3; the rest are uniform random;
    0: all uniform), ``starts`` (local optimizer starts, default 5),
    ``candidates`` (screening points, default 500), ``max_points`` (cases in the fit,
    default 100; with more cases told, a subset as the module says; it bounds the cost of
    an ask), plus ``metrics`` and ``priority`` (``bo`` minimizes the worst metric, or with a
    priority the worst top-ranked one).
    """

    name = "bo"
    options = ActiveSampler.options + ("kernel", "acquisition", "kappa", "xi", "init", "starts",
                                       "candidates", "max_points", "corners")

    def __init__(self, space, seed=0, kernel: str = "matern", acquisition: str = "ei",
                 kappa: float = 2.0, xi: float = 0.01, init: int = 5, starts: int = 5,
                 candidates: int = 500, max_points: int = 100, corners: int = 3, **options: Any):
        super().__init__(space, seed=seed, **options)
        if kernel not in ("matern", "rbf"):
            raise SamplerError(f"bo kernel must be 'matern' or 'rbf', got {kernel!r}")
        if acquisition not in ("ei", "lcb"):
            raise SamplerError(f"bo acquisition must be 'ei' or 'lcb', got {acquisition!r}")
        import scipy.optimize  # noqa: F401  (fail at make time, not at the first ask)
        import scipy.special  # noqa: F401

        self.kernel, self.acquisition = kernel, acquisition
        self.kappa = check_float(kappa, "bo kappa")
        self.xi = check_float(xi, "bo xi")
        self.init = check_int(init, "bo init")
        self.starts = check_int(starts, "bo starts")
        self.candidates = check_int(candidates, "bo candidates")
        self.max_points = check_int(max_points, "bo max_points", lo=4)
        self.n_corners = check_int(corners, "bo corners", lo=0)
        from .design import corner_design

        # the first asks: corners of the box, the rest of the initial cases uniform
        self._design = corner_design(self.space, min(self.n_corners, self.init), self.rng)
        self.gp = GaussianProcess(kernel, max(self.d, 1))
        # every told case (unit cube) and its rho (NaN: invalid), in arrays grown by doubling
        self._n = 0
        self._U = np.zeros((16, self.d))
        self._R = np.zeros(16)
        self._n_valid = 0
        self._next_fit = 0  # hyperparameters are re-optimized once _n reaches this
        self._fill: list[int] | None = None  # the space-filling part of the fitting subset
        # asked, not told yet: the unit points, and the parameters each produced as unit
        # points (what ``tell`` computes from them), by which a told case finds its ask
        self.pending: list[list[float]] = []
        self._pending_keys: list[tuple[float, ...]] = []

    @property
    def X(self) -> np.ndarray:
        """The told cases' unit points, (n, d)."""
        return self._U[: self._n]

    @property
    def y(self) -> list[float | None]:
        """The told cases' rho (None: invalid)."""
        return [None if v != v else v for v in self._R[: self._n].tolist()]

    # -- proposing ----------------------------------------------------------------------
    def ask_unit(self) -> np.ndarray:
        self.n_asked += 1
        if self._n_valid < self.init or self.d == 0:
            # a sampler told enough cases before its first ask (a history) skips the design
            x = (self._design[self.n_asked - 1].copy() if self.n_asked <= len(self._design)
                 else self.rng.random(self.d))
        else:
            x = self._propose()
        self.pending.append(x.tolist())
        self._pending_keys.append(self._key(x))
        if len(self.pending) > self.max_points:
            # asks never told (skipped cases) must not pile up in the believer fit
            del self.pending[0], self._pending_keys[0]
        return x

    def _key(self, u: Any) -> tuple[float, ...]:
        """The unit point ``tell`` computes from the case ``u`` stands for."""
        return tuple(self._unit(self._params(u)))

    def tell(self, params: Mapping[str, Any], rho: Rho) -> None:
        """Feedback for an evaluated case; learned at the unit point it was asked as."""
        u = self._unit(params)
        key = tuple(u)
        for j in range(len(self._pending_keys) - 1, -1, -1):
            if self._pending_keys[j] == key:
                u = self.pending[j]
                break
        self.tell_unit(u, rho)

    def _training_set(self, refresh: bool) -> tuple[np.ndarray, np.ndarray]:
        X = self.X
        raw = self._R[: self._n]
        fin = np.isfinite(raw)
        if fin.any():
            lo, hi = raw[fin].min(), raw[fin].max()
            span = max(hi - lo, 1e-9)
            # +inf (holds trivially) is "far above anything seen", not a number to fit
            y = np.where(np.isposinf(raw), hi + span, np.where(np.isneginf(raw), lo - span, raw))
            y = np.where(np.isnan(raw), np.median(raw[fin]), y)
        else:
            y = np.where(np.isnan(raw), 0.0, np.sign(raw))
        if len(y) > self.max_points:
            keep = self._subset(X, y, refresh)
            X, y = X[keep], y[keep]
        return X, y

    def _subset(self, X: np.ndarray, y: np.ndarray, refresh: bool) -> np.ndarray:
        """Indices of the at most ``max_points`` cases the GP is fitted to: the best, the
        most recent of the rest, and a space-filling share chosen by greedy maximin
        (distances in the current length scales) from the remaining cases. The
        space-filling part is chosen again only with the hyperparameters (``refresh``): it
        is the costly part and changes slowly. No randomness: the cases decide."""
        n, m = len(y), self.max_points
        n_fill = int(m * _FILL_SHARE)
        n_best = (m - n_fill + 1) // 2
        n_recent = m - n_fill - n_best
        chosen = np.zeros(n, dtype=bool)
        chosen[np.argsort(y, kind="stable")[:n_best]] = True
        rest = np.flatnonzero(~chosen)
        chosen[rest[len(rest) - n_recent:]] = True
        if refresh or self._fill is None:
            Xs = X / np.exp(self.gp.theta[: self.d])
            dmin = _sq_dist(Xs, Xs[chosen]).min(1)
            dmin[chosen] = -1.0
            fill = []
            for _ in range(n_fill):
                j = int(np.argmax(dmin))
                fill.append(j)
                t = Xs - Xs[j]
                dmin = np.minimum(dmin, (t * t).sum(1))
                dmin[j] = -1.0
            self._fill = fill
        chosen[self._fill] = True
        return np.flatnonzero(chosen)

    def _propose(self) -> np.ndarray:
        from scipy.optimize import minimize
        from scipy.special import ndtr

        optimize = self._n >= self._next_fit
        if optimize:
            self._next_fit = self._n + min(_REFIT_MAX, max(1, self._n // _REFIT_SHARE))
        X, y = self._training_set(refresh=optimize)
        mean, sd = float(y.mean()), float(y.std())
        sd = sd if sd > 1e-12 else 1.0
        ys = (y - mean) / sd
        self.gp.fit(X, ys, optimize=optimize)
        if self.pending:  # kriging believer: pending asks count at their posterior mean
            P = np.asarray(self.pending, dtype=float).reshape(-1, self.d)
            mu_p, _ = self.gp.predict(P)
            self.gp.fit(np.vstack([X, P]), np.concatenate([ys, mu_p]), optimize=False)
        best = float(ys.min())
        d = self.d

        def acq(Z: np.ndarray, grad: bool):
            # returns the value to MINIMIZE (negative EI, or LCB) and its gradient
            if not grad:
                mu, s = self.gp.predict(Z)
            else:
                mu, s, dmu, ds = self.gp.predict(Z, grad=True)
            if self.acquisition == "lcb":
                val = mu - self.kappa * s
                return (val, dmu - self.kappa * ds) if grad else val
            imp = best - mu - self.xi
            z = imp / s
            cdf = ndtr(z)
            pdf = np.exp(-0.5 * z * z) / math.sqrt(2 * math.pi)
            ei = imp * cdf + s * pdf
            if not grad:
                return -ei
            return -ei, -(-cdf[:, None] * dmu + pdf[:, None] * ds)

        # screening: uniform points plus Gaussian perturbations of the best cases
        n_loc = self.candidates // 2
        top = X[np.argsort(ys)[: max(1, min(5, len(ys)))]]
        loc = top[self.rng.integers(len(top), size=n_loc)] + \
            self.gp.ell * 0.3 * self.rng.standard_normal((n_loc, d))
        C = np.vstack([self.rng.random((self.candidates - n_loc, d)), np.clip(loc, 0.0, 1.0)])
        vals = acq(C, False)
        order = np.argsort(vals, kind="stable")[: self.starts]
        S = C[order]

        def joint(z: np.ndarray):
            v, g = acq(z.reshape(-1, d), True)
            return float(v.sum()), g.ravel()

        res = minimize(joint, S.ravel(), jac=True, method=_METHOD,
                       bounds=[(0.0, 1.0)] * S.size, options={"maxfun": 60})
        Z = np.clip(np.asarray(res.x, dtype=float).reshape(-1, d), 0.0, 1.0)
        Z = np.vstack([Z, S])
        v = acq(Z, False)
        return Z[int(np.argmin(v))].copy()

    # -- learning -----------------------------------------------------------------------
    def _learn(self, u: Any, r: float | None, rho: Rho) -> None:
        u = np.asarray(u, dtype=float).reshape(self.d)
        if self.pending and self.d == 0:
            self.pending.pop()
            self._pending_keys.pop()
        elif self.pending:
            P = np.asarray(self.pending, dtype=float)
            j = int(np.argmin(np.abs(P - u).sum(1)))
            if np.abs(P[j] - u).max() >= 1e-6:
                # told as the case it stands for (tell_unit of a stratum centre)
                key = self._key(u)
                j = next((i for i, k in enumerate(self._pending_keys) if k == key), -1)
            if j >= 0:
                del self.pending[j], self._pending_keys[j]
        self._append(u, r)

    def _append(self, u: np.ndarray, r: float | None) -> None:
        if self._n == len(self._R):
            self._U = np.concatenate([self._U, np.zeros_like(self._U)])
            self._R = np.concatenate([self._R, np.zeros_like(self._R)])
        self._U[self._n] = u
        self._R[self._n] = math.nan if r is None else r
        self._n += 1
        self._n_valid += r is not None

    # -- state --------------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        st = super().state()
        st.update(X=self.X.tolist(), y=[None if v is None else json_float(v) for v in self.y],
                  pending=self.pending, theta=self.gp.theta.tolist(), fits=self.gp.n_fits,
                  next_fit=self._next_fit, fill=self._fill, design=self._design.tolist())
        return st

    def restore(self, state: Mapping[str, Any]) -> None:
        super().restore(state)
        self._n = self._n_valid = 0
        self._U = np.zeros((16, self.d))
        self._R = np.zeros(16)
        for x, v in zip(state["X"], state["y"]):
            self._append(np.array(x, dtype=float).reshape(self.d), None if v is None else float(v))
        self.pending = [list(map(float, x)) for x in state["pending"]]
        self._pending_keys = [self._key(x) for x in self.pending]
        self.gp.theta = np.array(state["theta"], dtype=float)
        # states written before the fit schedule existed re-optimize at the next ask
        self.gp.n_fits = int(state.get("fits", 0))
        self._next_fit = int(state.get("next_fit", 0))
        if "design" in state:  # the design drawn at construction, whatever the seed's state
            design = state["design"]
            self._design = np.array(design, dtype=float).reshape(len(design), self.d)
        fill = state.get("fill")
        self._fill = None if fill is None else [int(i) for i in fill]

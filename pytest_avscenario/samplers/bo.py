"""The Bayesian-optimization sampler (``bo``): a Gaussian process on rho, minimized actively.

The first ``init`` cases are uniform random. After that, a Gaussian process with a Matérn-5/2
(or RBF) kernel and one length scale per dimension is fitted to the standardized rho values
by maximizing the log marginal likelihood (scipy.optimize's bounded truncated Newton, TNC,
with analytic gradients, warm-started from the previous fit), and the next case maximizes
the acquisition — expected improvement below the best rho so far, or the lower confidence
bound ``mu - kappa * sigma``. The acquisition is screened on random and near-best candidates,
then polished from the ``starts`` best of them with TNC (all starts in one call: the
objective is their sum, which is separable).

Plain numpy/scipy, cubic in the number of cases: beyond ``max_points`` the fit keeps the best
half and the most recent half. Cases asked but not told yet count at the posterior mean
("kriging believer"), so a batch of asks spreads out instead of repeating one point.
A told case is matched to its ask through the parameters the ask produced, so integer and
categorical parameters (whose told value maps back to the centre of its stratum, not to the
asked point) match too. Invalid cases are kept at the median rho: no evidence, but not
proposed again.
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


def _inv_from_cholesky(L: np.ndarray) -> np.ndarray:
    """K^-1 from its Cholesky factor.

    Written with numpy's own LAPACK and einsum on purpose: on a loaded 2-core machine the
    multi-threaded BLAS-3 paths (scipy.linalg.cho_solve, matmul of a candidate batch) were
    measured 30-60x slower than these (threads spinning against the simulations)."""
    Li = np.linalg.inv(L)
    return np.einsum("ki,kj->ij", Li, Li)


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
        """Kernel values and the factor f with dk/dlog(l_k) = f * D2_k (and dk/dx = -f*diff/l^2)."""
        r2 = D2.sum(-1)
        if self.kernel == "rbf":
            k = s2 * np.exp(-0.5 * r2)
            return k, k
        r = np.sqrt(r2)
        e = np.exp(-_SQRT5 * r)
        k = s2 * (1.0 + _SQRT5 * r + (5.0 / 3.0) * r2) * e
        return k, s2 * (5.0 / 3.0) * (1.0 + _SQRT5 * r) * e

    def nll(self, theta: np.ndarray, X: np.ndarray, y: np.ndarray) -> tuple[float, np.ndarray]:
        """Negative log marginal likelihood and its gradient in theta."""
        d = self.d
        ell = np.exp(theta[:d])
        s2, sn2 = math.exp(theta[d]), math.exp(theta[d + 1])
        diff = (X[:, None, :] - X[None, :, :]) / ell
        D2 = diff * diff
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
            best = None
            for t0 in starts:
                res = minimize(self.nll, t0, args=(X, y), jac=True, method=_METHOD,
                               bounds=self.bounds, options={"maxfun": 60})
                if best is None or res.fun < best.fun:
                    best = res
            if np.all(np.isfinite(best.x)):
                self.theta = np.asarray(best.x, dtype=float)
        d = self.d
        self.ell = np.exp(self.theta[:d])
        self.s2 = math.exp(self.theta[d])
        self.X = X
        diff = (X[:, None, :] - X[None, :, :]) / self.ell
        noise = math.exp(self.theta[d + 1]) + 1e-10
        K = self._k(diff * diff, self.s2)[0] + noise * np.eye(len(y))
        self._Kinv = _inv_from_cholesky(np.linalg.cholesky(K))
        self.alpha = self._Kinv @ y

    def predict(self, Z: np.ndarray, grad: bool = False):
        """Posterior mean and standard deviation at Z (m, d); with gradients if asked."""
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
    ``init`` (random cases first, default 5), ``starts`` (local optimizer starts, default 5),
    ``candidates`` (screening points, default 500), ``max_points`` (cases in the fit,
    default 300), plus ``metrics`` and ``priority`` (``bo`` minimizes the worst metric, or with a
    priority the worst top-ranked one).
    """

    name = "bo"
    options = ActiveSampler.options + ("kernel", "acquisition", "kappa", "xi", "init", "starts",
                                       "candidates", "max_points")

    def __init__(self, space, seed=0, kernel: str = "matern", acquisition: str = "ei",
                 kappa: float = 2.0, xi: float = 0.01, init: int = 5, starts: int = 5,
                 candidates: int = 500, max_points: int = 300, **options: Any):
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
        self.gp = GaussianProcess(kernel, max(self.d, 1))
        self.X: list[list[float]] = []  # every told case (unit cube) and its rho (None: invalid)
        self.y: list[float | None] = []
        # asked, not told yet: the unit points, and the parameters each produced as unit
        # points (what ``tell`` computes from them), by which a told case finds its ask
        self.pending: list[list[float]] = []
        self._pending_keys: list[tuple[float, ...]] = []

    # -- proposing ----------------------------------------------------------------------
    def ask_unit(self) -> np.ndarray:
        self.n_asked += 1
        valid = [v for v in self.y if v is not None]
        if len(valid) < self.init or self.d == 0:
            x = self.rng.random(self.d)
        else:
            x = self._propose()
        self.pending.append(x.tolist())
        self._pending_keys.append(self._key(x))
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

    def _training_set(self) -> tuple[np.ndarray, np.ndarray]:
        X = np.asarray(self.X, dtype=float).reshape(-1, self.d)
        raw = np.array([np.nan if v is None else v for v in self.y], dtype=float)
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
            half = self.max_points // 2
            keep = np.union1d(np.argsort(y, kind="stable")[:half], np.arange(len(y) - half, len(y)))
            X, y = X[keep], y[keep]
        return X, y

    def _propose(self) -> np.ndarray:
        from scipy.optimize import minimize
        from scipy.special import ndtr

        X, y = self._training_set()
        mean, sd = float(y.mean()), float(y.std())
        sd = sd if sd > 1e-12 else 1.0
        ys = (y - mean) / sd
        self.gp.fit(X, ys)
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
        u = np.asarray(u, dtype=float)
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
            elif len(self.pending) > 4 * self.max_points:
                # asks never told (skipped cases) must not pile up
                del self.pending[0], self._pending_keys[0]
        self.X.append(u.tolist())
        self.y.append(r)

    # -- state --------------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        st = super().state()
        st.update(X=self.X, y=[None if v is None else json_float(v) for v in self.y],
                  pending=self.pending, theta=self.gp.theta.tolist())
        return st

    def restore(self, state: Mapping[str, Any]) -> None:
        super().restore(state)
        self.X = [list(map(float, x)) for x in state["X"]]
        self.y = [None if v is None else float(v) for v in state["y"]]
        self.pending = [list(map(float, x)) for x in state["pending"]]
        self._pending_keys = [self._key(x) for x in self.pending]
        self.gp.theta = np.array(state["theta"], dtype=float)

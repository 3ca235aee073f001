r"""A Gaussian-process emulator in numpy (docs/CALIBRATION.md): one output of the uniaxial
test as a function of the law's parameters (scaled to the unit cube), from a few tens of runs.

Squared-exponential kernel with one length per input (automatic relevance), a signal
variance and a noise variance (the seed-to-seed scatter of a run: the same parameters with
another packing give another value), on standardised outputs:

.. math:: k(x, x') = s^2 \exp\!\Big(-\tfrac12 \sum_i (x_i - x'_i)^2 / \ell_i^2\Big)
          + \sigma_n^2 \delta_{xx'}

The hyperparameters maximise the log marginal likelihood (Rasmussen and Williams 2006, eq.
2.30): a space-filling start of the log-hyperparameters, then Nelder-Mead from the best
few. :meth:`GP.predict` gives the mean and the variance of the latent function (the noise
variance is :attr:`GP.noise`, in the output's units, for the caller to add where it
compares with a measurement).
"""

from __future__ import annotations

import math

import numpy as np


def nelder_mead(f, x0: np.ndarray, step: float = 0.5, iters: int = 300, tol: float = 1e-7):
    """Minimise ``f`` from ``x0`` with the Nelder-Mead simplex (standard coefficients).
    Returns (x, f(x))."""
    n = len(x0)
    pts = [np.asarray(x0, dtype=float)]
    for i in range(n):
        p = pts[0].copy()
        p[i] += step
        pts.append(p)
    vals = [f(p) for p in pts]
    for _ in range(iters):
        order = np.argsort(vals)
        pts = [pts[i] for i in order]
        vals = [vals[i] for i in order]
        if abs(vals[-1] - vals[0]) < tol * (1 + abs(vals[0])):
            break
        c = np.mean(pts[:-1], axis=0)
        xr = c + (c - pts[-1])
        fr = f(xr)
        if fr < vals[0]:
            xe = c + 2 * (c - pts[-1])
            fe = f(xe)
            pts[-1], vals[-1] = (xe, fe) if fe < fr else (xr, fr)
        elif fr < vals[-2]:
            pts[-1], vals[-1] = xr, fr
        else:
            xc = c + 0.5 * (pts[-1] - c)
            fc = f(xc)
            if fc < vals[-1]:
                pts[-1], vals[-1] = xc, fc
            else:
                for i in range(1, n + 1):
                    pts[i] = pts[0] + 0.5 * (pts[i] - pts[0])
                    vals[i] = f(pts[i])
    k = int(np.argmin(vals))
    return pts[k], vals[k]


class GP:
    """The emulator of one output: fit on ``x`` (n x d, inputs in [0, 1]) and ``y`` (n)."""

    def __init__(self, x, y, seed: int = 0):
        self.x = np.asarray(x, dtype=float)
        y = np.asarray(y, dtype=float)
        self.mean, self.scale = float(y.mean()), float(y.std()) or 1.0
        self.z = (y - self.mean) / self.scale
        self.params = self._fit(np.random.default_rng(seed))
        self._factor()

    # hyperparameters h = (log l_1..l_d, log s^2, log sn^2), on standardised outputs
    def _kernel(self, a, b, h):
        d = self.x.shape[1]
        ell = np.exp(h[:d])
        diff = (a[:, None, :] - b[None, :, :]) / ell
        return math.exp(h[d]) * np.exp(-0.5 * np.sum(diff**2, axis=2))

    def _nll(self, h) -> float:
        d = self.x.shape[1]
        if np.any(np.abs(h) > 12) or h[d + 1] < -14:
            return 1e10
        k = self._kernel(self.x, self.x, h) + (math.exp(h[d + 1]) + 1e-10) * np.eye(len(self.z))
        try:
            c = np.linalg.cholesky(k)
        except np.linalg.LinAlgError:
            return 1e10
        a = np.linalg.solve(c.T, np.linalg.solve(c, self.z))
        return float(0.5 * self.z @ a + np.sum(np.log(np.diag(c))))

    def _fit(self, rng) -> np.ndarray:
        d = self.x.shape[1]
        starts = np.column_stack(
            [
                rng.uniform(math.log(0.05), math.log(3.0), (64, d)),
                rng.uniform(-1.0, 1.0, 64),
                rng.uniform(-8.0, -1.0, 64),
            ]
        )
        vals = np.array([self._nll(h) for h in starts])
        best = None
        for h0 in starts[np.argsort(vals)[:3]]:
            h, v = nelder_mead(self._nll, h0)
            if best is None or v < best[1]:
                best = (h, v)
        return best[0]

    def _factor(self) -> None:
        d = self.x.shape[1]
        h = self.params
        k = self._kernel(self.x, self.x, h) + (math.exp(h[d + 1]) + 1e-10) * np.eye(len(self.z))
        self._c = np.linalg.cholesky(k)
        self._alpha = np.linalg.solve(self._c.T, np.linalg.solve(self._c, self.z))

    @property
    def lengths(self) -> np.ndarray:
        """The fitted length of each input [unit-cube units]."""
        return np.exp(self.params[: self.x.shape[1]])

    @property
    def noise(self) -> float:
        """The fitted noise variance, in the output's units squared."""
        return math.exp(self.params[self.x.shape[1] + 1]) * self.scale**2

    def predict(self, xs) -> tuple[np.ndarray, np.ndarray]:
        """Mean and variance of the latent output at ``xs`` (m x d), in the output's units."""
        xs = np.atleast_2d(np.asarray(xs, dtype=float))
        d = self.x.shape[1]
        ks = self._kernel(xs, self.x, self.params)
        mu = ks @ self._alpha
        v = np.linalg.solve(self._c, ks.T)
        var = np.maximum(math.exp(self.params[d]) - np.sum(v**2, axis=0), 1e-12)
        return self.mean + self.scale * mu, var * self.scale**2


__all__ = ["GP", "nelder_mead"]

r"""A Gaussian-process emulator in numpy, fitted with scipy's optimiser (docs/CALIBRATION.md):
one output of the uniaxial test as a function of the law's parameters (scaled to the unit
cube), from a few tens of runs.

Squared-exponential kernel with one length per input (automatic relevance), a signal
variance and a noise variance (the seed-to-seed scatter of a run: the same parameters with
another packing give another value), on standardised outputs:

.. math:: k(x, x') = s^2 \exp\!\Big(-\tfrac12 \sum_i (x_i - x'_i)^2 / \ell_i^2\Big)
          + \sigma_n^2 \delta_{xx'}

The hyperparameters maximise the log marginal likelihood (Rasmussen and Williams 2006, eq.
2.30): a space-filling start of the log-hyperparameters, then Nelder-Mead
(``scipy.optimize.minimize``) from the best few. :meth:`GP.predict` gives the mean and the
variance of the latent function (the noise variance is :attr:`GP.noise`, in the output's
units, for the caller to add where it compares with a measurement).
"""

from __future__ import annotations

import math

import numpy as np


def _minimise(f, x0: np.ndarray, step: float = 0.5, iters: int = 300) -> tuple[np.ndarray, float]:
    """Minimise ``f`` from ``x0`` with scipy's Nelder-Mead simplex (standard coefficients; the
    first simplex ``x0`` and a ``step`` along each axis, at most ``iters`` iterations).
    Returns (x, f(x))."""
    from scipy.optimize import minimize

    x0 = np.asarray(x0, dtype=float)
    simplex = np.vstack([x0, x0 + step * np.eye(len(x0))])
    # stop on the spread of the simplex's values alone (relative 1e-7): a length the data do
    # not bound lies along a flat valley, where a test on the points would walk to the
    # search's edge for nothing
    fatol = 1e-7 * (1.0 + abs(f(x0)))
    r = minimize(
        f,
        x0,
        method="Nelder-Mead",
        options={"initial_simplex": simplex, "maxiter": iters, "xatol": np.inf, "fatol": fatol},
    )
    return r.x, float(r.fun)


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
            h, v = _minimise(self._nll, h0)
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


__all__ = ["GP"]

"""The response surface's Gaussian process, one scalar answer at a time (scikit-learn's
:class:`~sklearn.gaussian_process.GaussianProcessRegressor`; hcmt does not write its own GP): on standardized inputs
``z`` and a standardized log output ``y``, the kernel

    k(z, z') = c² exp(−½ Σ_d (z_d − z'_d)² / ℓ_d²) + σ_n² δ(z, z')      (ARD RBF + white noise)

fitted by maximizing the marginal likelihood (:func:`fit_gp`), or refitted with stored hyperparameters and no
optimizer run, and its central 95 % interval back in the answer's unit (:func:`intervals`). The design parameters,
the transforms and the file around it are :class:`hcmt.design.surrogate.Surrogate`'s."""

from __future__ import annotations

import warnings

import numpy as np
from sklearn.exceptions import ConvergenceWarning
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel

from hcmt.design.summary import SurrogateAnswer

Z95 = 1.959963984540054  # the standard normal's 97.5 % quantile: a central 95 % interval


def kernel(d: int, hyper: dict | None = None):
    """c² RBF(ℓ_1..ℓ_d) + σ_n², with the stored values when ``hyper`` is given."""
    if hyper is None:
        return ConstantKernel(1.0, (1e-3, 1e3)) * RBF(np.ones(d), (1e-2, 1e3)) + WhiteKernel(1e-4, (1e-8, 1e-1))
    return ConstantKernel(float(hyper["constant"]), "fixed") * RBF(
        np.asarray(hyper["length_scales"], float), "fixed"
    ) + WhiteKernel(float(hyper["noise"]), "fixed")


def hyperparameters(fitted) -> dict:
    """The fitted hyperparameters of :func:`kernel`'s structure as plain numbers."""
    prod, white = fitted.k1, fitted.k2
    return {
        "constant": float(prod.k1.constant_value),
        "length_scales": [float(v) for v in np.atleast_1d(prod.k2.length_scale)],
        "noise": float(white.noise_level),
    }


def fit_gp(
    z: np.ndarray, y: np.ndarray, hyper: dict | None = None, restarts: int = 0, seed: int = 0
) -> tuple[GaussianProcessRegressor, dict]:
    """(the fitted process, its hyperparameters) on ``z`` [n, d] and ``y`` [n]: ``hyper`` None, fitted by the
    marginal likelihood (``restarts`` restarts, ``seed``); else those values, no optimizer run."""
    if hyper is None:
        gp = GaussianProcessRegressor(kernel(z.shape[1]), n_restarts_optimizer=restarts, random_state=seed)
    else:
        gp = GaussianProcessRegressor(kernel(z.shape[1], hyper), optimizer=None)
    with warnings.catch_warnings():  # a length scale at its upper bound: that parameter does not matter
        warnings.simplefilter("ignore", ConvergenceWarning)
        gp.fit(z, y)
    return gp, hyper or hyperparameters(gp.kernel_)


def intervals(gp: GaussianProcessRegressor, z: np.ndarray, mean: float, std: float) -> list[SurrogateAnswer]:
    """Per row of ``z``, the answer's :class:`~hcmt.design.summary.SurrogateAnswer` ``exp(m + s (μ ± 1.96 σ))``: the
    process predicts the standardized log answer (``mean``, ``std``: its standardization), σ from the
    white-noise-including kernel."""
    mu, sd = gp.predict(z, return_std=True)
    return [
        SurrogateAnswer(
            float(np.exp(mean + std * mu[i])),
            float(np.exp(mean + std * (mu[i] - Z95 * sd[i]))),
            float(np.exp(mean + std * (mu[i] + Z95 * sd[i]))),
        )
        for i in range(len(z))
    ]

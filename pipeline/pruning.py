"""Spurious-IMF pruning by correlation with the signal (Aftab et al. 2016, §2.3, eq. 7–8).

End effects of the spline envelopes creep inwards and create pseudo-components (Peng et al.
2005).  Significant IMFs correlate with the signal: ``rho_i = cov(c_i, x) / (sigma_x sigma_ci)``
(eq. 7), normalised ``lambda_i = rho_i / max_j rho_j`` (eq. 8); IMFs with ``lambda > 0.5`` are
kept, the others go to the residue.
"""

from __future__ import annotations

import numpy as np

__all__ = ["imf_correlation", "significant_imfs"]


def imf_correlation(imfs: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Correlation coefficient ``rho_i`` of every IMF with the signal (eq. 7); 0 for a flat IMF."""
    imfs = np.atleast_2d(np.asarray(imfs, dtype=np.float64))
    xc = np.asarray(x, dtype=np.float64) - np.mean(x)
    cc = imfs - imfs.mean(axis=-1, keepdims=True)
    num = cc @ xc
    den = np.sqrt(np.einsum("ij,ij->i", cc, cc) * (xc @ xc))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0)


def significant_imfs(imfs: np.ndarray, x: np.ndarray, *, threshold: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the IMFs with ``lambda_i = rho_i / max(rho) > threshold`` (eq. 8), and all lambdas.

    Returns
    -------
    keep : int array of kept IMF indices (ascending).
    lam : float array of ``lambda_i`` for every IMF (NaN when no IMF correlates positively).
    """
    rho = imf_correlation(imfs, x)
    top = rho.max(initial=0.0)
    if top <= 0:
        return np.empty(0, dtype=int), np.full(rho.shape, np.nan)
    lam = rho / top
    return np.flatnonzero(lam > threshold), lam

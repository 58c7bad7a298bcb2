"""The error a broadband model's smoothed ratios share between neighbouring lines, and what it
does to a steady run's shapes.

The ratios a_k / a_1 of the operating shape are smoothed over the scan's lines
(:func:`forcecal.model.ratios.smooth_ratios`): each smoothed value is a weighted sum of its
neighbours' noise, so the errors at two frequencies correlate. A calibration over frequency
(steps of a stepped sine, each run taking its shapes at its own frequency) fits a law to the
trend of its steps: errors that move every step alike, or smoothly with the frequency, must be
one error of every run, not each run's own, or the law's parameters are stated too precisely.
The splines' noise covariance over the lines, S diag(var) S^T, is kept as its principal
directions (:func:`error_directions`), and a steady run's model carries each as one error of
its shapes (:func:`shared_ratio_errors`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .broadband import BroadbandModel

__all__ = ["shared_ratio_errors"]


DIRECTIONS_KEPT = 1.0 - 1e-3
"""The share of a smoothed ratio's noise variance (summed over the lines) its error
directions keep (:func:`error_directions`); the rest stays each line's own."""


def principal_directions(cov: np.ndarray, share: float = 1.0, floor: float = 0.0
                         ) -> np.ndarray:
    """(n_dirs, n) the principal directions of a covariance, each scaled by its standard
    deviation, the strongest first: those whose variance exceeds ``floor``, and no more than
    hold ``share`` of its trace (sum_d D_d D_d^T is the covariance to that share)."""
    lam, vec = np.linalg.eigh(0.5 * (cov + cov.T))
    lam, vec = lam[::-1].clip(min=0.0), vec[:, ::-1]
    total = float(lam.sum())
    if not total > 0:
        return np.zeros((0, cov.shape[0]))
    n = int(np.searchsorted(np.cumsum(lam), share * total)) + 1 if share < 1.0 else len(lam)
    n = min(n, int(np.count_nonzero(lam > floor)))
    out: np.ndarray = (vec[:, :n] * np.sqrt(lam[:n])).T
    return out


def error_directions(cov: np.ndarray) -> np.ndarray:
    """(n_dirs, n) a smoothed ratio's error directions over the lines: the principal
    directions of its noise covariance that hold :data:`DIRECTIONS_KEPT` of its trace."""
    return principal_directions(cov, DIRECTIONS_KEPT)


def shared_ratio_errors(model: BroadbandModel, real: np.ndarray, at: np.ndarray
                        ) -> tuple[tuple[tuple[str, np.ndarray, np.ndarray], ...], np.ndarray]:
    """The ratios' errors that the lines share (:meth:`BroadbandModel.mixing_directions`) as
    changes of the shapes' coefficients at the frequencies ``at`` (the harmonics', then the
    quasi-static shape's; of Re and of Im of each ratio), and the variance (n_shapes, n_at) of
    each ratio left to each frequency alone."""
    own = model.mixing_std(at) ** 2
    out = []
    for k, dirs in model.mixing_directions(at):
        own[k] = np.maximum(own[k] - np.sum(dirs**2, axis=0), 0.0)
        for d, row in enumerate(dirs):
            change = real[:, k][None, :] * row[:, None]          # (n_at, n_coef)
            for part, unit in (("re", 1.0), ("im", 1j)):
                out.append((f"scan ratio {k} direction {d} {part}", unit * change[:-1],
                            unit * change[-1]))
    return tuple(out), own


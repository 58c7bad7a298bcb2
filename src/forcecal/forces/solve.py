"""The force solve of METHOD.md section 2 (eq. 8, 24 corrected), once for every estimator:
F = Psi^+ (J - R), and the reactions-only estimate it becomes without the inertia term."""

from __future__ import annotations

import numpy as np

__all__ = ["force_solve", "reactions_only"]

SPLIT_CONDITION = 30.0
"""cond(Psi) above which the split between the forces is flagged as poorly determined."""


def force_solve(pinv: np.ndarray, inertia: np.ndarray, reactions: np.ndarray) -> np.ndarray:
    """F = Psi^+ (J - R) (eq. 8, 24 corrected): the forces from the inertia term and the
    reactions, exact when there are as many forces as gauges, least squares otherwise.

    Parameters
    ----------
    pinv : (n_forces, n_gauges) ndarray
        [1] Psi^+.
    inertia : (n_gauges, ...) ndarray
        [N] J (phasors of any harmonics, or samples).
    reactions : (n_gauges, ...) ndarray
        [N] R, the forces the gauges exert on the structure.

    Returns
    -------
    (n_forces, ...) ndarray [N]
    """
    forces: np.ndarray = pinv @ (inertia - reactions)
    return forces


def reactions_only(pinv: np.ndarray, reactions: np.ndarray) -> np.ndarray:
    """-Psi^+ R: the reactions-only (static) estimate, the baseline every result is compared
    with (METHOD.md section 2: :func:`force_solve` without J).

    Parameters
    ----------
    pinv : (n_forces, n_gauges) ndarray
        [1] Psi^+.
    reactions : (n_gauges, ...) ndarray
        [N] R.

    Returns
    -------
    (n_forces, ...) ndarray [N]
    """
    static: np.ndarray = -(pinv @ reactions)
    return static

"""The reference form of the streaming kernel: textbook recursive least squares with
forgetting in information form, for any regressor (:mod:`forcecal.realtime.rls` derives the
fast exact form for the harmonic regressor and checks itself against this one)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import DimensionError

__all__: list[str] = []

PRIOR = 1.0
"""r0: information of the prior at the start (P_0 = I / r0), in samples' worth of regressor."""


@dataclass(frozen=True)
class RlsState:
    """Recursive least squares in information form.

    Attributes
    ----------
    information : (p, p) [1] R_k = sum lambda^(k-i) phi_i phi_i^T + lambda^k r0 I
    moment : (p, n_outputs) [unit of y] b_k = sum lambda^(k-i) phi_i y_i^T
    count : samples seen
    """

    information: np.ndarray
    moment: np.ndarray
    count: int = 0


def rls_start(n_regressors: int, n_outputs: int, prior: float = PRIOR) -> RlsState:
    """The state before any sample: prior information ``prior * I``, no data.

    Parameters
    ----------
    n_regressors : int
        p, the regressor's length.
    n_outputs : int
        Outputs sharing the regressor.
    prior : float
        r0, the prior's information per regressor.

    Returns
    -------
    RlsState
    """
    return RlsState(information=prior * np.eye(n_regressors),
                    moment=np.zeros((n_regressors, n_outputs)))


def rls_update(state: RlsState, y: np.ndarray, regressors: np.ndarray,
               lam: float) -> tuple[RlsState, np.ndarray]:
    """Exact RLS with forgetting over a block of samples (the reference form).

    Parameters
    ----------
    state : the state after the previous sample
    y : (n_outputs, n) [any unit] samples of every output, sharing the regressor
    regressors : (p, n) [1] phi_k of every sample
    lam : forgetting factor lambda, 0 < lambda <= 1

    Returns
    -------
    state : after the last sample
    estimates : (n_outputs, p, n) x_k = R_k^{-1} b_k of every sample
    """
    y = np.atleast_2d(np.asarray(y, dtype=float))
    phi = np.atleast_2d(np.asarray(regressors, dtype=float))
    p, n = phi.shape
    if y.shape[-1] != n or state.information.shape != (p, p) or y.shape[0] != \
            state.moment.shape[1]:
        raise DimensionError(f"rls_update: y {y.shape}, regressors {phi.shape}, state for "
                             f"{state.information.shape[0]} regressors and "
                             f"{state.moment.shape[1]} outputs")
    if n == 0:
        return state, np.zeros((y.shape[0], p, 0))
    a = [1.0, -lam]
    outer = (phi[:, None, :] * phi[None, :, :]).reshape(p * p, n)
    from scipy.signal import lfilter  # the reference form only; keeps start-up light

    info = lfilter([1.0], a, outer, axis=-1, zi=lam * state.information.reshape(-1, 1))[0]
    cross = (phi[:, None, :] * y[None, :, :]).reshape(p * y.shape[0], n)
    mom = lfilter([1.0], a, cross, axis=-1, zi=lam * state.moment.reshape(-1, 1))[0]
    info = info.reshape(p, p, n)
    mom = mom.reshape(p, y.shape[0], n)
    x = np.linalg.solve(info.transpose(2, 0, 1), mom.transpose(2, 0, 1))     # (n, p, n_out)
    new = RlsState(information=info[:, :, -1].copy(), moment=mom[:, :, -1].copy(),
                   count=state.count + n)
    return new, x.transpose(2, 1, 0)

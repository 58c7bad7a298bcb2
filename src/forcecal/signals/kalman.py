"""A band-limited signal and its derivatives from noisy samples: Kalman filter and smoother
(METHOD.md section 7, "any drive").

Each signal (a generalized coordinate, a gauge's reaction) is modelled as white noise through
an analog Butterworth low-pass of order p at the band's top, f_c: its state is the signal and
its first p - 1 derivatives (an integrator chain closed by the Butterworth polynomial), so the
acceleration is a state with a covariance. The measurement is the signal plus white noise. The
model is time-invariant, so the gains reach steady values within a few periods of f_c; they
are used from the first sample (the record extended at both ends by its odd reflection):

- filter (real time, causal): x_k = Phi x_{k-1} + K (z_k - H Phi x_{k-1}), K from the discrete
  algebraic Riccati equation;
- smoother (batch, Rauch-Tung-Striebel): x_k^s = x_k + G (x_{k+1}^s - Phi x_k),
  G = P Phi^T P_pred^-1, its covariance from a discrete Lyapunov equation.

Both are state-space recursions compiled with Numba (a transfer-function form of a high order
loses its digits when sampled far faster than its cutoff). The prior's level is the signal's
own mean power density in the band, at most ``SNR_CAP`` times the noise's: within the band the
gain is 1 to within 1 / SNR_CAP; beyond f_c the prior falls as f^-2p, so noise is let through
only up to f_c SNR_CAP^(1/2p).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
import scipy.linalg

__all__ = ["BandModel", "band_model", "smooth_states"]

ORDER = 8
"""The prior's Butterworth order p: states are the signal and p - 1 derivatives."""
SNR_CAP = 1.0e4
"""Largest ratio of the prior's in-band density to the noise's."""


@dataclass(frozen=True)
class BandModel:
    """The discrete state-space model of one band-limited signal and its steady gains.

    Attributes
    ----------
    phi : (p, p) array
        State transition over one sample.
    gain : (p,) array
        The filter's steady Kalman gain.
    smoother_gain : (p, p) array
        The RTS smoother's steady gain G.
    filtered_cov : (p, p) array
        Steady covariance of the filtered state (units of the measurement squared, per
        derivative order [1/s^k]).
    smoothed_cov : (p, p) array
        Steady covariance of the smoothed state.
    fs : float [Hz]
        Sampling rate.
    settle : int
        Samples the gains take to settle (the reflection's length).
    scale : (p,) array
        wc^k: the model's state k is the k-th derivative divided by wc^k.
    """

    phi: np.ndarray
    gain: np.ndarray
    smoother_gain: np.ndarray
    filtered_cov: np.ndarray
    smoothed_cov: np.ndarray
    fs: float
    settle: int
    scale: np.ndarray


def band_model(fs: float, cutoff: float, level: float, noise_var: float,
               order: int = ORDER) -> BandModel:
    """The model of a signal whose in-band power density is ``level`` under white noise.

    Parameters
    ----------
    fs : float [Hz]
        Sampling rate.
    cutoff : float [Hz]
        f_c, the band's top.
    level : float [unit^2 / Hz]
        The signal's one-sided power density in the band (capped at ``SNR_CAP`` times the
        noise's).
    noise_var : float [unit^2]
        Variance of the measurement noise of one sample (white).
    order : int
        p >= 3 (the acceleration is the third state).

    Returns
    -------
    BandModel
    """
    import scipy.signal  # on use: a steady stream starts without it

    if order < 3:
        raise ValueError("the band model needs order >= 3 (acceleration is a state)")
    unit = max(float(noise_var), np.finfo(float).tiny)          # computed in units of noise
    noise_density = 2.0 / fs                                    # one-sided [1/Hz]
    level = min(max(float(level) / unit, noise_density), SNR_CAP * noise_density)
    noise_var = 1.0
    wc = 2 * np.pi * cutoff
    # states scaled as y^(k) / wc^k (the derivatives' own scales differ by wc^k):
    # A = wc A_1, A_1 the companion matrix of the Butterworth polynomial of unit cutoff
    _, a = scipy.signal.butter(order, 1.0, analog=True)
    a_cont = np.zeros((order, order))
    a_cont[:-1, 1:] = np.eye(order - 1)
    a_cont[-1] = -a[::-1][:-1]
    a_cont *= wc
    # white noise of two-sided density q on y^(p) through 1 / a(s) has the one-sided density
    # 2 q / wc^(2p) at 0 Hz = level; on the scaled last state its density is q / wc^(2(p-1))
    q = level * wc**2 / 2.0
    dt = 1.0 / fs
    phi, qd = _discretize(a_cont, q, dt)
    h = np.zeros((1, order))
    h[0, 0] = 1.0
    p_pred = scipy.linalg.solve_discrete_are(phi.T, h.T, qd, np.array([[noise_var]]))
    p_pred = 0.5 * (p_pred + p_pred.T)
    s = float(p_pred[0, 0]) + noise_var
    gain = (p_pred @ h.T)[:, 0] / s
    p_filt = p_pred - np.outer(gain, h @ p_pred)
    p_filt = 0.5 * (p_filt + p_filt.T)
    g = p_filt @ phi.T @ np.linalg.inv(p_pred)
    p_smooth = _smoothed_covariance(g, p_filt, p_pred)
    settle = int(np.ceil(12 * fs / cutoff)) + 8
    scale = wc ** np.arange(order)                               # back to y^(k)
    p_filt, p_smooth = p_filt * unit, p_smooth * unit
    return BandModel(phi=phi, gain=gain, smoother_gain=g,
                     filtered_cov=p_filt * np.outer(scale, scale),
                     smoothed_cov=0.5 * (p_smooth + p_smooth.T) * np.outer(scale, scale),
                     fs=fs, settle=settle, scale=scale)


def _smoothed_covariance(g: np.ndarray, p_filt: np.ndarray, p_pred: np.ndarray) -> np.ndarray:
    """The RTS smoother's steady covariance: P_s = P_f + G (P_s - P_pred) G^T, summed as its
    series (G's spectral radius is below 1; the terms fade within the gains' settling)."""
    step = p_filt - g @ p_pred @ g.T
    out, term = step.copy(), step
    for _ in range(20000):
        term = g @ term @ g.T
        out += term
        if np.max(np.abs(term)) <= 1e-15 * np.max(np.abs(out)):
            break
    return out


def _discretize(a: np.ndarray, q: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Phi = exp(A dt) and the process covariance over dt (Van Loan), noise on the last
    state with two-sided density q."""
    n = a.shape[0]
    bq = np.zeros((n, n))
    bq[-1, -1] = q
    m = np.zeros((2 * n, 2 * n))
    m[:n, :n] = -a
    m[:n, n:] = bq
    m[n:, n:] = a.T
    e = scipy.linalg.expm(m * dt)
    phi = e[n:, n:].T
    qd = phi @ e[:n, n:]
    return phi, 0.5 * (qd + qd.T)


def _extend(z: np.ndarray, n: int) -> np.ndarray:
    """``z`` (..., N) with its odd reflection of n samples at both ends."""
    n = min(n, z.shape[-1] - 1)
    head = 2 * z[..., :1] - z[..., n:0:-1]
    tail = 2 * z[..., -1:] - z[..., -2:-n - 2:-1]
    return np.concatenate([head, z, tail], axis=-1)


def _run(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray,
         u: np.ndarray) -> np.ndarray:
    """Outputs (n_out, N) of s_{k+1} = A s_k + B u_k, y_k = C s_k + D u_k from rest, for
    inputs u (n_in, N)."""
    return _recursion(np.ascontiguousarray(a, dtype=float), np.ascontiguousarray(b, dtype=float),
                      np.ascontiguousarray(c, dtype=float), np.ascontiguousarray(d, dtype=float),
                      np.ascontiguousarray(u, dtype=float))


@numba.njit(cache=True)
def _recursion(a, b, c, d, u):  # pragma: no cover - compiled
    n_s, n_in = b.shape
    n_out = c.shape[0]
    n = u.shape[1]
    s = np.zeros(n_s)
    nxt = np.zeros(n_s)
    y = np.zeros((n_out, n))
    for k in range(n):
        for i in range(n_out):
            acc = 0.0
            for j in range(n_s):
                acc += c[i, j] * s[j]
            for j in range(n_in):
                acc += d[i, j] * u[j, k]
            y[i, k] = acc
        for i in range(n_s):
            acc = 0.0
            for j in range(n_s):
                acc += a[i, j] * s[j]
            for j in range(n_in):
                acc += b[i, j] * u[j, k]
            nxt[i] = acc
        for i in range(n_s):
            s[i] = nxt[i]
    return y


def filter_states(model: BandModel, z: np.ndarray, states: tuple[int, ...] = (0, 2)
                  ) -> np.ndarray:
    """The causal filter's estimates of the chosen states.

    Parameters
    ----------
    model : BandModel
    z : (N,) array
        The measured signal.
    states : tuple of int
        Which derivatives to return (0: the signal, 2: its second derivative).

    Returns
    -------
    (len(states), N) array
    """
    p = model.phi.shape[0]
    a_f = (np.eye(p) - np.outer(model.gain, np.eye(p)[0])) @ model.phi
    c = np.eye(p)[list(states)] * model.scale[list(states), None]
    # x_k = A_f x_{k-1} + K z_k: with s_k = x_{k-1}, y_k = C A_f s_k + C K z_k
    n = model.settle
    zz = np.concatenate([np.full(n, z[0]), z])      # a causal filter starts at rest on z_0
    y = _run(a_f, model.gain[:, None], c @ a_f, (c @ model.gain)[:, None], zz[None, :])
    return y[:, n:]


def smooth_states(model: BandModel, z: np.ndarray, states: tuple[int, ...] = (0, 2)
                  ) -> np.ndarray:
    """The RTS smoother's estimates of the chosen states over the whole record.

    Parameters
    ----------
    model : BandModel
    z : (N,) array
        The measured signal.
    states : tuple of int
        Which derivatives to return.

    Returns
    -------
    (len(states), N) array
    """
    p = model.phi.shape[0]
    n = model.settle
    zz = _extend(np.asarray(z, dtype=float), n)
    m = (zz.shape[-1] - z.shape[-1]) // 2
    eye = np.eye(p)
    a_f = (eye - np.outer(model.gain, eye[0])) @ model.phi
    xf = _run(a_f, model.gain[:, None], a_f, model.gain[:, None], zz[None, :])
    # backward: x^s_k = G x^s_{k+1} + (I - G Phi) x_k, run on the reversed record
    g = model.smoother_gain
    b = eye - g @ model.phi
    c = eye[list(states)] * model.scale[list(states), None]
    rev = xf[:, ::-1]
    ys = _run(g, b, c @ g, c @ b, rev)[:, ::-1]
    return ys[:, m:m + z.shape[-1]]

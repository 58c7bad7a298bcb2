"""The structure's transfer from its reactions to its motion, fitted over a record (METHOD.md
section 7, "any drive").

Under any drive the first shape's coordinate q_1 from the probes carries the inertia, and its
second derivative carries the probes' noise times w^2; the gauges are far quieter. The
structure is linear and does not change while it runs, so its reactions-only force
u(t) = -1^T Psi^+ R(t) and the coordinate are tied, frequency by frequency, by a transfer of
the structure alone (not of the drive, the magnet or the gap):

    Q_1(w) = G(w) U(w),   G(s) = b_0 / (1 + a_1 s + a_2 s^2),   s = i w / w_top.

G's poles lie where the reactions vanish for a force, on either side of the imaginary axis: G
ties two measured signals, not a cause to its effect, and is applied over a record, never as a
causal filter. It is fitted by least squares on the band's bins (Sanathanan-Koerner iterations
towards the output error (Q - G U) / sigma, sigma the probes' noise in one bin).
:mod:`forcecal.forces.transient` then takes q_1'' as the gauges' part, IFFT(s^2 G U), plus the
smoothed second derivative of the residual q_1 - G u: the probes' own evidence of what the
transfer misses (a load whose pattern changes, a second force, a structure that is not linear).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..signals.mains import near_mains

__all__: list[str] = []

NUM_ORDER = 0
"""Order of G's numerator in s."""
DEN_ORDER = 2
"""Order of G's denominator in s: one flexible mode (the reactions' zero for a force)."""
ITERATIONS = 30
"""Sanathanan-Koerner iterations at most (they settle within about ten)."""
POLE_MARGIN = 1e-5
"""A pole whose real part is less than this share of its magnitude lies on the axis of real
frequencies (a damping ratio below 1e-5): no transfer, its response being unbounded there."""
MIN_BINS = 32
"""Fewest band bins a fit takes (fewer: no transfer)."""
MAINS_WIDTH = 1.0
"""[Hz] the lines left out of the fit on either side of a mains harmonic: a hum tone leaks into
the record's neighbouring lines (on a 4 s record 4 lines a side)."""


def filtered(x: np.ndarray, fs: float, response: Callable[[np.ndarray], np.ndarray]
             ) -> np.ndarray:
    """Signals ``x`` (n, N) through a response (a function of the frequencies [Hz] giving
    (n, n_freq) or (n_freq,) complex factors), by the discrete Fourier transform of the record
    extended at both ends by its odd reflection (no jump where it wraps)."""
    return fourier_filter(x, fs)(response)


def fourier_filter(x: np.ndarray, fs: float
                   ) -> Callable[[Callable[[np.ndarray], np.ndarray]], np.ndarray]:
    """:func:`filtered` of ``x`` (n, N) as a function of the response alone, the record's
    transform taken once: many responses of one signal (a type-B parameter's each)."""
    n = x.shape[-1]
    pad = min(n - 1, max(n // 4, 1))
    ext = np.concatenate([2 * x[:, :1] - x[:, pad:0:-1], x,
                          2 * x[:, -1:] - x[:, -2:-pad - 2:-1]], axis=-1)
    f = np.fft.rfftfreq(ext.shape[-1], 1.0 / fs)
    spectrum = np.fft.rfft(ext, axis=-1)

    def through(response: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        out = np.fft.irfft(spectrum * response(f), n=ext.shape[-1], axis=-1)
        return out[:, pad:pad + n]

    return through


@dataclass(frozen=True)
class ReactionTransfer:
    """G(s) = sum_k b_k s^k / (1 + sum_k a_k s^k), s = i w / ``scale``, from the
    reactions-only force [N] to the first shape's coordinate [1].

    Attributes
    ----------
    num : (NUM_ORDER + 1,) array
        b_0 .. [1/N].
    den : (DEN_ORDER + 1,) array
        1, a_1, a_2 ...
    scale : float [rad/s]
        The band's top.
    cov : (n_params, n_params) array
        Covariance of (b_0 .., a_1 ..), scaled by the fit's chi-square per degree of freedom
        where that exceeds 1.
    chi2 : float [1]
        The residual's chi-square per degree of freedom: 1 where the transfer explains the
        coordinate to its noise.
    """

    num: np.ndarray
    den: np.ndarray
    scale: float
    cov: np.ndarray
    chi2: float

    def _s(self, f: np.ndarray) -> np.ndarray:
        return 2j * np.pi * np.asarray(f, dtype=float) / self.scale

    def response(self, f: np.ndarray) -> np.ndarray:
        """G at the frequencies ``f`` [Hz]."""
        s = self._s(f)
        return np.polyval(self.num[::-1], s) / np.polyval(self.den[::-1], s)

    def sensitivities(self, f: np.ndarray) -> np.ndarray:
        """(n_params, n_freq): dG / d(b_0 .., a_1 ..) at the frequencies ``f`` [Hz]."""
        s = self._s(f)
        a = np.polyval(self.den[::-1], s)
        g = np.polyval(self.num[::-1], s) / a
        return np.vstack([*(s**k / a for k in range(self.num.size)),
                          *(-g * s**k / a for k in range(1, self.den.size))])


def fit_reaction_transfer(q: np.ndarray, u: np.ndarray, fs: float, band: tuple[float, float],
                          var_q: float, mains: float | None = None) -> ReactionTransfer | None:
    """The transfer from the reactions-only force ``u`` (N,) [N] to the coordinate ``q`` (N,)
    over the ``band`` [Hz], ``var_q`` the coordinate's noise variance per sample, the lines
    within ``MAINS_WIDTH`` of a harmonic of the ``mains`` [Hz] left out (their hum is no
    motion); None when the band holds fewer than ``MIN_BINS`` bins, the fit is not finite or
    it puts a pole on the axis of real frequencies (the inertia is then the probes' alone, and
    the note says so).

    The record's transform ties Q = (B U + C) / A: C(s), a polynomial of order
    ``DEN_ORDER + NUM_ORDER``, is the record's ends' share (the transient term of a finite
    record: what the structure held at its first sample and still holds at its last), fitted
    beside G and set aside (Pintelon and Schoukens, System Identification, ch. 2 and 6). The
    Sanathanan-Koerner iterations give the start; the output error (Q - (B U + C) / A) / sigma
    is then minimised (Levenberg-Marquardt): on a record whose drive holds a narrow band (a
    sweep's first seconds) the iterations settle away from that minimum, its static gain off
    and its chi-square well above the minimum's (docs/method.md, "any drive").
    """
    n = q.size
    f = np.fft.rfftfreq(n, 1.0 / fs)
    sel = (f >= band[0]) & (f <= band[1]) & ~near_mains(f, mains, MAINS_WIDTH)
    if sel.sum() < MIN_BINS or not var_q > 0:
        return None
    scale = 2 * np.pi * band[1]
    s = 2j * np.pi * f[sel] / scale
    qf = np.fft.rfft(q - q.mean())[sel]
    uf = np.fft.rfft(u - u.mean())[sel]
    sigma = np.sqrt(var_q * n / 2.0)                  # noise of Re or Im of a bin
    p = _sanathanan_koerner(s, qf, uf)
    if p is None:
        return None
    p = _output_error_minimum(p, s, qf, uf, sigma)
    nb, na = NUM_ORDER + 1, DEN_ORDER
    # a pole on the axis of real frequencies would make the response infinite there
    poles = np.roots(np.r_[1.0, p[nb:nb + na]][::-1])
    if np.any(np.abs(poles.real) < POLE_MARGIN * np.abs(poles)):
        return None
    res, jac = _output_error(p, s, qf, uf, sigma)
    jr = np.hstack([jac.real, jac.imag]).T
    dof = 2 * res.size - p.size
    chi2 = float(np.sum(np.abs(res) ** 2) / dof)
    try:
        cov = np.linalg.inv(jr.T @ jr)[:nb + na, :nb + na] * max(chi2, 1.0)
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(cov)):
        return None
    return ReactionTransfer(num=p[:nb], den=np.r_[1.0, p[nb:nb + na]], scale=scale, cov=cov,
                            chi2=chi2)


def _sanathanan_koerner(s: np.ndarray, qf: np.ndarray, uf: np.ndarray) -> np.ndarray | None:
    """(b_0 .., a_1 .., c_0 ..) of Q A = B U + C by iterations weighted by the last
    denominator; None when they are not finite."""
    nb, na, nc = NUM_ORDER + 1, DEN_ORDER, DEN_ORDER + NUM_ORDER + 1
    den = np.ones(s.size, dtype=complex)
    p = np.zeros(nb + na + nc)
    for _ in range(ITERATIONS):
        # Q (1 + sum a_k s^k) = U sum b_k s^k + sum c_k s^k, weighted by the last denominator
        cols = np.stack([*(uf * s**k for k in range(nb)),
                         *(-qf * s**k for k in range(1, na + 1)),
                         *(s**k for k in range(nc))], axis=1) / den[:, None]
        rhs = qf / den
        new = np.linalg.lstsq(np.vstack([cols.real, cols.imag]),
                              np.concatenate([rhs.real, rhs.imag]), rcond=None)[0]
        if not np.all(np.isfinite(new)):
            return None
        settled = np.allclose(new, p, rtol=1e-9, atol=0.0)
        p = new
        den = np.polyval(np.r_[1.0, p[nb:nb + na]][::-1], s)
        if settled:
            break
    return p


def _output_error(p: np.ndarray, s: np.ndarray, qf: np.ndarray, uf: np.ndarray, sigma: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The residual (Q - (B U + C) / A) / sigma at the bins and its derivatives
    (n_params, n_bins) by (b_0 .., a_1 .., c_0 ..)."""
    nb, na, nc = NUM_ORDER + 1, DEN_ORDER, DEN_ORDER + NUM_ORDER + 1
    den = np.polyval(np.r_[1.0, p[nb:nb + na]][::-1], s)
    g = np.polyval(p[:nb][::-1], s) / den
    ends = np.polyval(p[nb + na:][::-1], s) / den
    res = (qf - g * uf - ends) / sigma
    jac = np.vstack([*(-(s**k) * uf / den for k in range(nb)),
                     *((g * uf + ends) * s**k / den for k in range(1, na + 1)),
                     *(-(s**k) / den for k in range(nc))]) / sigma
    return res, jac


def _output_error_minimum(p: np.ndarray, s: np.ndarray, qf: np.ndarray, uf: np.ndarray,
                          sigma: float) -> np.ndarray:
    """The parameters at the output error's least squares from ``p`` (Levenberg-Marquardt);
    ``p`` kept where the minimisation does not end finite and lower."""
    from scipy.optimize import least_squares  # on use: a steady stream starts without it

    def fun(x: np.ndarray) -> np.ndarray:
        res = _output_error(x, s, qf, uf, sigma)[0]
        return np.concatenate([res.real, res.imag])

    def jac(x: np.ndarray) -> np.ndarray:
        d = _output_error(x, s, qf, uf, sigma)[1]
        return np.hstack([d.real, d.imag]).T

    start = float(np.sum(fun(p) ** 2))
    with np.errstate(all="ignore"):
        sol = least_squares(fun, p, jac=jac, method="lm", x_scale="jac")
    if np.all(np.isfinite(sol.x)) and 2.0 * sol.cost < start:
        return np.asarray(sol.x)
    return p

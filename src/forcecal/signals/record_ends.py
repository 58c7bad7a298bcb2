"""The record's ends: every channel carried past them by linear prediction (METHOD.md
section 7, "any drive").

The reactions' transfer to the motion has a pole on the right of the imaginary axis
(:mod:`forcecal.forces.reaction_transfer`), so each sample's inertia takes the reactions of a
little while after it, and the smoothers take both sides of every sample: at a record's ends
that future is missing, and an odd reflection loses much of the force there.

Each channel is instead carried past both ends by an autoregressive model fitted to the
samples next to that end (covariance method: least squares on the channel's own past, of an
order spanning ``ORDER_PERIODS`` periods of the band's top), run forward from the end and,
on the reversed channel, backward from the start, and faded to the fitted samples' mean over
its length by a raised cosine (what lies beyond, which the smoothers reflect, stays quiet). A
channel whose prediction grows unstable is carried by its odd reflection instead. The
estimate then runs over the extended stretch and keeps the record's samples; each pad is a
whole number of the Wiener frames' hops, so that their grid stays the record's.

What the prediction misses is measured on the channel itself: the same model, run from a few
cuts before the end, against the samples that follow them (:attr:`Extension.missed`); that
share scales the inertia the ends could lose (:mod:`forcecal.forces.transient`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg

__all__ = ["extend"]

ORDER_PERIODS = 2.0
"""The prediction's order spans this many periods of the band's top (100 samples at 10 kHz
for a 200 Hz band)."""
MAX_ORDER = 160
"""The prediction's order at most (its fit costs the order squared per sample fitted)."""
FIT_ORDERS = 50
"""The samples next to an end the prediction is fitted to, in orders (5000 at 10 kHz)."""
EXTEND_PERIODS = 6.0
"""Periods of the band's top the record is carried past each end (30 ms for 200 Hz): several
times the reach of the reactions' transfer and of the smoothers at the ends."""
CUTS = 4
"""Cuts before an end at which :func:`extend` tries the prediction."""
_RIDGE = 1e-10
"""The normal equations' ridge, relative to their mean diagonal (a noise-free channel)."""
_GROWTH = 10.0
"""A prediction larger than this times the fitted samples' largest is unstable; the channel is
then carried past its end by its odd reflection instead."""


@dataclass(frozen=True)
class Extension:
    """A stretch of channels carried past its ends.

    Attributes
    ----------
    values : (n_channels, L0 + N + L1) array
        The channels with ``L0`` predicted samples before and ``L1`` after.
    pad : (int, int)
        (L0, L1).
    missed : (2, n_channels) array
        The share of every channel's signal the prediction misses past the start (first row)
        and past the end (1: all, as for an end left as it is).
    """

    values: np.ndarray
    pad: tuple[int, int]
    missed: np.ndarray

    def inner(self, x: np.ndarray) -> np.ndarray:
        """The stretch's own samples of ``x`` (..., L0 + N + L1)."""
        return x[..., self.pad[0]:x.shape[-1] - self.pad[1]]


def _sizes(fs: float, top: float, n: int) -> tuple[int, int, int]:
    """(order, samples fitted, samples predicted) for a stretch of ``n`` samples at ``fs``
    [Hz] under a band reaching ``top`` [Hz]; order 0 when the stretch is too short."""
    order = min(int(math.ceil(ORDER_PERIODS * fs / top)), MAX_ORDER)
    fit = min(n, FIT_ORDERS * order)
    if fit < 4 * order:
        return 0, 0, 0
    return order, fit, int(math.ceil(EXTEND_PERIODS * fs / top))


def _coefficients(s: np.ndarray, order: int) -> np.ndarray:
    """a (order,): s[n] ~ sum_k a_k s[n - 1 - k], by least squares over ``s``."""
    past = np.lib.stride_tricks.sliding_window_view(s[:-1], order)[:, ::-1]
    gram = past.T @ past
    gram[np.diag_indices(order)] += _RIDGE * max(float(np.trace(gram)) / order, 1e-300)
    return scipy.linalg.solve(gram, past.T @ s[order:], assume_a="pos")


def _predict(past: np.ndarray, coef: np.ndarray, count: int) -> np.ndarray:
    """The ``count`` samples after ``past`` (at least len(coef) long) with no innovation."""
    import scipy.signal  # on use: a steady stream starts without it

    den = np.r_[1.0, -coef]
    zi = scipy.signal.lfiltic([1.0], den, past[::-1][:coef.size])
    return scipy.signal.lfilter([1.0], den, np.zeros(count), zi=zi)[0]


def _carry(x: np.ndarray, order: int, fit: int, count: int) -> tuple[np.ndarray, np.ndarray,
                                                                       float]:
    """``count`` samples after ``x``'s end, predicted from its last ``fit``; also the model's
    coefficients and the fitted samples' mean (the prediction runs about it)."""
    seg = x[-fit:]
    mean = float(seg.mean())
    s = seg - mean
    try:
        coef = _coefficients(s, order)
        ahead = _predict(s, coef, count)
    except (np.linalg.LinAlgError, ValueError):
        coef, ahead = np.zeros(order), np.full(count, np.inf)
    peak = float(np.max(np.abs(s))) if s.size else 0.0
    if not np.all(np.isfinite(ahead)) or np.max(np.abs(ahead), initial=0.0) > _GROWTH * peak:
        ahead = 2 * s[-1] - s[-2:-count - 2:-1] if count < s.size - 1 else np.zeros(count)
        coef = np.zeros(order)
    fade = 0.5 * (1.0 + np.cos(np.pi * np.arange(count) / count))   # to the mean at its end
    return ahead * fade + mean, coef, mean


def extend(x: np.ndarray, fs: float, top: float, reach: int,
           noise: np.ndarray | None = None, sides: tuple[bool, bool] = (True, True),
           align: int = 1) -> Extension:
    """Every channel of ``x`` (n_channels, N) carried past its ends, and the share of its
    signal the prediction misses over ``reach`` samples past them.

    Each end's model is also run from ``CUTS`` cuts before that end (inside the samples it was
    fitted to), its ``reach`` samples compared with those that follow the cut: the mean square
    of the difference less the channel's white noise (which no prediction can foresee, and which
    the smoothers take at the ends as everywhere), over the fitted samples' mean square about
    their mean less that noise.

    Parameters
    ----------
    x : (n_channels, N) array
    fs : float
        [Hz] the sampling rate.
    top : float
        [Hz] the band's top: it sets the prediction's order and reach.
    reach : int
        Samples past an end whose prediction counts.
    noise : (n_channels,) array, optional
        Each channel's white-noise variance per sample (default none).
    sides : (bool, bool)
        Whether to carry the start, the end (a stream's window is carried at the record's
        ends only: inside the record its edges are far from the samples it gives).
    align : int
        Each pad is a whole number of this many samples (a short-time transform's hop keeps
        its frames on the stretch's own).

    Returns
    -------
    Extension
        An end left as it is (not in ``sides``, or a stretch too short to fit) has no pad and
        share 1 (all lost).
    """
    x = np.asarray(x, dtype=float)
    order, fit, count = _sizes(fs, top, x.shape[-1])
    reach = max(int(reach), 1)
    shares = np.ones((2, len(x)))
    if not order or fit < order + reach + CUTS:
        return Extension(x, (0, 0), shares)
    count = -(-count // align) * align
    noise = np.zeros(len(x)) if noise is None else np.asarray(noise, dtype=float)
    pads = []
    for k, (side, wanted) in enumerate(zip((x[:, ::-1], x), sides, strict=True)):
        ahead = []                                                  # the start reversed
        for c, (ch, var) in enumerate(zip(side, noise, strict=True)):
            if not wanted:
                break
            more, coef, mean = _carry(ch, order, fit, count)
            ahead.append(more)
            shares[k, c] = min(_missed(ch[-fit:] - mean, coef, order, reach, var), 1.0)
        pads.append(np.stack(ahead) if ahead else np.zeros((len(x), 0)))
    values = np.concatenate([pads[0][:, ::-1], x, pads[1]], axis=1)
    return Extension(values, (pads[0].shape[1], pads[1].shape[1]), shares)


def _missed(seg: np.ndarray, coef: np.ndarray, order: int, reach: int, noise: float) -> float:
    """The share of ``seg``'s signal (about its mean, less ``noise`` [variance]) that ``coef``
    misses over ``reach`` samples after ``CUTS`` cuts before its end; 1 for a channel carried
    by its reflection, 0 for one that holds no signal above its noise."""
    power = float(np.mean(seg**2)) - noise
    if power <= 0:
        return 0.0
    if not np.any(coef):
        return 1.0
    span = (seg.size - order - reach) // CUTS
    miss = [seg[cut:cut + reach] - _predict(seg[:cut], coef, reach)
            for cut in (seg.size - reach - j * span for j in range(CUTS))]
    return float(np.sqrt(max(float(np.mean(np.square(miss))) - noise, 0.0) / power))

"""The inertia's uncertainty at a record's ends under any drive (METHOD.md section 7, "any
drive").

Within about a period of the coordinate's cutoff of an end, the smoothers and the reactions'
transfer take samples beyond it, which :mod:`forcecal.signals.record_ends` carries by a
prediction: the inertia there is lost in the share that prediction misses. Used by
:func:`forcecal.forces.transient.window_forces`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..signals.kalman import BandModel

__all__: list[str] = []


EDGE_PERIODS = 2.0
"""The record's first and last this many periods of the coordinate's cutoff hold an inertia
the smoother cannot see whole (:func:`edge_std`)."""


def edge_length(fs: float, bm: BandModel, n: int) -> int:
    """Samples at either end of ``n`` within ``EDGE_PERIODS`` periods of the cutoff of ``bm``."""
    return min(int(np.ceil(EDGE_PERIODS * fs / (bm.scale[1] / (2 * np.pi)))), n // 2)


def kernel_tails(kernel: np.ndarray, m: int) -> np.ndarray:
    """(2, m): of an impulse response ``kernel`` (circular, lag 0 first), the square root of
    the share of its energy at lags more than t samples into the past (row 0) and into the
    future (row 1), t = 0 .. m - 1: how much of a sample t from a record's start (its end)
    the samples beyond that end make."""
    n = kernel.size
    lag = np.rint(np.fft.fftfreq(n, 1.0 / n)).astype(int)
    energy = np.square(kernel)
    total = max(float(np.sum(energy)), 1e-300)
    t = np.arange(m)
    past = np.array([np.sum(energy[lag < -k]) for k in t]) / total
    future = np.array([np.sum(energy[lag > k]) for k in t]) / total
    return np.sqrt(np.vstack([past, future]))


def edge_std(part: np.ndarray, m: int, missed: np.ndarray,
             tails: np.ndarray | None = None) -> np.ndarray:
    """(n, N) [N]: the uncertainty of the inertia's part ``part`` (n, N) at the record's ends.

    Within about a period of the cutoff of an end the smoothers and the reactions' transfer
    take samples beyond it, which the record carries by a prediction
    (:mod:`forcecal.signals.record_ends`): the inertia there is lost in the share the prediction
    misses (``missed``, at the start and at the end; 1, its whole size, for a reflection).
    Stated as the inertia part's RMS over the ``m`` samples next to each end times that share,
    times, t samples from the end, the share of the part's kernel that lies beyond it
    (``tails``, :func:`kernel_tails`; without them tapered as (1 - t / T_e)^2)."""
    n = part.shape[-1]
    out = np.zeros_like(part)
    if m < 1:
        return out
    if tails is None:
        taper = (1.0 - np.arange(m) / m) ** 2                    # from the end inwards
        tails = np.vstack([taper, taper])
    out[:, :m] = (missed[0] * np.sqrt(np.mean(part[:, :m] ** 2, axis=1)))[:, None] * tails[0]
    out[:, n - m:] = ((missed[1] * np.sqrt(np.mean(part[:, n - m:] ** 2, axis=1)))[:, None]
                      * tails[1][::-1])
    return out


def ends_std(inner: Callable[[np.ndarray], np.ndarray], missed: np.ndarray, pinv: np.ndarray,
             by_gauges: np.ndarray, by_probes: np.ndarray, reach: int, n_g: int,
             kernels: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """(n_forces + 1, N) [N]: each force's and the total's uncertainty at the stretch's ends,
    the gauges' part of the inertia lost in the share the gauges' prediction misses
    (``missed``, (2, n_channels), the gauges first), the probes' in the probes', each by the
    share of its kernel (``kernels``: the gauges' part's, the probes' part's) beyond the end."""
    part_g, part_p = (inner(pinv @ x) for x in (by_gauges, by_probes))
    tails = (None, None) if kernels is None else tuple(kernel_tails(k, reach) for k in kernels)
    return np.hypot(
        edge_std(np.vstack([part_g, part_g.sum(axis=0)]), reach, missed[:, :n_g].max(axis=1),
                 tails[0]),
        edge_std(np.vstack([part_p, part_p.sum(axis=0)]), reach, missed[:, n_g:].max(axis=1),
                 tails[1]))

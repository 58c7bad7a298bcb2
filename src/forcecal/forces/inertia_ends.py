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


def edge_std(part: np.ndarray, m: int, missed: np.ndarray) -> np.ndarray:
    """(n, N) [N]: the uncertainty of the inertia's part ``part`` (n, N) at the record's ends.

    Within about a period of the cutoff of an end the smoothers and the reactions' transfer
    take samples beyond it, which the record carries by a prediction
    (:mod:`forcecal.signals.record_ends`): the inertia there is lost in the share the prediction
    misses (``missed``, at the start and at the end; 1, its whole size, for a reflection).
    Stated as the inertia part's RMS over the ``m`` samples next to each end times that share,
    tapered as (1 - t / T_e)^2 from the end."""
    n = part.shape[-1]
    out = np.zeros_like(part)
    if m < 1:
        return out
    taper = (1.0 - np.arange(m) / m) ** 2                        # from the end inwards
    out[:, :m] = (missed[0] * np.sqrt(np.mean(part[:, :m] ** 2, axis=1)))[:, None] * taper
    out[:, n - m:] = ((missed[1] * np.sqrt(np.mean(part[:, n - m:] ** 2, axis=1)))[:, None]
                      * taper[::-1])
    return out


def ends_std(inner: Callable[[np.ndarray], np.ndarray], missed: np.ndarray, pinv: np.ndarray,
             by_gauges: np.ndarray, by_probes: np.ndarray, reach: int, n_g: int
             ) -> np.ndarray:
    """(n_forces + 1, N) [N]: each force's and the total's uncertainty at the stretch's ends,
    the gauges' part of the inertia lost in the share the gauges' prediction misses
    (``missed``, (2, n_channels), the gauges first), the probes' in the probes'."""
    part_g, part_p = (inner(pinv @ x) for x in (by_gauges, by_probes))
    return np.hypot(
        edge_std(np.vstack([part_g, part_g.sum(axis=0)]), reach, missed[:, :n_g].max(axis=1)),
        edge_std(np.vstack([part_p, part_p.sum(axis=0)]), reach, missed[:, n_g:].max(axis=1)))

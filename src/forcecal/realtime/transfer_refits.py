"""The structure's transfer in a stream under any drive, fitted again as the record grows.

The transfer from the reactions-only force to the first shape's coordinate
(:mod:`forcecal.forces.reaction_transfer`) is the structure's, so every sample of the run is
evidence about it; but a stream sets it up from its first seconds, and a drive that holds a
narrow band there (a sweep's bottom) determines it only near that band. Extrapolated to a mode
the drive reaches later, that transfer leaves the probes to carry the inertia there, with their
noise times w^2, and the stream errs several times the batch (docs/method.md, "any drive";
the ``dwell`` preset). So the stream keeps the coordinate and the
reactions-only force it has received (single precision: their noise lies far above its
rounding) and fits the transfer again from all of them at twice the warm-up, four times, and so
on up to :data:`LAST` seconds, after which it forgets them: memory stays bounded.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..forces.any_setup import AnyDriveSetup
from ..forces.reaction_transfer import fit_reaction_transfer

__all__: list[str] = []     # used by the stream alone (realtime.any_drive)

LAST = 16.0
"""[s] the last refit: by then a slow sweep through the band has shown the transfer its modes
(the ``dwell`` preset reaches its mode halfway)."""


class TransferRefits:
    """The transfer of a stream's setup, fitted again from all it has received.

    Parameters
    ----------
    setup : AnyDriveSetup
        The setup from the first ``gauges`` and ``probes`` (n_gauges, n), (n_probes, n) [N, m].
    fs : float
        [Hz]
    mains : float or None
        [Hz] the rig's mains (its lines left out of the fits).
    """

    def __init__(self, setup: AnyDriveSetup, gauges: np.ndarray, probes: np.ndarray,
                 fs: float, mains: float | None) -> None:
        self.fs, self.mains = float(fs), mains
        self._q: list[np.ndarray] | None = []
        self._u: list[np.ndarray] = []
        self.received = 0
        self._next = 2 * gauges.shape[1]
        self._last = int(math.ceil(LAST * self.fs))
        self.add(setup, gauges, probes)

    def add(self, setup: AnyDriveSetup, gauges: np.ndarray, probes: np.ndarray
            ) -> AnyDriveSetup:
        """Take the next samples; ``setup`` with the transfer fitted again where a refit falls
        due (a refit that fails keeps the transfer it had)."""
        self.received += gauges.shape[1]
        if self._q is None:
            return setup
        self._q.append((setup.coordinate_map @ probes).astype(np.float32))
        self._u.append((setup.total_row @ gauges).astype(np.float32))
        if self.received < self._next:
            return setup
        q, u = np.concatenate(self._q), np.concatenate(self._u)
        self._q, self._u = [q], [u]
        self._next *= 2
        if self._next > self._last:
            self._q, self._u = None, []                     # forgotten: the last refit
        transfer = fit_reaction_transfer(q.astype(float), u.astype(float), self.fs, setup.band,
                                         setup.var_q, self.mains)
        if transfer is None:
            return setup
        return dataclasses.replace(setup, transfer=transfer)

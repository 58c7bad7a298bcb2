"""A steady stream's cross-checks: those of ``reconstruct``, made on the stream's first seconds.

The recursive estimator tracks harmonic phasors; ``reconstruct`` judges a record's harmonic
fits with their covariance (the probes against the shapes, the run against the scan, the forces
against their poles' flux, pole against pole, the DC against the current). A stream keeps its
first :data:`PERIODS` drive periods (at least :data:`MIN_SECONDS`), estimates them as
``reconstruct`` would and says the notes at the end, before the table is in place: a mistake
of the set-up (a scale, a sign, a skew, a position, a mass) holds over the whole record, so its
first seconds tell it. A record the batch estimate refuses (it cannot be used) stops the stream
with the same message and leaves no table. A record shorter than the segment
is checked whole at its end. A file's stream comes with its gauges zeroed by the tare's means
(its offsets): the segment is then estimated without the tare, whose own check, its weight,
``stream`` makes before it starts.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ..forces.steady import reconstruct
from ..model.spatial import SpatialModel
from ..records import Run
from ..rig import Rig

__all__: list[str] = []     # used by the stream alone (realtime.replay)

PERIODS = 10.0
"""Drive periods the checks take, as many as a campaign's run holds."""

MIN_SECONDS = 0.5
"""[s] The checks' least segment, whatever the drive's frequency."""


class FirstSegment:
    """The checks of ``reconstruct`` on a steady stream's first seconds.

    Parameters
    ----------
    rig : Rig
    model : SpatialModel
    fs, t0 : float
        [Hz], [s] the stream's sampling rate and first sample's time.
    n_samples : int
        The record's length (a shorter record is checked whole).
    channels : list of str
        The file's channels: the segment keeps the rig's among them.
    source : str
        The run's path, for the notes.
    note : callable
        Called with each note once the segment is checked.
    tare : Run, optional
        The zero-current record, for samples not yet zeroed by its means (a run held in
        memory): the segment is then estimated with it, its weight checked too.
    """

    def __init__(self, rig: Rig, model: SpatialModel, fs: float, t0: float, n_samples: int,
                 channels: list[str], source: str, note: Callable[[str], None],
                 tare: Run | None = None) -> None:
        self.rig, self.model, self.fs, self.t0 = rig, model, float(fs), float(t0)
        wanted = [*rig.gauge_names, *rig.sensor_names, rig.actuator.current,
                  *rig.flux_channels]
        self.channels = [c for c in dict.fromkeys(wanted) if c and c in channels]
        seconds = max(MIN_SECONDS, PERIODS / model.f0)
        self.length = min(int(n_samples), int(math.ceil(seconds * self.fs)))
        self.source, self.note, self.tare = source, note, tare
        self._held: list[np.ndarray] = []
        self._count = 0
        self.notes: tuple[str, ...] | None = None     # None until checked

    def add(self, samples: np.ndarray) -> None:
        """Take the next samples, (len(channels), m), as read, while the segment lasts."""
        take = min(samples.shape[1], self.length - self._count)
        if take > 0:
            self._held.append(np.array(samples[:, :take]))
        self._count += take

    def finish(self) -> None:
        """Check the segment (or the whole record, where shorter) and say its notes."""
        if self.notes is not None:
            return
        held = np.hstack(self._held)
        self._held = []
        run = Run(channels=dict(zip(self.channels, held, strict=True)), fs=self.fs, t0=self.t0,
                  name="segment", source=self.source)
        est = reconstruct(self.rig, self.model, run, tare=self.tare)
        head = f"run '{self.source}'"
        first = f"{head} (its first {held.shape[1] / self.fs:.3g} s, as reconstruct checks it)"
        self.notes = tuple(first + text[len(head):] if text.startswith(head) else text
                           for text in est.notes)
        for text in self.notes:
            self.note(text)

"""A steady stream's cross-checks: those of ``reconstruct``, made on its first and last seconds.

The recursive estimator tracks harmonic phasors; ``reconstruct`` judges a record's harmonic
fits with their covariance (the probes against the shapes, the run against the scan, the forces
against their poles' flux, pole against pole, the DC against the current). A stream keeps its
first :data:`PERIODS` drive periods (at least :data:`MIN_SECONDS`) and its latest as many,
estimates them as ``reconstruct`` would and says the notes at the end, before the table is in
place: a mistake of the set-up (a scale, a sign, a skew, a position, a mass) holds over the
whole record, so its first seconds tell it; one that starts later (a gauge that slips, a probe
that comes loose) shows in its last, which are checked where the first drew no note. A record
the batch estimate refuses (it cannot be used) stops the stream with the same message and
leaves no table. A record shorter than two segments is checked whole. A file's stream comes
with its gauges zeroed by the tare's means (its offsets): the segments are then estimated
without the tare, whose own check, its weight, ``stream`` makes before it starts.
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
"""Drive periods a segment holds, as many as a campaign's run."""

MIN_SECONDS = 0.5
"""[s] A segment's least length, whatever the drive's frequency."""


class EndSegments:
    """The checks of ``reconstruct`` on a steady stream's first and last seconds.

    Parameters
    ----------
    rig : Rig
    model : SpatialModel
    fs, t0 : float
        [Hz], [s] the stream's sampling rate and first sample's time.
    n_samples : int
        The record's length (one shorter than two segments is checked whole).
    channels : list of str
        The file's channels: the segments keep the rig's among them.
    source : str
        The run's path, for the notes.
    note : callable
        Called with each note once the record is through.
    tare : Run, optional
        The zero-current record, for samples not yet zeroed by its means (a run held in
        memory): the segments are then estimated with it, its weight checked too.
    """

    def __init__(self, rig: Rig, model: SpatialModel, fs: float, t0: float, n_samples: int,
                 channels: list[str], source: str, note: Callable[[str], None],
                 tare: Run | None = None) -> None:
        self.rig, self.model, self.fs, self.t0 = rig, model, float(fs), float(t0)
        wanted = [*rig.gauge_names, *rig.sensor_names, rig.actuator.current,
                  *rig.flux_channels]
        self.channels = [c for c in dict.fromkeys(wanted) if c and c in channels]
        length = int(math.ceil(max(MIN_SECONDS, PERIODS / model.f0) * self.fs))
        self.length = int(n_samples) if n_samples < 2 * length else length
        self.source, self.note, self.tare = source, note, tare
        self._first: list[np.ndarray] = []
        self._last: list[np.ndarray] = []
        self._count = 0
        self.notes: tuple[str, ...] | None = None     # None until checked

    def add(self, samples: np.ndarray) -> None:
        """Take the next samples, (len(channels), m), as read."""
        take = min(samples.shape[1], self.length - self._count)
        if take > 0:
            self._first.append(np.array(samples[:, :take]))
        self._count += samples.shape[1]
        if self._count > self.length:                    # the latest ``length`` samples
            self._last.append(np.array(samples[:, take:][:, -self.length:]))
            held = sum(s.shape[1] for s in self._last)
            while held - self._last[0].shape[1] >= self.length:
                held -= self._last.pop(0).shape[1]

    def finish(self) -> None:
        """Check the first segment (the whole record, where shorter than two), then the last
        where the first drew no note, and say the notes."""
        if self.notes is not None:
            return
        notes = self._check(np.hstack(self._first), 0, "first")
        if not notes and self._last:
            last = np.hstack(self._last)[:, -self.length:]
            notes = self._check(last, self._count - last.shape[1], "last")
        self._first, self._last = [], []
        self.notes = notes
        for text in notes:
            self.note(text)

    def _check(self, held: np.ndarray, start: int, which: str) -> tuple[str, ...]:
        run = Run(channels=dict(zip(self.channels, held, strict=True)), fs=self.fs,
                  t0=self.t0 + start / self.fs, name="segment", source=self.source)
        est = reconstruct(self.rig, self.model, run, tare=self.tare)
        head = f"run '{self.source}'"
        said = f"{head} (its {which} {held.shape[1] / self.fs:.3g} s, as reconstruct checks it)"
        return tuple(said + text[len(head):] if text.startswith(head) else text
                     for text in est.notes)

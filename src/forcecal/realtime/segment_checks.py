"""The cross-checks of ``reconstruct`` under any drive, made by a stream segment by segment.

``reconstruct`` weighs the whole record's forces against their poles' Maxwell force, a core's
flux channels against each other and a core's poles against each other
(:mod:`forcecal.forces.crosschecks`, on lines of the record's spectrum). A stream holds only a
window, so it gathers the samples it gives into segments of :data:`SEGMENT` seconds (the
record's length split evenly), makes the same checks on each as it completes and forgets it:
memory stays flat. The false-alarm rate of a record is shared among its segments, so a clean
stream draws a note no more often than ``reconstruct`` does; a mistake that holds over the
record shows in every segment. At the end it says the first segment's notes and in how many
segments the checks drew one.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

import numpy as np

from ..forces.crosschecks import flux_notes, line_terms, pole_notes
from ..forces.diagnostics import FALSE_ALARM
from ..forces.scan_check import SEGMENT
from ..forces.transient import WindowEstimate
from ..records import Run
from ..rig import Rig

__all__ = ["SegmentChecks"]


class SegmentChecks:
    """The flux and pole checks of a stream, segment by segment (see the module docstring).

    Parameters
    ----------
    rig : Rig
        The rig as the run's file declares it (its flux scale is applied here).
    band : (low, high) [Hz]
        The model's band: the lines compared.
    fs, t0 : float
        [Hz], [s] the stream's sampling rate and first sample's time.
    n_samples : int
        The record's length: its segments are :data:`SEGMENT` seconds, evenly split.
    channels : sequence of str
        The raw channels :meth:`add` is given with the samples (the flux channels, the coil
        current): the checks read them by name.
    """

    def __init__(self, rig: Rig, band: tuple[float, float], fs: float, t0: float,
                 n_samples: int, channels: list[str]) -> None:
        self.rig, self.band, self.fs, self.t0 = rig, band, float(fs), float(t0)
        self.count = max(1, int(round(n_samples / (SEGMENT * fs))))
        self.length = int(math.ceil(n_samples / self.count))
        self.channels = list(channels)
        self._held: list[tuple[WindowEstimate, np.ndarray]] = []
        self._start = 0                 # the first held sample's index
        self._first: tuple[float, float, list[str]] | None = None
        self._alarmed = 0
        self._checked = 0

    def add(self, estimate: WindowEstimate, raw: np.ndarray, pinv: np.ndarray) -> None:
        """The next samples given: their estimate, the raw samples of :attr:`channels` (n, m),
        and the estimate's Psi^+ force rows."""
        self._held.append((estimate, np.asarray(raw, dtype=float).reshape(-1, raw.shape[-1])))
        held = sum(e.force.shape[-1] for e, _ in self._held)
        while held >= self.length:
            est = WindowEstimate.join([e for e, _ in self._held])
            raw_all = np.hstack([r for _, r in self._held])
            self._check(est.part(slice(0, self.length)), raw_all[:, :self.length], pinv)
            rest = est.part(slice(self.length, None))
            self._held = [(rest, raw_all[:, self.length:])] if rest.force.shape[-1] else []
            self._start += self.length
            held -= self.length

    def finish(self, pinv: np.ndarray) -> None:
        """The record's end: its last samples, if a tenth of a segment or more, are checked."""
        if self._held:
            est = WindowEstimate.join([e for e, _ in self._held])
            if est.force.shape[-1] >= max(64, self.length // 10):
                self._check(est, np.hstack([r for _, r in self._held]), pinv)
            self._held = []

    def _check(self, est: WindowEstimate, raw: np.ndarray, pinv: np.ndarray) -> None:
        n = est.force.shape[-1]
        t0 = self.t0 + self._start / self.fs
        terms = line_terms(est.force_std, est.reactions, est.inertia, pinv, self.fs, t0,
                           self.band, self.rig.mains, (est.noise_density, est.borne))
        terms = dataclasses.replace(terms, rate=FALSE_ALARM / self.count)
        channels: Mapping[str, np.ndarray] = dict(zip(self.channels, raw, strict=True)) or {
            name: r for name, r in zip(self.rig.gauge_names, est.reactions, strict=True)}
        run = Run(channels=channels, fs=self.fs, t0=t0)
        notes = [*flux_notes(self.rig, run, terms, "{what}"),
                 *pole_notes(self.rig, run, terms, "{what}")]
        self._checked += 1
        if notes:
            self._alarmed += 1
            if self._first is None:
                self._first = (t0, t0 + n / self.fs, notes)

    def notes(self, what: str) -> list[str]:
        """The first segment's notes, if any segment drew one, with the count (``what``: the
        run, at the start of each)."""
        if self._first is None:
            return []
        start, end, notes = self._first
        where = (f"{what}, the stream's segment {start:.4g}-{end:.4g} s ({self._alarmed} of "
                 f"{self._checked} segments drew a note; each checked at a "
                 f"{FALSE_ALARM / self.count:.2g} rate, the record's {FALSE_ALARM:g} shared)")
        return [note.replace("{what}", where, 1) for note in notes]


"""Forces under any drive in real time (METHOD.md section 7, "any drive"): the batch estimate
of :mod:`forcecal.forces.transient` over a window that slides with the stream.

A smoother needs the future a causal filter lacks: the best causal estimate of an acceleration
from displacements lags it. So the stream gives every sample once the samples a fixed
``latency`` after it have arrived, computed over a window that also keeps ``history`` before
the samples it gives:

- the first ``warmup`` seconds set what the batch estimate takes from the whole record
  (:func:`forcecal.forces.any_setup.any_drive_setup`); nothing is given before they arrive;
- then, whenever ``step`` seconds can be given, the window from ``history`` before them to the
  newest sample goes through :func:`forcecal.forces.transient.window_forces` and the samples
  at least ``latency`` old are given; the window starts on the Wiener frames' hop, as the
  batch's frames do, so that inside the record the two use the same frames;
- at the end of the record the rest is given at once.

Memory and work per sample stay flat in the record's length. A stream set up from its own
first seconds sets its smoothers again in every window from the window's own records
(:func:`forcecal.forces.any_setup.with_reaction_priors`: a sweep's first seconds hold only its
bottom).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO

import numpy as np

from ..errors import InputError
from ..forces.any_setup import AnyDriveSetup, any_drive_setup, with_reaction_priors
from ..forces.budget import type_b_notes
from ..forces.inertia_errors import ScanNoiseShare
from ..forces.inertia_scale import InertiaScale
from ..forces.scan_check import SEGMENT, LineRatio, run_line_notes
from ..forces.transient import (
    TRANSFER_MISFIT,
    TransientEstimate,
    WindowEstimate,
    check_length,
    hum_notes,
    inertia_scaled,
    run_channels,
    run_inputs,
    transfer_note,
    window_forces,
    with_scale_std,
)
from ..forces.unseen_motion import unseen_notes
from ..io.blocks import RunBlocks
from ..io.table_writer import CSV_DIGITS, table_writer
from ..model.broadband import BroadbandModel
from ..model.spatial import check_rig_keys
from ..records import Run
from ..rig import Rig
from ..signals.checks import NOISE_BLOCK, AboveBand, check_channel_noise
from ..signals.wiener import stft_frame
from .replay import Check, stream_columns, stream_rows
from .segment_checks import SegmentChecks
from .transfer_refits import TransferRefits

__all__ = ["stream_any", "stream_any_table"]

LATENCY = 0.5
"""[s] every sample is given once this much of the record after it has arrived (at least two
Wiener frames and the smoothers' settling)."""
HISTORY = 0.5
"""[s] the past the window keeps before the samples it gives (as long as :data:`LATENCY`)."""
WARMUP = 2.0
"""[s] the first seconds, from which the channels' noise and the band models are set."""
STEP = 0.5
"""[s] the window is computed again once this much more can be given."""


@dataclass(frozen=True)
class StreamChunk:
    """Samples the stream gives at once: their ``time`` (n,) [s] and ``estimate``."""

    time: np.ndarray
    estimate: WindowEstimate

    @property
    def std(self) -> np.ndarray:
        """(n_forces + 1, n) [N]: each force's standard uncertainty, then the total's."""
        return np.vstack([self.estimate.force_std, self.estimate.total_std[None, :]])


class AnyDriveStream:
    """The real-time estimate under any drive, fed block by block.

    Parameters
    ----------
    rig : Rig
    model : BroadbandModel
    fs : float
        [Hz] the stream's sampling rate.
    t0 : float
        [s] the time of its first sample.
    setup : AnyDriveSetup, optional
        The channels' noise and band models; default: from the first ``warmup`` seconds.
    latency, history, warmup, step : float
        [s] see the module's account (defaults :data:`LATENCY`, :data:`HISTORY`,
        :data:`WARMUP`, :data:`STEP`).
    source : str
        The run, named in messages.
    tare, tare_fs : (n_gauges + n_probes, n) array [N and m] and float [Hz], optional
        A zero-current record's gauges, then its probes: with ``acquisition.mains``, their hum
        tones join the noise (:func:`forcecal.forces.any_setup.any_drive_setup`).
    flux : sequence of str
        The run's flux channels, fed after the probes: the inertia's scale is calibrated in
        situ from the first ``warmup`` seconds (:mod:`forcecal.forces.inertia_scale`, as
        ``reconstruct`` does over the whole record) and applied from then on where they
        determine it.

    Attributes
    ----------
    scan_share : ScanNoiseShare
        The share of the total's stated variance the scan's noise makes, over the samples
        given so far (:class:`forcecal.forces.inertia_errors.ScanNoiseShare`).
    inertia_scale : InertiaScale or None
        The scale read from the warm-up (None without flux channels, or before it).

    Raises
    ------
    InputError
        A model of another rig.
    DataError
        From :meth:`process` and :meth:`finish`: a gauge or probe constant over the first
        seconds, or whose noise changes later (:func:`forcecal.signals.checks.check_channel_noise`).
    """

    def __init__(self, rig: Rig, model: BroadbandModel, fs: float, t0: float = 0.0,
                 setup: AnyDriveSetup | None = None, latency: float = LATENCY,
                 history: float = HISTORY, warmup: float = WARMUP, step: float = STEP,
                 source: str = "<stream>", tare: np.ndarray | None = None,
                 tare_fs: float | None = None, flux: Sequence[str] = ()):
        check_rig_keys(model.rig, model.origin, rig)
        self.rig, self.model, self.fs, self.t0 = rig, model, float(fs), float(t0)
        self.source = source
        self._tare, self._tare_fs = tare, tare_fs
        self._setup = setup
        self._own_setup = setup is None
        self.scan_share = ScanNoiseShare(self.fs, self.t0)
        frame = stft_frame(fs, 1 << 62)            # the Wiener frame of any record long enough
        self._hop = frame // 4
        self._warmup = int(math.ceil(warmup * fs))
        self._latency = max(int(math.ceil(latency * fs)), 2 * frame)
        self._history = max(int(math.ceil(history * fs)), 2 * frame)
        self._step = max(int(math.ceil(step * fs)), 1)
        self._flux = tuple(flux)
        self.inertia_scale: InertiaScale | None = None
        self._scale = np.array([g.scale for g in rig.gauges] + [s.scale for s in rig.sensors]
                               + [1.0] * len(self._flux))
        self._n_g = len(rig.gauges)
        self._n_p = len(rig.sensors)
        self._buffer = np.empty((len(self._scale), 0))
        self._start = 0          # absolute index of the buffer's first sample
        self._received = 0
        self._given = 0
        self._checked = 0        # samples whose channels' noise has been checked
        self._block = int(round(NOISE_BLOCK * fs))
        self._refits: TransferRefits | None = None      # its own setup's transfer, refitted

    @property
    def channel_names(self) -> list[str]:
        """The channels a block holds, in order: the gauges', the probes', the flux's."""
        return [*self.rig.gauge_names, *self.rig.sensor_names, *self._flux]

    @property
    def latency(self) -> float:
        """[s] how long after a sample it is given."""
        return self._latency / self.fs

    @property
    def setup(self) -> AnyDriveSetup | None:
        """The setup in use (None before the warm-up has arrived)."""
        return self._setup

    def process(self, block: np.ndarray) -> list[StreamChunk]:
        """Feed raw samples of :attr:`channel_names` (n_channels, m); returns what can now be
        given (possibly nothing)."""
        block = np.asarray(block, dtype=float)
        if block.ndim != 2 or block.shape[0] != len(self._scale):
            raise InputError(f"stream: a block must hold {len(self._scale)} channels "
                             f"({', '.join(self.channel_names)}); got shape {block.shape}")
        self._buffer = np.hstack([self._buffer, block * self._scale[:, None]])
        self._received += block.shape[1]
        return self._give(final=False)

    def finish(self) -> list[StreamChunk]:
        """The end of the record: every sample not yet given."""
        if self._received:
            check_length(self.model, self._received, self.fs, self.source)
        return self._give(final=True)

    def _give(self, final: bool) -> list[StreamChunk]:
        out: list[StreamChunk] = []
        if self._setup is None:
            if not self._received or (self._received < self._warmup and not final):
                return out
            first = self._buffer[:, :self._warmup]     # the first seconds, whatever the blocks
            g, p = first[:self._n_g], first[self._n_g:self._n_g + self._n_p]
            self._setup = any_drive_setup(self.rig, self.model, g, p, self.fs, self.source,
                                          self._tare, self._tare_fs)
            if self._own_setup:
                self._refits = TransferRefits(self._setup, g, p, self.fs, self.rig.mains)
            if self._flux and self._own_setup:     # the inertia's scale from the warm-up
                n = self._n_g + self._n_p
                est = window_forces(self._setup, self.model, g, p,
                                    stft_frame(self.fs, first.shape[1]), self.source,
                                    (True, False))
                self._setup, self.inertia_scale = inertia_scaled(
                    self.rig, self.model, self._setup, est, first[n:], self.source)
        self._check()
        if self._refits is not None and self._refits.received < self._received:
            new = self._buffer[:, self._refits.received - self._start:
                               self._received - self._start]
            self._setup = self._refits.add(self._setup, new[:self._n_g],
                                           new[self._n_g:self._n_g + self._n_p])
        end = self._received if final else self._received - self._latency
        if end - self._given < (1 if final else self._step):
            return out
        start = max(self._given - self._history, 0)
        start -= start % self._hop                       # on the batch's frames
        window = self._buffer[:, start - self._start:]
        setup = self._setup
        if self._own_setup:            # its smoothers follow the drive, from the window's gauges
            setup = with_reaction_priors(setup, window[:self._n_g],
                                         window[self._n_g:self._n_g + self._n_p], self.rig.mains)
        est = window_forces(setup, self.model, window[:self._n_g],
                            window[self._n_g:self._n_g + self._n_p],
                            stft_frame(self.fs, window.shape[1]), self.source,
                            (start == 0, final))
        if self.inertia_scale is not None and self.inertia_scale.applied:
            est = with_scale_std(est, setup.pinv, self.inertia_scale)
        given = est.part(slice(self._given - start, end - start))
        self.scan_share.add(np.vstack([given.scan_noise, given.total_std**2]))
        out.append(StreamChunk(time=self.t0 + np.arange(self._given, end) / self.fs,
                               estimate=given))
        self._given = end
        keep = max(self._given - self._history, 0)
        keep -= keep % self._hop
        self._buffer = self._buffer[:, keep - self._start:]
        self._start = keep
        return out


    def _check(self) -> None:
        """Every complete stretch of ``NOISE_BLOCK`` not yet checked, against the setup's
        noise (:func:`forcecal.signals.checks.check_channel_noise`): a sensor that dies after the
        first seconds is refused where it dies."""
        assert self._setup is not None
        n = (self._received - self._checked) // self._block * self._block
        if n:
            part = self._buffer[:, self._checked - self._start:self._checked - self._start + n]
            setup = self._setup
            check_channel_noise(part[:self._n_g], part[self._n_g:self._n_g + self._n_p],
                                [*self.rig.gauge_names, *self.rig.sensor_names],
                                self.fs, setup.band, self.t0 + self._checked / self.fs,
                                self.source, np.r_[setup.var_g, 1.0 / setup.probe_weights])
            self._checked += n


def _chunks(stream: AnyDriveStream, blocks: Iterator[np.ndarray]) -> Iterator[StreamChunk]:
    for block in blocks:
        yield from stream.process(block)
    yield from stream.finish()


def stream_arrays(rig: Rig, model: BroadbandModel, gauges: np.ndarray, probes: np.ndarray,
                  fs: float, t0: float = 0.0, name: str = "<run>",
                  setup: AnyDriveSetup | None = None, block: int = 1 << 14,
                  tare: np.ndarray | None = None, tare_fs: float | None = None,
                  flux: Mapping[str, np.ndarray] | None = None,
                  current: Mapping[str, np.ndarray] | None = None) -> TransientEstimate:
    """A run held in memory through :class:`AnyDriveStream`, in blocks of ``block`` samples.

    Parameters
    ----------
    rig : Rig
    model : BroadbandModel
    gauges : (n_gauges, N) array [N]
    probes : (n_probes, N) array [m]
        In SI (the stream's scales are then 1: the rig's are applied before).
    fs, t0 : float
        [Hz], [s].
    name : str
        The run's name.
    setup : AnyDriveSetup, optional
        As :class:`AnyDriveStream`.
    block : int
        Samples per block.
    tare, tare_fs : array and float, optional
        As :class:`AnyDriveStream`.
    flux : mapping of str to (N,) array, optional
        The run's flux channels, raw: the inertia's scale from the warm-up
        (:class:`AnyDriveStream`), and the flux checks segment by segment
        (:class:`~forcecal.realtime.segment_checks.SegmentChecks`, as every stream makes).
    current : mapping of str to (N,) array, optional
        The coil current's channel, raw, which the flux checks read (whether the drive is
        biased).

    Returns
    -------
    TransientEstimate
        ``smoothed`` False.
    """
    unit = dataclasses.replace(
        rig, gauges=tuple(dataclasses.replace(g, scale=1.0) for g in rig.gauges),
        sensors=tuple(dataclasses.replace(s, scale=1.0) for s in rig.sensors))
    flux = dict(flux or {})
    stream = AnyDriveStream(unit, model, fs, t0, setup=setup, source=name, tare=tare,
                            tare_fs=tare_fs, flux=tuple(flux))
    data = np.vstack([gauges, probes, *flux.values()])
    raw = {**flux, **(current or {})}
    checks = SegmentChecks(rig, model.band, fs, t0, data.shape[1], list(raw))
    rows = np.array(list(raw.values())).reshape(len(raw), data.shape[1])
    chunks = []
    for c in _chunks(stream, (data[:, k:k + block] for k in range(0, data.shape[1], block))):
        given = np.round((c.time - t0) * fs).astype(int)
        assert stream.setup is not None
        checks.add(c.estimate, rows[:, given], stream.setup.pinv)
        chunks.append(c)
    note = (f"real time: every sample given {stream.latency:.3g} s after it, from a window of "
            f"the samples up to then; noise and band models from the first {WARMUP:g} s")
    assert stream.setup is not None
    checks.finish(stream.setup.pinv)
    notes = (*checks.notes(f"run '{name}'"), note, transfer_note(stream.setup.transfer, name),
             *unseen_notes(stream.setup.unseen, tuple(rig.sensor_names), name),
             *type_b_notes(rig, name), *hum_notes(rig, tare, name),
             *stream.scan_share.notes(name), *_scale_notes(stream, name))
    est = TransientEstimate.from_window(rig, name, t0, fs,
                                        WindowEstimate.join([c.estimate for c in chunks]),
                                        model.band, False, notes)
    return dataclasses.replace(est, inertia_scale=stream.inertia_scale)


def stream_any_table(rig: Rig, model: BroadbandModel, blocks: RunBlocks, target: str | Path,
                     *, check: Check | None = None, digits: int = CSV_DIGITS,
                     stdout: IO[bytes] | None = None, read: int = 1 << 14,
                     note: Callable[[str], None] | None = None, tare: Run | None = None) -> int:
    """Stream a run file under any drive into the table ``stream`` writes.

    Parameters
    ----------
    rig : Rig
    model : BroadbandModel
    blocks : RunBlocks
        The run, open and checked.
    target : str or Path
        As :func:`forcecal.realtime.replay.stream_table`, with its columns.
    check : callable, optional
        Called with (time, forces, static) of every chunk before it is written.
    digits : int
        Significant digits of the CSV columns.
    stdout : binary file, optional
        Where ``-`` writes.
    read : int
        Samples read at a time.
    note : callable, optional
        Called once the table is written with the note of the half second in which the
        drive's force held the most above the scan's band, when it held more than
        :data:`forcecal.signals.checks.ABOVE_BAND` (:class:`forcecal.signals.checks.AboveBand`: a
        stream cannot see ahead, but it can say so at the end), with the warnings of its
        setup (a transfer that misfits, probes that contradict the operating shapes), and with
        the notes of ``reconstruct``'s cross-checks made segment by segment
        (:class:`~forcecal.realtime.segment_checks.SegmentChecks`).
    tare : Run, optional
        A zero-current record: with ``acquisition.mains`` its gauges' hum tones join the
        noise (its means are the zero the ``blocks``' ``offsets`` take off).

    Returns
    -------
    int
        Rows written.
    """
    check_length(model, blocks.n_samples, blocks.fs, blocks.source)
    stream = AnyDriveStream(rig, model, blocks.fs, blocks.t0, source=blocks.source,
                            tare=None if tare is None
                            else np.vstack(run_channels(rig, tare)[:2]),
                            tare_fs=None if tare is None else tare.fs,
                            flux=[c for c in rig.flux_channels if c in blocks.channel_names])
    names = list(rig.force_names)
    above = AboveBand(blocks.fs, model.band, blocks.t0)
    current = rig.actuator.current
    scan = LineRatio(model, blocks.fs, rig.mains, int(round(SEGMENT * blocks.fs)))
    flux = stream.channel_names[len(rig.gauges) + len(rig.sensors):]
    checks = SegmentChecks(rig, model.band, blocks.fs, blocks.t0, blocks.n_samples,
                           [*flux, current])
    pending: list[np.ndarray] = []   # the flux's and current's samples not yet given: a latency

    def channels() -> Iterator[np.ndarray]:
        for block in blocks.blocks([*stream.channel_names, current], read):
            pending.append(block[-1 - len(flux):])
            above.add(block[-1] * rig.actuator.current_scale)
            yield block[:-1]

    with table_writer(target, stream_columns(names, std=True), blocks.fs, blocks.t0, digits=digits,
                      rows=blocks.n_samples, stdout=stdout) as out:
        for c in _chunks(stream, channels()):
            est = c.estimate
            if check is not None:
                check(c.time, dict(zip(names, est.force, strict=True)),
                      dict(zip(names, est.static, strict=True)))
            out.write(c.time, stream_rows(est.force, est.static, c.std))
            held = np.hstack(pending)
            scan.add(est.coordinate, held[-1, :len(c.time)] * rig.actuator.current_scale)
            assert stream.setup is not None
            checks.add(est, held[:, :len(c.time)], stream.setup.pinv)
            pending[:] = [held[:, len(c.time):]]
        rows = out.rows
    if stream.setup is not None:
        checks.finish(stream.setup.pinv)
    if note is not None:
        for text in checks.notes(f"run '{blocks.source}'"):
            note(text)
        for text in scan.notes(list(rig.sensor_names), f"run '{blocks.source}'"):
            note(text)
        for text in _scale_notes(stream, blocks.source):
            note(text)
        transfer = stream.setup.transfer if stream.setup is not None else None
        if transfer is None or transfer.chi2 > TRANSFER_MISFIT:
            note(transfer_note(transfer, blocks.source))
        if stream.setup is not None:
            for text in unseen_notes(stream.setup.unseen, tuple(rig.sensor_names),
                                     blocks.source):
                note(text)
        for text in (*hum_notes(rig, tare, blocks.source),
                     *stream.scan_share.notes(blocks.source)):
            note(text)
        for text in above.notes(blocks.source):
            note(text)
    return rows


def _scale_notes(stream: AnyDriveStream, source: str) -> tuple[str, ...]:
    """What the stream did with the inertia's scale (read from its first seconds, as
    ``reconstruct`` reads it from the whole record); nothing without flux channels."""
    sc = stream.inertia_scale
    if sc is None:
        return ()
    return (f"{sc.note} (the stream reads it from its first {WARMUP:g} s; reconstruct from the "
            "whole record)",)


def stream_any(rig: Rig, model: BroadbandModel, run: Run, tare: Run | None = None
               ) -> TransientEstimate:
    """The real-time estimate of a run under any drive, as ``stream`` gives it
    (:class:`AnyDriveStream`: every sample from the samples up to a fixed latency after it,
    its setup from the run's first seconds); the batch one is
    :func:`forcecal.forces.transient.reconstruct_any`.

    Raises
    ------
    InputError, DataError
        As :func:`forcecal.forces.transient.reconstruct_any`.
    """
    gauges, probes, zero, above = run_inputs(rig, model, run, tare)
    current = rig.actuator.current
    live = stream_arrays(rig, model, gauges, probes, run.fs, run.t0, run.name,
                         tare=zero, tare_fs=None if tare is None else tare.fs,
                         flux={c: run.channel(c) for c in rig.flux_channels
                               if c in run.channels},
                         current={current: run.channel(current)} if current in run.channels
                         else None)
    scan = run_line_notes(rig, model, run, live.coordinates[0], f"run '{run.source}'")
    return dataclasses.replace(live, notes=(*scan, *live.notes, *above))

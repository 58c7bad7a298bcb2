"""Forces for any drive, sample by sample (METHOD.md section 7, "any drive").

A swept, multi-tone or random drive has no harmonics to fit; eq. 15-16 hold at every instant
instead. With the span of shapes of a broadband scan (:mod:`forcecal.broadband`):

1. the first shape's coordinate at every sample from the probes,
   q_1(t) = (g_1^T W s(t)) / (g_1^T W g_1), g_1 = phi_1 at the probes, W their inverse noise
   variances (eq. 15-16);
2. every gauge's reaction from a Kalman smoother of a band-limited signal
   (:mod:`forcecal.kalman`), and q_1'' from the reactions: the structure's transfer from the
   reactions-only force to q_1, fitted over the record (:mod:`forcecal.reaction_transfer`),
   plus the smoothed second derivative of what it leaves of q_1 (the probes' evidence of what
   the transfer misses; their noise alone where it holds);
3. J_r = m_{r,1} q_1'' corrected frequency by frequency to the operating shape of every
   frequency (:meth:`forcecal.broadband.BroadbandModel.inertia_correction`), and
   f(t) = Psi^+ (J(t) - R(t)) (eq. 8, 24), beside the reactions-only estimate -Psi^+ R(t);
4. short-time Wiener gains on every force (:mod:`forcecal.wiener`), which keep the few hertz
   a moving drive holds at any instant and set the rest of the band's noise aside, each
   sample's uncertainty being the noise they let through, plus the errors of the scan's
   shapes (:mod:`forcecal.inertia_errors`), of the transfer's parameters and of the rig's
   declared sensitivities, positions and masses (:mod:`forcecal.transient_budget`).

What the estimate fixes before its first sample (the channels' noise, the band priors, the
transfer, the checks of the probes, the type-B moves, the hum) is its setup
(:mod:`forcecal.transient_setup`), from the whole run in batch. The smoothers and the
reactions' transfer take samples on both sides of each one: the record is carried past its
ends by a prediction of every channel (:mod:`forcecal.record_ends`), and what that prediction
misses is in the ends' uncertainty.

In real time (``stream``, :mod:`forcecal.stream.any_drive`) the same estimate is computed
over a window that slides with the stream: every sample is given once the samples a fixed
latency after it have arrived (a smoother needs the future a causal filter lacks: the best
causal estimate of an acceleration from displacements lags it).

Force content above the scan's band (a drive's harmonics beyond it) has no measured operating
shape: the gauges carry it as far as their smoother lets through, its inertia through the
transfer with the band top's correction, whose slope there is counted in the uncertainty.

The noise of every channel is read from its spectrum above the band (white beyond the drive's
reach), so that a probe's noise sets its weight and the smoother's gain; a channel whose noise
changes while the run goes on is refused, and force above the scan's band noted
(:mod:`forcecal.channel_checks`). Probes that leave the scan's operating shapes (forces that
do not keep the scan's load pattern, a probe's sign or scale wrong) are noted, and the
inertia of the motion the scan did not see bounds every force's uncertainty
(:mod:`forcecal.unseen_motion`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields

import numpy as np

from .broadband import BroadbandModel
from .channel_checks import AboveBand, check_channel_noise
from .errors import DataError
from .forces import channels_si
from .inertia_errors import ScanNoiseShare
from .kalman import BandModel, smooth_states
from .reaction_transfer import ReactionTransfer, filtered
from .record_ends import extend
from .records import Run
from .rig import Rig
from .spatial import check_rig_keys
from .transient_budget import type_b_notes, type_b_variance
from .transient_setup import AnyDriveSetup, any_drive_setup, hum_notes
from .unseen_motion import unseen_notes
from .wiener import (
    short_time_variance,
    smoother_response,
    stft_frame,
    tone_density,
    wiener_smooth,
)

__all__ = ["AnyDriveSetup", "TransientEstimate", "WindowEstimate", "any_drive_setup",
           "check_length", "hum_notes", "reconstruct_any", "run_channels", "transfer_note",
           "window_forces"]


@dataclass(frozen=True)
class TransientEstimate:
    """The forces of one run under any drive, at every sample.

    Attributes
    ----------
    run_name : str
    force_names : tuple of str
    time : (N,) array [s]
    force : (n_forces, N) array [N]
        Reactions and inertia.
    force_std : (n_forces, N) array [N]
        Standard uncertainty of every sample: the smoother's noise the short-time Wiener gains
        let through and the signal they take, and at the record's ends the inertia that the
        prediction carrying the record past them misses (:mod:`forcecal.record_ends`).
    total : (N,) array [N]
    total_std : (N,) array [N]
    static : (n_forces, N) array [N]
        Reactions only, -Psi^+ R(t) (the raw gauge samples).
    inertia : (n_gauges, N) array [N]
        J_r(t).
    reactions : (n_gauges, N) array [N]
        The smoothed reactions.
    coordinates : (1, N) array [m per unit coordinate]
        The first shape's coordinate q_1(t) from the probes.
    band : (low, high) [Hz]
    smoothed : bool
        True for the batch estimate, False for the real-time one (``stream``: each sample
        from the samples up to a fixed latency after it).
    notes : tuple of str
    """

    run_name: str
    force_names: tuple[str, ...]
    time: np.ndarray
    force: np.ndarray
    force_std: np.ndarray
    total: np.ndarray
    total_std: np.ndarray
    static: np.ndarray
    inertia: np.ndarray
    reactions: np.ndarray
    coordinates: np.ndarray
    band: tuple[float, float]
    smoothed: bool = True
    notes: tuple[str, ...] = ()

    @classmethod
    def from_window(cls, rig: Rig, run_name: str, t0: float, fs: float,
                    est: WindowEstimate, band: tuple[float, float], smoothed: bool,
                    notes: tuple[str, ...]) -> TransientEstimate:
        """The estimate of a run whose samples, from ``t0``, ``est`` holds."""
        return cls(run_name=run_name, force_names=tuple(rig.force_names),
                   time=t0 + np.arange(est.total.size) / fs, force=est.force,
                   force_std=est.force_std, total=est.total, total_std=est.total_std,
                   static=est.static, inertia=est.inertia, reactions=est.reactions,
                   coordinates=est.coordinate[None, :], band=band, smoothed=smoothed,
                   notes=notes)

    @property
    def inertia_share(self) -> float:
        """RMS of the AC inertia term's part in the total over the AC total's RMS [1]."""
        total = self.total - self.total.mean()
        static = self.static.sum(axis=0)
        part = (self.total - static) - (self.total - static).mean()
        rms = float(np.sqrt(np.mean(total**2)))
        return float(np.sqrt(np.mean(part**2))) / rms if rms > 0 else 0.0


@dataclass(frozen=True)
class WindowEstimate:
    """The forces over a stretch of samples (a whole run, or a stream's window).

    ``force``, ``force_std`` (n_forces, N); ``total``, ``total_std`` (N,); ``static``
    (n_forces, N) reactions only; ``inertia``, ``reactions`` (n_gauges, N); ``coordinate``
    (N,); ``passed`` (n_forces,): the share of each force's smoothed noise the Wiener gains
    let through; ``scan_noise`` (N,) [N^2]: the part of the total's variance the scan's noise
    gives (:func:`forcecal.inertia_errors.scan_noise_weights`).
    """

    force: np.ndarray
    force_std: np.ndarray
    total: np.ndarray
    total_std: np.ndarray
    static: np.ndarray
    inertia: np.ndarray
    reactions: np.ndarray
    coordinate: np.ndarray
    passed: np.ndarray
    scan_noise: np.ndarray

    def part(self, samples: slice) -> WindowEstimate:
        """The ``samples`` of the stretch (``passed`` is the window's)."""
        return WindowEstimate(**{f.name: getattr(self, f.name) if f.name == "passed"
                                 else getattr(self, f.name)[..., samples] for f in fields(self)})

    @staticmethod
    def join(parts: Sequence[WindowEstimate]) -> WindowEstimate:
        """Stretches one after another (``passed``: the largest share)."""
        return WindowEstimate(**{
            f.name: np.max([p.passed for p in parts], axis=0) if f.name == "passed"
            else np.concatenate([getattr(p, f.name) for p in parts], axis=-1)
            for f in fields(WindowEstimate)})


def window_forces(setup: AnyDriveSetup, model: BroadbandModel, gauges: np.ndarray,
                  probes: np.ndarray, frame: int, source: str = "<run>",
                  ends: tuple[bool, bool] = (True, True)) -> WindowEstimate:
    """Steps 1-4 over a stretch of samples with a fixed setup and Wiener frame.

    Parameters
    ----------
    setup : AnyDriveSetup
    model : BroadbandModel
    gauges : (n_gauges, N) array [N]
    probes : (n_probes, N) array [m]
    frame : int
        Samples per Wiener frame (:func:`forcecal.wiener.stft_frame`).
    source : str
        Named in messages.
    ends : (bool, bool)
        Whether the stretch starts, ends, the record: those ends are carried past by a
        prediction of every channel (:mod:`forcecal.record_ends`).

    Returns
    -------
    WindowEstimate

    Raises
    ------
    DataError
        Forces that are not finite.
    """
    fs = setup.fs
    bm_r, bm_res, transfer = setup.reaction_models, setup.residual_model, setup.transfer
    reach = _edge_length(fs, setup.coordinate_model, gauges.shape[-1])
    white = np.r_[setup.var_g, 1.0 / setup.probe_weights]          # each channel's noise
    ext = extend(np.vstack([gauges, probes]), fs, setup.band[1], reach, white, ends,
                 frame // 4)                                     # carried past the ends
    level = gauges.mean(axis=1, keepdims=True)    # the DC passes whole (in the band the
    gauges_x, probes_x = ext.values[:len(gauges)], ext.values[len(gauges):]
    q = setup.coordinate_map @ probes_x                          # the first shape's coordinate
    reactions = level + np.stack([smooth_states(bm_r[r], gauges_x[r] - level[r], states=(0,))[0]
                                  for r in range(len(gauges))])   # gain is 1 - 1 / SNR_CAP)
    u = (setup.total_row @ reactions)[None, :]                   # the reactions-only total
    rest = q
    if transfer is not None:                                     # the gauges' part of q_1''
        rest = q - filtered(u, fs, transfer.response)[0]
    acc_probes = smooth_states(bm_res, rest, states=(2,))[0]       # the probes' part of q_1''
    acc_gauges = (np.zeros_like(acc_probes) if transfer is None else
                  filtered(u, fs, lambda f: (2j * np.pi * f) ** 2 * transfer.response(f))[0])
    acc = acc_probes + acc_gauges
    m1 = setup.couplings
    gam, w = setup.probe_shapes, setup.probe_weights

    def correction(f: np.ndarray) -> np.ndarray:
        return (model.inertia_correction(f, gam, w) if model.n_shapes > 1
                else np.ones((len(m1), len(f))))

    def inertia_of(x: np.ndarray) -> np.ndarray:             # (k, N) accelerations
        lumped = m1[None, :, None] * x[:, None, :]
        if model.n_shapes > 1:
            lumped = np.stack([filtered(part, fs, correction) for part in lumped])
        return lumped

    by_probes, by_gauges = inertia_of(np.vstack([acc_probes, acc_gauges]))   # (n_gauges, N)
    inertia = by_probes + by_gauges
    pinv = setup.pinv
    force = pinv @ (inertia - reactions)
    if not np.all(np.isfinite(force)):
        raise DataError(f"run '{source}': the forces are not finite (a channel holds "
                        "non-finite samples?)")
    f = np.fft.rfftfreq(frame, 1.0 / fs)
    to_force = pinv @ (m1[:, None] * correction(f))             # q_1'' -> forces, (k, bins)
    via_u = (np.zeros_like(f) if transfer is None
             else (2j * np.pi * f) ** 2 * transfer.response(f))
    per_gauge = [(-pinv[:, r, None] + to_force * via_u * setup.total_row[r])
                 * smoother_response(bm_r[r], 0, frame) for r in range(len(gauges))]
    per_q = smoother_response(bm_res, 2, frame) * to_force        # the probes' path, per q_1
    n_g = len(gauges)
    hum = [(per_gauge[c] if c < n_g else setup.coordinate_map[c - n_g] * per_q)
           * tone_density(frame, fs, tone, power)     # each gauge's and probe's hum tones
           for c, tone, power in setup.hum if power > 0]
    noise = np.concatenate([
        (np.sqrt(setup.var_q) * per_q)[:, None, :],
        np.stack([g * np.sqrt(v) for g, v in zip(per_gauge, setup.var_g, strict=True)]
                 + hum, axis=1)], axis=1)
    # smoothed as the total and its complement (an orthonormal basis whose first row is the
    # sum's): the total keeps its own, smaller noise (a gauge's hum or noise splits between
    # the forces far more than it moves their sum)
    start = np.eye(len(pinv))
    start[:, 0] = 1.0
    basis = np.linalg.qr(start)[0].T
    sw = wiener_smooth(basis @ force, np.einsum("jk,ksb->jsb", basis, noise), fs, frame,
                       np.vstack([basis.T, basis.sum(axis=1)]))
    # the ends: the gauges' part of the inertia lost in the share the gauges' prediction
    # misses, the probes' in the probes'
    part_g, part_p = (ext.inner(pinv @ x) for x in (by_gauges, by_probes))
    edge = np.hypot(
        _edge_std(np.vstack([part_g, part_g.sum(axis=0)]), reach,
                  ext.missed[:, :n_g].max(axis=1)),
        _edge_std(np.vstack([part_p, part_p.sum(axis=0)]), reach,
                  ext.missed[:, n_g:].max(axis=1)))
    scan = short_time_variance(acc, np.vstack([setup.error_weights(model, frame),
                                               setup.noise_weights(model, frame)[-1:]]),
                               fs, frame)                 # and the total's by its noise alone
    var = ext.inner(_transfer_std(transfer, u, fs, inertia_of, pinv) ** 2 + scan[:-1]
                    + type_b_variance(setup.type_b, model, gam, setup.coordinate_map, pinv,
                                      acc, inertia, reactions, fs)) + edge**2
    inner = ext.inner
    return WindowEstimate(force=inner(sw.values[:-1]),
                          force_std=np.sqrt(inner(sw.std[:-1] ** 2) + var[:-1]),
                          total=inner(sw.total), total_std=np.sqrt(inner(sw.total_std**2)
                                                                   + var[-1]),
                          static=-pinv @ gauges, inertia=inner(inertia),
                          reactions=inner(reactions), coordinate=inner(q), passed=sw.passed,
                          scan_noise=inner(scan[-1]))


TRANSFER_MISFIT = 2.0
"""A transfer whose residual's chi-square per degree of freedom exceeds this is noted: the
reactions do not explain the probes' coordinate, and the probes carry what it misses."""


def transfer_note(transfer: ReactionTransfer | None, source: str) -> str:
    """What the run's reactions tell of its inertia, in a line."""
    if transfer is None:
        return (f"run '{source}': no transfer from the reactions to the motion could be fitted "
                "over the band; the inertia is the probes' alone")
    gain = 100 * float(np.sqrt(transfer.cov[0, 0]) / abs(transfer.num[0]))
    line = (f"the reactions carry the inertia: their transfer to the first shape's coordinate "
            f"(its static gain known to {gain:.2g} %) leaves chi-square {transfer.chi2:.3g} per "
            "degree of freedom")
    if transfer.chi2 > TRANSFER_MISFIT:
        line += (f"; run '{source}': the reactions do not explain the probes' motion (a load "
                 "whose pattern changes, a second force, a structure that is not linear?), "
                 "and the probes carry what they miss")
    return line


def _transfer_std(transfer: ReactionTransfer | None, u: np.ndarray, fs: float,
                  inertia_of: Callable[[np.ndarray], np.ndarray], pinv: np.ndarray
                  ) -> np.ndarray:
    """(n_forces + 1, N) [N]: each force's and the total's standard uncertainty from the
    transfer's parameters, sample by sample (their covariance through the inertia each one
    moves)."""
    if transfer is None:
        return np.zeros((len(pinv) + 1, u.shape[-1]))
    sens = transfer.sensitivities
    moves = filtered(np.repeat(u, len(transfer.cov), axis=0), fs,
                     lambda f: (2j * np.pi * f) ** 2 * sens(f))  # (n_params, N) in q_1''
    part = np.einsum("fg,kgn->kfn", pinv, inertia_of(moves))    # (n_params, n_forces, N)
    part = np.concatenate([part, part.sum(axis=1, keepdims=True)], axis=1)
    return np.sqrt(np.maximum(np.einsum("kfn,kl,lfn->fn", part, transfer.cov, part), 0.0))


EDGE_PERIODS = 2.0
"""The record's first and last this many periods of the coordinate's cutoff hold an inertia
the smoother cannot see whole (:func:`_edge_std`)."""


def _edge_length(fs: float, bm: BandModel, n: int) -> int:
    """Samples at either end of ``n`` within ``EDGE_PERIODS`` periods of the cutoff of ``bm``."""
    return min(int(np.ceil(EDGE_PERIODS * fs / (bm.scale[1] / (2 * np.pi)))), n // 2)


def _edge_std(part: np.ndarray, m: int, missed: np.ndarray) -> np.ndarray:
    """(n, N) [N]: the uncertainty of the inertia's part ``part`` (n, N) at the record's ends.

    Within about a period of the cutoff of an end the smoothers and the reactions' transfer
    take samples beyond it, which the record carries by a prediction
    (:mod:`forcecal.record_ends`): the inertia there is lost in the share the prediction
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


def run_channels(rig: Rig, run: Run, tare: Run | None = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The run's gauges (n_gauges, N) [N] and probes (n_probes, N) [m], less the tare's means,
    and its coil current (N,) [A]."""
    sig = channels_si(rig, run)
    gauges = np.stack([sig[g] for g in rig.gauge_names])
    probes = np.stack([sig[s] for s in rig.sensor_names])
    if tare is not None:
        tsig = channels_si(rig, tare)
        gauges -= np.array([np.mean(tsig[g]) for g in rig.gauge_names])[:, None]
        probes -= np.array([np.mean(tsig[s]) for s in rig.sensor_names])[:, None]
    return gauges, probes, sig[rig.actuator.current]


def check_length(model: BroadbandModel, n: int, fs: float, source: str) -> None:
    """DataError unless ``n`` samples at ``fs`` are long enough for the model's band."""
    band = model.band
    if n < 4 * fs / max(band[0], 1.0) or n < 8 * fs / band[1]:
        raise DataError(f"run '{source}': {n} samples are too short for the band "
                        f"{band[0]:g}-{band[1]:g} Hz")


def reconstruct_any(rig: Rig, model: BroadbandModel, run: Run, tare: Run | None = None,
                    smooth: bool = True) -> TransientEstimate:
    """The forces of a run under any drive, sample by sample.

    Parameters
    ----------
    rig : Rig
        With ``acquisition.band``.
    model : BroadbandModel
        From a broadband scan of the rig.
    run : Run
        The recording.
    tare : Run, optional
        A zero-current record: its mean gauge and probe values are the zero, and with
        ``acquisition.mains`` its gauges' hum tones enter the uncertainty.
    smooth : bool
        The batch estimate over the whole record (default), or the real-time one that
        ``stream`` gives (:class:`forcecal.stream.any_drive.AnyDriveStream`: every sample from
        the samples up to a fixed latency after it, its setup from the run's first seconds).

    Returns
    -------
    TransientEstimate

    Raises
    ------
    InputError
        More span shapes than probes, or a model of another rig.
    DataError
        A record too short for the band, or a gauge or probe channel that is constant or
        changes while it runs (:func:`check_channel_noise`).
    """
    check_rig_keys(model.rig, model.source, rig)
    fs = run.fs
    n = run.n_samples
    check_length(model, n, fs, run.source)
    gauges, probes, current = run_channels(rig, run, tare)
    reach = AboveBand(fs, model.band, run.t0)
    reach.add(current)
    above = reach.notes(run.source)
    zero = None if tare is None else np.vstack(run_channels(rig, tare)[:2])
    if not smooth:
        from .stream.any_drive import stream_arrays

        live = stream_arrays(rig, model, gauges, probes, fs, run.t0, run.name,
                             tare=zero, tare_fs=None if tare is None else tare.fs)
        return dataclasses.replace(live, notes=live.notes + above)
    setup = any_drive_setup(rig, model, gauges, probes, fs, run.source, zero,
                            None if tare is None else tare.fs)
    check_channel_noise(gauges, probes, (*rig.gauge_names, *rig.sensor_names), fs, model.band,
                        run.t0, run.source)
    frame = stft_frame(fs, n)
    est = window_forces(setup, model, gauges, probes, frame, run.source)
    scan = ScanNoiseShare(fs, run.t0)
    scan.add(np.vstack([est.scan_noise, est.total_std**2]))
    notes = (f"short-time Wiener gains ({frame} samples a frame) let through "
             f"{100 * float(np.max(est.passed)):.3g} % of the smoothed noise at most",
             transfer_note(setup.transfer, run.source),
             *unseen_notes(setup.unseen, tuple(rig.sensor_names), run.source),
             *type_b_notes(rig, run.source), *hum_notes(rig, tare, run.source),
             *scan.notes(run.source), *above)
    return TransientEstimate.from_window(rig, run.name, run.t0, fs, est, model.band, True,
                                         notes)

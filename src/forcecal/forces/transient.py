"""Forces for any drive, sample by sample (METHOD.md section 7, "any drive").

A swept, multi-tone or random drive has no harmonics to fit; eq. 15-16 hold at every instant
instead. With the span of shapes of a broadband scan (:mod:`forcecal.model.broadband`):

1. q_1(t), the first shape's coordinate, from the probes by weighted least squares;
2. every gauge's reaction from a Kalman smoother (:mod:`forcecal.signals.kalman`), and q_1''
   through the structure's transfer from the reactions (:mod:`.reaction_transfer`) plus the
   smoothed second derivative of what it leaves of q_1;
3. J_r = m_{r,1} q_1'' corrected frequency by frequency to the operating shape, and
   f(t) = Psi^+ (J(t) - R(t)) (eq. 8, 24), beside the reactions-only estimate -Psi^+ R(t);
4. short-time Wiener gains on every force (:mod:`forcecal.signals.wiener`); each sample's
   uncertainty is the noise they let through plus the errors of the scan's shapes, of the
   transfer and of the rig's type-B inputs (:mod:`.inertia_errors`, :mod:`.budget`).

:func:`~forcecal.forces.any_setup.any_drive_setup` (:mod:`.any_setup`) fixes what the
estimate needs before its first sample (the channels' noise, band models, transfer, probe
checks, type-B moves, hum); :func:`window_forces` runs
steps 1-4 over a stretch whose ends are carried past by :mod:`forcecal.signals.record_ends`;
:func:`reconstruct_any` over a whole run, :mod:`forcecal.realtime.any_drive` over a sliding window.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields
from typing import Any, ClassVar

import numpy as np

from ..errors import DataError
from ..model.broadband import BroadbandModel
from ..model.spatial import check_rig_keys
from ..records import Run
from ..rig import Rig
from ..signals.checks import AboveBand, check_channel_noise
from ..signals.kalman import BandModel, smooth_states
from ..signals.record_ends import extend
from ..signals.wiener import (
    short_time_variance,
    smoother_response,
    stft_frame,
    tone_density,
    wiener_smooth,
)
from .any_setup import AnyDriveSetup, any_drive_setup
from .budget import series_type_b_variance, type_b_notes
from .crosschecks import flux_notes, line_terms, pole_notes
from .estimate import inertia_share_of, series_summary
from .inertia_ends import edge_length, ends_std
from .inertia_errors import ScanNoiseShare
from .inertia_scale import (
    InertiaScale,
    estimate_inertia_scale,
    plausible_deviation,
    scale_shift,
    scale_variance,
)
from .reaction_transfer import (
    ReactionTransfer,
    filtered,
    fourier_filter,
)
from .scan_check import run_line_notes
from .solve import force_solve, reactions_only
from .steady import channels_si
from .unseen_motion import unseen_notes
from .weight import current_rms, weight_notes

__all__ = [
    "TransientEstimate",
    "WindowEstimate",
    "check_length",
    "hum_notes",
    "reconstruct_any",
    "run_channels",
    "run_inputs",
    "transfer_note",
    "window_forces",
]


def hum_notes(rig: Rig, tare: object, source: str) -> tuple[str, ...]:
    """The run's note when the rig names its mains but no zero-current record says its hum."""
    if rig.mains is None or tare is not None:
        return ()
    return (f"run '{source}': acquisition.mains is {rig.mains:g} Hz, but without a tare record "
            "the gauges' and probes' hum on its harmonics is not in the uncertainty (give a "
            "zero-current record, --tare)",)


# --- from transient ---
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
        prediction carrying the record past them misses (:mod:`forcecal.signals.record_ends`).
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
    inertia_scale : InertiaScale or None
        The inertia term's scale calibrated in situ (:mod:`.inertia_scale`), applied to
        ``inertia`` and the forces where ``applied``; None where it was not asked for.
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
    provenance: dict | None = None
    inertia_scale: InertiaScale | None = None

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

    formats: ClassVar[tuple[str, ...]] = ("csv",)

    def columns(self) -> dict[str, np.ndarray]:
        """Each force and ``total``, then the same with ``_static`` (reactions only) and with
        ``_std`` (standard uncertainty of every sample) [N]."""
        names = [*self.force_names, "total"]
        series = [*self.force, self.total]
        static = [*self.static, self.static.sum(axis=0)]
        std: list[np.ndarray] = [*self.force_std, self.total_std]
        cols = dict(zip(names, series, strict=True))
        cols.update({f"{n}_static": s for n, s in zip(names, static, strict=True)})
        cols.update({f"{n}_std": s for n, s in zip(names, std, strict=True)})
        return cols

    def force_over_time(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """One force's (or ``total``'s) samples and their standard uncertainties [N]."""
        cols = self.columns()
        return cols[name], cols[f"{name}_std"]

    def summary(self) -> dict:
        """The JSON document of the run: band, estimator, every force's and the total's mean,
        AC RMS and RMS uncertainty, the reactions-only AC RMS, the inertia share, the notes."""
        return {"run": self.run_name, "drive": "any", "band_hz": list(self.band),
                "estimator": ("Kalman smoother, short-time Wiener gains" if self.smoothed
                              else "Kalman filter"),
                **series_summary(self.columns(), self.force_names),
                "inertia_share": self.inertia_share, "notes": list(self.notes)}

    def to_dataframe(self) -> Any:
        """The force series as a pandas DataFrame: index ``time`` [s], the columns of
        :meth:`columns` (the columns of ``NAME.forces.csv``)."""
        import pandas  # type: ignore[import-untyped]  # imported on use only

        return pandas.DataFrame(self.columns(), index=pandas.Index(self.time, name="time"))

    def __repr__(self) -> str:
        """One line: the run, its band, the total's AC RMS with its uncertainty, the inertia
        share."""
        s = series_summary(self.columns(), self.force_names)["total"]
        return (f"TransientEstimate(run '{self.run_name}', band {self.band[0]:g}-"
                f"{self.band[1]:g} Hz, total AC RMS {s['ac_rms_n']:.4g} N ± {s['std_n']:.2g}; "
                f"inertia share {100 * self.inertia_share:.1f} %)")

    def _repr_html_(self) -> str:
        """A small table for notebooks: per force and the total, AC RMS, the RMS of its
        uncertainty and the reactions-only AC RMS."""
        from html import escape

        doc = series_summary(self.columns(), self.force_names)
        static = [*self.static, self.static.sum(axis=0)]
        rows = "".join(
            f"<tr><td>{escape(n)}</td><td>{v['ac_rms_n']:.4g}</td><td>{v['std_n']:.2g}</td>"
            f"<td>{float(np.std(st)):.4g}</td></tr>"
            for (n, v), st in zip([*doc["forces"].items(), ("total", doc["total"])], static,
                                  strict=True))
        return (f"<p><b>TransientEstimate</b> of run '{escape(self.run_name)}': band "
                f"{self.band[0]:g}-{self.band[1]:g} Hz, inertia share "
                f"{100 * self.inertia_share:.1f} %</p><table><tr><th>force</th>"
                "<th>AC RMS [N]</th><th>std (RMS) [N]</th><th>reactions only [N]</th></tr>"
                f"{rows}</table>")

    @property
    def inertia_share(self) -> float:
        """RMS of the AC inertia term's part in the total over the AC total's RMS [1]."""
        return inertia_share_of(self.total, self.static.sum(axis=0))


@dataclass(frozen=True)
class WindowEstimate:
    """The forces over a stretch of samples (a whole run, or a stream's window).

    ``force``, ``force_std`` (n_forces, N); ``total``, ``total_std`` (N,); ``static``
    (n_forces, N) reactions only; ``inertia``, ``reactions`` (n_gauges, N); ``coordinate``
    (N,); ``passed`` (n_forces,): the share of each force's smoothed noise the Wiener gains
    let through; ``scan_noise`` (N,) [N^2]: the part of the total's variance the scan's noise
    gives (:func:`forcecal.forces.inertia_errors.scan_noise_weights`); ``noise_density``
    (n_forces, frame // 2 + 1): the density per sample of the noise of each force before the
    Wiener gains, Psi^+ (J - R) as the cross-checks compare it, at the frame's bins (its
    variance per sample ``noise_density @ fold / frame``); ``borne`` (n_forces, N) [N^2]: the
    part of each force's variance that is no noise (the transfer's parameters, the scan, the
    type-B sources, the record's ends, the inertia's scale).
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
    noise_density: np.ndarray
    borne: np.ndarray

    _WHOLE = ("passed", "noise_density")
    """The fields of the window as a whole, not sample by sample."""

    def part(self, samples: slice) -> WindowEstimate:
        """The ``samples`` of the stretch (``passed`` and ``noise_density`` are the
        window's)."""
        return WindowEstimate(**{f.name: getattr(self, f.name) if f.name in self._WHOLE
                                 else getattr(self, f.name)[..., samples] for f in fields(self)})

    @staticmethod
    def join(parts: Sequence[WindowEstimate]) -> WindowEstimate:
        """Stretches one after another (``passed``, ``noise_density``: the largest, the
        densities on the finest frame's bins)."""
        bins = max(p.noise_density.shape[-1] for p in parts)
        grid = np.linspace(0.0, 1.0, bins)
        density = np.max([np.stack([np.interp(grid, np.linspace(0.0, 1.0, d.shape[-1]), d)
                                    for d in p.noise_density]) for p in parts], axis=0)
        return WindowEstimate(**{
            f.name: np.max([p.passed for p in parts], axis=0) if f.name == "passed"
            else density if f.name == "noise_density"
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
        Samples per Wiener frame (:func:`forcecal.signals.wiener.stft_frame`).
    source : str
        Named in messages.
    ends : (bool, bool)
        Whether the stretch starts, ends, the record: those ends are carried past by a
        prediction of every channel (:mod:`forcecal.signals.record_ends`).

    Returns
    -------
    WindowEstimate

    Raises
    ------
    DataError
        Forces that are not finite.
    """
    fs = setup.fs
    transfer = setup.transfer
    reach = edge_length(fs, setup.coordinate_model, gauges.shape[-1])
    white = np.r_[setup.var_g, 1.0 / setup.probe_weights]          # each channel's noise
    ext = extend(np.vstack([gauges, probes]), fs, setup.band[1], reach, white, ends,
                 frame // 4)                                     # carried past the ends
    q, reactions, u = _coordinate_and_reactions(setup, gauges, ext.values)
    acc_probes, acc_gauges = _accelerations(setup, q, u)
    acc = acc_probes + acc_gauges
    gam = setup.probe_shapes
    correction, inertia_of = _inertia_maps(setup, model)
    by_probes, by_gauges = inertia_of(np.vstack([acc_probes, acc_gauges]))   # (n_gauges, N)
    inertia = by_probes + by_gauges
    pinv = setup.pinv
    force = force_solve(pinv, inertia, reactions)
    if not np.all(np.isfinite(force)):
        raise DataError(f"run '{source}': the forces are not finite (a channel holds "
                        "non-finite samples?)")
    noise = _noise_paths(setup, correction, frame, len(gauges))
    # smoothed as the total and its complement (an orthonormal basis whose first row is the
    # sum's): the total keeps its own, smaller noise (a gauge's hum or noise splits between
    # the forces far more than it moves their sum)
    basis = _total_basis(len(pinv))
    sw = wiener_smooth(basis @ force, np.einsum("jk,ksb->jsb", basis, noise), fs, frame,
                       np.vstack([basis.T, basis.sum(axis=1)]))
    edge = ends_std(ext.inner, ext.missed, pinv, by_gauges, by_probes, reach, len(gauges),
                    _part_kernels(setup, frame))
    scan = short_time_variance(acc, np.vstack([setup.error_weights(model, frame),
                                               setup.noise_weights(model, frame)[-1:]]),
                               fs, frame)                 # and the total's by its noise alone
    shift = setup.scale_shift
    var = ext.inner(_transfer_std(transfer, u, fs, inertia_of, pinv,
                                  setup.residual_model) ** 2 + scan[:-1]
                    + series_type_b_variance(setup.type_b, model, gam, setup.coordinate_map, pinv,
                                             acc, inertia, reactions, fs, None if shift is None
                                             else lambda d: shift(ext.inner(d)))) + edge**2
    inner = ext.inner
    return WindowEstimate(force=inner(sw.values[:-1]),
                          force_std=np.sqrt(inner(sw.std[:-1] ** 2) + var[:-1]),
                          total=inner(sw.total), total_std=np.sqrt(inner(sw.total_std**2)
                                                                   + var[-1]),
                          static=reactions_only(pinv, gauges), inertia=inner(inertia),
                          reactions=inner(reactions), coordinate=inner(q), passed=sw.passed,
                          scan_noise=inner(scan[-1]),
                          noise_density=np.sum(np.abs(noise) ** 2, axis=1), borne=var[:-1])


def _coordinate_and_reactions(setup: AnyDriveSetup, gauges: np.ndarray, values: np.ndarray
                              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Steps 1 and 2 on the extended channels ``values`` (gauges, then probes): the first
    shape's coordinate q_1, every gauge's smoothed reaction (n_gauges, N') and the
    reactions-only total u (1, N')."""
    bm_r = setup.reaction_models
    level = gauges.mean(axis=1, keepdims=True)    # the DC passes whole (in the band the
    gauges_x, probes_x = values[:len(gauges)], values[len(gauges):]
    q = setup.coordinate_map @ probes_x                          # the first shape's coordinate
    reactions = level + np.stack([smooth_states(bm_r[r], gauges_x[r] - level[r], states=(0,))[0]
                                  for r in range(len(gauges))])   # gain is 1 - 1 / SNR_CAP)
    u = (setup.total_row @ reactions)[None, :]                   # the reactions-only total
    return q, reactions, u


def _accelerations(setup: AnyDriveSetup, q: np.ndarray, u: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Step 2's q_1'' in two parts: the probes' (the smoothed second derivative of what the
    reactions' transfer leaves of q_1) and the gauges' (u through the transfer; zero without
    one)."""
    fs, transfer = setup.fs, setup.transfer
    rest = q
    if transfer is not None:                                     # the gauges' part of q_1''
        rest = q - filtered(u, fs, transfer.response)[0]
    acc_probes = smooth_states(setup.residual_model, rest,
                               states=(2,))[0]                   # the probes' part of q_1''
    acc_gauges = (np.zeros_like(acc_probes) if transfer is None else
                  filtered(u, fs, lambda f: (2j * np.pi * f) ** 2 * transfer.response(f))[0])
    return acc_probes, acc_gauges


def _inertia_maps(setup: AnyDriveSetup, model: BroadbandModel
                  ) -> tuple[Callable[[np.ndarray], np.ndarray],
                             Callable[[np.ndarray], np.ndarray]]:
    """Step 3's maps: ``correction``, frequencies [Hz] to every gauge's factor on the first
    shape's coupling (the operating shape's correction; 1 with one shape), and ``inertia_of``,
    accelerations q_1'' (k, N) to every gauge's inertia (k, n_gauges, N)."""
    fs, m1 = setup.fs, setup.couplings
    gam, w = setup.probe_shapes, setup.probe_weights

    def correction(f: np.ndarray) -> np.ndarray:
        return (model.inertia_correction(f, gam, w) if model.n_shapes > 1
                else np.ones((len(m1), len(f))))

    def inertia_of(x: np.ndarray) -> np.ndarray:             # (k, N) accelerations
        lumped = m1[None, :, None] * x[:, None, :]
        if model.n_shapes > 1:
            lumped = np.stack([filtered(part, fs, correction) for part in lumped])
        return lumped

    return correction, inertia_of


def _noise_paths(setup: AnyDriveSetup, correction: Callable[[np.ndarray], np.ndarray],
                 frame: int, n_g: int) -> np.ndarray:
    """Every noise source's amplitude on every force per bin of a Wiener frame,
    (n_forces, n_sources, bins): the coordinate's noise, then each gauge's, then the hum tones
    of the gauges and probes, through the smoothers, the transfer and the force solve."""
    fs, pinv, transfer = setup.fs, setup.pinv, setup.transfer
    bm_r, bm_res = setup.reaction_models, setup.residual_model
    f = np.fft.rfftfreq(frame, 1.0 / fs)
    to_force = pinv @ (setup.couplings[:, None] * correction(f))  # q_1'' -> forces, (k, bins)
    by_probes = smoother_response(bm_res, 2, frame)               # q_1 -> its part of q_1''
    # u reaches q_1'' through the transfer, less what the probes' part takes back of it (their
    # smoother is fed q_1 - G u): where that smoother passes, a gauge's noise does not reach
    # the inertia
    via_u = (np.zeros_like(f) if transfer is None
             else ((2j * np.pi * f) ** 2 - by_probes) * transfer.response(f))
    per_gauge = [(-pinv[:, r, None] + to_force * via_u * setup.total_row[r])
                 * smoother_response(bm_r[r], 0, frame) for r in range(n_g)]
    per_q = by_probes * to_force                                  # the probes' path, per q_1
    hum = [(per_gauge[c] if c < n_g else setup.coordinate_map[c - n_g] * per_q)
           * tone_density(frame, fs, tone, power)     # each gauge's and probe's hum tones
           for c, tone, power in setup.hum if power > 0]
    return np.concatenate([
        (np.sqrt(setup.var_q) * per_q)[:, None, :],
        np.stack([g * np.sqrt(v) for g, v in zip(per_gauge, setup.var_g, strict=True)]
                 + hum, axis=1)], axis=1)


def _part_kernels(setup: AnyDriveSetup, frame: int) -> tuple[np.ndarray, np.ndarray]:
    """The impulse responses (``frame`` samples, lag 0 first) of q_1'' to a gauge's reaction
    (its smoother, then the transfer, s^2 G) and to the coordinate (the probes' part's
    smoother): how far each part of the inertia reaches past a sample."""
    f = np.fft.rfftfreq(frame, 1.0 / setup.fs)
    transfer = setup.transfer
    to_gauges = (np.zeros_like(f) if transfer is None
                 else smoother_response(setup.reaction_models[0], 0, frame)
                 * (2j * np.pi * f) ** 2 * transfer.response(f))
    to_probes = smoother_response(setup.residual_model, 2, frame)
    return np.fft.irfft(to_gauges, frame), np.fft.irfft(to_probes, frame)


def _total_basis(n: int) -> np.ndarray:
    """(n, n): an orthonormal basis of the forces whose first row is along their sum."""
    start = np.eye(n)
    start[:, 0] = 1.0
    return np.linalg.qr(start)[0].T


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
                  inertia_of: Callable[[np.ndarray], np.ndarray], pinv: np.ndarray,
                  residual: BandModel) -> np.ndarray:
    """(n_forces + 1, N) [N]: each force's and the total's standard uncertainty from the
    transfer's parameters, sample by sample (their covariance through the inertia each one
    moves: through the gauges' part of q_1'', less what the probes' part, fed q_1 - G u and
    smoothed by ``residual``, takes back)."""
    if transfer is None:
        return np.zeros((len(pinv) + 1, u.shape[-1]))
    through = fourier_filter(np.repeat(u, len(transfer.cov), axis=0), fs)
    in_q = through(transfer.sensitivities)                       # (n_params, N) in q_1
    moves = through(lambda f: (2j * np.pi * f) ** 2 * transfer.sensitivities(f)) - np.stack(
        [smooth_states(residual, row, states=(2,))[0] for row in in_q])   # in q_1''
    part = np.einsum("fg,kgn->kfn", pinv, inertia_of(moves))    # (n_params, n_forces, N)
    part = np.concatenate([part, part.sum(axis=1, keepdims=True)], axis=1)
    return np.sqrt(np.maximum(np.einsum("kfn,kl,lfn->fn", part, transfer.cov, part), 0.0))


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


def run_inputs(rig: Rig, model: BroadbandModel, run: Run, tare: Run | None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, tuple[str, ...]]:
    """A run's gauges [N] and probes [m], the tare's (their zero, or None), and the notes of
    the drive's force above the scan's band; the model checked against the rig and the
    record's length against the band (batch and stream alike)."""
    check_rig_keys(model.rig, model.origin, rig)
    check_length(model, run.n_samples, run.fs, run.source)
    gauges, probes, current = run_channels(rig, run, tare)
    reach = AboveBand(run.fs, model.band, run.t0)
    reach.add(current)
    zero = None if tare is None else np.vstack(run_channels(rig, tare)[:2])
    return gauges, probes, zero, reach.notes(run.source)


def inertia_scaled(rig: Rig, model: BroadbandModel, setup: AnyDriveSetup, est: WindowEstimate,
                   flux: np.ndarray | None, source: str
                   ) -> tuple[AnyDriveSetup, InertiaScale]:
    """The inertia's scale s read from an estimate and the run's flux channels
    (:func:`.inertia_scale.estimate_inertia_scale`), and the setup with every gauge's coupling
    (and its basis functions') times s where it is applied (else the setup as it was)."""
    total = np.ones(len(setup.pinv)) @ setup.pinv
    scale = estimate_inertia_scale(total @ est.inertia, total @ est.reactions, flux, setup.fs,
                                   model.band, plausible_deviation(rig.type_b), source)
    if not scale.applied:
        return setup, scale
    return dataclasses.replace(setup, couplings=scale.scale * setup.couplings,
                               basis_couplings=scale.scale * setup.basis_couplings,
                               _weights={}), scale


def with_scale_std(est: WindowEstimate, pinv: np.ndarray, scale: InertiaScale
                   ) -> WindowEstimate:
    """The estimate with the scale's uncertainty through its (scaled) inertia term in every
    force's and the total's."""
    var = scale_variance(pinv, est.inertia, scale.std / scale.scale)
    return dataclasses.replace(est, force_std=np.sqrt(est.force_std**2 + var[:-1]),
                               total_std=np.sqrt(est.total_std**2 + var[-1]),
                               borne=est.borne + var[:-1])


def _calibrated_inertia(rig: Rig, run: Run, model: BroadbandModel, setup: AnyDriveSetup,
                        est: WindowEstimate, gauges: np.ndarray, probes: np.ndarray, frame: int
                        ) -> tuple[WindowEstimate, InertiaScale]:
    """The estimate with its inertia term scaled in situ (:func:`inertia_scaled`, from the
    run's flux channels): where applied, the forces again with the scaled couplings, the
    type-B changes less what the scale absorbs, and s's uncertainty in every force's."""
    names = [c for c in rig.flux_channels if c in run.channels]
    flux = np.stack([run.channel(c) for c in names]) if names else None
    scaled, scale = inertia_scaled(rig, model, setup, est, flux, run.source)
    if not scale.applied or flux is None:
        return est, scale
    total = np.ones(len(setup.pinv)) @ setup.pinv
    scaled = dataclasses.replace(scaled, scale_shift=scale_shift(
        total @ est.inertia, flux, setup.fs, model.band, scale.scale))
    est = window_forces(scaled, model, gauges, probes, frame, run.source)
    return with_scale_std(est, setup.pinv, scale), scale


def reconstruct_any(rig: Rig, model: BroadbandModel, run: Run, tare: Run | None = None,
                    inertia_scale: bool = True) -> TransientEstimate:
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
    inertia_scale : bool
        Calibrate the inertia term's scale in situ (:mod:`.inertia_scale`; a note says what
        was found and whether it was applied); False keeps the scan's and the probes' scale.

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
    gauges, probes, zero, above = run_inputs(rig, model, run, tare)
    fs = run.fs
    n = run.n_samples
    setup = any_drive_setup(rig, model, gauges, probes, fs, run.source, zero,
                            None if tare is None else tare.fs)
    check_channel_noise(gauges, probes, (*rig.gauge_names, *rig.sensor_names), fs, model.band,
                        run.t0, run.source)
    frame = stft_frame(fs, n)
    est = window_forces(setup, model, gauges, probes, frame, run.source)
    scale = None
    if inertia_scale:
        est, scale = _calibrated_inertia(rig, run, model, setup, est, gauges, probes, frame)
    scan = ScanNoiseShare(fs, run.t0)
    scan.add(np.vstack([est.scan_noise, est.total_std**2]))
    terms = line_terms(est.force_std, est.reactions, est.inertia, setup.pinv, fs, run.t0,
                       model.band, rig.mains, (est.noise_density, est.borne))
    what = f"run '{run.source}'"
    notes = (*flux_notes(rig, run, terms, what), *pole_notes(rig, run, terms, what),
             *run_line_notes(rig, model, run, est.coordinate, what),
             f"short-time Wiener gains ({frame} samples a frame) let through "
             f"{100 * float(np.max(est.passed)):.3g} % of the smoothed noise at most",
             transfer_note(setup.transfer, run.source),
             *unseen_notes(setup.unseen, tuple(rig.sensor_names), run.source),
             *type_b_notes(rig, run.source), *hum_notes(rig, tare, run.source),
             *weight_notes(rig, tare, current_rms(rig, run), what),
             *scan.notes(run.source), *above, *(() if scale is None else (scale.note,)))
    return dataclasses.replace(
        TransientEstimate.from_window(rig, run.name, run.t0, fs, est, model.band, True, notes),
        inertia_scale=scale)

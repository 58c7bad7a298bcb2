"""What the estimate under any drive needs before its first sample (METHOD.md section 7, "any
drive"): :func:`any_drive_setup` reads, from a record of the gauges and probes (a whole run,
or a stream's first seconds), every channel's noise, the probes' weights and the first shape's
coordinate map, the band models of the coordinate and of every reaction, the structure's
transfer from the reactions-only force to the coordinate (:mod:`.reaction_transfer`) with the
band model of what it leaves, the probes' misfit to the scan's operating shapes, the type-B
moves and the channels' hum; :func:`with_reaction_priors` sets a stream's smoothers again from
each window. :mod:`.transient` runs the estimate with it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import DataError
from ..model.broadband import BroadbandModel
from ..model.inertia import mass_coupling
from ..model.relaxation import force_matrix
from ..rig import Rig
from ..signals.checks import channel_noise
from ..signals.kalman import BandModel, band_model
from ..signals.mains import hum_tones, near_mains
from .budget import TypeBMoves, type_b_moves
from .inertia_errors import inertia_error_weights
from .reaction_transfer import (
    ReactionTransfer,
    filtered,
    fit_reaction_transfer,
)
from .unseen_motion import UnseenMotion, probe_misfit, unseen_weights

__all__ = ["AnyDriveSetup", "any_drive_setup", "with_reaction_priors"]

TOP_MARGIN = 100.0
"""The drive's reach: the highest line of the band whose density exceeds the noise's this many
times."""


RESIDUAL_MARGIN = 10.0
"""What the reactions' transfer leaves of the coordinate counts as signal up to the highest
line of the band whose density exceeds the noise's this many times (a noise-only line of a
Welch estimate over a few seconds stays within 3 times); none: the band's bottom."""


def _prior(x: np.ndarray, fs: float, band: tuple[float, float], noise_var: float,
           margin: float = TOP_MARGIN, quiet: float | None = None,
           mains: float | None = None) -> tuple[float, float]:
    """The band-limited prior of a signal: its cutoff [Hz], 1.2 x the highest line of the band
    the signal rises ``margin`` above its noise (at least the band's bottom, at most its top;
    ``quiet`` [Hz] where no line does, by default the band's top; the lines of the ``mains``'
    harmonics [Hz] are hum, not signal), and its mean one-sided density below that line
    [unit^2 / Hz]."""
    import scipy.signal  # on use: a steady stream starts without it

    nperseg = int(min(x.shape[-1], max(256, 2 ** int(np.log2(fs / 2)))))
    f, p = scipy.signal.welch(x, fs=fs, nperseg=nperseg)
    sel = (f <= band[1]) & (f > 0) & ~near_mains(f, mains, 2.0 * f[1])
    loud = np.flatnonzero(sel & (p > margin * 2 * noise_var / fs))
    top = float(f[loud[-1]]) if len(loud) else (band[1] if quiet is None else quiet)
    top = min(max(top, band[0], f[1]), band[1])
    under = sel & (f <= top)
    level = float(np.mean(p[under])) if np.any(under) else float(np.mean(p))
    return 1.2 * top, level


@dataclass(frozen=True)
class AnyDriveSetup:
    """What the estimate under any drive fixes before its first sample.

    Attributes
    ----------
    band : (low, high) [Hz]
    fs : float [Hz]
    probe_shapes : (n_probes, n_shapes) array [m]
        The span's shapes at the probes.
    probe_weights : (n_probes,) array [1/m^2]
        Their inverse noise variances.
    coordinate_map : (n_probes,) array [1/m]
        q_1 = coordinate_map @ probes (eq. 15-16 on the first shape).
    var_q : float [1]
        The noise variance of one sample of q_1.
    coordinate_model : BandModel
        The band model of q_1.
    reaction_models : tuple of BandModel
        Every gauge's reaction's.
    var_g : (n_gauges,) array [N^2]
        Every gauge's noise variance per sample.
    couplings : (n_gauges,) array [kg]
        m_{r,1}, every gauge's coupling with the first shape.
    pinv : (n_forces, n_gauges) array
        Psi^+.
    transfer : ReactionTransfer or None
        From the reactions-only force u = ``total_row`` @ gauges to q_1
        (:mod:`forcecal.forces.reaction_transfer`); None where it could not be fitted.
    residual_model : BandModel
        The band model of what the transfer leaves of q_1, q_1 - G u (of q_1 itself without
        a transfer).
    total_row : (n_gauges,) array
        -1^T Psi^+: the reactions-only total force from the gauges.
    basis_couplings : (n_gauges, n_funcs) array
        The mass couplings of the shapes' basis functions (their coefficients' errors move the
        inertia through them).
    basis_probes : (n_probes, n_funcs) array
        The basis functions at the probes.
    unseen : UnseenMotion or None
        The probes' misfit to the scan's operating shapes (:mod:`forcecal.forces.unseen_motion`).
    type_b : TypeBMoves or None
        How the rig's declared type-B uncertainties move the estimate
        (:mod:`forcecal.forces.budget`).
    hum : tuple of (int, float, float)
        (channel, frequency [Hz], |a|^2 [N^2 or m^2]): every gauge's and probe's mains hum
        tones (channels: the gauges, then the probes), read from a zero-current record
        (:func:`forcecal.signals.mains.hum_tones`); the Wiener gains take them for noise (a
        probe's hum is no motion, yet the inertia takes it for one: 0.6 um at 50 Hz on both
        probes of the beam moves the total by 0.06 N).
    scale_shift : callable or None
        Where the inertia's scale was calibrated in situ, how it absorbs a change of the total
        (:func:`forcecal.forces.inertia_scale.scale_shift`): the type-B parameters' changes
        keep only what it does not absorb.
    """

    band: tuple[float, float]
    fs: float
    probe_shapes: np.ndarray
    probe_weights: np.ndarray
    coordinate_map: np.ndarray
    var_q: float
    coordinate_model: BandModel
    reaction_models: tuple[BandModel, ...]
    var_g: np.ndarray
    couplings: np.ndarray
    pinv: np.ndarray
    transfer: ReactionTransfer | None
    residual_model: BandModel
    total_row: np.ndarray
    basis_couplings: np.ndarray
    basis_probes: np.ndarray
    unseen: UnseenMotion | None = None
    type_b: TypeBMoves | None = None
    hum: tuple[tuple[int, float, float], ...] = ()
    scale_shift: Callable[[np.ndarray], float] | None = None
    _weights: dict[int, tuple[np.ndarray, np.ndarray]] = dataclasses.field(
        default_factory=dict, compare=False, repr=False)

    def error_weights(self, model: BroadbandModel, frame: int) -> np.ndarray:
        """(n_forces + 1, frame // 2 + 1) [kg^2]: the variance the scan's errors give each
        force and the total per unit |q''_1|^2 at the frame's bins
        (:func:`forcecal.forces.inertia_errors.inertia_error_weights`), with the bound on a motion
        the scan did not see where the probes found one
        (:func:`forcecal.forces.unseen_motion.unseen_weights`); computed once per frame length (a
        stream's windows share it)."""
        return self._scan_weights(model, frame)[0]

    def noise_weights(self, model: BroadbandModel, frame: int) -> np.ndarray:
        """(n_forces + 1, frame // 2 + 1) [kg^2]: the part of :meth:`error_weights` that the
        scan's noise gives (:func:`forcecal.forces.inertia_errors.scan_noise_weights`)."""
        return self._scan_weights(model, frame)[1]

    def _scan_weights(self, model: BroadbandModel, frame: int
                      ) -> tuple[np.ndarray, np.ndarray]:
        if frame not in self._weights:
            f = np.fft.rfftfreq(frame, 1.0 / self.fs)
            rows = np.vstack([self.pinv, self.pinv.sum(axis=0)])
            every, noise = inertia_error_weights(
                model, f, self.probe_shapes, self.probe_weights, self.couplings,
                self.basis_couplings, self.basis_probes, rows)
            self._weights[frame] = every + unseen_weights(
                self.unseen, f, self.couplings, self.probe_shapes, rows), noise
        return self._weights[frame]


def any_drive_setup(rig: Rig, model: BroadbandModel, gauges: np.ndarray, probes: np.ndarray,
                    fs: float, source: str = "<run>", tare: np.ndarray | None = None,
                    tare_fs: float | None = None) -> AnyDriveSetup:
    """What the estimate under any drive needs before its first sample, from a record of the
    gauges and probes (the whole run in batch; the first seconds of a stream): every channel's
    noise from its spectrum above the band, the probes' weights and the first shape's
    coordinate map, the band models of the coordinate and of every reaction, the
    structure's transfer from the reactions-only force to the coordinate with the band model
    of what it leaves, the probes' misfit to the scan's operating shapes, the type-B moves
    and the gauges' and probes' hum.

    Parameters
    ----------
    rig : Rig
    model : BroadbandModel
    gauges : (n_gauges, N) array [N]
    probes : (n_probes, N) array [m]
    fs : float [Hz]
    source : str
        The run, named in messages.
    tare : (n_gauges + n_probes, n) array [N and m], optional
        A zero-current record's gauges, then its probes: with ``acquisition.mains``, each
        channel's hum tones (:func:`forcecal.signals.mains.hum_tones`).
    tare_fs : float, optional [Hz]
        Its sampling rate.

    Returns
    -------
    AnyDriveSetup

    Raises
    ------
    DataError
        A gauge or probe channel that is constant over the record: a dead sensor would take
        the weight of a noiseless one.
    """
    for name, x in zip((*rig.gauge_names, *rig.sensor_names), (*gauges, *probes), strict=True):
        if np.ptp(x) == 0:
            raise DataError(f"run '{source}': channel '{name}' is constant over "
                            f"{x.size / fs:.3g} s; a dead or disconnected sensor cannot follow "
                            "any drive")
    band = model.band
    var_s = channel_noise(probes, fs, band)
    var_g = channel_noise(gauges, fs, band)
    at_probes = rig.structure.coordinates(rig.sensor_points, source=f"rig '{rig.source}'")
    gam = model.values(at_probes).real
    basis = model.shapes[0].basis
    w = 1.0 / var_s
    g1 = gam[:, 0]
    var_q = 1.0 / float(g1 @ (w * g1))
    q_map = var_q * (g1 * w)
    q = q_map @ probes
    hum = rig.mains
    bm_q = band_model(fs, *_prior(q, fs, band, var_q, mains=hum), var_q)
    bm_r = tuple(band_model(fs, *_prior(gauges[r], fs, band, var_g[r], mains=hum), var_g[r])
                 for r in range(len(gauges)))
    pinv = np.linalg.pinv(force_matrix(rig))
    total_row = -np.ones(len(pinv)) @ pinv
    u = total_row @ gauges
    transfer = fit_reaction_transfer(q, u, fs, band, var_q, hum)
    bm_res = bm_q if transfer is None else _residual_model(q, u, transfer, fs, band, var_q,
                                                           hum)
    return AnyDriveSetup(band=band, fs=fs, probe_shapes=gam, probe_weights=w,
                         coordinate_map=q_map, var_q=var_q, coordinate_model=bm_q,
                         reaction_models=bm_r, var_g=var_g, couplings=model.couplings[:, 0],
                         pinv=pinv, transfer=transfer, residual_model=bm_res,
                         total_row=total_row,
                         basis_couplings=np.real(mass_coupling(rig, basis.evaluate)),
                         basis_probes=np.real(basis.evaluate(at_probes)),
                         unseen=probe_misfit(model, probes, fs, gam, model.stds(at_probes).real,
                                             w, q_map, rig.type_b.probe_scale, hum),
                         type_b=type_b_moves(rig, model),
                         hum=_channel_hum(rig, band, tare, tare_fs))


HUM_REACH = 4.0
"""The channels' hum tones are read up to this many times the band's top (at most 0.45 of the
tare's sampling rate): the smoothers let through a part of those beyond the band, and nothing
(their eighth-order fall, 4^-8) beyond."""


def _channel_hum(rig: Rig, band: tuple[float, float], tare: np.ndarray | None,
                 tare_fs: float | None) -> tuple[tuple[int, float, float], ...]:
    """Every channel's hum tones, from the zero-current record's gauges and probes (none
    without ``acquisition.mains`` or a tare), up to ``HUM_REACH`` times the band's top."""
    if rig.mains is None or tare is None or tare_fs is None:
        return ()
    tones, power = hum_tones(tare, tare_fs, rig.mains, min(0.45 * tare_fs, HUM_REACH * band[1]))
    return tuple((r, float(f), float(power[r, m])) for r in range(len(tare))
                 for m, f in enumerate(tones))


def _residual_model(q: np.ndarray, u: np.ndarray, transfer: ReactionTransfer, fs: float,
                    band: tuple[float, float], var_q: float, mains: float | None) -> BandModel:
    """The band model of what the reactions' transfer leaves of the first shape's coordinate,
    q_1 - G u: the probes' part of the inertia, smoothed up to where it rises above their
    noise."""
    rest = q - filtered(u[None, :], fs, transfer.response)[0]
    return band_model(fs, *_prior(rest, fs, band, var_q, RESIDUAL_MARGIN, band[0], mains),
                      var_q)


def with_reaction_priors(setup: AnyDriveSetup, gauges: np.ndarray, probes: np.ndarray,
                         mains: float | None = None) -> AnyDriveSetup:
    """``setup`` with every gauge's band model set from ``gauges`` (n_gauges, N) [N], their
    noise kept, and the probes' part of the inertia's from the same stretch with ``probes``
    (n_probes, N) [m]: a stream's smoothers follow its drive. A sweep's first seconds hold only
    its bottom: smoothers set there, at 170 Hz where the whole run's were at 182 Hz, put the
    stream 1.3 of the batch's uncertainty off at the sweep's top, 140-150 Hz; and a transfer
    fitted there misses a mode the sweep reaches later (the ``dwell`` preset) until the stream
    fits it again (:mod:`forcecal.realtime.transfer_refits`): the probes' part takes what it
    misses, its band set from what the transfer leaves in the stretch."""
    fs, band = setup.fs, setup.band
    models = tuple(band_model(fs, *_prior(g, fs, band, v, mains=mains), v)
                   for g, v in zip(gauges, setup.var_g, strict=True))
    if setup.transfer is None:
        return dataclasses.replace(setup, reaction_models=models)
    residual = _residual_model(setup.coordinate_map @ probes, setup.total_row @ gauges,
                               setup.transfer, fs, band, setup.var_q, mains)
    return dataclasses.replace(setup, reaction_models=models, residual_model=residual)

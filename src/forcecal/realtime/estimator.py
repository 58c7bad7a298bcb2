"""Forces in real time: the streaming estimator (METHOD.md section 3, step 7).

:class:`StreamEstimator` runs the recursive least-squares kernel of :mod:`forcecal.realtime.rls`
on every channel; its readout from the tracked phasors to the forces is built from the same
formulas as the batch estimate (:func:`forcecal.forces.coordinates.coordinate_map`,
:func:`forcecal.model.inertia.inertia_term`, :func:`forcecal.forces.solve.force_solve`,
:func:`forcecal.forces.steady.kept_harmonics`). The exponential window sets the latency, the
settling and the noise; a phase-locked loop on the current's fundamental follows a drifting
drive; with a model built from several scans the probes choose each harmonic's members as the
batch estimate does. The class's notes tell all three.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import replace
from functools import lru_cache

import numpy as np

from ..errors import DataError, DimensionError, InputError
from ..forces.coordinates import check_sensor_gain, choose_members, coordinate_map, member_fit
from ..forces.solve import force_solve, reactions_only
from ..forces.steady import FREQUENCY_MISMATCH, kept_harmonics, significant_reactions
from ..model.inertia import inertia_term
from ..model.relaxation import force_matrix
from ..model.spatial import SpatialModel, check_model_rig
from ..rig import Rig
from .rls import (
    PRIOR,
    HarmonicState,
    chunk_limit,
    harmonic_start,
    kernel,
    last_coefficients,
    mixing,
    stationary,
    to_complex,
    to_real,
    window_tables,
)

__all__ = ["StreamEstimator"]

DEFAULT_MEMORY_PERIODS = 2.0
"""Default memory 1 / (1 - lambda) of the forgetting, in drive periods."""
LOOP_MEMORIES = 1.5
"""The frequency loop's time constant, in memories 1 / ((1 - lambda) fs) of the forgetting."""
LOOP_DAMPING = 0.7
"""Damping ratio of the frequency loop."""
LOOP_MAX_STEP = 1.0 / 3.0
"""Largest loop bandwidth [rad/s] times the loop's update interval (stability of the
discrete loop when the memory is short)."""
ENGAGE_MEMORIES = 1.0
ENGAGE_PERIODS = 2.0
"""The frequency loop starts after this many memories and drive periods, whichever is later."""
LOCK_SNR = 5.0
"""The frequency loop acts only while |X_1| of the current exceeds this many noise stds."""
FREQUENCY_RANGE = 0.05
"""The tracked frequency stays within this relative distance of the initial guess."""
SPAN_SWITCH = 2.0
"""Lowering of the information criterion (AIC units) that makes the readout change the set of
a harmonic's shapes it uses."""


# --------------------------------------------------------------------------------------------
# the stateful estimator


def _settings(model: SpatialModel, f0_guess: float, fs: float, n_harmonics: int | None,
              forgetting: float | None) -> tuple[int, float]:
    """The number of harmonics H and the forgetting factor lambda, checked."""
    if not (fs > 0 and f0_guess > 0):
        raise InputError(f"stream: fs and f0_guess must be positive; got fs = {fs} Hz, "
                         f"f0_guess = {f0_guess} Hz")
    h = int(n_harmonics or len(model.snr))
    if h < 1:
        raise InputError(f"stream: n_harmonics must be >= 1; got {h}")
    if h * f0_guess * (1 + FREQUENCY_RANGE) >= 0.5 * fs:
        raise DataError(f"stream: harmonic {h} of {f0_guess:.6g} Hz is not below the "
                        f"Nyquist frequency {0.5 * fs:.6g} Hz of fs = {fs:.6g} Hz; "
                        "reduce n_harmonics")
    lam = 1.0 - f0_guess / (fs * DEFAULT_MEMORY_PERIODS) if forgetting is None \
        else float(forgetting)
    if not 0.0 < lam < 1.0:
        raise InputError(f"stream: the forgetting factor must lie in (0, 1); got {lam}")
    if 1.0 / (1.0 - lam) < 2 * (2 * h + 1):
        raise InputError(f"stream: forgetting {lam} keeps a memory of "
                         f"{1 / (1 - lam):.3g} samples, less than twice the "
                         f"{2 * h + 1} regressors of {h} harmonics")
    return h, lam


@lru_cache(maxsize=8)
def _decay(lam: float, m: int, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The factors of the noise tracking's scaled cumulative sum over a piece of ``m``
    samples whose last ``n`` have a second difference: lam^-i and lam^(i+1) (i = 0..m-1), and
    the cumulative sum of lam^-i over those ``n`` (the same for every piece of that length)."""
    ages = np.arange(m, dtype=float)
    grow = np.exp(-ages * math.log(lam))
    ones = np.zeros(m)
    ones[m - n:] = 1.0
    shrink = np.exp((ages + 1.0) * math.log(lam))
    counted = np.cumsum(ones * grow)
    for a in (grow, shrink, counted):
        a.setflags(write=False)
    return grow, shrink, counted


class StreamEstimator:
    """Forces of a live acquisition, one block of samples after another.

    Parameters
    ----------
    rig : Rig
        The rig (channel names and scales, gauges, force points, probes).
    model : SpatialModel
        The spatial model from the scan (shapes and mass couplings).
    f0_guess, fs : float [Hz]
        The drive frequency to start from (tracked from then on); the sampling rate.
    n_harmonics : int, optional
        H: harmonics 0..H are tracked (default: as many as the scan was fitted with).
    forgetting : float, optional
        lambda (default 1 - f0 / (2 fs): a memory of ``DEFAULT_MEMORY_PERIODS`` periods).
    t0 : float [s]
        Absolute time of the first sample (phasors then follow the batch convention).
    track_frequency : bool
        Follow a drift of the drive frequency (phase-locked to the current).
    sensor_std : (n_sensors,) array [m], optional
        Noise of each probe, the weights of the Q_n fit (default: equal).
    tare_dc : (n_gauges,) array [N], optional
        Gauge DC of a zero-current record, subtracted.
    ac_coupled : bool
        The gauges do not measure DC: no DC force; the static estimate is AC only.
    extra_harmonics : sequence of int
        Harmonics without a shape that enter the force from the start (reactions only); the
        others join once the reactions show them above their noise over the window
        (:func:`forcecal.forces.steady.kept_harmonics`, checked once per drive period).

    Notes
    -----
    Channel order of an array block: :attr:`channel_names` (gauges, probes, current), raw
    values as recorded (the rig's scales are applied here).

    The state is of fixed size (:class:`HarmonicState` plus the frequency loop's scalars), so
    memory does not grow with the number of blocks; per-frequency tables and inverses are
    kept in small bounded caches. The probes' weights are fixed (``sensor_std``), where the
    batch estimate takes them from each probe's fit residual; with probes of equal noise the
    two agree.

    *Latency and noise.* The exponential window has memory 1 / (1 - lambda) samples and mean
    age (group delay) lambda / (1 - lambda) samples (:attr:`latency_periods`, in drive
    periods; the default memory is ``DEFAULT_MEMORY_PERIODS`` periods). A step settles to a
    fraction eps of its size within ln(eps) / ln(lambda) samples (:meth:`settling_periods`).
    For white noise of std sigma each phasor has var(Re) = var(Im) ~ (1 - lambda) /
    (1 + lambda) 2 sigma^2, the batch fit's 2 sigma^2 / N with N -> (1 + lambda) /
    (1 - lambda); the exact value for the forces is :meth:`noise_std`.

    *Frequency tracking.* The regressor's phase advances by w / fs per sample. Once per grid
    step (one period) the phase of the current's fundamental phasor X_1 (referred to theta) is
    read; a drive faster than w makes it rotate at (w_true - w). Since the window's phase lags
    by its mean age, the loop adds that lead (the last advance times lambda / (1 - lambda) /
    grid) and feeds a proportional-integral correction of w (a type-2 phase-locked loop: no
    steady frequency error even along a linear drift) of bandwidth
    min(1 / (``LOOP_MEMORIES`` memory), ``LOOP_MAX_STEP`` / period) and damping
    ``LOOP_DAMPING``. The loop starts after one memory and two periods, stays within
    ``FREQUENCY_RANGE`` of the guess, and holds while |X_1| is below ``LOCK_SNR`` times its
    noise (no drive, a tare record). Changing w changes M_k and the readout with it: the
    estimate is then the RLS estimate with the window's regressors taken at the current
    frequency.

    *Several shapes per harmonic.* With a model built from several scans
    (:mod:`forcecal.model.spatial`) each harmonic's readout starts on its first shape; once
    the window is engaged, every grid step the probes' phasors choose the members of the span
    as the batch estimate does (:func:`forcecal.forces.coordinates.choose_members`), and the
    readout switches when another set's information criterion is lower by more than
    ``SPAN_SWITCH`` (no flicker between two sets that explain the probes equally well).
    """

    def __init__(self, rig: Rig, model: SpatialModel, f0_guess: float, fs: float, *,
                 n_harmonics: int | None = None, forgetting: float | None = None,
                 t0: float = 0.0, track_frequency: bool = True,
                 sensor_std: Sequence[float] | np.ndarray | None = None,
                 tare_dc: Sequence[float] | np.ndarray | None = None, ac_coupled: bool = False,
                 extra_harmonics: Sequence[int] = ()) -> None:
        h, lam = _settings(model, f0_guess, fs, n_harmonics, forgetting)
        check_model_rig(model, rig)
        if abs(f0_guess / model.f0 - 1.0) > FREQUENCY_MISMATCH:
            warnings.warn(f"stream: drive at {f0_guess:.4g} Hz but the scan model was measured "
                          f"at {model.f0:.4g} Hz; its shapes may not apply", stacklevel=2)
        self.rig = rig
        self.model = model
        self.fs = float(fs)
        self.lam = lam
        self.prior = PRIOR
        self.n_harmonics = h
        self.f0_guess = float(f0_guess)
        self.track_frequency = bool(track_frequency)
        self.ac_coupled = bool(ac_coupled)
        self.channel_names: tuple[str, ...] = (*rig.gauge_names, *rig.sensor_names,
                                               rig.actuator.current)
        self.force_names: tuple[str, ...] = tuple(rig.force_names)
        self._scale = np.array([g.scale for g in rig.gauges] + [s.scale for s in rig.sensors]
                               + [rig.actuator.current_scale])[:, None]
        self._n_g, self._n_s = len(rig.gauges), len(rig.sensors)
        self._pinv = np.linalg.pinv(force_matrix(rig))                   # (n_f, n_g)
        n_f = self._pinv.shape[0]
        self._n_f = n_f
        tare = np.zeros(self._n_g) if tare_dc is None else np.asarray(tare_dc, dtype=float)
        if tare.shape != (self._n_g,):
            raise DimensionError(f"stream: tare_dc has shape {tare.shape}; expected "
                                 f"({self._n_g},), one DC per gauge")
        self._offset = (self._pinv @ tare)[:, None]
        self._shaped = self._shape_terms(sensor_std)
        extra = np.zeros(h + 1, dtype=bool)
        extra[[int(n) for n in extra_harmonics if 1 <= int(n) <= h]] = True
        self._kept = kept_harmonics(h, [n for n, _, _ in self._shaped], extra,
                                    dc=not ac_coupled)[1]
        self._force_harmonics = [int(n) for n in np.flatnonzero(self._kept)]
        self._loop_settings()
        self._tail: np.ndarray | None = None
        self.last_std = np.empty((self._n_f + 1, 0))
        self._d2_energy = np.zeros(len(self.channel_names))
        self._d2_weight = 0.0
        self._state = harmonic_start(len(self.channel_names), h, f0_guess, fs, t0)
        self._t0 = float(t0)
        self._retune()

    def _track_noise(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Follow every channel's white-noise variance over the window from its second
        differences (which remove the slow harmonics: var(d2) = 6 sigma^2 for white noise),
        exponentially weighted like the phasors, independent of the frequency loop.

        Returns the weighted energy (n_channels, m) and weight (m,) after each sample of ``y``
        (the same whatever the blocks the record arrives in)."""
        z = y if self._tail is None else np.concatenate([self._tail, y], axis=1)
        self._tail = z[:, -2:]
        d2 = z[:, 2:] - 2.0 * z[:, 1:-1] + z[:, :-2]
        m, n = y.shape[1], d2.shape[1]                # d2[:, i] ends at sample m - n + i
        # E_j = lam^(j+1) E_prev + sum_{i <= j} lam^(j - i) d2_i^2, as a scaled cumulative sum
        # (pieces are at most chunk_limit(lam) samples: lam^-m stays finite)
        grow, shrink, counted = _decay(self.lam, m, n)
        if n == m:
            sq = d2 * d2
        else:
            sq = np.zeros((y.shape[0], m))
            sq[:, m - n:] = d2 * d2
        energy = shrink * (self._d2_energy[:, None] + np.cumsum(sq * grow, axis=1))
        weight = shrink * (self._d2_weight + counted)
        if m:
            self._d2_energy, self._d2_weight = energy[:, -1].copy(), float(weight[-1])
        return energy, weight

    @property
    def noise_level(self) -> np.ndarray:
        """(n_channels,) [SI] white-noise std of every channel over the window, from its
        second differences (NaN before two samples)."""
        if self._d2_weight <= 0:
            return np.full(len(self.channel_names), np.nan)
        level: np.ndarray = np.sqrt(self._d2_energy / self._d2_weight / 6.0)
        return level

    def _update_kept(self) -> None:
        """Add the harmonics without a shape that the reactions now show above their noise:
        the batch estimate's policy (:func:`forcecal.forces.steady.kept_harmonics`) applied to the
        window. A harmonic once kept stays kept (no flicker at the threshold)."""
        h, n_g = self.n_harmonics, self._n_g
        cov = np.diag(stationary(self.lam, self._state.step, h)[2])
        per_phasor = np.sqrt(np.concatenate([[cov[0]], 0.5 * (cov[1::2] + cov[2::2])]))
        std = self.noise_level[:n_g, None] * per_phasor[None, :]
        significant = significant_reactions(self.phasors[:n_g], std)
        significant[self._kept] = True
        kept = kept_harmonics(h, [n for n, _, _ in self._shaped], significant,
                              dc=not self.ac_coupled)[1]
        if np.array_equal(kept, self._kept):
            return
        self._kept = kept
        self._force_harmonics = [int(n) for n in np.flatnonzero(kept)]
        self._retune()

    def _loop_settings(self) -> None:
        """The frequency loop's grid, gains and start (see the class's notes)."""
        lam, fs = self.lam, self.fs
        self.grid = max(1, round(fs / self.f0_guess))
        self._piece = min(self.grid, chunk_limit(lam))
        memory_s = 1.0 / ((1.0 - lam) * fs)
        w_loop = min(1.0 / (LOOP_MEMORIES * memory_s), LOOP_MAX_STEP * fs / self.grid)
        self._kp, self._ki = 2.0 * LOOP_DAMPING * w_loop, w_loop**2
        # the window's phase lags by its mean age lam / (1 - lam) samples: the loop adds that
        # lead (in grid steps) to act on the phase of the latest sample
        self._lead = lam / (1.0 - lam) / self.grid
        # the loop starts once the window is well conditioned (spans whole periods)
        self._engage = math.ceil(max(ENGAGE_MEMORIES / (1.0 - lam),
                                     ENGAGE_PERIODS * fs / self.f0_guess))
        self._loop_phase: float | None = None
        self._loop_x1 = 0j
        self._loop_integral = 0.0
        self._warned = False

    def _retune(self) -> None:
        """Readout, mixing and per-sample tables for the state's frequency."""
        step = self._state.step
        self._readout = self._force_readout(2 * np.pi * step * self.fs)
        self._kappa = mixing(self._readout, self.lam, step, self.n_harmonics)
        self._var_rows: np.ndarray | None = None      # _piece_std's, for this readout

    # ------------------------------------------------------------------ set-up

    def _shape_terms(self, sensor_std: Sequence[float] | np.ndarray | None
                     ) -> list[tuple[int, np.ndarray, np.ndarray]]:
        """[(n, m_n, G_n)]: every shaped harmonic's mass couplings (n_g, n_q) of the members
        of its span in use (the first at the start) and the map G_n (n_q, n_s) from the probes'
        phasors to their coordinates Q_n = G_n S_n."""
        rig, model = self.rig, self.model
        if sensor_std is None:
            weight = np.ones(self._n_s)
        else:
            std = np.asarray(sensor_std, dtype=float)
            if std.shape != (self._n_s,) or np.any(std <= 0):
                raise InputError(f"stream: sensor_std must hold {self._n_s} positive values; "
                                 f"got {std}")
            weight = 1.0 / std**2
        self._weight = weight
        self._at_sensors = rig.structure.coordinates(rig.sensor_points)
        self._members: dict[int, tuple[int, ...]] = {}
        terms = []
        for k, n in enumerate(model.harmonics):
            n = int(n)
            if n > self.n_harmonics:
                continue
            check_sensor_gain(model, rig, n, "stream")
            terms.append(self._shape_term(k, (0,)))
        return terms

    def _shape_term(self, k: int, members: tuple[int, ...]
                    ) -> tuple[int, np.ndarray, np.ndarray]:
        """(n, m_n, G_n) of harmonic k on the given members of its span."""
        n = int(self.model.harmonics[k])
        self._members[n] = members
        phi = self.model.member_values(k, self._at_sensors)[:, list(members)]
        gain, _ = coordinate_map(phi, self._weight)
        return n, self.model.member_couplings(k)[:, list(members)], np.atleast_2d(gain)

    def _update_span(self) -> None:
        """Let the probes' phasors choose each harmonic's members (several scans only)."""
        model = self.model
        if not model.span:
            return
        n_g, n_s = self._n_g, self._n_s
        cov = np.diag(stationary(self.lam, self._state.step, self.n_harmonics)[2])
        per_phasor = np.sqrt(0.5 * (cov[1::2] + cov[2::2]))
        std = self.noise_level[n_g:n_g + n_s, None] * per_phasor[None, :]      # (n_s, H)
        phasors = self.phasors[n_g:n_g + n_s]
        changed = False
        for i, (n, _, _) in enumerate(self._shaped):
            k = model.index(n)
            if len(model.members(k)) < 2 or not np.all(std[:, n - 1] > 0):
                continue
            w = 1.0 / std[:, n - 1] ** 2
            phi = model.member_values(k, self._at_sensors)
            phi_std = model.member_std(k, self._at_sensors)
            scale = self.rig.type_b.probe_scale
            best = choose_members(phi, phi_std, phasors[:, n], w, scale_std=scale)
            now = self._members[n]
            if best.members == now:
                continue
            current = member_fit(phi, phi_std, phasors[:, n], w, now, check=False,
                                 scale_std=scale)
            if current is None or best.aic < current.aic - SPAN_SWITCH:
                self._shaped[i] = self._shape_term(k, best.members)
                changed = True
        if changed:
            self._retune()

    @property
    def members(self) -> dict[int, tuple[int, ...]]:
        """The members of each shaped harmonic's span the readout uses now."""
        return dict(self._members)

    def _force_readout(self, w: float) -> np.ndarray:
        """(n_out, n_channels, p) readout of the forces (and, AC-coupled, of the static DC):
        the force solve F_n = Psi^+ (J_n - R_n) as a linear map of the channels' phasors, with
        J_n = m_n Qdd_n and Q_n = G_n S_n."""
        n_f, n_g, n_s = self._n_f, self._n_g, self._n_s
        n_out = 2 * n_f if self.ac_coupled else n_f
        c = np.zeros((n_out, len(self.channel_names), 2 * self.n_harmonics + 1))
        from_reactions = reactions_only(self._pinv, np.eye(n_g))
        for n in self._force_harmonics:
            c[:n_f, :n_g, 0 if n == 0 else 2 * n - 1] = from_reactions
        for n, couplings, gain in self._shaped:
            a = force_solve(self._pinv, inertia_term(couplings, gain, n * w),
                            np.zeros((n_g, n_s)))
            c[:n_f, n_g:n_g + n_s, 2 * n - 1] = a.real
            c[:n_f, n_g:n_g + n_s, 2 * n] = -a.imag
        if self.ac_coupled:
            c[n_f:, :n_g, 0] = from_reactions
        return c

    # ------------------------------------------------------------------ properties

    @property
    def state(self) -> HarmonicState:
        """The current :class:`HarmonicState` (read only; fixed size)."""
        return self._state

    @property
    def kept(self) -> np.ndarray:
        """(H+1,) bool: the harmonics that enter the forces now."""
        return self._kept.copy()

    @property
    def frequency(self) -> float:
        """[Hz] the tracked drive frequency."""
        return self._state.step * self.fs

    @property
    def memory(self) -> float:
        """[samples] memory 1 / (1 - lambda) of the forgetting."""
        return 1.0 / (1.0 - self.lam)

    @property
    def latency_periods(self) -> float:
        """Group delay lambda / (1 - lambda) samples of the estimate, in drive periods."""
        return self.lam / (1.0 - self.lam) * self._state.step

    def settling_periods(self, fraction: float = 1e-3) -> float:
        """Drive periods after which a step has settled to ``fraction`` of its size."""
        return math.log(fraction) / math.log(self.lam) * self._state.step

    @property
    def phasors(self) -> np.ndarray:
        """(n_channels, H+1) complex [SI] phasors of the last sample, referred to the tracked
        phase (the batch convention while the frequency has not moved)."""
        u = last_coefficients(self._state, self.lam, self.prior)
        rot = np.exp(-2j * np.pi * self._state.phase * np.arange(self.n_harmonics + 1))
        return to_complex(u[..., None])[..., 0] * rot

    def force_phasors(self, phasors: np.ndarray) -> np.ndarray:
        """The force phasors that the readout assigns to given channel phasors: the linear map
        the estimator applies at every sample, F_n = Psi^+ (J_n - R_n) with J_n from the probes.

        Parameters
        ----------
        phasors : (n_channels, H+1) complex ndarray
            [SI] phasors of every channel in the order of :attr:`channel_names`, after the
            rig's scales.

        Returns
        -------
        (n_forces, H+1) complex ndarray
            [N]
        """
        c = self._readout[:self._n_f]                              # (n_f, n_ch, p)
        gain = np.empty((*c.shape[:2], self.n_harmonics + 1), dtype=complex)
        gain[..., 0] = c[..., 0]
        gain[..., 1:] = c[..., 1::2] - 1j * c[..., 2::2]
        forces: np.ndarray = np.einsum("fcn,cn->fn", gain, phasors)
        return forces

    def noise_std(self, channel_std: Sequence[float] | np.ndarray) -> np.ndarray:
        """(n_forces,) [N] steady-state std of each force estimate for white noise.

        Parameters
        ----------
        channel_std : (n_channels,) [SI] noise std of each channel (:attr:`noise_level`)
        """
        sigma = np.asarray(channel_std, dtype=float)
        cov = stationary(self.lam, self._state.step, self.n_harmonics)[2]
        k = self._readout[:self._n_f]                                    # (n_f, n_ch, p)
        var = np.einsum("fcp,pq,fcq->fc", k, cov, k)
        return np.sqrt(var @ sigma**2)

    def _piece_std(self, y: np.ndarray, energy: np.ndarray, weight: np.ndarray,
                   count0: int) -> np.ndarray:
        """(n_forces + 1, m) [N]: the white-noise standard uncertainty of each force and of
        their total at each sample of a piece, with the readout in effect over it.

        The stationary value (as :meth:`noise_std`, from the channels' noise level at that
        sample; the total through the summed readout, so the forces' correlation counts),
        scaled up while the window fills as an exponentially weighted mean's is: its variance
        after k samples is (1 + lambda^k) / (1 - lambda^k) times its stationary one. Before a
        channel's noise can be measured (its first two samples) its own size stands for it."""
        sigma2 = np.divide(energy, 6.0 * weight, out=y * y, where=weight > 0)
        if self._var_rows is None:        # (n_f + 1, n_ch): per unit variance of each channel
            cov = stationary(self.lam, self._state.step, self.n_harmonics)[2]
            k = self._readout[:self._n_f]                                # (n_f, n_ch, p)
            rows = np.concatenate([k, k.sum(axis=0, keepdims=True)])
            self._var_rows = np.einsum("fcp,pq,fcq->fc", rows, cov, rows)
        var = self._var_rows @ sigma2                                    # (n_f + 1, m)
        counts = count0 + 1.0 + np.arange(energy.shape[1])
        power = np.exp(counts * math.log(self.lam))
        std: np.ndarray = np.sqrt(var * ((1.0 + power) / (1.0 - power)))
        return std

    # ------------------------------------------------------------------ streaming

    def _samples(self, block: Mapping[str, np.ndarray] | np.ndarray) -> np.ndarray:
        if isinstance(block, Mapping):
            missing = [n for n in self.channel_names if n not in block]
            if missing:
                raise DataError(f"stream: channel '{missing[0]}' named in the rig is missing "
                                f"from the block (found: {', '.join(sorted(block))})")
            rows = [np.asarray(block[n], dtype=float).ravel() for n in self.channel_names]
            lengths = {len(r) for r in rows}
            if len(lengths) != 1:
                raise DimensionError("stream: the channels of a block differ in length: "
                                     + ", ".join(f"{n} {len(r)}" for n, r in
                                                 zip(self.channel_names, rows, strict=True)))
            y = np.stack(rows)
        else:
            y = np.asarray(block, dtype=float)
            if y.shape == (len(self.channel_names),):                 # a single sample
                y = y[:, None]
            if y.ndim != 2 or y.shape[0] != len(self.channel_names):
                raise DimensionError(f"stream: a block must be ({len(self.channel_names)}, n) "
                                     f"for channels {', '.join(self.channel_names)}; got shape "
                                     f"{y.shape}")
        if not np.isfinite(y).all():
            bad = ~np.isfinite(y)
            row, col = np.argwhere(bad)[0]
            t = self._t0 + (self._state.count + col) / self.fs
            raise DataError(f"stream: channel '{self.channel_names[row]}' has "
                            f"{int(bad[row].sum())} NaN or infinite samples in this block, "
                            f"the first at t={t:.6g} s")
        return y * self._scale

    def process(self, block: Mapping[str, np.ndarray] | np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
        """Forces of every sample of a block.

        Parameters
        ----------
        block : {channel name: (n,) raw samples} or (n_channels, n) raw samples in the order
            of :attr:`channel_names` ((n_channels,) for a single sample)

        Returns
        -------
        force : (n_forces, n) [N] sum_n Re(F_n(k) exp(j n theta_k)) with the phasors of each
            sample (inertia compensated)
        static : (n_forces, n) [N] the reactions-only estimate -Psi^+ R(t_k), sample by sample

        The white-noise standard uncertainty of every sample's forces and of their total
        follows in :attr:`last_std`, (n_forces + 1, n) [N].
        """
        y = self._samples(block)
        n = y.shape[1]
        out = np.empty((self._readout.shape[0], n))
        self.last_std = np.empty((self._n_f + 1, n))
        pos = 0
        while pos < n:
            stop = min(n, pos + self.grid - self._state.count % self.grid, pos + self._piece)
            # tables as long as the piece (rounded up to a power of two), cached per frequency
            length = min(self._piece, 1 << (stop - pos - 1).bit_length())
            tables = window_tables(self.lam, self._state.step, self.n_harmonics, length)
            energy, weight = self._track_noise(y[:, pos:stop])
            self.last_std[:, pos:stop] = self._piece_std(y[:, pos:stop], energy, weight,
                                                         self._state.count)
            self._state, out[:, pos:stop] = kernel(
                self._state, y[:, pos:stop], self.lam, tables, self._readout, self._kappa,
                self.prior)
            pos = stop
            if self._state.count % self.grid == 0:
                self._on_grid()
        force = out[:self._n_f]
        static = reactions_only(self._pinv, y[:self._n_g])
        if self.ac_coupled:
            static -= out[self._n_f:]
        else:
            force += self._offset
            static += self._offset
        return force, static

    def _on_grid(self) -> None:
        """Once per grid step: the harmonics kept, then the frequency loop."""
        st = self._state
        if st.count < self._engage:
            return
        self._update_kept()
        self._update_span()
        if not self.track_frequency:
            return
        ic = len(self.channel_names) - 1
        u = last_coefficients(replace(st, demod=st.demod[ic:], energy=st.energy[ic:]),
                               self.lam, self.prior)[0]
        x1 = complex(u[1], u[2]) * np.exp(-2j * np.pi * st.phase)
        # lock: |X_1| against its noise, from the current's residual over the window
        rot = np.exp(-2j * np.pi * st.phase * np.arange(self.n_harmonics + 1))
        beta = to_real((st.demod[ic] * rot.conj())[:, None])[:, 0]
        weight = (1.0 - self.lam**st.count) / (1.0 - self.lam)
        dof = max(weight - u.size, 1.0)
        var = max(st.energy[ic] - beta @ u, 0.0) / dof
        cov = stationary(self.lam, st.step, self.n_harmonics)[2]
        if abs(x1) <= LOCK_SNR * math.sqrt(var * 0.5 * (cov[1, 1] + cov[2, 2])):
            self._loop_phase = None                                   # hold; re-engage later
            return
        w0 = 2 * np.pi * self.f0_guess
        if self._loop_phase is None:                  # (re)start from the present frequency
            self._loop_phase, self._loop_x1 = 0.0, x1
            self._loop_integral = 2 * np.pi * st.step * self.fs - w0
            return
        advance = float(np.angle(x1 * np.conj(self._loop_x1)))
        self._loop_phase += advance
        self._loop_x1 = x1
        error = self._loop_phase + self._lead * advance
        dt = self.grid / self.fs
        self._loop_integral += self._ki * error * dt
        w = w0 + self._kp * error + self._loop_integral
        bounded = min(max(w, w0 * (1 - FREQUENCY_RANGE)), w0 * (1 + FREQUENCY_RANGE))
        if bounded != w:                                              # no wind-up
            self._loop_integral += bounded - w
            w = bounded
        self._state = replace(st, step=w / (2 * np.pi * self.fs))
        self._retune()
        if not self._warned and abs(self.frequency / self.model.f0 - 1) > FREQUENCY_MISMATCH:
            self._warned = True
            warnings.warn(f"stream: the drive moved to {self.frequency:.4g} Hz but the scan "
                          f"model was measured at {self.model.f0:.4g} Hz; its shapes may not "
                          "apply", stacklevel=3)

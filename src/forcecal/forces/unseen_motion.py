"""What the probes see that the scan's operating shapes do not (METHOD.md section 7, "any drive").

Under any drive the inertia rests on one coordinate, the first shape's, corrected frequency by
frequency to the operating shape of the broadband scan (:mod:`forcecal.forces.transient`). That
holds while the run keeps the scan's load pattern. Forces that do not keep their ratio (a
second actuator, a gap ratio changed since the scan) deflect the structure in shapes the scan
never saw, and so does a probe whose sign, scale or position is wrong: the reactions then split
between the forces by an inertia nobody measured, while their total stays right.

The probes tell (:func:`probe_misfit`). At every frequency of the band their spectra should lie
on the operating shape at the probes, p(nu) = G a(nu). Over the record's Hann segments (half
overlapping) each segment's probes are fitted on p by weighted least squares, and the
residual's reduced chi-square per line, against the probes' noise and the operating shape's own
uncertainty at the probes, is averaged over the lines where the probes stand clear of their
noise (``LIVE_SNR``). Above ``MISFIT_LIMIT`` the run is noted (:func:`unseen_notes`), and every
force's stated uncertainty takes a bound on the inertia of the unseen motion
(:func:`unseen_weights`): its deflection at the probes per unit of the first coordinate, times
the first shape's mass coupling per unit deflection at the probes, through each force's row of
Psi^+ at its full length (the worst direction). The unseen shape's own coupling is unknown, so
the bound is wide.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.broadband import BroadbandModel
from ..signals.mains import near_mains

__all__ = ["unseen_notes"]

MISFIT_LIMIT = 4.0
"""The probes' reduced chi-square off the operating shapes above which the run is noted and
the unseen motion's inertia enters the uncertainty: twice the noise in amplitude (over hundreds
of lines the statistic of a run that fits scatters by a few hundredths)."""
LIVE_SNR = 10.0
"""A line counts where the probes' power over the segments stands this many times above their
noise's."""
SMOOTH_LINES = 9
"""Lines over which each line's chi-square is averaged before its excess is taken."""


@dataclass(frozen=True)
class UnseenMotion:
    """The probes' misfit to the scan's operating shapes over a record.

    Attributes
    ----------
    chi2 : float
        Reduced chi-square per line, averaged over the live lines.
    lines : int
        The live lines.
    frequencies : (n_live,) array [Hz]
    deflection : (n_live,) array [m per unit coordinate]
        The unseen motion's RMS deflection at the probes per unit of the first shape's
        coordinate (what noise and the shape's uncertainty do not explain; zero where they
        do).
    """

    chi2: float
    lines: int
    frequencies: np.ndarray
    deflection: np.ndarray

    @property
    def found(self) -> bool:
        """True where the probes contradict the operating shapes."""
        return self.chi2 > MISFIT_LIMIT


def probe_misfit(model: BroadbandModel, probes: np.ndarray, fs: float, probe_shapes: np.ndarray,
                 probe_stds: np.ndarray, weights: np.ndarray, coordinate_map: np.ndarray,
                 probe_scale: float = 0.0, mains: float | None = None) -> UnseenMotion | None:
    """The probes' misfit to the operating shapes of ``model`` over a record.

    Parameters
    ----------
    model : BroadbandModel
    probes : (n_probes, N) array [m]
    fs : float [Hz]
    probe_shapes : (n_probes, n_shapes) array [m]
        The span's shapes at the probes (G).
    probe_stds : (n_probes, n_shapes) array [m]
        Their standard uncertainties.
    weights : (n_probes,) array [1/m^2]
        The probes' inverse noise variances per sample.
    coordinate_map : (n_probes,) array [1/m]
        q_1 = coordinate_map @ probes.
    probe_scale : float
        The probes' declared relative standard uncertainty of sensitivity (a probe off by it
        is the type-B budget's, not an unseen motion).
    mains : float, optional [Hz]
        The mains: the lines of its harmonics hold hum, and are left out.

    Returns
    -------
    UnseenMotion or None
        None with a single probe (nothing to check against) or no live line.
    """
    import scipy.ndimage  # on use: a steady stream starts without it
    import scipy.signal

    n_p, n = probes.shape
    if n_p < 2:
        return None
    seg = int(min(n, max(256, 2 ** int(np.log2(fs / 2)))))
    win = scipy.signal.get_window("hann", seg)
    frames = np.lib.stride_tricks.sliding_window_view(probes, seg, axis=-1)[:, ::seg // 2]
    spec = np.fft.rfft((frames - frames.mean(axis=-1, keepdims=True)) * win, axis=-1)
    f = np.fft.rfftfreq(seg, 1.0 / fs)                               # spec: (n_p, n_seg, n_f)
    inside = ((f >= model.band[0]) & (f <= model.band[1]) & (f > 0)
              & ~near_mains(f, mains, 2.0 * f[1]))
    f, spec = f[inside], spec[..., inside]
    mix = model.mixing(f)
    p = probe_shapes @ mix                                          # (n_p, n_f)
    norm = np.sum(weights[:, None] * np.abs(p) ** 2, axis=0)
    seen = norm > 0                            # a line whose shape the probes do not see: out
    f, spec, mix, p, norm = f[seen], spec[..., seen], mix[:, seen], p[:, seen], norm[seen]
    c = np.einsum("jf,j,jsf->sf", np.conj(p), weights, spec) / norm  # (n_seg, n_f)
    resid = spec - p[:, None, :] * c[None]
    power = np.sum(win**2)
    shape_var = (probe_shapes**2 @ (2 * model.mixing_std(f) ** 2)
                 + probe_stds**2 @ np.abs(mix) ** 2
                 + probe_scale**2 * np.abs(p) ** 2)                 # E|dp_j|^2, (n_p, n_f)
    expected = power / weights[:, None] + shape_var * np.mean(np.abs(c) ** 2, axis=0)
    chi2 = np.sum(np.mean(np.abs(resid) ** 2, axis=1) / expected, axis=0) / (n_p - 1)
    snr = np.sum(weights[:, None] * np.mean(np.abs(spec) ** 2, axis=1), axis=0) / (n_p * power)
    live = snr > LIVE_SNR
    if not np.any(live):
        return None
    smooth = scipy.ndimage.uniform_filter1d(chi2, SMOOTH_LINES, mode="nearest")
    unseen = np.maximum(smooth - 1.0, 0.0) * (n_p - 1) * np.mean(expected, axis=0) / n_p
    q1 = np.mean(np.abs(np.einsum("j,jsf->sf", coordinate_map, spec)) ** 2, axis=0)
    return UnseenMotion(chi2=float(np.mean(chi2[live])), lines=int(np.count_nonzero(live)),
                        frequencies=f[live], deflection=np.sqrt(unseen[live] / q1[live]))


def unseen_weights(unseen: UnseenMotion | None, frequencies: np.ndarray,
                   couplings: np.ndarray, probe_shapes: np.ndarray, rows: np.ndarray
                   ) -> np.ndarray:
    """(n_rows, n_freq) [kg^2]: the variance the unseen motion's inertia gives each row of
    ``rows`` (forces from the gauges' inertia) per unit |q''_1|^2 (zero unless
    :attr:`UnseenMotion.found`).

    The bound: the first shape's mass coupling per unit deflection at the probes,
    |m_1| / rms(g_1) [kg/m], times the unseen deflection per unit q_1 (held beyond the live
    lines), through each row at its full length."""
    out = np.zeros((len(rows), len(frequencies)))
    if unseen is None or not unseen.found:
        return out
    g1 = probe_shapes[:, 0]
    per_deflection = np.linalg.norm(couplings) / np.sqrt(np.mean(g1**2))
    d = np.interp(frequencies, unseen.frequencies, unseen.deflection)
    return (np.linalg.norm(rows, axis=1)[:, None] * per_deflection * d[None, :]) ** 2


def unseen_notes(unseen: UnseenMotion | None, probe_names: tuple[str, ...], source: str
                 ) -> tuple[str, ...]:
    """The run's note where its probes contradict the operating shapes (none otherwise)."""
    if unseen is None or not unseen.found:
        return ()
    return (f"run '{source}': the probes {', '.join(probe_names)} disagree with the scan's "
            f"operating shapes (reduced chi-square {unseen.chi2:.3g} over {unseen.lines} lines, "
            f"limit {MISFIT_LIMIT:g}): the run deflects in a shape the scan did not see (forces "
            "that do not keep the scan's ratio: a second actuator, a load pattern changed since "
            "the scan) or a probe's sign, scale or position is wrong; how the reactions split "
            "between the forces is then not known, and each force's uncertainty takes a bound "
            "on the inertia of that motion: scan under this load pattern",)

"""The actuator's law over frequency: K(f) and the force's lag against frequency.

:func:`fig_frequency_law` draws a :class:`~forcecal.actuator.FrequencyLaw`: the
non-parametric value of every frequency step with its 2-sigma error bar beside the fitted
curve of the chosen model (first or half order) and its 2-sigma band, and optionally a
first-order truth (a virtual rig's).
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import LogLocator, NullFormatter, ScalarFormatter

from ...actuator import FrequencyLaw
from ...errors import InputError
from ._common import MARKERS, legend_right, panel_title

__all__: list[str] = []

COVERAGE = 2.0
"""Error bars and bands span this many standard uncertainties."""


def fig_frequency_law(law: FrequencyLaw, truth: tuple[float, float] | None = None,
                      relative: bool = True, n_points: int = 200) -> Figure:
    """K(f) (or K(f) / K) and the force's lag behind i^2 against frequency (log axis).

    Top: the gain ``K(f) / K`` (``relative``) or ``K(f)`` [N m²/A²]; bottom: the lag [deg].
    Every frequency step of ``law.steps`` is an open marker with its ±2σ error bar (the
    non-parametric fit); the chosen model's curve (``law.model``: first order
    ``1 / (1 + j 2 pi f tau)``, or half order) is a line with its
    ±2σ band (tau's uncertainty; for ``K(f)`` also K's), drawn a little beyond the calibrated
    range, whose ends are dotted.

    Parameters
    ----------
    law : FrequencyLaw
        The fitted law.
    truth : (float, float) or None
        ``(K [N m²/A²], tau [s])`` of a known first-order truth, drawn dashed; K is used only
        when not ``relative``.
    relative : bool
        Draw ``K(f) / K`` rather than ``K(f)``.
    n_points : int
        Frequencies of the curves.

    Returns
    -------
    matplotlib.figure.Figure
        Two axes sharing the frequency axis [Hz]: the gain (y: ``K(f)/K`` [-] or ``K(f)``
        [N m²/A²]) and the lag (y: deg). Lines are labelled "MODEL law" (``law.model``: "first-order
        law", "half-order law"), "MODEL law ±2σ", "steps ±2σ" and "truth".

    Raises
    ------
    InputError
        When ``n_points`` is below 2 or the truth is not two finite numbers.
    """
    if n_points < 2:
        raise InputError(f"n_points = {n_points}; at least 2 are drawn")
    if truth is not None and (len(truth) != 2 or not np.all(np.isfinite(truth))):
        raise InputError(f"truth must be (K, tau), two finite numbers; found {truth!r}")
    lo, hi = law.frequency_range
    f = np.geomspace(lo / 1.5, hi * 1.5, n_points)
    gain, gain_std = law.gain(f) if relative else law.k_at(f)
    lag, lag_std = law.lag_deg(f)
    fig = Figure(figsize=(9.5, 7.0), layout="constrained")
    ax_g = fig.add_subplot(2, 1, 1)
    ax_l = fig.add_subplot(2, 1, 2, sharex=ax_g)
    steps = law.steps
    freq = np.array([s.frequency for s in steps])
    points = (np.array([s.gain for s in steps]), np.array([s.gain_std for s in steps])) \
        if relative else (np.array([s.k for s in steps]), np.array([s.k_std for s in steps]))
    for ax, curve, std, (y, y_std) in (
            (ax_g, gain, gain_std, points),
            (ax_l, lag, lag_std, (np.array([s.lag_deg for s in steps]),
                                  np.array([s.lag_deg_std for s in steps])))):
        ax.fill_between(f, curve - COVERAGE * std, curve + COVERAGE * std, color="C0",
                        alpha=0.35, lw=0, label=f"{law.model} law ±2σ")
        ax.plot(f, curve, "-", color="C0", lw=1.5, label=f"{law.model} law")
        if steps:
            ax.errorbar(freq, y, yerr=COVERAGE * y_std, fmt=MARKERS[0], color="C1", ms=7,
                        mfc="none", mew=1.4, capsize=3, label="steps ±2σ")
        for edge in (lo, hi):
            ax.axvline(edge, color="0.5", lw=0.8, ls=":")
        ax.set_xscale("log")
        ax.xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.grid(alpha=0.3, which="both")
    if truth is not None:
        k_true, tau_true = float(truth[0]), float(truth[1])
        x = 1.0 + (2 * np.pi * f * tau_true) ** 2
        ax_g.plot(f, x**-0.5 * (1.0 if relative else k_true), "--", color="k", lw=1.2,
                  label="truth")
        ax_l.plot(f, np.degrees(np.arctan(2 * np.pi * f * tau_true)), "--", color="k",
                  lw=1.2, label="truth")
    ax_g.set_ylabel("K(f) / K [-]" if relative else "K(f) [N m²/A²]")
    panel_title(ax_g, "Gain of the force against i² (the magnetising current's fundamental)")
    ax_l.set_ylabel("lag of the force behind i² [deg]")
    ax_l.set_xlabel("frequency [Hz]")
    panel_title(ax_l, "Lag of the force behind i²")
    ax_g.tick_params(labelbottom=False)
    legend_right(ax_g)
    tau, tau_std = law.tau, float(law.stderr[2])
    fig.suptitle(f"Actuator law over frequency: {len(steps)} steps, {lo:.4g} to {hi:.4g} Hz\n"
                 f"K = {law.k:.5g} ± {law.stderr[0]:.2g} N m²/A², "
                 f"s_fe = {1e3 * law.s_fe:.4g} ± {1e3 * law.stderr[1]:.2g} mm, "
                 f"tau = {1e3 * tau:.4g} ± {1e3 * tau_std:.2g} ms")
    return fig

"""Diagnostics of a run's estimate: fit residuals, sensor-fit chi-square, force amplitudes."""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

from ...errors import InputError
from ...forces.diagnostics import misfit_limits
from ...forces.steady import ForceEstimate, channels_si
from ...records import Run
from ...rig import Rig
from ...signals.harmonics import fit_harmonics
from ..cells import quantity
from ._common import check_run, panel_title

__all__ = ["fig_residuals"]

_CHANNEL_UNITS = {"gauge": "N", "sensor": "m", "current": "A", "flux": "Wb"}


def fig_residuals(estimate: ForceEstimate, run: Run | None = None, rig: Rig | None = None
                  ) -> Figure:
    """Diagnostics of one run's estimate.

    With ``run`` and ``rig``: the harmonic-fit residuals of every channel over the record, each
    divided by its residual standard deviation (stated in the channel's unit) and stacked. Then
    the reduced chi-square of the sensor fit per harmonic (about 1 when the shape model explains
    the probes), and the amplitude of each force per harmonic with its standard uncertainty
    (error bars) on a log axis, beside the reactions-only amplitude (open markers); harmonics the
    estimate did not keep are left out.

    Parameters
    ----------
    estimate : ForceEstimate
        The forces of one run.
    run : Run, optional
        The run the estimate was computed from; with ``rig``, draws the channels' residuals.
    rig : Rig, optional
        The rig it was measured on; given together with ``run``.

    Returns
    -------
    matplotlib.figure.Figure
        3 axes (residuals, chi-square, amplitudes) when ``run`` and ``rig`` are given, else 2.
        The amplitude lines are labelled "NAME" (with inertia) and "NAME reactions only",
        x = harmonic number (offset by a few hundredths per force), y = amplitude [N]; the
        chi-square line is labelled "chi2".

    Raises
    ------
    InputError
        When only one of ``run`` and ``rig`` is given.
    """
    if (run is None) != (rig is None):
        raise InputError("fig_residuals: the channel residuals need both the run and the rig")
    fig = Figure(figsize=(12.0, 9.0 if run is not None else 4.5), layout="constrained")
    fig.suptitle(f"Run '{estimate.run_name}': fit residuals and force amplitudes per harmonic")
    if run is not None and rig is not None:
        check_run(run, estimate)
        grid = fig.add_gridspec(2, 2, width_ratios=(1.0, 2.2), height_ratios=(1.1, 1.0))
        _draw_residuals(fig.add_subplot(grid[0, :]), run, rig, estimate)
        ax_c, ax_a = fig.add_subplot(grid[1, 0]), fig.add_subplot(grid[1, 1])
    else:
        ax_c, ax_a = fig.subplots(1, 2, width_ratios=(1.0, 2.2))
    _draw_chi2(ax_c, estimate, len(rig.sensor_names) if rig is not None else 0)
    _draw_amplitudes(ax_a, estimate)
    return fig


def _channel_kinds(rig: Rig, sig: dict[str, np.ndarray]) -> list[tuple[str, str]]:
    """(name, kind) of every gauge, sensor, the current and (if recorded) the flux channel."""
    kinds = [(g, "gauge") for g in rig.gauge_names] + [(s, "sensor") for s in rig.sensor_names]
    kinds.append((rig.actuator.current, "current"))
    if rig.actuator.flux and rig.actuator.flux in sig:
        kinds.append((rig.actuator.flux, "flux"))
    return kinds


def _draw_residuals(ax: Axes, run: Run, rig: Rig, estimate: ForceEstimate) -> None:
    """Every channel's harmonic-fit residual over its standard deviation, stacked, over time."""
    sig = channels_si(rig, run)
    kinds = _channel_kinds(rig, sig)
    h = len(estimate.harmonics) - 1
    fit = fit_harmonics(np.stack([sig[name] for name, _ in kinds]), run.fs, estimate.f0, h,
                        t0=run.t0)
    t = run.time
    spacing = 10.0
    ticks, labels = [], []
    for k, (name, kind) in enumerate(kinds):
        sigma = float(fit.residual_std[k])
        offset = (len(kinds) - 1 - k) * spacing
        scaled = fit.residuals[k] / sigma if sigma > 0 else fit.residuals[k] * 0.0
        ax.plot(t, scaled + offset, "-", lw=0.4, color=f"C{k % 10}", label=name)
        ticks.append(offset)
        labels.append(f"{name}\nσ = {quantity(sigma, _CHANNEL_UNITS[kind], 2)}")
    ax.set_yticks(ticks)
    ax.set_yticklabels(labels, fontsize="small")
    ax.set_ylim(-spacing / 2 - 1.5, (len(kinds) - 1) * spacing + spacing / 2 + 1.5)
    ax.set_xlim(t[0], t[-1])
    ax.set_xlabel("time [s]")
    ax.set_ylabel("residual / σ [1], stacked")
    panel_title(ax, f"Residuals of the harmonic fits (harmonics 0..{h}) over the whole record")
    ax.grid(alpha=0.3, axis="x")


def _draw_chi2(ax: Axes, estimate: ForceEstimate, n_sensors: int) -> None:
    """The reduced chi-square of the sensor fit per harmonic on a log axis, with the range the
    probe check accepts."""
    c = estimate.coordinates
    finite = np.isfinite(c.chi2)
    if finite.any():
        rate, _, limits = misfit_limits(c, n_sensors)
        _draw_acceptance(ax, c.harmonics, limits, rate)
        ax.axhline(1.0, color="0.5", lw=0.8, ls="--", label="expected (1)")
        ax.plot(c.harmonics[finite], c.chi2[finite], "o", color="C0", ms=7, label="chi2")
        for n, v in zip(c.harmonics[finite], c.chi2[finite], strict=True):
            ax.annotate(f"{v:.2g}", (n, v), textcoords="offset points", xytext=(6, 4),
                        fontsize="small")
        ax.set_yscale("log")
        values = np.concatenate([c.chi2[finite], limits[np.isfinite(limits)], [1.0]])
        ax.set_ylim(values.min() / 3, values.max() * 3)
        ax.yaxis.set_major_locator(LogLocator(base=10.0, subs=(1.0, 2.0, 5.0)))
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))
        ax.yaxis.set_minor_formatter(NullFormatter())
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.2), fontsize="small")
    else:
        ax.text(0.5, 0.5, "one sensor:\nno chi-square\n(the fit is exact)",
                transform=ax.transAxes, ha="center", va="center")
    ax.set_xticks(c.harmonics)
    ax.set_xlim(c.harmonics.min() - 0.6, c.harmonics.max() + 0.6)
    ax.set_xlabel("harmonic n")
    ax.set_ylabel(r"reduced $\chi^2$ of the sensor fit [1]")
    panel_title(ax, "Shape model vs probes")
    ax.grid(alpha=0.3, which="both")


def _draw_acceptance(ax: Axes, harmonics: np.ndarray, limits: np.ndarray, rate: float) -> None:
    """The range of chi-square the probe check accepts, per harmonic: a shaded bar from the
    axis' bottom up to its quantile (at ``rate`` per harmonic), the quantile as a line."""
    ok = np.isfinite(limits)
    if not ok.any():
        return
    for j, (n, q) in enumerate(zip(harmonics[ok], limits[ok], strict=True)):
        ax.fill_between([n - 0.4, n + 0.4], [1e-12, 1e-12], [q, q], color="C2", alpha=0.15,
                        lw=0, label="accepted by the probe check" if j == 0 else "_nolegend_")
        ax.plot([n - 0.4, n + 0.4], [q, q], "-", color="C2", lw=1.2,
                label=f"the check's limit (quantile at {1 - rate:.5g})" if j == 0
                else "_nolegend_")


def _draw_amplitudes(ax: Axes, estimate: ForceEstimate) -> None:
    """Each force's amplitude per kept harmonic with error bars, beside the reactions-only."""
    harmonics = estimate.harmonics
    show = estimate.kept.copy()
    show[0] = show[0] and estimate.dc_observed
    n_f = len(estimate.force_names)
    offsets = (np.arange(n_f) - (n_f - 1) / 2) * 0.18
    for k, name in enumerate(estimate.force_names):
        amp = np.abs(estimate.force[k])
        std = estimate.force_std[k]
        ok = show & (amp > 0)
        lower = np.minimum(std[ok], 0.95 * amp[ok])
        color = f"C{(k + 2) % 10}"
        ax.errorbar(harmonics[ok] + offsets[k], amp[ok], yerr=np.vstack([lower, std[ok]]),
                    fmt="o", ms=6, color=color, capsize=3, label=name)
        stat = np.abs(estimate.static[k])
        ok_s = show & (stat > 0)
        ax.plot(harmonics[ok_s] + offsets[k] + 0.07, stat[ok_s], "D", ms=6, mfc="none",
                color=color, label=f"{name} reactions only")
    ax.set_yscale("log")
    ax.set_xticks(harmonics)
    ax.set_xticklabels([f"{n}\n{n * estimate.f0:.0f} Hz" if n else "0\nDC" for n in harmonics])
    ax.set_xlabel("harmonic n")
    ax.set_ylabel("amplitude $|F_n|$ [N]")
    panel_title(ax, "Force amplitudes (error bars: standard uncertainty)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(loc="upper right", fontsize="small", ncols=2)
    dropped = [int(n) for n in harmonics[~estimate.kept]]
    if dropped:
        ax.text(0.01, 0.02, "not kept (not supported by the data): "
                + ", ".join(map(str, dropped)), transform=ax.transAxes, fontsize="small",
                va="bottom")

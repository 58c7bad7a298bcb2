"""The inertia term's scale, calibrated in situ from a run under any drive.

The external force does not know where the structure resonates: a component of the estimate
F(t) = s J(t) - R(t) (totals over the gauges) shaped like the inertia J is a scale error of J
(a probe's sensitivity, a mass; at the first mode J is many times F, and so is its error).
The electromagnet's force is a function of its flux, f = Phi^2 / (mu0 A): s is the
coefficient that leaves R + ... = s J - B(Phi) c least, B a low-order basis of every flux
channel (1, Phi, Phi^2, Phi', Phi Phi'; the derivatives take a lag of the channel), solved
jointly for s and c by linear least squares. The coil current alone does not serve: the force
also follows the gap, which resonates with the structure (the magnet's negative stiffness),
and a basis of the current takes s off by far more than its uncertainty.

Its uncertainty: the residual is coloured and not stationary, so the score x e (x: J less its
projection on the basis) is summed over blocks of a period of the band's bottom and their
spread taken (a sandwich estimate), with the change a basis one order higher makes. s is not
applied, and stays 1 with a note saying why, without a flux channel, where the basis leaves
more than :data:`MAX_MISFIT` of the force (naming a skew between the probes' and the gauges'
records where one explains much of it), where u(s) exceeds :data:`MAX_STD`, or where s is
farther from 1 than the rig's declared sensitivities and masses allow (a force that itself
resonates, or one that is not the flux's alone).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..rig import TypeB

__all__ = ["InertiaScale", "estimate_inertia_scale"]

MAX_MISFIT = 0.2
"""The flux's basis must explain the force estimate to this share of its RMS (it leaves 1.5 %
on the ideal `sweep` and `random` rigs, 3.5-4.1 % on the lab's, the noise of the estimate
before its Wiener gains); beyond it the force is not the flux's alone, or the estimate is off
for another reason, and no scale is read from it."""

MAX_STD = 0.01
"""[1] a scale known no better than this (the order of a probe's declared sensitivity) is not
applied: the run does not determine it."""

PLAUSIBLE_SIGMAS = 3.0
"""s may differ from 1 by this many combined type-B uncertainties of the inertia's scale (the
probes' and gauges' sensitivities, the masses) ..."""

PLAUSIBLE_FLOOR = 0.02
"""... and by at least this [1], for a rig that declares its sensors exact."""


@dataclass(frozen=True)
class InertiaScale:
    """The in-situ scale of the inertia term.

    Attributes
    ----------
    scale : float [1]
        s, applied to the inertia (1 where not applied).
    std : float [1]
        Its standard uncertainty (0 where not applied).
    estimate : float [1]
        The estimate before the checks (nan without a flux channel).
    estimate_std : float [1]
        Its standard uncertainty.
    misfit : float [1]
        RMS of what the flux's basis leaves of s J - R over the RMS of its AC part.
    applied : bool
    note : str
        What was done and why, in a line.
    """

    scale: float
    std: float
    estimate: float
    estimate_std: float
    misfit: float
    applied: bool
    note: str


def _varying(flux: np.ndarray) -> np.ndarray:
    """The flux channels (rows) that vary: a constant one (a dead channel) holds no shape."""
    flux = np.atleast_2d(np.asarray(flux, dtype=float))
    out: np.ndarray = flux[np.ptp(flux, axis=1) > 1e-12 * np.max(np.abs(flux), axis=1)]
    return out


def flux_basis(flux: np.ndarray, fs: float, order: int = 2) -> np.ndarray:
    """(N, n_funcs): a constant and, per flux channel that varies, its powers up to ``order``
    and each of them times its derivative, every column but the constant of unit RMS.

    Parameters
    ----------
    flux : (n_channels, N) array [Wb or the channel's unit]
    fs : float [Hz]
    order : int
        The highest power of the flux (2: Phi, Phi^2, Phi', Phi Phi').
    """
    cols = [np.ones(flux.shape[-1])]
    for phi in _varying(flux):
        x = phi - phi.mean()
        x = x / (np.std(x) or 1.0)
        dx = np.gradient(x) * fs
        dx = dx / (np.std(dx) or 1.0)
        powers = [x**k for k in range(1, order + 1)]
        cols += powers + [dx] + [p * dx for p in powers[:-1]]
    out = np.column_stack(cols)
    out[:, 1:] /= np.sqrt(np.mean(out[:, 1:] ** 2, axis=0))
    return out


def _regress(inertia: np.ndarray, reactions: np.ndarray, basis: np.ndarray, block: int,
             q: np.ndarray | None = None) -> tuple[float, float, float]:
    """s, its sandwich standard uncertainty over blocks of ``block`` samples, and the misfit:
    reactions = s inertia - basis c + e by least squares (Frisch-Waugh: both less their
    projections on the basis; ``q``, the basis orthonormalised, where it is at hand)."""
    if q is None:
        q, _ = np.linalg.qr(basis)
    x = inertia - q @ (q.T @ inertia)
    y = reactions - q @ (q.T @ reactions)
    xx = float(x @ x)
    if xx <= 1e-12 * float(inertia @ inertia) or xx == 0.0:
        return 1.0, np.inf, np.inf
    s = float(x @ y) / xx
    e = y - s * x
    sums = np.add.reduceat(x * e, np.arange(0, x.size, max(block, 1)))
    force = s * inertia - reactions
    misfit = float(np.std(e) / (np.std(force) or np.inf))
    return s, float(np.sqrt(np.sum(sums**2)) / xx), misfit


def _probe_delay(inertia: np.ndarray, reactions: np.ndarray, basis: np.ndarray, fs: float,
                 band: tuple[float, float], block: int) -> tuple[float, float]:
    """(tau [s], misfit then): the delay of the inertia term against the reactions, whole
    samples within a quarter period of the band's top, that lets the flux's basis explain the
    estimate best (the inertia taken tau later: the probes' records tau late against the
    gauges', or the gauges' early); 0 where the best lies at the search's edge."""
    q, _ = np.linalg.qr(basis)
    w = 2 * np.pi * np.fft.rfftfreq(inertia.size, 1.0 / fs)
    spec = np.fft.rfft(inertia)
    reach = max(2, int(np.ceil(fs / band[1] / 4)))
    misfits = [_regress(np.fft.irfft(spec * np.exp(1j * w * d / fs), inertia.size),  # J(t + d/fs)
                        reactions, basis, block, q)[2] for d in range(-reach, reach + 1)]
    k = int(np.argmin(misfits))
    return (0.0 if k in (0, 2 * reach) else (k - reach) / fs), float(misfits[k])


def _delay_said(inertia: np.ndarray, reactions: np.ndarray, basis: np.ndarray, fs: float,
                band: tuple[float, float], block: int, misfit: float) -> str:
    """Where a delay between the probes' and the gauges' records explains much of what the
    flux does not (a sharp minimum of the misfit over the delay, at most half of it as
    recorded), the words naming it."""
    tau, then = _probe_delay(inertia, reactions, basis, fs, band, block)
    if tau == 0.0 or not then <= misfit / 2:
        return ""
    late, early = ("probes", "gauges") if tau > 0 else ("gauges", "probes")
    return (f"; with the probes' and the gauges' records {1e3 * abs(tau):.3g} ms apart it "
            f"explains it to {100 * then:.3g} %: the {late} recorded about "
            f"{1e3 * abs(tau):.3g} ms late against the {early} (DAQ skew between modules, or "
            "a filter's delay)")


def plausible_deviation(type_b: TypeB) -> float:
    """[1] how far s may lie from 1: :data:`PLAUSIBLE_SIGMAS` times the root sum of squares of
    the declared probe and gauge sensitivities' and the masses' relative uncertainties (at the
    mode the reactions nearly cancel the inertia, so a gauge's sensitivity reads as its
    scale), at least :data:`PLAUSIBLE_FLOOR`."""
    u = float(np.sqrt(type_b.probe_scale**2 + type_b.gauge_scale**2 + type_b.mass**2))
    return max(PLAUSIBLE_SIGMAS * u, PLAUSIBLE_FLOOR)


def estimate_inertia_scale(inertia: np.ndarray, reactions: np.ndarray, flux: np.ndarray | None,
                           fs: float, band: tuple[float, float], allowed: float,
                           source: str = "<run>") -> InertiaScale:
    """The inertia term's scale s from a run: F = s J - R explained by the flux.

    Parameters
    ----------
    inertia : (N,) array [N]
        The inertia term's total over the gauges, 1^T Psi^+ J(t).
    reactions : (N,) array [N]
        The reactions' total, 1^T Psi^+ R(t).
    flux : (n_channels, N) array or None
        Every flux channel of the run [Wb, or the channel's unit: only their shape counts].
    fs : float [Hz]
    band : (low, high) [Hz]
        The scan's band: a period of its bottom is left out at both ends of the record (the
        ends carry the prediction past them) and is the blocks' length for u(s).
    allowed : float [1]
        How far s may lie from 1 (:func:`plausible_deviation`).
    source : str
        The run, named in the note.

    Returns
    -------
    InertiaScale
    """
    what = f"run '{source}': the inertia's scale"
    flux = None if flux is None else _varying(flux)
    if flux is None or len(flux) == 0:
        return InertiaScale(1.0, 0.0, np.nan, np.nan, np.nan, False, (
            f"{what} is not estimated from the run: it has no flux channel that varies, and "
            "the coil current alone does not explain a force that also follows the moving "
            "gap"))
    edge = int(round(fs / max(band[0], 1e-9)))
    inner = _inner(inertia.size, fs, band)
    j, r, phi = inertia[inner], reactions[inner], np.atleast_2d(flux)[:, inner]
    s, u, misfit = _regress(j, r, flux_basis(phi, fs), edge)
    s_next = _regress(j, r, flux_basis(phi, fs, 3), edge)[0]
    u = float(np.hypot(u, s_next - s))                   # the basis's truncation
    why = ""
    if not misfit <= MAX_MISFIT:
        why = (f"the flux explains the force estimate only to {100 * misfit:.3g} % of its RMS "
               f"(a force that is not the flux's alone, or an estimate off for another reason)"
               + _delay_said(j, r, flux_basis(phi, fs), fs, band, edge, misfit))
    elif not u <= MAX_STD:
        why = f"the run determines it only to {100 * u:.2g} %"
    elif abs(s - 1.0) > allowed:
        why = (f"its estimate {s:.4f} lies farther from 1 than the rig's declared "
               f"sensitivities and masses allow ({100 * allowed:.3g} %): a probe's scale "
               "(sensors[].scale) or a mass off by more than declared, or a force that itself "
               "resonates or is not the flux's alone")
    if why:
        return InertiaScale(1.0, 0.0, s, u, misfit, False,
                            f"{what} is not taken from the run: {why}")
    note = (f"{what}, calibrated in situ (the force estimate explained by the flux, to "
            f"{100 * misfit:.2g} % of its RMS): s = {s:.5f} +/- {u:.2g}, applied")
    if abs(s - 1.0) > 3.0 * u:
        note += (f"; it differs from 1 by {abs(s - 1.0) / u:.3g} standard uncertainties: the "
                 f"probes' sensitivities or the rig's masses differ from their nominal values by "
                 f"about {100 * abs(s - 1.0):.2g} %, within what the rig declares, and the run "
                 "calibrates it")
    return InertiaScale(s, u, s, u, misfit, True, note)


def scale_shift(inertia: np.ndarray, flux: np.ndarray, fs: float, band: tuple[float, float],
                scale: float) -> Callable[[np.ndarray], float]:
    """How the in-situ scale absorbs a change of the estimate: the function of a change D(t)
    of the total force [N] (a declared type-B parameter moved by its uncertainty) that gives
    the relative change of s the fit then makes, -x.D / (s x.x), x the inertia's total less its
    projection on the flux's basis over the samples the fit used: the change left in the
    estimate is D + that times the (scaled) inertia term.

    Parameters
    ----------
    inertia : (N,) array [N]
        The unscaled inertia term's total over the gauges.
    flux : (n_channels, N) array
    fs : float [Hz]
    band : (low, high) [Hz]
    scale : float [1]
        s, as applied.
    """
    inner = _inner(inertia.size, fs, band)
    q, _ = np.linalg.qr(flux_basis(np.atleast_2d(flux)[:, inner], fs))
    j = inertia[inner]
    x = j - q @ (q.T @ j)
    xx = float(x @ x) * scale

    def shift(move: np.ndarray) -> float:
        return -float(x @ move[inner]) / xx

    return shift


def _inner(n: int, fs: float, band: tuple[float, float]) -> slice:
    """The samples the fit uses: a period of the band's bottom left out at both ends."""
    edge = int(round(fs / max(band[0], 1e-9)))
    return slice(edge, n - edge) if n > 4 * edge else slice(None)


def scale_variance(pinv: np.ndarray, inertia: np.ndarray, rel_std: float) -> np.ndarray:
    """(n_forces + 1, N) [N^2]: the variance the scale's relative uncertainty ``rel_std`` [1]
    gives each force and the total, from the (scaled) inertia term ``inertia``
    (n_gauges, N) [N] through Psi^+ ``pinv`` (n_forces, n_gauges)."""
    part = pinv @ inertia
    return (rel_std * np.vstack([part, part.sum(axis=0)])) ** 2

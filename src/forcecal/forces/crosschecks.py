"""The estimate against the data's own redundancy: each pole's force against the Maxwell force of
its flux (:func:`flux_notes`), the flux channels of one core against each other
(:func:`flux_pair_notes`), and without a flux, the poles of one core against each other
(:func:`pole_notes`) (METHOD.md section 6; docs/method.md section 7).

A pole face of area A carrying the flux Phi pulls with Maxwell's stress Phi^2 / (2 mu0 A), to
within fringing; poles of one core carry one flux and pull alike. The reconstructed forces
must follow it at every harmonic, in magnitude and in phase, up to one factor c common to the
poles (the fringing). The declared type-B sources that move every harmonic alike (each gauge's
scale, the inertia's) are fitted as parameters held to their declared uncertainties.
:func:`flux_notes` draws a note when the whole misfit, or the gain of freeing one sensor's
mistake (a gauge's scale or offset, a delay of the gauges or of the probes against the other
channels, the inertia's scale: a mass, a probe's scale, the probes' sign), is beyond chance at
a stated false-alarm rate; the note names the mistakes that explain it, the best first with
the size each would have, the tare (every gauge's offset at once) and the rig's geometry (a
position, a swap) beside them where the data cannot tell them apart. A steady drive's
harmonics are compared; any drive's, lines of the record's spectrum over the band
(:func:`line_terms`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np

from ..model.relaxation import force_matrix
from ..records import Run
from ..rig import Rig
from ..signals.harmonics import fit_harmonics
from ..signals.mains import near_mains
from ..signals.noise import GUARD
from .diagnostics import FALSE_ALARM, chi_square_limit

__all__ = ["EstimateTerms", "flux_notes", "line_terms", "pole_notes"]

MU0 = 4e-7 * math.pi
FRINGING = 0.02
"""[1] relative standard deviation of each pole's force about c Phi^2 / (2 mu0 A) at every
harmonic: fringing that differs between poles at unequal gaps and changes with the gap over a
cycle. A lab mistake that moves a force by less is not told from it."""


ALIKE = 4.0
"""Causes whose chi-squares lie within this of the best one's are told apart by less than
two standard deviations: the note says the data cannot tell them apart."""
INERTIA_SHARE = 0.5
"""Under any drive, the lines compared are those where each force's inertia part is at most
this share of its reactions' part."""
MAX_LINES = 400
"""Under any drive, the most lines of the record's spectrum compared (spread over the band)."""
AKAIKE = 2.0
"""Chi-square a cause of several sizes (every gauge's offset: the tare) must gain per size
beyond the best single gauge's offset to be named beside it (Akaike's criterion)."""
DEAD_RATIO = 1e-4
"""A flux channel reading less than this share of its core's other is said to carry next to no
flux (a dead or unplugged channel, or a unit far off; mWb read as Wb, 1e-3, is a scale)."""
SHIFT_MM = 200.0
"""[mm] the farthest a point is looked for from where the rig puts it."""
NUISANCE = ("gauge sensitivity", "probe sensitivity", "masses")
"""The type-B sources of the uncertainty budget that the check fits as parameters, each held
to its declared uncertainty (a gauge's scale, the inertia's scale), rather than as noise on
every harmonic: a systematic error moves every harmonic alike."""


@dataclass(frozen=True)
class EstimateTerms:
    """The parts of a steady estimate a lab mistake would change (forces = pinv (J - R)).

    Attributes
    ----------
    force : (n_f, H+1) complex ndarray [N]
    std : (n_f, H+1) ndarray [N]
        Standard uncertainty of Re and of Im of each force: its noise and the rig's declared
        type-B uncertainties but those of :data:`NUISANCE`, which the check fits.
    reactions : (n_g, H+1) complex ndarray [N]
    inertia : (n_g, H+1) complex ndarray [N]
    pinv : (n_f, n_g) ndarray
        The force rows of Psi^+.
    kept : (H+1,) bool ndarray
        The harmonics estimated; the DC among them only where the gauges observe it.
    w0 : float [rad/s]
    lines : (H+1,) int ndarray, optional
        Under any drive (:func:`line_terms`), the columns are these lines of the record's
        discrete Fourier transform, ``w0`` apart, the first the DC; None: harmonics 0..H of a
        steady drive's fundamental w0.
    rate : float
        The false-alarm rate the checks are judged at (:data:`FALSE_ALARM` per record; a
        stream checked segment by segment shares it among its segments).
    """

    force: np.ndarray
    std: np.ndarray
    reactions: np.ndarray
    inertia: np.ndarray
    pinv: np.ndarray
    kept: np.ndarray
    w0: float
    lines: np.ndarray | None = None
    rate: float = FALSE_ALARM

    @property
    def angular(self) -> np.ndarray:
        """[rad/s] each column's angular frequency."""
        n = np.arange(self.force.shape[1]) if self.lines is None else self.lines
        out: np.ndarray = n * self.w0
        return out

    def phasors(self, x: np.ndarray, run: Run) -> tuple[np.ndarray, np.ndarray]:
        """The columns' phasors of a record of the run (x = X_0 + sum Re X_n e^{j w_n t}) and
        their standard uncertainties (none for lines: the forces' and the fringing's count)."""
        if self.lines is None:
            fit = fit_harmonics(x, run.fs, self.w0 / (2 * np.pi), self.force.shape[1] - 1,
                                t0=run.t0)
            return fit.phasors, fit.phasor_std
        return _at_lines(x, self.lines, self.w0, run.t0), np.zeros(len(self.lines))


def _at_lines(x: np.ndarray, lines: np.ndarray, spacing: float, t0: float) -> np.ndarray:
    """The phasors X_n (x = X_0 + sum Re X_n e^{j w_n t}, t from ``t0``) of these lines of the
    records' discrete Fourier transform, ``spacing`` [rad/s] apart, on the last axis."""
    rows = np.reshape(x, (-1, x.shape[-1]))
    # row by row: a record's whole spectrum lives only while its lines are read
    spectrum = np.stack([np.fft.rfft(row)[lines] for row in rows]) * (2 / x.shape[-1])
    spectrum[:, lines == 0] /= 2
    out: np.ndarray = (spectrum * np.exp(-1j * lines * spacing * t0)).reshape(
        *x.shape[:-1], len(lines))
    return out


def line_terms(force_std: np.ndarray, reactions: np.ndarray, inertia: np.ndarray,
               pinv: np.ndarray, fs: float, t0: float, band: tuple[float, float],
               mains: float | None,
               noise: tuple[np.ndarray, np.ndarray] | None = None) -> EstimateTerms:
    """The terms of an estimate under any drive, on at most :data:`MAX_LINES` lines of the
    records' discrete Fourier transform spread over the band (and the DC): none within
    GUARD + 1 lines of a harmonic of the mains (hum on the flux or the gauges is not the
    force's), only those where the reactions carry the forces (:data:`INERTIA_SHARE`). The
    forces are Psi^+ (J - R) line by line, each line's noise the force's mean variance over the
    record shared among the lines the reactions carry (more than its share: it lies on the
    band's other lines too). With ``noise``, the noise of Psi^+ (J - R) itself (not the Wiener
    gains' less) lies on each line as its density does, and the rest of the variance (the
    transfer's, the scan's, the type-B sources') is shared as above: a record whose drive
    holds a narrow band has gains that take most of the noise away from the estimate, but not
    from the terms compared.

    Parameters
    ----------
    force_std : (n_f, N) ndarray [N]
        Each force's standard uncertainty sample by sample.
    reactions, inertia : (n_g, N) ndarray [N]
        R(t) and J(t), as the estimate used them.
    pinv : (n_f, n_g) ndarray
    fs : float [Hz]
    t0 : float [s]
        Time of the first sample.
    band : (low, high) [Hz]
    mains : float or None [Hz]
        ``acquisition.mains``.
    noise : ((n_f, bins), (n_f, N)) ndarrays, optional
        ``WindowEstimate.noise_density`` and ``WindowEstimate.borne``.

    Returns
    -------
    EstimateTerms
    """
    n = reactions.shape[-1]
    freq = np.fft.rfftfreq(n, 1 / fs)
    spacing = 2 * np.pi * fs / n
    inside = np.flatnonzero((freq >= band[0]) & (freq <= band[1]) & (freq > 0)
                            & ~near_mains(freq, mains, (GUARD + 1) * fs / n))
    every = np.concatenate([[0], inside]).astype(int)             # the DC, then the band
    r, j = (_at_lines(x, every, spacing, t0) for x in (reactions, inertia))
    # the inertia is the estimate's least known part, most near a resonance: lines where the
    # reactions carry the forces (the inertia at most INERTIA_SHARE of them) are compared,
    # judged by their neighbours' power, not the line's own: a line picked for its own
    # reactions' size is one whose noise happens to be large
    carried = np.all(_beside(np.abs(pinv @ j) ** 2)
                     <= INERTIA_SHARE**2 * _beside(np.abs(pinv @ r) ** 2), axis=0)
    carried[0] = True
    n_carried = int(np.count_nonzero(carried[1:]))
    chosen = np.flatnonzero(carried)
    chosen = np.concatenate([[0], chosen[1::max(1, -(-n_carried // MAX_LINES))]])
    var = np.repeat((np.mean(np.square(force_std), axis=1) / max(n_carried, 1))[:, None],
                    len(chosen), axis=1)
    if noise is not None:
        var[:, 1:] = _line_noise(noise[0], freq[every[chosen[1:]]], freq[1:], fs) + (
            np.mean(noise[1], axis=1) / max(n_carried, 1))[:, None]
    r, j = r[:, chosen], j[:, chosen]
    return EstimateTerms(force=pinv @ (j - r), std=np.sqrt(var),
                         reactions=r, inertia=j, pinv=pinv, kept=np.ones(len(chosen), dtype=bool),
                         w0=spacing, lines=every[chosen])


NEIGHBOURS = 4
"""Lines on either side whose power judges whether the reactions carry a line's forces."""


def _beside(power: np.ndarray) -> np.ndarray:
    """(n, L): each line's neighbours' mean ``power`` (n, L), :data:`NEIGHBOURS` on either side
    (fewer at the ends), the line itself left out."""
    kernel = np.ones(2 * NEIGHBOURS + 1)
    kernel[NEIGHBOURS] = 0.0
    ones = np.ones(power.shape[-1])
    count = np.convolve(ones, kernel, mode="same")
    return np.stack([np.convolve(row, kernel, mode="same") for row in power]) / count


def _line_noise(density: np.ndarray, at: np.ndarray, lines: np.ndarray, fs: float
                ) -> np.ndarray:
    """(n_f, len(at)): the variance of the real (and of the imaginary) part of a record's
    phasors at the frequencies ``at`` [Hz] from a noise of ``density`` (n_f, bins) per sample
    at a frame's bins, the record's lines above the DC being ``lines`` [Hz] (Parseval: the
    lines' variances sum to the noise's variance per sample)."""
    bins = density.shape[-1]
    grid = np.linspace(0.0, fs / 2, bins)
    fold = np.full(bins, 2.0)
    fold[0] = fold[-1] = 1.0
    per_sample = density @ fold / (2 * (bins - 1))
    shape = np.stack([np.interp(lines, grid, d) for d in density])
    share = np.stack([np.interp(at, grid, d) for d in density]) / np.maximum(
        np.sum(shape, axis=1, keepdims=True), 1e-300)
    return per_sample[:, None] * share


def pole_fluxes(rig: Rig, run: Run) -> dict[int, np.ndarray]:
    """[Wb] each force's pole flux over the record, by the force's index: its own channel
    (``forces[].flux``) or the actuator's (``actuator.flux``), scaled; forces without one, or
    whose channel the run lacks, are left out. Forces on one channel share one array."""
    out = {}
    scaled: dict[str, np.ndarray] = {}
    for k, name in _flux_channels(rig, run).items():
        if name not in scaled:
            scaled[name] = rig.actuator.flux_scale * run.channel(name)
        out[k] = scaled[name]
    return out


def _flux_channels(rig: Rig, run: Run) -> dict[int, str]:
    """Each force's pole flux channel (its own, else the actuator's) that the run holds."""
    names = {k: f.flux or rig.actuator.flux for k, f in enumerate(rig.forces)}
    return {k: name for k, name in names.items() if name is not None and name in run.channels}


def _maxwell(flux: np.ndarray, area: float, run: Run,
             terms: EstimateTerms) -> tuple[np.ndarray, np.ndarray]:
    """Phasors of Phi^2 / (2 mu0 A) in the terms' columns and their standard uncertainties."""
    stress = np.square(flux)                       # Phi^2 / (2 mu0 A), made in place
    stress /= 2 * MU0 * area
    return terms.phasors(stress, run)


@dataclass(frozen=True)
class _Cause:
    """One lab mistake: its name, the unit of its size, and the forces it would leave,
    ``forces(size)`` (the estimate's own forces with the mistake undone)."""

    name: str
    unit: str
    forces: Callable[[float], np.ndarray]
    form: str = "relative"
    """``relative``: forces(x) = F + d x / (100 + x), x in %; ``linear``: F + d x; ``delay``
    and ``shift``: nonlinear in x; ``swap``: no size; ``offsets``: F + sum_j d_j x_j, one
    size per name of ``parts`` (forces(j) the forces with x_j = 1, the others 0)."""
    parts: tuple[str, ...] = ()
    """The sizes' names of an ``offsets`` cause."""
    prior: float = 0.0
    """[1] the standard uncertainty the rig declares for it (type B, relative): within it, a
    mistake is not one, and every fit allows it."""


def _rescaled(force: np.ndarray, d: np.ndarray, x: float) -> np.ndarray:
    return force + d * (x / (100 + x))


def _offset(force: np.ndarray, d: np.ndarray, x: float) -> np.ndarray:
    return force + d * x


_Size = float | tuple[tuple[str, float], ...]
"""A cause's size: one number, or one per part of an ``offsets`` cause."""


def _tared(t: EstimateTerms, dc: np.ndarray, j: float) -> np.ndarray:
    """The forces with a unit offset on gauge ``j - 1`` (none for ``j = 0``)."""
    if j == 0:
        return t.force
    return t.force + t.pinv[:, int(j) - 1:int(j)] * dc


def _moved(rig: Rig, t: EstimateTerms, group: str, k: int, axis: str, mm: float) -> np.ndarray:
    """The forces were point ``k`` of ``group`` (gauges or forces) ``mm`` further along
    ``axis`` than the rig says."""
    points = list(getattr(rig, group))
    points[k] = dataclasses.replace(points[k], **{axis: getattr(points[k], axis) + mm / 1e3})
    moved_rig = (dataclasses.replace(rig, forces=tuple(points)) if group == "forces"
                 else dataclasses.replace(rig, gauges=tuple(points)))
    psi = force_matrix(moved_rig)
    moved: np.ndarray = np.linalg.pinv(psi) @ (t.inertia - t.reactions)
    return moved


def _swapped(t: EstimateTerms, rows: list[int], of: str, _: float) -> np.ndarray:
    if of == "gauges":
        return t.pinv @ (t.inertia - t.reactions[rows])
    return t.force[rows]


def _geometry(rig: Rig, t: EstimateTerms) -> list[_Cause]:
    """Mistakes of the rig's geometry: a gauge's or a force point's position along each axis
    of the structure, two gauges' columns or two forces' names swapped."""
    out: list[_Cause] = []
    for group, what in (("forces", "force"), ("gauges", "gauge")):
        items = getattr(rig, group)
        for k, item in enumerate(items):
            out += [_Cause(f"{group}[{k}].{axis} ({what} '{item.name}')", "mm",
                           partial(_moved, rig, t, group, k, axis), "shift")
                    for axis in rig.structure.axes]
        for a in range(len(items)):
            for b in range(a):
                rows = list(range(len(items)))
                rows[a], rows[b] = b, a
                where = ("their columns in the run, or [channels]" if group == "gauges"
                         else "their names in the rig")
                out.append(_Cause(f"the {what}s '{items[b].name}' and '{items[a].name}' "
                                  f"swapped ({where})", "", partial(_swapped, t, rows, group),
                                  "swap"))
    return out


def _causes(rig: Rig, t: EstimateTerms) -> list[_Cause]:
    """The single mistakes tried. A gauge's scale off by x leaves reactions (1 + x) R and
    forces that differ by x / (1 + x) Psi^+ R_g, linear in that; an offset, the inertia's
    scale alike; a delay tau turns harmonic n by n w0 tau, undone exactly."""
    jw = 1j * t.angular
    out: list[_Cause] = []
    for g, name in enumerate(rig.gauge_names):
        col, r_g = t.pinv[:, g:g + 1], t.reactions[g]
        out.append(_Cause(f"gauge '{name}' scale (its 'scale' in the rig)", "%",
                          partial(_rescaled, t.force, col * r_g), prior=rig.type_b.gauge_scale))
        if t.kept[0]:
            out.append(_Cause(f"gauge '{name}' offset (a tare missing or wrong)", "N",
                              partial(_offset, t.force, col * (jw == 0)), "linear"))
    if t.kept[0] and len(rig.gauge_names) > 1:
        out.append(_Cause("the tare (every gauge's offset: the tare record missing, wrong or of "
                          "another day)", "N", partial(_tared, t, jw == 0), "offsets",
                          parts=tuple(rig.gauge_names)))
    out.append(_Cause(
        "a delay of the gauges " + ", ".join(rig.gauge_names) + " behind the other channels "
        "(DAQ skew)", "ms", lambda ms: t.pinv @ (t.inertia - t.reactions * np.exp(jw * ms / 1e3)),
        "delay"))
    out.append(_Cause(
        "a delay of the probes " + ", ".join(rig.sensor_names) + " behind the other channels "
        "(DAQ skew)", "ms", lambda ms: t.pinv @ (t.inertia * np.exp(jw * ms / 1e3) - t.reactions),
        "delay"))
    out.append(_Cause("the inertia's scale (a mass: structure.mass_per_length or a lumped "
                      "mass, the probes' scale, or at -200 % the probes' sign)", "%",
                      partial(_rescaled, t.force, -(t.pinv @ t.inertia)),
                      prior=math.hypot(rig.type_b.mass, rig.type_b.probe_scale)))
    return out + _geometry(rig, t)


@dataclass(frozen=True)
class _Problem:
    """The forces of the poles (selected harmonics, stacked) against c times Maxwell's, with
    the declared type-B mistakes as nuisance parameters held to their priors."""

    m: np.ndarray
    w: np.ndarray
    nuisance: tuple[tuple[str, np.ndarray, float], ...]
    c_prior: float = 0.0
    """The standard deviation that holds the reference's coefficient to zero; 0: free."""

    def freeing(self, name: str) -> _Problem:
        """The problem with the nuisance ``name`` left out (a cause fitted free in its place)."""
        return dataclasses.replace(self, nuisance=tuple(n for n in self.nuisance
                                                        if n[0] != name))

    def fit(self, y: np.ndarray, extra: tuple[np.ndarray, ...] = ()) -> tuple[float, np.ndarray]:
        """(chi-square, coefficients [c, nuisance..., extra...]) of ``y`` (complex)."""
        cols = [self.m, *(d for _, d, _ in self.nuisance), *extra]
        a = np.stack([np.concatenate([c.real, c.imag]) for c in cols], axis=1) * self.w[:, None]
        b = np.concatenate([y.real, y.imag]) * self.w
        held = [(1 + j, sigma) for j, (_, _, sigma) in enumerate(self.nuisance)]
        held += [(0, self.c_prior)] if self.c_prior > 0 else []
        prior = np.zeros((len(held), len(cols)))
        for j, (col, sigma) in enumerate(held):
            prior[j, col] = 1.0 / sigma
        a, b = np.vstack([a, prior]), np.concatenate([b, np.zeros(len(held))])
        coef, *_ = np.linalg.lstsq(a, b, rcond=None)
        return float(np.sum((b - a @ coef) ** 2)), coef


def _column(cause: _Cause, pick: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """The change a ``relative`` cause makes per unit of b = x / (1 + x) (x as a fraction), or a
    ``linear`` one per unit of x, with the sign that adds it to the truth."""
    base = pick(cause.forces(0.0))
    if cause.form == "linear":
        return base - pick(cause.forces(1.0))
    return -2 * (pick(cause.forces(100.0)) - base)          # x = 100 % gives b = 1/2


def _size(cause: _Cause, problem: _Problem, pick: Callable[[np.ndarray], np.ndarray],
          period_ms: float) -> tuple[float, _Size]:
    """(chi-square, size) of the forces with ``cause`` free against c times Maxwell's."""
    if cause.form in ("relative", "linear"):
        c2, coef = problem.freeing(cause.name).fit(pick(cause.forces(0.0)),
                                                   (_column(cause, pick),))
        b = float(coef[-1])
        if cause.form == "linear":
            return c2, b
        return c2, (100 * b / (1 - b) if b != 1 else math.inf)
    if cause.form == "swap":
        return problem.fit(pick(cause.forces(0.0)))[0], math.nan
    if cause.form == "offsets":
        base = pick(cause.forces(0.0))
        c2, coef = problem.fit(base, tuple(base - pick(cause.forces(j))
                                           for j in range(1, len(cause.parts) + 1)))
        return c2, tuple(zip(cause.parts, (float(x) for x in coef[-len(cause.parts):]),
                             strict=True))
    from scipy.optimize import minimize_scalar  # on use: a steady stream starts without it

    bound = period_ms / 2 if cause.form == "delay" else SHIFT_MM
    best = minimize_scalar(lambda x: problem.fit(pick(cause.forces(x)))[0],
                           bounds=(-bound, bound), method="bounded",
                           options={"xatol": 1e-4 * bound})
    size = float(best.x)
    return float(best.fun), (-size if cause.form == "shift" else size)


def _cause_text(name: str, unit: str, size: _Size) -> str:
    if isinstance(size, tuple):
        return f"{name}, off by " + ", ".join(f"{x:+.3g} {unit} on '{part}'"
                                              for part, x in size)
    return name if math.isnan(size) else f"{name} off by {size:+.3g} {unit}"


def _weighed(fluxes: dict[int, np.ndarray], poles: list[int], area: float, run: Run,
             terms: EstimateTerms) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The poles' Maxwell phasors (n_poles, H+1), the harmonics compared (the kept ones, the
    DC where observed) and the weights of their real and imaginary parts, stacked."""
    h = terms.force.shape[1] - 1
    m = np.zeros((len(poles), h + 1), dtype=complex)
    m_std = np.zeros((len(poles), h + 1))
    for j, k in enumerate(poles):
        m[j], m_std[j] = _maxwell(fluxes[k], area, run, terms)
    scale = np.abs(m).max(axis=1, keepdims=True)
    sigma = np.sqrt(terms.std[poles] ** 2 + m_std**2 + (FRINGING * np.abs(m)) ** 2
                    + (1e-6 * scale) ** 2) + 1e-300
    return (m, *_compared(terms.kept, sigma))


def _compared(kept: np.ndarray, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The elements compared of rows (n, H+1) with standard deviations ``sigma``: the kept
    harmonics, the DC where observed; and the weights of their real parts, then of their
    imaginary parts (the DC's none)."""
    sel = np.zeros(sigma.shape, dtype=bool)
    sel[:, kept] = True
    sel[:, 0] &= bool(kept[0])
    harmonic = np.arange(sigma.shape[1])[None, :] > 0
    w = np.concatenate([(1 / sigma)[sel], np.where(harmonic, 1 / sigma, 0.0)[sel]])
    return sel, w


def flux_notes(rig: Rig, run: Run, terms: EstimateTerms, what: str) -> list[str]:
    """A note when the forces contradict their poles' Maxwell forces (see the module
    docstring), naming the causes that explain it; first, a core's own flux channels against
    each other (:func:`flux_pair_notes`), which the Maxwell check then leaves aside.

    Parameters
    ----------
    rig : Rig
        With ``actuator.pole_area`` and a flux channel (``forces[].flux`` or
        ``actuator.flux``); without them the check is not made (without the area, the flux
        channels of one core are still compared).
    run : Run
    terms : EstimateTerms
    what : str
        The run, at the start of the note.

    Returns
    -------
    list of str
    """
    fluxes = pole_fluxes(rig, run)
    area = rig.actuator.pole_area
    if not fluxes:
        return []
    if area is None:
        return flux_pair_notes(rig, run, terms, what)
    notes = [f"{what}: force '{f.name}': its flux channel '{f.flux}' (forces[{k}].flux) is not "
             "in the run; its force is not checked against Maxwell's stress"
             for k, f in enumerate(rig.forces) if f.flux is not None and k not in fluxes]
    poles = sorted(fluxes)
    pairs = _pair_misfits(rig, run, terms)           # once for the notes and the reason
    notes += _pair_texts(pairs, what, terms.rate)
    skipped = _unusable(rig, run, terms, fluxes, pairs)
    if skipped:
        return [*notes, f"{what}: {skipped}: the forces are not checked against Maxwell's "
                "stress Phi^2 / (2 mu0 A)"]
    m, sel, w = _weighed(fluxes, poles, area, run, terms)

    def pick(forces: np.ndarray) -> np.ndarray:
        return forces[poles][sel]

    def head(coef: np.ndarray) -> str:
        return (f"{what}: the forces {', '.join(rig.force_names[k] for k in poles)} disagree "
                f"with their poles' Maxwell force Phi^2 / (2 mu0 A) (A = actuator.pole_area, "
                f"c = {coef[0]:.3g})")

    return [*notes, *_judged(rig, terms, _Problem(m[sel], w, ()), pick, head)]


def _own_channels(rig: Rig, run: Run) -> dict[str, dict[int, str]]:
    """Each core whose poles read two or more flux channels of their own in the run: the
    first pole on each channel and its channel."""
    channels = _flux_channels(rig, run)
    out = {}
    for core, poles in rig.cores.items():
        own: dict[int, str] = {}
        for k in poles:
            if k in channels and channels[k] not in own.values():
                own[k] = channels[k]
        if len(own) > 1:
            out[core] = own
    return out


def _flux_misfit(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray],
                 kept: np.ndarray) -> tuple[float, int, float, float]:
    """(chi-square, its degrees of freedom, the chi-square of b - r a with r free, r) of two
    fluxes that must be one, each (phasors, standard uncertainties) over the kept columns: b
    = r a with r held to 1 within the fringing (the leakage between the poles: one ratio at
    every harmonic), the rest noise (for lines, whose noise is not stated, a thousandth of the
    largest)."""
    (pa, sa), (pb, sb) = a, b
    floor = (1e-3 if not np.any(sa) else 1e-6) * float(np.abs(pa[kept]).max())
    sel, w = _compared(kept, np.sqrt(sa**2 + sb**2 + floor**2)[None, :] + 1e-300)
    x, y = pa[None, :][sel], pb[None, :][sel]
    xs, ys = np.concatenate([x.real, x.imag]) * w, np.concatenate([y.real, y.imag]) * w
    free = float(xs @ ys / max(float(xs @ xs), 1e-300))
    held = float((xs @ ys + 1 / FRINGING**2) / (xs @ xs + 1 / FRINGING**2))
    chi2 = float(np.sum((ys - held * xs) ** 2)) + ((held - 1) / FRINGING) ** 2
    return chi2, int(np.count_nonzero(w)), float(np.sum((ys - free * xs) ** 2)), free


def flux_pair_notes(rig: Rig, run: Run, terms: EstimateTerms, what: str) -> list[str]:
    """A note per core whose poles' own flux channels disagree: poles in series on one coil
    carry one flux, so a channel's scale, sign or unit is off: the whole misfit with their
    ratio held to 1 within the fringing (:data:`FRINGING`), or the gain of freeing the ratio,
    beyond chance (each at half the terms' rate, :data:`FALSE_ALARM` a record); the ratio is
    named, and with the pole area the channel whose pole's force departs further from its
    Maxwell force is named first (both for a sign, which Phi^2 hides).

    Parameters
    ----------
    rig : Rig
        Poles of one core (``forces[].core``) with their own ``forces[].flux``.
    run : Run
    terms : EstimateTerms
    what : str
        The run, at the start of the note.

    Returns
    -------
    list of str
    """
    return _pair_texts(_pair_misfits(rig, run, terms), what, terms.rate)


def _pair_texts(pairs: list[tuple[str, str, str, tuple[float, int, float, float], str]],
                what: str, rate: float) -> list[str]:
    """The notes of :func:`flux_pair_notes` on the pairs :func:`_pair_misfits` found."""
    notes = []
    for core, c0, c, (chi2, dof, scaled, r), look in pairs:
        notes.append(
            f"{what}: the flux channels '{c0}' and '{c}' of core '{core}' (forces[].flux) "
            f"disagree, though poles of one core carry one flux: '{c}' reads {r:+.4g} times "
            f"'{c0}' (chi-square {chi2:.3g} for {dof} degrees of freedom with the ratio held "
            f"to 1 within the fringing ({FRINGING:.0%}), {scaled:.3g} with the ratio free; "
            f"chance exceeds {chi_square_limit(dof, rate / 2):.3g} and a gain of "
            f"{chi_square_limit(1, rate / 2):.3g}); look at {look}"
            + ("" if scaled <= chi_square_limit(dof - 1, rate)
               else "; or a delay, or another channel"))
    return notes


def _pair_misfits(rig: Rig, run: Run, terms: EstimateTerms
                  ) -> list[tuple[str, str, str, tuple[float, int, float, float], str]]:
    """(core, reference channel, channel, :func:`_flux_misfit`, where to look) of every pair
    of one core's flux channels that disagree, the reference the core's first channel unless
    it carries next to no flux (:data:`DEAD_RATIO`; then it reads 0 times the other)."""
    out = []
    for core, own in _own_channels(rig, run).items():
        phasors = {k: terms.phasors(rig.actuator.flux_scale * run.channel(c), run)
                   for k, c in own.items()}
        size = {k: float(np.abs(p[0][terms.kept]).sum()) for k, p in phasors.items()}
        (k0, c0), *rest = own.items()
        for k1, c1 in rest:
            (kr, cr), (k, c) = (((k1, c1), (k0, c0)) if size[k0] < DEAD_RATIO * size[k1]
                                else ((k0, c0), (k1, c1)))
            misfit = _flux_misfit(phasors[kr], phasors[k], terms.kept)
            chi2, dof, scaled, _ = misfit
            if chi2 <= chi_square_limit(dof, terms.rate / 2) and chi2 - scaled <= chi_square_limit(
                    1, terms.rate / 2):
                continue                  # neither the whole misfit nor the ratio's gain
            if abs(misfit[3]) < DEAD_RATIO:
                look = (f"'{c}' first: it carries next to no flux (a dead or unplugged channel, "
                        "or its unit far off)")
            elif _sign_only(misfit[3]):
                look = ("both: a sign (the force follows Phi^2, so neither force tells which; "
                        "the Maxwell check stands)")
            elif rig.actuator.pole_area is None:
                look = "both: a scale (actuator.flux_scale), sign or unit"
            else:
                off = {cr: _maxwell_departure(rig, run, terms, kr),
                       c: _maxwell_departure(rig, run, terms, k)}
                look = (f"'{max(off, key=off.__getitem__)}' first (its pole's force departs "
                        "further from its Maxwell force): a scale (actuator.flux_scale), sign "
                        "or unit")
            out.append((core, cr, c, misfit, look))
    return out


def _sign_only(ratio: float) -> bool:
    """Whether a ratio of two fluxes that must be one is -1 to within the fringing (3 of its
    standard deviations)."""
    return abs(ratio + 1) <= 3 * FRINGING


def _maxwell_departure(rig: Rig, run: Run, terms: EstimateTerms, pole: int) -> float:
    """How far a pole's force is from its Maxwell force over the kept columns (|g - 1|, g the
    fitted ratio), 0 without the pole area."""
    area = rig.actuator.pole_area
    channel = _flux_channels(rig, run).get(pole)
    if area is None or channel is None:
        return 0.0
    m, _ = _maxwell(rig.actuator.flux_scale * run.channel(channel), area, run, terms)
    f = terms.force[pole]
    keep = terms.kept
    g = float(np.real(np.vdot(m[keep], f[keep])) / max(float(np.vdot(m[keep], m[keep]).real),
                                                         1e-300))
    return abs(g - 1.0)


def _unusable(rig: Rig, run: Run, terms: EstimateTerms, fluxes: dict[int, np.ndarray],
              pairs: list[tuple[str, str, str, tuple[float, int, float, float], str]] | None
              = None) -> str | None:
    """Why the poles' flux channels cannot be weighed against their forces (a constant
    channel, one that lost the DC a drive's bias gives it, or a core's channels that
    disagree: ``pairs`` of :func:`_pair_misfits`, found here when not given), or None."""
    pairs = _pair_misfits(rig, run, terms) if pairs is None else pairs
    if any(not _sign_only(m[3][3]) for m in pairs):
        return "the flux channels of one core disagree (the note on them)"
    poles = sorted(fluxes)
    dc = max(abs(float(np.mean(fluxes[k]))) for k in poles)
    ac = max(float(np.std(fluxes[k])) for k in poles)
    if ac <= 1e-12 * dc:                 # a constant channel, to rounding
        return "the flux is constant, without any drive"
    if dc < 0.05 * ac and _biased(rig, run, terms, poles):
        return ("the flux holds no DC though the forces pull mostly at the drive's fundamental "
                "(an AC-coupled flux sensor, a search coil?)")
    return None


def _biased(rig: Rig, run: Run, terms: EstimateTerms, poles: list[int]) -> bool:
    """Whether the drive is biased, so that the flux must hold a DC: a steady drive's forces
    pull more at its fundamental than at twice it; any drive's current holds a DC (without the
    current channel, not said)."""
    if terms.lines is None:
        return bool(terms.force.shape[1] > 2 and np.abs(terms.force[poles, 1]).sum()
                    > np.abs(terms.force[poles, 2]).sum())
    if rig.actuator.current not in run.channels:
        return False
    current = run.channel(rig.actuator.current)
    return abs(float(np.mean(current))) > 0.05 * float(np.std(current))


def pole_notes(rig: Rig, run: Run, terms: EstimateTerms, what: str) -> list[str]:
    """A note per core whose poles pull unalike (see the module docstring), naming the causes
    that explain it; the cores whose every pole :func:`flux_notes` checks against its own
    flux are left to it (not where it cannot: a constant or AC-coupled flux channel).

    Parameters
    ----------
    rig : Rig
        Its :attr:`~forcecal.rig.Rig.cores` (``forces[].core``, or poles on one flux channel).
    run : Run
    terms : EstimateTerms
    what : str
        The run, at the start of the note.

    Returns
    -------
    list of str
    """
    fluxes = pole_fluxes(rig, run) if rig.actuator.pole_area is not None else {}
    maxwell = set(fluxes) if fluxes and not _unusable(rig, run, terms, fluxes) else set()
    return [note for core, poles in rig.cores.items() if not set(poles) <= maxwell
            for note in _core_notes(rig, terms, core, poles, what)]


def _core_notes(rig: Rig, terms: EstimateTerms, core: str, poles: list[int],
                what: str) -> list[str]:
    """:func:`pole_notes` of one core."""
    mean, sel, w = _alike(poles, terms)

    def pick(forces: np.ndarray) -> np.ndarray:
        f = forces[poles]
        return (f[:-1] - f.mean(axis=0))[sel]

    def head(coef: np.ndarray) -> str:
        # two poles: (F_a - mean) = (F_a - F_b) / 2 = c mean, their difference 2 c of the mean
        fitted = f"; their difference, fitted: {2 * coef[0]:+.2%}" if len(poles) == 2 else ""
        return (f"{what}: the forces {', '.join(rig.force_names[k] for k in poles)} of core "
                f"'{core}' (forces[].core) pull unalike, though poles of one core carry one "
                f"flux and pull alike to within fringing ({FRINGING:.0%}{fitted})")

    problem = _Problem(np.broadcast_to(mean, sel.shape)[sel], w, (), c_prior=FRINGING)
    return _judged(rig, terms, problem, pick, head)


def _alike(poles: list[int], terms: EstimateTerms) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The core's mean force (H+1,), the compared elements (each pole but the last, minus the
    mean; the kept harmonics, the DC where observed) and the weights of their real and
    imaginary parts, stacked."""
    n = len(poles)
    mean = terms.force[poles].mean(axis=0)
    std = terms.std[poles]
    # pole k less the mean, (1 - 1/n) F_k - (1/n) sum of the others: the forces' errors
    # correlate through Psi^+ (close poles' split errs in opposite senses), so their standard
    # deviations add, the most they can
    own = (1 - 2 / n) * std[:-1] + std.sum(axis=0) / n
    sigma = np.sqrt(own**2 + (FRINGING * np.abs(mean)) ** 2
                    + (1e-6 * np.abs(mean).max()) ** 2) + 1e-300
    return (mean, *_compared(terms.kept, sigma))


def _judged(rig: Rig, terms: EstimateTerms, problem: _Problem,
            pick: Callable[[np.ndarray], np.ndarray],
            head: Callable[[np.ndarray], str]) -> list[str]:
    """The note, if any, on the forces ``pick`` selects against ``problem``'s reference: the
    sensors' mistakes, one parameter each, decide (the whole misfit or one of their gains
    beyond chance, each at half the terms' rate, :data:`FALSE_ALARM` a record); the
    geometry's (a search over positions, a swap) only explain what they decided."""
    causes = _causes(rig, terms)
    problem = dataclasses.replace(problem, nuisance=tuple(
        (c.name, _column(c, pick), c.prior) for c in causes if c.prior > 0))
    dof = int(np.count_nonzero(problem.w)) - (0 if problem.c_prior else 1)
    if dof < 2:
        return []
    chi2, coef = problem.fit(pick(terms.force))
    period_ms = 1e3 * 2 * np.pi / max(float(terms.angular.max()), terms.w0)
    sensors = [c for c in causes if c.form in ("relative", "linear", "delay")]
    rate = terms.rate
    gain = chi_square_limit(1, rate / (2 * len(sensors)))
    whole = chi_square_limit(dof, rate / 2)
    if chi2 <= min(gain, whole):
        return []                    # no cause can gain more than the whole chi-square
    tried = sorted((c2, c.name, c.unit, size) for c in sensors
                   for c2, size in [_size(c, problem, pick, period_ms)])
    best_gain = chi2 - tried[0][0]
    if chi2 <= whole and best_gain <= gain:
        return []
    tried = sorted(tried + [(c2, c.name, c.unit, size) for c in causes if c not in sensors
                            for c2, size in [_size(c, problem, pick, period_ms)]])
    single = min((t[0] for t in tried if t[1] in {c.name for c in causes if c.form == "linear"}),
                 default=math.inf)
    tried = [t for t in tried if _free(t[3]) == 1 or single - t[0] > AKAIKE * (_free(t[3]) - 1)]
    each = rate / (2 * len(sensors))
    explain = [t for t in tried if chi2 - t[0] > chi_square_limit(_free(t[3]), each)
               and t[0] <= chi_square_limit(dof - _free(t[3]), rate)]
    return [f"{head(coef)}: chi-square {chi2:.3g} for {dof} degrees of freedom (chance exceeds "
            f"{whole:.3g} at a {rate / 2:.3g} rate), {best_gain:.3g} less with one sensor's "
            f"mistake free (chance: {gain:.3g})"
            + _explained(tried, explain, {c.name for c in sensors})]


def _free(size: _Size) -> int:
    """The parameters a cause of this size frees."""
    return len(size) if isinstance(size, tuple) else 1


def _explained(tried: list[tuple[float, str, str, _Size]],
               explain: list[tuple[float, str, str, _Size]], sensors: set[str]) -> str:
    """The note's tail: the causes that explain the misfit, the best first (among those the
    data cannot tell apart, a sensor's first: the likelier), or the closest when none does."""
    if not explain:
        best = tried[0]
        return ("; no single cause tried explains it (a gauge's scale or offset, a delay of the "
                "gauges or the probes, the inertia's scale, a gauge's or a force's position, a "
                f"swap); the closest: {_cause_text(best[1], best[2], best[3])} (chi-square "
                f"then {best[0]:.3g})")
    alike = sum(1 for t in explain if t[0] - explain[0][0] <= ALIKE)
    explain[:alike] = sorted(explain[:alike], key=lambda t: t[1] not in sensors)
    said = "; ".join(f"{_cause_text(name, unit, size)} (chi-square then {c2:.3g})"
                     for c2, name, unit, size in explain[:max(alike, 3)])
    return f"; explained by {said}" + (
        f" (the data cannot tell the first {alike} apart)" if alike > 1 else "")

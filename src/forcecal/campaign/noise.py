"""What the errors of one run do to its calibration samples: :class:`RunNoise` (METHOD.md
sections 5 and 7, "the whole uncertainty").

A run's calibration samples (:mod:`forcecal.campaign.samples`) are Fourier series of a few
phasors: the total force's (from the force estimate), the current's (its harmonic fit) and the
displacement at the poles (the probes' coordinates on the scan's shapes, and the probes' DC on
the quasi-static shape). Their errors are therefore errors of those phasors, and
:func:`run_noise` describes them per source (the force's, the current's and the probes' noise,
the tare record's, the scan's shapes and the rig's type-B parameters), as standard
uncertainties or as signed changes per standard uncertainty.
:mod:`forcecal.campaign.statistics` turns these into noise columns and systematic effects for
the calibration's parameters.

Shapes: ``H+1`` harmonics 0..H, ``n_poles`` force points of the actuator. SI units throughout.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..actuator.gaps import quasi_static_shape
from ..forces.budget import Parameter, SolveInputs, combination_phasors, model_couplings, parameters
from ..forces.coordinates import coordinate_map, sensor_weights
from ..forces.steady import ForceEstimate, channels_si, solve_inputs
from ..forces.uncertainty import ShapeOperators, shape_operators
from ..model.inertia import inertia_term
from ..model.ratio_errors import principal_directions
from ..model.relaxation import force_matrix
from ..model.spatial import SpatialModel
from ..records import Run
from ..rig import Rig
from ..signals.harmonics import HarmonicFit, fit_harmonics

__all__ = ["RunNoise"]

FORCE_NOISE_SOURCES = ("gauge noise", "unresolved harmonics", "probe noise")
"""The estimate's budget sources carried by :attr:`RunNoise.force_std` (``probe noise`` only
at harmonics without coordinates)."""

_PROBE_SCALE = re.compile(r"sensors\[(\d+)\]\.scale")


@dataclass(frozen=True)
class CoordinateNoise:
    """The probes' noise through the coordinates of one harmonic.

    Attributes
    ----------
    harmonic : int
        n.
    force : (n_q,) complex array [N]
        Change of the total force's phasor per unit change of each coordinate (zero when the
        harmonic's inertia is not in the estimate).
    motion : (n_poles, n_q) complex array [m]
        Change of the displacement phasor at every pole per unit change of each coordinate.
    cov : (n_q, n_q) array [1]
        Covariance of Re and of Im of the coordinates.
    """

    harmonic: int
    force: np.ndarray
    motion: np.ndarray
    cov: np.ndarray


@dataclass(frozen=True)
class SharedEffect:
    """One error shared by runs (a tare's noise, a shape error, a type-B parameter): its
    signed effect on a run, per standard uncertainty. Runs' effects with the same name are one
    error.

    Attributes
    ----------
    name : str
        The error (for a type-B parameter its rig key, as :func:`forcecal.forces.budget.parameters`
        names it).
    source : str
        Its budget source (``tare record``, ``scan shapes``,
        :data:`forcecal.forces.budget.SOURCES`).
    total : (H+1,) complex array [N]
        Change of the total force's phasors.
    motion : (n_poles, H+1) complex array [m]
        Change of the displacement phasors at the poles.
    """

    name: str
    source: str
    total: np.ndarray
    motion: np.ndarray


@dataclass(frozen=True)
class RunNoise:
    """The errors of one run's calibration samples, per source.

    Attributes
    ----------
    force_std : dict str -> (H+1,) array [N]
        Independent noise of the total force's phasors (Re and Im each; the DC real) per
        source of :data:`FORCE_NOISE_SOURCES`.
    current_std : (H+1,) array [A]
        The current phasors' standard uncertainties (Re and Im each; the DC real).
    coordinates : tuple of CoordinateNoise
        The probes' noise through the coordinates, one per harmonic with a shape.
    dc_shape : (n_poles,) array [m]
        The quasi-static shape at the poles: the DC displacement is its amplitude [1] times
        this.
    dc_std : float [1]
        Standard uncertainty of that amplitude from the run's own probe records.
    shared : tuple of SharedEffect
        The statistical errors shared with other runs: the tare record's gauge and probe
        means, the scan's shape coefficients.
    type_b : tuple of SharedEffect
        The rig's type-B parameters with a non-zero standard uncertainty.
    estimated : (H+1,) bool array or None
        The harmonics of the total force the estimate holds (its ``kept`` harmonics; the DC
        where the gauges measure it). The estimate sets the others to zero: they are not
        measured (a harmonic above the scan's band with no reaction above the gauges' noise),
        so their zero noise above says nothing of their error. None: every harmonic.
    """

    force_std: dict[str, np.ndarray]
    current_std: np.ndarray
    coordinates: tuple[CoordinateNoise, ...]
    dc_shape: np.ndarray
    dc_std: float
    shared: tuple[SharedEffect, ...] = field(default=())
    type_b: tuple[SharedEffect, ...] = field(default=())
    estimated: np.ndarray | None = None


def _total_gain(rig: Rig) -> np.ndarray:
    """(n_gauges,) [1]: the total force's change per unit change of each gauge's inertia term
    minus reaction (the total is the sum of the forces, ``Psi^+ (J - R)``)."""
    out: np.ndarray = np.ones(len(rig.forces)) @ np.linalg.pinv(force_matrix(rig))
    return out


def _coordinate_noise(rig: Rig, model: SpatialModel, estimate: ForceEstimate
                      ) -> tuple[tuple[CoordinateNoise, ...], set[int]]:
    """The coordinates' noise of every harmonic with a shape, and the harmonics whose force
    noise from the probes they carry."""
    h = int(estimate.harmonics[-1])
    coords = estimate.coordinates
    xp = rig.structure.coordinates(rig.force_points)
    a_total = _total_gain(rig)
    w0 = 2 * np.pi * estimate.f0
    out, carried = [], set()
    for k, n in enumerate(model.harmonics):
        n = int(n)
        if n > h or n == 0:
            continue
        members, _, cov = coords.span(k)
        cols = list(members)
        force = np.zeros(len(cols), dtype=complex)
        if estimate.with_inertia[n] and estimate.kept[n]:
            m = model.member_couplings(k)[:, cols]
            force = a_total @ inertia_term(m, np.eye(len(cols)), n * w0)
            carried.add(n)
        out.append(CoordinateNoise(harmonic=n, force=np.atleast_1d(force),
                                   motion=model.member_values(k, xp)[:, cols],
                                   cov=np.atleast_2d(np.real(cov))))
    return tuple(out), carried


def _probe_dc(rig: Rig, inputs: SolveInputs, tare: Run | None
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The probes' DC minus the tare's mean, as :func:`forcecal.actuator.gaps.pole_motion` takes it
    (the DC of the probes' harmonic fit, ``inputs.sensors``).

    Returns
    -------
    dc : (n_probes,) array [m]
    var_run : (n_probes,) array [m^2]
        Variance of the run's DC.
    var_tare : (n_probes,) array [m^2]
        Variance of the tare's mean (zero without a tare).
    """
    dc = inputs.sensors[:, 0].real.copy()
    var_run = inputs.sensor_std[:, 0] ** 2
    var_tare = np.zeros_like(var_run)
    if tare is not None:
        t_sig = channels_si(rig, tare)
        dc = dc - np.array([t_sig[s].mean() for s in rig.sensor_names])
        var_tare = np.array([t_sig[s].var() / t_sig[s].size for s in rig.sensor_names])
    return dc, var_run, var_tare


def _dc_amplitude(rig: Rig, model: SpatialModel, dc: np.ndarray, var: np.ndarray
                  ) -> tuple[float, np.ndarray, np.ndarray]:
    """The quasi-static amplitude fitted to the probes' DC, its gain on every probe's DC and
    the shape at the poles (the weights of :func:`forcecal.actuator.gaps.pole_motion`)."""
    shape = quasi_static_shape(model, rig)
    at_probes = shape(rig.sensor_points)
    w = 1.0 / np.maximum(var, np.finfo(float).tiny)
    gain = w * at_probes / np.sum(w * at_probes**2)
    xp = rig.structure.coordinates(rig.force_points)
    return float(gain @ dc), gain, np.asarray(shape(xp), dtype=float)


def pole_phasors(rig: Rig, model: SpatialModel, inputs: SolveInputs, dc: np.ndarray,
                 dc_var: np.ndarray) -> np.ndarray:
    """The displacement phasors at the poles from fixed probe phasors, as
    :func:`forcecal.actuator.gaps.pole_motion` computes them (the coordinates by the weighted least
    squares of the estimate over the members it used, the DC on the quasi-static shape).

    Parameters
    ----------
    rig : Rig
        Possibly perturbed (moved points).
    model : SpatialModel
    inputs : SolveInputs
        The probes' phasors and standard uncertainties, and the members used.
    dc : (n_probes,) array [m]
        The probes' DC minus the tare's.
    dc_var : (n_probes,) array [m^2]
        Its variances (the weights of the DC fit).

    Returns
    -------
    (n_poles, H+1) complex array [m]
    """
    h = inputs.sensors.shape[1] - 1
    at = rig.structure.coordinates(rig.sensor_points)
    xp = rig.structure.coordinates(rig.force_points)
    out = np.zeros((len(rig.forces), h + 1), dtype=complex)
    for k, n in enumerate(model.harmonics):
        n = int(n)
        if n > h or n == 0:
            continue
        cols = list(inputs.members[k])
        phi = model.member_values(k, at)[:, cols]
        gain, _ = coordinate_map(phi, sensor_weights(inputs.sensor_std[:, n]))
        out[:, n] = model.member_values(k, xp)[:, cols] @ np.atleast_1d(gain @ inputs.sensors[:, n])
    amplitude, _, at_poles = _dc_amplitude(rig, model, dc, dc_var)
    out[:, 0] = amplitude * at_poles
    return out


def _type_b_effects(rig: Rig, model: SpatialModel, inputs: SolveInputs, dc: np.ndarray,
                    dc_var: np.ndarray, row: int) -> tuple[SharedEffect, ...]:
    """Every type-B parameter's signed change of the total force and of the pole displacement
    per standard uncertainty (central differences, the estimate's force solve)."""
    out = []
    for p in parameters(rig, inputs):
        ends = [_moved(rig, model, p, d, dc, dc_var, row) for d in (p.std, -p.std)]
        out.append(SharedEffect(name=p.name, source=p.source,
                                total=0.5 * (ends[0][0] - ends[1][0]),
                                motion=0.5 * (ends[0][1] - ends[1][1])))
    return tuple(out)


def _moved(rig: Rig, model: SpatialModel, p: Parameter, d: float, dc: np.ndarray,
           dc_var: np.ndarray, row: int) -> tuple[np.ndarray, np.ndarray]:
    """The total force's and the pole displacement's phasors with parameter ``p`` at ``d``."""
    rig_p, inputs_p, recouple = p.apply(d)
    couplings = model_couplings(rig_p, model) if recouple else None
    total = combination_phasors(rig_p, model, inputs_p, couplings)[row]
    scale = _PROBE_SCALE.fullmatch(p.name)
    dc_p = dc.copy()
    if scale is not None:
        dc_p[int(scale.group(1))] *= 1.0 + d
    return total, pole_phasors(rig_p, model, inputs_p, dc_p, dc_var)


def _rotor(model: SpatialModel, rig: Rig, values: Callable[[np.ndarray], np.ndarray]
           ) -> complex:
    """The unit rotor of :func:`forcecal.actuator.gaps.quasi_static_shape` (its shape is
    ``Re(values rotor)``, ``values`` the shape it stands on at structure coordinates: the
    lowest harmonic's, or the model's quasi-static shape), recovered by least squares at the
    probes and the poles."""
    shape = quasi_static_shape(model, rig)
    points = np.concatenate([rig.sensor_points, rig.force_points])
    phi = values(rig.structure.coordinates(points))
    a = np.column_stack([phi.real, -phi.imag])
    (c, s), *_ = np.linalg.lstsq(a, shape(points), rcond=None)
    return complex(c, s)


@dataclass(frozen=True)
class _ShapeRun:
    """What one run's shape errors act on (fixed inputs of :func:`_shape_change`): the
    estimate's inputs, the total's gain on the gauges, the probes' DC and its variances, the
    quasi-static shape (the harmonic whose shape stands in for it, None when the model has its
    own, its rotor and values at the probes and the poles), and the basis functions' couplings
    and values at the probes (:func:`forcecal.forces.uncertainty.shape_operators`)."""

    rig: Rig
    model: SpatialModel
    inputs: SolveInputs
    a_total: np.ndarray
    dc: np.ndarray
    dc_var: np.ndarray
    n1: int | None
    rotor: complex
    dc_probes: np.ndarray
    dc_poles: np.ndarray
    ops: ShapeOperators


def _dc_moved(run: _ShapeRun, at_probes: np.ndarray, at_poles: np.ndarray, rotor: complex
              ) -> np.ndarray:
    """(n_poles,) [m]: the DC deflection at the poles with the quasi-static shape moved by
    ``at_probes`` and ``at_poles`` (the change of the shape it stands on, before its rotor):
    its amplitude fitted to the probes' DC again, as
    :func:`forcecal.actuator.gaps.pole_motion` fits it."""
    shape_probes = run.dc_probes + (at_probes * rotor).real
    w = 1.0 / np.maximum(run.dc_var, np.finfo(float).tiny)
    amplitude = float(np.sum(w * shape_probes * run.dc) / np.sum(w * shape_probes**2))
    out: np.ndarray = amplitude * (run.dc_poles + (at_poles * rotor).real)
    return out


def _shape_change(run: _ShapeRun, k: int, member: int, at_poles: np.ndarray, delta: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The total force's and the pole displacement's phasors with harmonic k's member shape
    moved by ``delta`` (its coefficients; ``at_poles`` its basis at the poles): couplings,
    coordinates, the shape at the poles and, for the quasi-static shape's harmonic, the DC
    deflection."""
    rig, model, inputs = run.rig, run.model, run.inputs
    h = inputs.sensors.shape[1] - 1
    n = int(model.harmonics[k])
    at_probes = run.ops.at_sensors[k][member] @ delta
    total = np.zeros(h + 1, dtype=complex)
    motion = np.zeros((len(rig.forces), h + 1), dtype=complex)
    cols = list(inputs.members[k])
    phi_s = model.member_values(k, rig.structure.coordinates(rig.sensor_points))[:, cols]
    phi_p = model.member_values(k, rig.structure.coordinates(rig.force_points))[:, cols]
    m = model.member_couplings(k)[:, cols]
    if member in cols:
        j = cols.index(member)
        phi_s[:, j] += at_probes
        phi_p[:, j] += at_poles @ delta
        m[:, j] += run.ops.couplings[k][member] @ delta
    gain, _ = coordinate_map(phi_s, sensor_weights(inputs.sensor_std[:, n]))
    q = np.atleast_1d(gain @ inputs.sensors[:, n])
    if inputs.with_inertia[n] and inputs.kept[n]:
        total[n] = run.a_total @ inertia_term(m, q, n * inputs.w0)
    motion[:, n] = phi_p @ q
    if n == run.n1 and member == 0:
        motion[:, 0] = _dc_moved(run, at_probes, at_poles @ delta, run.rotor)
    return total, motion


def _static_covariance(model: SpatialModel) -> np.ndarray | None:
    """The covariance [m^2] of the coefficients of the model's own quasi-static shape (a
    broadband scan's, :func:`forcecal.model.broadband.steady_model`), None without one."""
    cov = getattr(model.static_shape, "coefficient_covariance", None)
    return None if cov is None else np.asarray(cov, dtype=float)


def _holds(cov: np.ndarray, part: np.ndarray) -> bool:
    """Whether a coefficient covariance holds ``part`` (of the same basis; what is left is a
    covariance, to round-off): a broadband model builds its quasi-static shape and every
    harmonic's on the span's first shape, ``phi_1 + sum_k phi_k a_k / a_1`` with real
    ``phi_k``, and the first shape's error is theirs alike."""
    if cov.shape != part.shape:
        return False
    scale = float(np.max(np.diag(cov), initial=0.0))
    return bool(np.linalg.eigvalsh(cov - part).min() >= -1e-9 * max(scale, 1e-300))


def _directions(cov: np.ndarray, scale: float) -> list[np.ndarray]:
    """The principal directions of a coefficient covariance, each scaled by its standard
    deviation, those above round-off of ``scale`` (the largest variance it is part of)."""
    return list(principal_directions(cov, floor=1e-12 * max(scale, 1e-300)))


def _static_effects(run: _ShapeRun, cov: np.ndarray) -> tuple[SharedEffect, ...]:
    """The error of the model's own quasi-static shape (:func:`_static_covariance`): along each
    principal direction of its covariance (real, as the span's shapes are), its signed change
    of the DC deflection and, with it, of every harmonic's shape that holds the same error
    (:func:`_holds`), and so of the total force and of the pole displacement (central
    differences). Every run of the model shares it, whatever its frequency."""
    model, rig = run.model, run.rig
    static = model.static_shape
    assert static is not None, "a model with a quasi-static shape of its own"
    xs = rig.structure.coordinates(rig.sensor_points)
    xp = rig.structure.coordinates(rig.force_points)
    at_probes, at_poles = static.basis.evaluate(xs), static.basis.evaluate(xp)
    rotor = _rotor(model, rig, static.evaluate)
    h = run.inputs.sensors.shape[1] - 1
    harmonics = [(k, model.shapes[k].basis.evaluate(xp)) for k, n in enumerate(model.harmonics)
                 if 1 <= int(n) <= h and _holds(np.asarray(
                     getattr(model.shapes[k], "coefficient_covariance", np.zeros(0)),
                     dtype=float), cov)]
    out = []
    for d, step in enumerate(_directions(cov, float(np.max(np.diag(cov), initial=0.0)))):
        ends = []
        for delta in (step, -step):
            total = np.zeros(h + 1, dtype=complex)
            motion = np.zeros((len(rig.forces), h + 1), dtype=complex)
            for k, basis_poles in harmonics:
                t, m = _shape_change(run, k, 0, basis_poles, delta)
                total, motion = total + t, motion + m
            motion[:, 0] = _dc_moved(run, at_probes @ delta, at_poles @ delta, rotor)
            ends.append((total, motion))
        out.append(SharedEffect(name=f"quasi-static shape direction {d}",
                                source="scan shapes", total=0.5 * (ends[0][0] - ends[1][0]),
                                motion=0.5 * (ends[0][1] - ends[1][1])))
    return tuple(out)


def _shared_shape_effects(run: _ShapeRun) -> tuple[SharedEffect, ...]:
    """The shapes' errors that every run of the model shares whatever its frequency
    (:attr:`forcecal.model.spatial.SpatialModel.shared_errors`: a broadband model's smoothed
    ratios): each moves every harmonic's shape and the quasi-static shape at once, and so the
    total force and the pole displacement (changes from the estimate's own: linear)."""
    model, rig = run.model, run.rig
    static = model.static_shape
    if not model.shared_errors or static is None:
        return ()
    xs = rig.structure.coordinates(rig.sensor_points)
    xp = rig.structure.coordinates(rig.force_points)
    dc_probes, dc_poles = static.basis.evaluate(xs), static.basis.evaluate(xp)
    rotor = _rotor(model, rig, static.evaluate)
    h = run.inputs.sensors.shape[1] - 1
    zero = np.zeros(dc_probes.shape[1])
    base_dc = _dc_moved(run, dc_probes @ zero, dc_poles @ zero, rotor)
    harmonics = [(k, model.shapes[k].basis.evaluate(xp)) for k, n in enumerate(model.harmonics)
                 if 1 <= int(n) <= h]
    base = {k: _shape_change(run, k, 0, at_poles, np.zeros(at_poles.shape[1]))
            for k, at_poles in harmonics}
    out = []
    for name, change, dc in model.shared_errors:
        total = np.zeros(h + 1, dtype=complex)
        motion = np.zeros((len(rig.forces), h + 1), dtype=complex)
        for k, at_poles in harmonics:
            t, m = _shape_change(run, k, 0, at_poles, change[k])
            total, motion = total + t - base[k][0], motion + m - base[k][1]
        motion[:, 0] = _dc_moved(run, dc_probes @ dc, dc_poles @ dc, rotor) - base_dc
        out.append(SharedEffect(name=name, source="scan shapes", total=total, motion=motion))
    return tuple(out)


def _shape_effects(run: _ShapeRun) -> tuple[SharedEffect, ...]:
    """The scan shapes' errors: for every harmonic's members, each principal direction of the
    coefficients' covariance (Re and Im), its signed change of the total force and of the pole
    displacement (central differences). Each is named with its harmonic's frequency: runs share
    it when their model's shape at that frequency is one (a steady scan's at its fundamental; a
    broadband model's differs from one frequency to the next). A model's own quasi-static
    shape has its error too, which moves the DC deflection of every run and the harmonics'
    shapes that hold it (:func:`_static_effects`); those keep the rest of their covariance."""
    model = run.model
    static = _static_covariance(model)
    out = list(_static_effects(run, static)) if static is not None else []
    out += _shared_shape_effects(run)
    xp = run.rig.structure.coordinates(run.rig.force_points)
    for k, n in enumerate(model.harmonics):
        if int(n) > run.inputs.sensors.shape[1] - 1 or int(n) == 0:
            continue
        for member, fit in enumerate(model.members(k)):
            cov = getattr(fit, "coefficient_covariance", None)
            if cov is None:
                continue
            cov = np.asarray(cov, dtype=float)
            scale = float(np.max(np.diag(cov), initial=0.0))
            if member == 0 and static is not None and _holds(cov, static):
                cov = cov - static
            at_poles = fit.basis.evaluate(xp)
            for d, step in enumerate(_directions(cov, scale)):
                for part, unit in (("re", 1.0), ("im", 1j)):
                    plus = _shape_change(run, k, member, at_poles, unit * step)
                    minus = _shape_change(run, k, member, at_poles, -unit * step)
                    out.append(SharedEffect(
                        name=f"shape n={int(n)} ({int(n) * model.f0:.4g} Hz) member "
                             f"{member} direction {d} {part}",
                        source="scan shapes", total=0.5 * (plus[0] - minus[0]),
                        motion=0.5 * (plus[1] - minus[1])))
    return tuple(out)


def _tare_effects(rig: Rig, tare: Run, name: str, dc_gain: np.ndarray, var_tare: np.ndarray,
                  dc_shape: np.ndarray, h: int, dc_observed: bool) -> tuple[SharedEffect, ...]:
    """The tare record's noise: every gauge's mean (the total force's DC, when observed) and
    every probe's mean (the DC deflection), shared by the runs that used it."""
    out = []
    n_poles = len(dc_shape)
    if dc_observed:
        t_sig = channels_si(rig, tare)
        gain = _total_gain(rig)
        for g, gauge in enumerate(rig.gauge_names):
            total = np.zeros(h + 1, dtype=complex)
            total[0] = gain[g] * np.sqrt(t_sig[gauge].var() / t_sig[gauge].size)
            out.append(SharedEffect(f"tare '{name}' {gauge}", "tare record", total,
                                    np.zeros((n_poles, h + 1), dtype=complex)))
    for j, sensor in enumerate(rig.sensor_names):
        motion = np.zeros((n_poles, h + 1), dtype=complex)
        motion[:, 0] = -dc_gain[j] * np.sqrt(var_tare[j]) * dc_shape
        out.append(SharedEffect(f"tare '{name}' {sensor}", "tare record",
                                np.zeros(h + 1, dtype=complex), motion))
    return tuple(out)


def run_noise(rig: Rig, model: SpatialModel, run: Run, estimate: ForceEstimate,
              tare: Run | None = None, tare_name: str | None = None,
              current: HarmonicFit | None = None) -> RunNoise:
    """The errors of one run's calibration samples, per source.

    Parameters
    ----------
    rig : Rig
        With the run's static gaps.
    model : SpatialModel
        The harmonic shapes.
    run : Run
        The recording.
    estimate : ForceEstimate
        Its reconstruction (with the budget).
    tare : Run or None
        The zero-current record the estimate subtracted.
    tare_name : str or None
        Its name (runs sharing a tare share its noise); default ``tare.name``.
    current : HarmonicFit or None
        The current channel's harmonic fit, when already made (over the estimate's ``f0`` and
        harmonics).

    Returns
    -------
    RunNoise

    Notes
    -----
    The sources, as standard uncertainties or as signed changes per standard uncertainty:

    - the force's own noise (the estimate's budget: ``gauge noise``, ``unresolved
      harmonics``, and ``probe noise`` of harmonics without coordinates), independent
      between runs;
    - the current's noise, from its harmonic fit, independent between runs;
    - the probes' noise through the coordinates ``Q_n``: one error of ``Q_n`` moves both the
      inertia force (``dF/dQ``) and the pole displacement (``dw/dQ``), so the two are kept
      together; the probes' DC moves the quasi-static deflection;
    - the tare record's noise, in the gauges' DC and the probes' zero: shared by every run
      that used the same tare;
    - the scan's shapes: one error of the shape coefficients (along each principal direction
      of their covariance, Re and Im) moves the mass couplings, the coordinates fitted to the
      probes, the shape at the poles and the quasi-static shape of every run at once; each
      run's resulting change of its total force and pole displacement is computed with the
      estimate's formulas;
    - the rig's type-B parameters (:func:`forcecal.forces.budget.parameters`), each as its
      signed change of the total force's phasors and of the pole displacement per standard
      uncertainty, with the estimate's own force solve and the displacement computed as
      :func:`forcecal.actuator.gaps.pole_motion` does.
    - which harmonics the estimate holds at all (``estimated``): the others are zero in the
      samples, not measured, and their noise is not stated.
    """
    h = int(estimate.harmonics[-1])
    row = estimate.combination_names.index("total")
    if current is None:
        sig = channels_si(rig, run)
        current = fit_harmonics(sig[rig.actuator.current], run.fs, estimate.f0, h, t0=run.t0)
    coordinates, carried = _coordinate_noise(rig, model, estimate)
    force_std = {}
    for source in FORCE_NOISE_SOURCES:
        std = np.array(estimate.budget.get(source, np.zeros((row + 1, h + 1)))[row], dtype=float)
        if source == "probe noise":
            std[sorted(carried)] = 0.0
        force_std[source] = std
    inputs = solve_inputs(rig, model, run, estimate, tare)
    dc, var_run, var_tare = _probe_dc(rig, inputs, tare)
    _, dc_gain, dc_shape = _dc_amplitude(rig, model, dc, var_run + var_tare)
    base = quasi_static_shape(model, rig)
    n1: int | None = None                    # a DC shape of its own: no harmonic's errors move it
    rotor = 1.0 + 0.0j
    if model.static_shape is None:           # the fundamental's shape stands in for it
        n1 = 1 if 1 in model.harmonics else int(np.min(model.harmonics))
        rotor = _rotor(model, rig, lambda at: model.shape_values(n1, at))
    shapes = _ShapeRun(rig=rig, model=model, inputs=inputs, a_total=_total_gain(rig), dc=dc,
                       dc_var=var_run + var_tare, n1=n1, rotor=rotor,
                       dc_probes=base(rig.sensor_points), dc_poles=base(rig.force_points),
                       ops=shape_operators(model, rig))
    shared = _shape_effects(shapes)
    if tare is not None:
        shared += _tare_effects(rig, tare, tare_name or tare.name, dc_gain, var_tare, dc_shape,
                                h, estimate.dc_observed)
    return RunNoise(
        force_std=force_std,
        current_std=np.asarray(current.phasor_std, dtype=float),
        coordinates=coordinates,
        dc_shape=dc_shape,
        dc_std=float(np.sqrt(np.sum(dc_gain**2 * var_run))),
        shared=shared,
        type_b=_type_b_effects(rig, model, inputs, dc, var_run + var_tare, row),
        estimated=np.asarray(estimate.kept, dtype=bool)
        & np.r_[bool(estimate.dc_observed), np.ones(h, dtype=bool)],
    )

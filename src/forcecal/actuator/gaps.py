"""Displacement of the structure at the actuator's poles and the instantaneous air gap.

METHOD.md section 5 fits the actuator's law against the instantaneous gap of every pole,
``s_p(t) = s_0,p - w(x_p, t)`` (not the mean gap), where the displacement at the pole comes
from the spatial model and the run's generalized coordinates,
``w(x_p, t) = w_dc(x_p) + sum_n Re(phi_n(x_p) Q_n exp(j n w0 t))``.

The harmonic shapes say nothing about the static (DC) deflection, which the probes' DC values
(minus the tare's) measure: they are fitted with one quasi-static shape
(:func:`quasi_static_shape`, which tells the approximation's limits), and that shape gives
the DC deflection at the poles (:func:`pole_motion`).

Shapes: ``n_poles`` force points of the actuator, ``H`` the highest harmonic, ``n_t`` instants.
SI units throughout.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..forces.coordinates import deflection
from ..forces.steady import ForceEstimate, channels_si
from ..model.spatial import SpatialModel
from ..records import Run
from ..rig import Rig
from ..signals.harmonics import fit_harmonics

__all__ = ["PoleMotion", "fourier_series", "pole_motion", "quasi_static_shape", "static_gaps"]

_SHAPE_GRID = 401


def fourier_series(phasors: np.ndarray, f0: float, t: np.ndarray) -> np.ndarray:
    """Fourier series ``X_0 + sum Re(X_n exp(j n w0 t))`` at absolute times.

    Parameters
    ----------
    phasors : (..., H+1) complex array
        ``X_0`` (real) to ``X_H``, in the convention of :mod:`forcecal.signals.harmonics`.
    f0 : float [Hz]
        The fundamental.
    t : (n_t,) array [s]
        Absolute instants.

    Returns
    -------
    (..., n_t) array
        Real values, in the unit of the phasors.
    """
    n = np.arange(phasors.shape[-1])
    cycles = np.mod(np.multiply.outer(n * f0, np.asarray(t, dtype=float)), 1.0)
    return (phasors @ np.exp(2j * np.pi * cycles)).real


def quasi_static_shape(model: SpatialModel, rig: Rig) -> Callable[[np.ndarray], np.ndarray]:
    """The shape used for the DC deflection: Re of the lowest harmonic's shape, made real (the
    model's own quasi-static shape, made real, when it has one).

    The fundamental's shape phi_1 (or the lowest harmonic the model has) is rotated by the
    phase that makes it most real, ``theta = arg(sum phi^2) / 2`` over the structure, and its
    real part is taken.

    The harmonic shapes come from the scan and say nothing about the static deflection, yet
    the DC pull of the magnet bends the structure by a sizeable fraction of the gap. The
    probes measure it: their DC values (minus the tare record's, which fixes the probes' zero
    at zero current) are fitted by least squares with this ONE shape, which then gives the DC
    deflection at the poles. This is an approximation whose limits are:

    - phi_1 is the response at w0, so it carries the inertia loading of the drive frequency;
      the static shape lacks it. The error grows like (f0 / f1)^2 relative to the first
      bending resonance f1; near a resonance the approximation fails.
    - The DC load must be distributed over the poles like the AC load: true for one magnet
      whose poles carry one flux, not for several magnets driven with different DC/AC ratios.
    - Any other static load (preload, a change of gravity sag) must be in the tare.
    - With more probes than one, the misfit of the probes' DC to the shape is reported per run
      (``dc_misfit``); it is the warning sign that the quasi-static shape does not hold.

    A model built from a broadband scan (:func:`forcecal.model.broadband.steady_model`) has
    measured the quasi-static shape itself, the operating shape at the lowest line of its band
    (``SpatialModel.static_shape``), and that shape is taken instead.

    Parameters
    ----------
    model : SpatialModel
        The harmonic shapes.
    rig : Rig
        The structure the shapes live on.

    Returns
    -------
    callable
        ``points -> (n,) [m]``, the shape at points of the structure (as
        :meth:`forcecal.structures.Structure.coordinates` gives them); its scale and sign are
        arbitrary (the DC amplitude is fitted to the probes).
    """
    n1 = 1 if 1 in model.harmonics else int(np.min(model.harmonics))
    static = model.static_shape
    values = ((lambda at: model.shape_values(n1, at)) if static is None
              else static.evaluate)
    phi = values(rig.structure.grid(_SHAPE_GRID))
    rotor = np.exp(-0.5j * np.angle(np.sum(phi**2)))

    def shape(points: np.ndarray) -> np.ndarray:
        return (values(rig.structure.coordinates(points)) * rotor).real

    return shape


@dataclass(frozen=True)
class PoleMotion:
    """Displacement of the structure at the actuator's poles over one run.

    Attributes
    ----------
    f0 : float [Hz]
        The run's fundamental.
    phasors : (n_poles, H+1) complex array [m]
        ``w(x_p)`` as a Fourier series; column 0 is the DC deflection (real), the others
        ``phi_n(x_p) Q_n`` (zero for harmonics without a shape in the model).
    static_gap : (n_poles,) array [m]
        Static gap of every pole with the structure at w = 0 (the manifest's, else the rig's).
    dc_misfit : float [m]
        RMS misfit of the probes' DC values to the quasi-static shape (NaN with one probe).
    """

    f0: float
    phasors: np.ndarray
    static_gap: np.ndarray
    dc_misfit: float

    @property
    def dc(self) -> np.ndarray:
        """DC deflection at every pole, (n_poles,) [m], positive toward the magnet."""
        return self.phasors[:, 0].real

    def deflection(self, t: np.ndarray) -> np.ndarray:
        """``w(x_p, t)`` at absolute times.

        Parameters
        ----------
        t : (n_t,) array [s]
            Absolute instants.

        Returns
        -------
        (n_poles, n_t) array [m]
            Displacement at every pole, positive toward the magnet.
        """
        return fourier_series(self.phasors, self.f0, t)

    def gaps(self, t: np.ndarray) -> np.ndarray:
        """Instantaneous air gaps ``s_0,p - w(x_p, t)``.

        Parameters
        ----------
        t : (n_t,) array [s]
            Absolute instants.

        Returns
        -------
        (n_poles, n_t) array [m]
            Air gap at every pole.
        """
        return self.static_gap[:, None] - self.deflection(t)


def static_gaps(rig: Rig) -> np.ndarray:
    """Static gap of every force point of the rig.

    Parameters
    ----------
    rig : Rig
        With the run's static gaps in ``rig.forces``.

    Returns
    -------
    (n_poles,) array [m]
        The static gap of every force point, in the rig's order.

    Raises
    ------
    InputError
        Naming the force points without a gap.
    """
    gaps = [f.gap for f in rig.forces]
    missing = [f.name for f, gap in zip(rig.forces, gaps, strict=True) if gap is None]
    if missing:
        raise InputError(
            f"rig '{rig.source}': no static gap for force point {', '.join(missing)}; give "
            "'gap' in the rig's [[forces]] or a 'gap' column in the manifest"
        )
    return np.array([float(gap) for gap in gaps if gap is not None])


def _harmonic_phasors(
    model: SpatialModel, estimate: ForceEstimate, xp: np.ndarray, n_poles: int
) -> np.ndarray:
    """``phi_n(x_p) Q_n`` of every harmonic, (n_poles, H+1) complex [m]; column 0 is zero."""
    h = int(estimate.harmonics[-1])
    phasors = np.zeros((n_poles, h + 1), dtype=complex)
    coords = estimate.coordinates
    for k, n in enumerate(coords.harmonics):
        n = int(n)
        if n <= h:
            phasors[:, n] = deflection(model, coords, k, xp)
    return phasors


def _probe_dc(
    rig: Rig, run: Run, estimate: ForceEstimate, tare: Run | None
) -> tuple[np.ndarray, np.ndarray]:
    """DC values of the probes, minus the tare's, and their variances.

    Returns
    -------
    dc : (n_probes,) array [m]
        DC of the harmonic fit of each probe, minus the tare record's mean.
    var : (n_probes,) array [m^2]
        Variance of ``dc``.
    """
    h = int(estimate.harmonics[-1])
    sig = channels_si(rig, run)
    probes = np.stack([sig[s] for s in rig.sensor_names])
    fit = fit_harmonics(probes, run.fs, estimate.f0, h, t0=run.t0)
    dc = fit.phasors[:, 0].real
    var = fit.phasor_std[:, 0] ** 2
    if tare is not None:
        t_sig = channels_si(rig, tare)
        zero = np.array([t_sig[s].mean() for s in rig.sensor_names])
        dc = dc - zero
        var = var + np.array([t_sig[s].var() / t_sig[s].size for s in rig.sensor_names])
    return dc, var


def pole_motion(
    rig: Rig, model: SpatialModel, run: Run, estimate: ForceEstimate, tare: Run | None = None
) -> PoleMotion:
    """Displacement at the poles from the spatial model, the run's coordinates and probes' DC.

    Parameters
    ----------
    rig : Rig
        With the run's static gaps in ``rig.forces`` (see
        :func:`forcecal.campaign.rig_for_entry`).
    model : SpatialModel
        The harmonic shapes.
    run : Run
        The recording, for the probes' DC values.
    estimate : ForceEstimate
        Its ``coordinates`` (Q_n) and refined ``f0``.
    tare : Run or None
        A zero-current record; its probe means are the probes' zero.

    Returns
    -------
    PoleMotion
        Harmonic phasors and DC deflection at the poles, with the static gaps.

    Raises
    ------
    InputError
        When a force point has no static gap.
    """
    xp = rig.structure.coordinates(rig.force_points)
    phasors = _harmonic_phasors(model, estimate, xp, len(rig.forces))
    dc, var = _probe_dc(rig, run, estimate, tare)
    shape = quasi_static_shape(model, rig)
    at_probes = shape(rig.sensor_points)
    w = 1.0 / np.maximum(var, np.finfo(float).tiny)
    amplitude = float(np.sum(w * at_probes * dc) / np.sum(w * at_probes**2))
    misfit = dc - amplitude * at_probes
    dc_misfit = float(np.sqrt(np.mean(misfit**2))) if dc.size > 1 else float("nan")
    phasors[:, 0] = amplitude * shape(xp)
    return PoleMotion(
        f0=estimate.f0, phasors=phasors, static_gap=static_gaps(rig), dc_misfit=dc_misfit
    )

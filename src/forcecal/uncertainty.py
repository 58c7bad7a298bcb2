"""Uncertainty of the reconstructed forces (METHOD.md section 6).

Linear propagation, per harmonic and separately for Re and Im, to any linear combination of the
forces (each force, the total, the resultant's moments) from:

- the gauges' noise (each channel's residual noise, through Psi^+);
- the generalized coordinate's noise (the sensors' noise, through m_{r,n} (n w0)^2);
- the scan model's shape coefficients (their covariance, through a numerical Jacobian of the
  whole inertia term: shape at the sensors, coordinate, mass coupling, computed with the same
  formulas as the estimate: :func:`forcecal.coordinates.coordinate_map`,
  :func:`forcecal.inertia.inertia_term`);
- for a harmonic the scan could not resolve, a bound on its uncompensated inertia.

The force solve F = Psi^+ (J - R) is linear: its sensitivity to J and to R is the map
``a_r`` = (combination rows) Psi^+ that every function here takes.

Near a resonance, where F is a small difference of large numbers, every term grows with the
inertia, and so does the stated uncertainty.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .coordinates import coordinate_map, sensor_weights
from .harmonics import HarmonicFit
from .inertia import inertia_term, mass_weights
from .rig import Rig
from .spatial import SpatialModel

__all__ = [
    "ShapeOperators",
    "combinations",
    "gauge_variance",
    "inertia_variance",
    "shape_jacobian",
    "shape_operators",
    "unresolved_inertia",
    "unresolved_inertia_bound",
]


def combinations(rig: Rig) -> tuple[tuple[str, ...], np.ndarray]:
    """Linear combinations of the forces that are reported
    (:meth:`forcecal.structures.Structure.combinations`).

    Parameters
    ----------
    rig : Rig

    Returns
    -------
    names : tuple of str
    matrix : (n_combinations, n_forces) ndarray
    """
    return rig.structure.combinations(rig.force_points, rig.force_names)


def gauge_variance(a_r: np.ndarray, gauges: HarmonicFit) -> np.ndarray:
    """Variance of Re (and of Im) of each combination from the gauges' noise.

    Parameters
    ----------
    a_r : (n_c, n_gauges) ndarray
        [1] combination rows times Psi^+.
    gauges : HarmonicFit
        The gauges' harmonic fit.

    Returns
    -------
    (n_c, H+1) ndarray [N^2]
    """
    var: np.ndarray = (a_r**2) @ gauges.phasor_std**2
    return var


@dataclass(frozen=True)
class ShapeOperators:
    """Every shape's basis functions where the inertia term needs them, for one rig and model.

    Attributes
    ----------
    couplings : tuple of (n_gauges, n_funcs) ndarray
        [kg] mass coupling of every basis function (the shape's coupling is ``c @ p``).
    at_sensors : tuple of (n_sensors, n_funcs) ndarray
        [1] the basis functions at the sensors (the shape there is ``b @ p``).
    """

    couplings: tuple[np.ndarray, ...]
    at_sensors: tuple[np.ndarray, ...]


def shape_operators(model: SpatialModel, rig: Rig) -> ShapeOperators:
    """The mass quadrature and the sensors applied to every basis function, once per run.

    Parameters
    ----------
    model : SpatialModel
    rig : Rig

    Returns
    -------
    ShapeOperators
    """
    pts, weights = mass_weights(rig)
    sensors = rig.structure.coordinates(rig.sensor_points)
    return ShapeOperators(
        couplings=tuple(weights @ fit.basis.evaluate(pts) for fit in model.shapes),
        at_sensors=tuple(fit.basis.evaluate(sensors) for fit in model.shapes))


def shape_jacobian(model: SpatialModel, ops: ShapeOperators, k: int, sensors: HarmonicFit,
                   w0n: float) -> tuple[np.ndarray, np.ndarray]:
    """d J_n / d(Re p, Im p): the inertia term's sensitivity to the shape coefficients p.

    Parameters
    ----------
    model : SpatialModel
    ops : ShapeOperators
        From :func:`shape_operators`.
    k : int
        Position of the harmonic in ``model.harmonics``.
    sensors : HarmonicFit
        The sensors' harmonic fit.
    w0n : float
        [rad/s] n w0.

    Returns
    -------
    jac : (n_gauges, 2 n_funcs) complex ndarray
        [N per coefficient unit]
    cov_p : (2 n_funcs, 2 n_funcs) ndarray
        Covariance of (Re p, Im p).
    """
    fit = model.shapes[k]
    n = int(model.harmonics[k])
    c, bs = ops.couplings[k], ops.at_sensors[k]
    s = sensors.phasors[:, n]
    w = sensor_weights(sensors.phasor_std[:, n])

    def inertia(p: np.ndarray) -> np.ndarray:
        gain, _ = coordinate_map(bs @ p, w)
        return inertia_term(c @ p, complex(gain @ s), w0n)

    p0 = fit.coefficients
    nf = len(p0)
    h = 1e-6 * np.linalg.norm(p0)
    jac = np.empty((c.shape[0], 2 * nf), dtype=complex)
    for j in range(nf):
        for part, d in ((0, h), (1, 1j * h)):
            e = np.zeros(nf, dtype=complex)
            e[j] = d
            jac[:, part * nf + j] = (inertia(p0 + e) - inertia(p0 - e)) / (2 * h)
    return jac, np.kron(np.eye(2), fit.coefficient_covariance)   # Re and Im independent


def inertia_variance(model: SpatialModel, ops: ShapeOperators, k: int, sensors: HarmonicFit,
                     a_r: np.ndarray, w0n: float, q_std: float) -> np.ndarray:
    """Variance of (Re, Im) of each combination from harmonic k's inertia term: the
    coordinate's noise and the shape coefficients' uncertainty.

    Parameters
    ----------
    model : SpatialModel
    ops : ShapeOperators
    k : int
        Position of the harmonic in ``model.harmonics``.
    sensors : HarmonicFit
    a_r : (n_c, n_gauges) ndarray
        Combination rows times Psi^+.
    w0n : float
        [rad/s] n w0.
    q_std : float
        [1] standard uncertainty of Re Q_n and of Im Q_n.

    Returns
    -------
    (n_c, 2) ndarray [N^2]
    """
    a_q = np.abs(a_r @ inertia_term(model.couplings[k], q_std, w0n))
    jac, cov_p = shape_jacobian(model, ops, k, sensors, w0n)
    cj = a_r @ jac                                                   # (n_c, 2 nf)
    return np.column_stack([
        a_q**2 + np.einsum("ca,ab,cb->c", cj.real, cov_p, cj.real),
        a_q**2 + np.einsum("ca,ab,cb->c", cj.imag, cov_p, cj.imag),
    ])


def unresolved_inertia_bound(rig: Rig, sensors: HarmonicFit, n: int, w0: float) -> float:
    """Bound on the inertia of a harmonic without a shape: the whole mass moving with the
    sensors' RMS amplitude at that harmonic (or their noise, whichever is larger).

    Parameters
    ----------
    rig : Rig
    sensors : HarmonicFit
    n : int
        The harmonic.
    w0 : float
        [rad/s] the fundamental.

    Returns
    -------
    float [N]
    """
    noise = float(np.sqrt(np.mean(sensors.phasor_std[:, n] ** 2)))
    motion = max(float(np.sqrt(np.mean(np.abs(sensors.phasors[:, n]) ** 2))), noise)
    return rig.structure.total_mass * (n * w0) ** 2 * motion


def unresolved_inertia(model: SpatialModel, rig: Rig, sensors: HarmonicFit, n: int,
                       w0: float) -> np.ndarray:
    """The inertia term a harmonic without a shape would have if it deflected in the shape of
    the nearest harmonic that has one: a proxy, from the probes' own phasors at harmonic n,
    that carries how the probes see the mass distribution (the whole mass moving with the
    probes' RMS motion misjudges it wherever the probes sit off the antinodes).

    Parameters
    ----------
    model : SpatialModel
    rig : Rig
    sensors : HarmonicFit
        The sensors' harmonic fit.
    n : int
        The harmonic without a shape.
    w0 : float
        [rad/s] the fundamental.

    Returns
    -------
    (n_gauges,) complex ndarray [N]
    """
    k = int(np.argmin(np.abs(model.harmonics - n)))
    phi = model.shape_values(int(model.harmonics[k]),
                             rig.structure.coordinates(rig.sensor_points))
    gain, _ = coordinate_map(phi, sensor_weights(sensors.phasor_std[:, n]))
    return inertia_term(model.couplings[k], complex(gain @ sensors.phasors[:, n]), n * w0)

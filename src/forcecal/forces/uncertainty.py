"""Uncertainty of the reconstructed forces (METHOD.md section 6).

Linear propagation, per harmonic and separately for Re and Im, to any linear combination of the
forces (each force, the total, the resultant's moments) from:

- the gauges' noise (each channel's residual noise, through Psi^+);
- the generalized coordinate's noise (the sensors' noise, through m_{r,n} (n w0)^2);
- the scan model's shape coefficients (their covariance, through a numerical Jacobian of the
  whole inertia term: shape at the sensors, coordinate, mass coupling, computed with the same
  formulas as the estimate: :func:`forcecal.forces.coordinates.coordinate_map`,
  :func:`forcecal.model.inertia.inertia_term`);
- for a harmonic the scan could not resolve, a bound on its uncompensated inertia.

The force solve F = Psi^+ (J - R) is linear: its sensitivity to J and to R is the map
``a_r`` = (combination rows) Psi^+ that every function here takes.

Near a resonance, where F is a small difference of large numbers, every term grows with the
inertia, and so does the stated uncertainty.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from ..model.inertia import inertia_term, mass_weights
from ..model.spatial import SpatialModel
from ..rig import Rig
from ..signals.harmonics import HarmonicFit
from .coordinates import Coordinates, coordinate_map, sensor_weights

__all__ = ["ShapeOperators", "shape_operators"]


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
    couplings : tuple of tuple of (n_gauges, n_funcs) ndarray
        [kg] per harmonic and member of its span, the mass coupling of every basis function
        (the shape's coupling is ``c @ p``).
    at_sensors : tuple of tuple of (n_sensors, n_funcs) ndarray
        [1] likewise, the basis functions at the sensors (the shape there is ``b @ p``).
    """

    couplings: tuple[tuple[np.ndarray, ...], ...]
    at_sensors: tuple[tuple[np.ndarray, ...], ...]


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
    spans = [model.members(k) for k in range(len(model.harmonics))]
    return ShapeOperators(
        couplings=tuple(tuple(weights @ f.basis.evaluate(pts) for f in fits) for fits in spans),
        at_sensors=tuple(tuple(f.basis.evaluate(sensors) for f in fits) for fits in spans))


def shape_jacobian(model: SpatialModel, ops: ShapeOperators, k: int, sensors: HarmonicFit,
                   w0n: float, members: tuple[int, ...] = (0,)) -> tuple[np.ndarray, np.ndarray]:
    """d J_n / d(Re p, Im p): the inertia term's sensitivity to the shape coefficients p of
    the members of harmonic k's span that the run uses.

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
    members : tuple of int
        The members used (:attr:`forcecal.forces.coordinates.Coordinates.members`).

    Returns
    -------
    jac : (n_gauges, 2 n_funcs) complex ndarray
        [N per coefficient unit], the members' (Re p, Im p) one after another.
    cov_p : (2 n_funcs, 2 n_funcs) ndarray
        Covariance of those coefficients (block diagonal: each member from its own scan).
    """
    fits = [model.members(k)[j] for j in members]
    n = int(model.harmonics[k])
    c = [ops.couplings[k][j] for j in members]
    bs = [ops.at_sensors[k][j] for j in members]
    s = sensors.phasors[:, n]
    w = sensor_weights(sensors.phasor_std[:, n])
    p0 = [f.coefficients for f in fits]

    def inertia(p: list[np.ndarray]) -> np.ndarray:
        phi = np.column_stack([b @ pj for b, pj in zip(bs, p, strict=True)])
        gain, _ = coordinate_map(phi, w)
        m = np.column_stack([cj @ pj for cj, pj in zip(c, p, strict=True)])
        return inertia_term(m, gain @ s, w0n)

    cols, blocks = [], []
    for i, (member, base) in enumerate(zip(members, p0, strict=True)):
        nf = len(base)
        h = 1e-6 * np.linalg.norm(base)
        part = np.empty((c[i].shape[0], 2 * nf), dtype=complex)
        for j in range(nf):
            for re_im, d in ((0, h), (1, 1j * h)):
                e = np.zeros(nf, dtype=complex)
                e[j] = d
                plus = [*p0[:i], base + e, *p0[i + 1:]]
                minus = [*p0[:i], base - e, *p0[i + 1:]]
                part[:, re_im * nf + j] = (inertia(plus) - inertia(minus)) / (2 * h)
        cols.append(part)
        blocks.append(np.kron(np.eye(2), model.shape_covariance(k, member)))  # Re, Im apart
    return np.hstack(cols), scipy.linalg.block_diag(*blocks)


def inertia_variance(model: SpatialModel, ops: ShapeOperators, k: int, sensors: HarmonicFit,
                     a_r: np.ndarray, w0n: float, coords: Coordinates) -> np.ndarray:
    """Variance of (Re, Im) of each combination from harmonic k's inertia term: the
    coordinates' noise and the shape coefficients' uncertainty (the sum of
    :func:`inertia_variance_parts`).

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
    coords : Coordinates
        The run's coordinates: the members used, the covariance of Re and of Im of their
        coordinates.

    Returns
    -------
    (n_c, 2) ndarray [N^2]
    """
    probes, shapes = inertia_variance_parts(model, ops, k, sensors, a_r, w0n, coords)
    total: np.ndarray = probes + shapes
    return total


def inertia_variance_parts(model: SpatialModel, ops: ShapeOperators, k: int,
                           sensors: HarmonicFit, a_r: np.ndarray, w0n: float,
                           coords: Coordinates) -> tuple[np.ndarray, np.ndarray]:
    """:func:`inertia_variance` split by source: the coordinates' noise (the probes') and the
    shape coefficients' uncertainty (the scan's), each (n_c, 2) [N^2]."""
    members, _, cov_q = coords.span(k)
    # J = M Qdd is linear in Q: each combination's sensitivity to Q is a_r M (-(n w0)^2), and
    # Re and Im of Q share the covariance cov_q
    sens = a_r @ inertia_term(model.member_couplings(k)[:, list(members)],
                              np.eye(len(members)), w0n)               # (n_c, n_q)
    var_q = np.einsum("ca,ab,cb->c", sens, cov_q, np.conj(sens)).real
    jac, cov_p = shape_jacobian(model, ops, k, sensors, w0n, members)
    cj = a_r @ jac                                                   # (n_c, 2 nf)
    shapes = np.column_stack([np.einsum("ca,ab,cb->c", cj.real, cov_p, cj.real),
                              np.einsum("ca,ab,cb->c", cj.imag, cov_p, cj.imag)])
    return np.column_stack([var_q, var_q]), shapes


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

"""Uncertainty of the reconstructed forces (METHOD.md section 6).

Linear propagation, per harmonic and separately for Re and Im, to any linear combination of the
forces (each force, the total, the resultant's first moments) from:

- the gauges' noise (each channel's residual noise, through Psi^+);
- the generalized coordinate's noise (the sensors' noise, through m_{r,n} (n w0)^2);
- the scan model's shape coefficients (their covariance, through a numerical Jacobian of the
  whole inertia term: shape at the sensors, coordinate, mass coupling);
- for a harmonic the scan could not resolve, a bound on its uncompensated inertia.

Near a resonance, where F is a small difference of large numbers, every term grows with the
inertia, and so does the stated uncertainty.
"""

from __future__ import annotations

import numpy as np

from .harmonics import HarmonicFit
from .inertia import mass_weights
from .rig import Rig
from .spatial import SpatialModel, structure_coordinates

__all__ = [
    "combinations",
    "gauge_variance",
    "inertia_variance",
    "shape_jacobian",
    "unresolved_inertia_bound",
]


def combinations(rig: Rig) -> tuple[tuple[str, ...], np.ndarray]:
    """Linear combinations of the forces that are reported: each force, the total (the
    resultant) and its first moments sum(f x) [N m] (and sum(f y) on a plate).

    On a body the total is the sum of the forces along their own directions (the actuator's
    pull when its poles act along one direction); the resultant's components ``resultant_x``,
    ``_y``, ``_z`` [N] and its moment about the origin ``moment_x``, ``_y``, ``_z`` [N m]
    (sum of (x_n - 0) x d_n f_n) follow.

    Returns names and the (n_combinations, n_forces) matrix.
    """
    n_f = len(rig.forces)
    pts = rig.force_points
    if rig.is_body:
        d = pts[:, 3:]
        arm = np.cross(pts[:, :3], d)
        return ((*rig.force_names, "total", "resultant_x", "resultant_y", "resultant_z",
                 "moment_x", "moment_y", "moment_z"),
                np.vstack([np.eye(n_f), np.ones(n_f), d.T, arm.T]))
    names = [*rig.force_names, "total", "moment_x"]
    rows = [*np.eye(n_f), np.ones(n_f), pts[:, 0]]
    if rig.structure.kind == "plate":
        names.append("moment_y")
        rows.append(pts[:, 1])
    return tuple(names), np.array(rows)


def gauge_variance(a_r: np.ndarray, gauges: HarmonicFit) -> np.ndarray:
    """(n_c, H+1) variance of Re (and of Im) of each combination from the gauges' noise.

    a_r : (n_c, n_gauges) combination rows times Psi^+ [1]
    """
    return (a_r**2) @ gauges.phasor_std**2


def shape_jacobian(model: SpatialModel, rig: Rig, k: int, sensors: HarmonicFit,
                   pinv: np.ndarray, w0n: float) -> tuple[np.ndarray, np.ndarray]:
    """d(Psi^+ J_n)/d(Re p, Im p) of the shape coefficients p, and their covariance.

    Returns
    -------
    jac : (n_forces, 2 n_funcs) complex [N per coefficient unit]
    cov_p : (2 n_funcs, 2 n_funcs) covariance of (Re p, Im p)
    """
    fit = model.shapes[k]
    n = int(model.harmonics[k])
    pts, weights = mass_weights(rig)
    c = weights @ fit.basis.evaluate(pts)                          # (n_g, nf)
    bs = fit.basis.evaluate(structure_coordinates(rig, rig.sensor_points))   # (n_s, nf)
    s = sensors.phasors[:, n]
    w = 1.0 / np.maximum(sensors.phasor_std[:, n], 1e-150) ** 2

    def inertia_force(p: np.ndarray) -> np.ndarray:
        phi = bs @ p
        q = np.sum(w * np.conj(phi) * s) / np.sum(w * np.abs(phi) ** 2)
        return pinv @ ((c @ p) * (-(w0n**2)) * q)

    p0 = fit.coefficients
    nf = len(p0)
    h = 1e-6 * np.linalg.norm(p0)
    jac = np.empty((pinv.shape[0], 2 * nf), dtype=complex)
    for j in range(nf):
        for part, d in ((0, h), (1, 1j * h)):
            e = np.zeros(nf, dtype=complex)
            e[j] = d
            jac[:, part * nf + j] = (inertia_force(p0 + e) - inertia_force(p0 - e)) / (2 * h)
    return jac, np.kron(np.eye(2), fit.coefficient_covariance)   # Re and Im independent


def inertia_variance(model: SpatialModel, rig: Rig, k: int, sensors: HarmonicFit,
                     pinv: np.ndarray, combo: np.ndarray, w0n: float,
                     q_std: float) -> np.ndarray:
    """(n_c, 2) variance of (Re, Im) of each combination from harmonic k's inertia term: the
    coordinate's noise and the shape coefficients' uncertainty."""
    a_q = np.abs(combo @ pinv @ model.couplings[k]) * w0n**2 * q_std
    jac, cov_p = shape_jacobian(model, rig, k, sensors, pinv, w0n)
    cj = combo @ jac                                                 # (n_c, 2 nf)
    return np.column_stack([
        a_q**2 + np.einsum("ca,ab,cb->c", cj.real, cov_p, cj.real),
        a_q**2 + np.einsum("ca,ab,cb->c", cj.imag, cov_p, cj.imag),
    ])


def unresolved_inertia_bound(rig: Rig, sensors: HarmonicFit, n: int, w0: float) -> float:
    """Bound [N] on the inertia of a harmonic without a shape: the whole mass moving with the
    sensors' RMS amplitude at that harmonic (or their noise, whichever is larger)."""
    noise = float(np.sqrt(np.mean(sensors.phasor_std[:, n] ** 2)))
    motion = max(float(np.sqrt(np.mean(np.abs(sensors.phasors[:, n]) ** 2))), noise)
    return rig.structure.total_mass * (n * w0) ** 2 * motion

"""Sensors -> generalized coordinates (METHOD.md section 3, step 4; eq. 15, 16).

Per harmonic n the probe phasors obey S_n(l_j) = phi_n(l_j) Q_n + noise. Q_n follows by least
squares weighted by each probe's noise: Q_n = G_n S_n with the weighted least-squares map
G_n = (phi^H W phi)^-1 phi^H W (:func:`coordinate_map`, the one implementation used by the
batch estimate, the streaming estimator and the uncertainty propagation). The problem needs no
more coordinates than sensors (the corrected eq. 16: Nq <= NS) and sensors away from the nodes
of phi_n: the gain of the sensor set on each shape is reported, and a set that sees a shape too
faintly is refused (:func:`check_sensor_gain`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.stats

from .errors import ConditioningError
from .harmonics import HarmonicFit
from .rig import Rig
from .spatial import SpatialModel

__all__ = [
    "MIN_SENSOR_GAIN",
    "Coordinates",
    "check_sensor_gain",
    "coordinate_map",
    "generalized_coordinates",
    "sensor_gain",
    "sensor_rows",
    "sensor_weights",
]

MIN_SENSOR_GAIN = 0.05
"""Smallest RMS of |phi_n| at the sensors, relative to its maximum over the structure."""
MISFIT_LEVEL = 0.99
"""Chi-square quantile above which the sensors contradict the shape and Q's uncertainty is
inflated by the reduced chi-square (the Birge ratio)."""


@dataclass(frozen=True)
class Coordinates:
    """Generalized coordinates of one run.

    Attributes
    ----------
    harmonics : (n_h,) int ndarray
        The model's harmonics.
    q : (n_h,) complex ndarray
        [1] w(x) at harmonic n is phi_n(x) Q_n.
    q_std : (n_h,) ndarray
        [1] standard uncertainty of Re Q_n and of Im Q_n, scaled by the reduced chi-square
        when the sensors disagree with the shape beyond their noise.
    gain : (n_h,) ndarray
        [1] RMS |phi_n| at the sensors / max |phi_n| on the structure.
    chi2 : (n_h,) ndarray
        [1] reduced chi-square of the sensor fit, against the probes' noise and the fitted
        shape's uncertainty at the probes (about 1 when the shape fits; NaN with a single
        sensor).
    """

    harmonics: np.ndarray
    q: np.ndarray
    q_std: np.ndarray
    gain: np.ndarray
    chi2: np.ndarray


def sensor_rows(model: SpatialModel, rig: Rig, n: int) -> np.ndarray:
    """phi_n at the sensors.

    Parameters
    ----------
    model : SpatialModel
    rig : Rig
    n : int
        The harmonic.

    Returns
    -------
    (n_sensors,) complex ndarray [m]
    """
    return model.shape_values(n, rig.structure.coordinates(rig.sensor_points))


def sensor_gain(model: SpatialModel, rig: Rig, n: int) -> float:
    """RMS |phi_n| at the sensors relative to its maximum over the structure.

    Parameters
    ----------
    model : SpatialModel
    rig : Rig
    n : int
        The harmonic.

    Returns
    -------
    float [1]
    """
    peak = np.max(np.abs(model.shape_values(n, rig.structure.grid())))
    at = sensor_rows(model, rig, n)
    return float(np.sqrt(np.mean(np.abs(at) ** 2)) / peak)


def check_sensor_gain(model: SpatialModel, rig: Rig, n: int, what: str) -> float:
    """The sensors' gain on harmonic n's shape, refused when they sit near a node.

    Parameters
    ----------
    model : SpatialModel
    rig : Rig
    n : int
        The harmonic.
    what : str
        Who asks, at the start of the message (``run 'r01.csv'``, ``stream``).

    Returns
    -------
    float
        :func:`sensor_gain`.

    Raises
    ------
    ConditioningError
        When the gain is below ``MIN_SENSOR_GAIN``.
    """
    gain = sensor_gain(model, rig, n)
    if gain < MIN_SENSOR_GAIN:
        raise ConditioningError(
            f"{what}: sensors {', '.join(rig.sensor_names)} sit near a node of the "
            f"harmonic-{n} shape (they see {gain:.1%} of its peak; at least "
            f"{MIN_SENSOR_GAIN:.0%} is needed): move a sensor")
    return gain


def sensor_weights(std: np.ndarray) -> np.ndarray:
    """Inverse variances of the sensors' phasors (finite for noise-free data).

    Parameters
    ----------
    std : (n_sensors,) ndarray
        [m] standard uncertainties of the phasors.

    Returns
    -------
    (n_sensors,) ndarray [1/m^2]
    """
    weights: np.ndarray = 1.0 / np.maximum(np.asarray(std, dtype=float), 1e-150) ** 2
    return weights


def coordinate_map(phi: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The weighted least-squares map from sensor phasors to coordinates (eq. 15, 16).

    Parameters
    ----------
    phi : (n_sensors,) or (n_sensors, n_shapes) complex ndarray
        [m] the shapes at the sensors.
    weights : (n_sensors,) ndarray
        Inverse noise variances of the sensors (any common scale).

    Returns
    -------
    gain : (n_sensors,) or (n_shapes, n_sensors) complex ndarray
        G with Q = G @ S.
    information : float or (n_shapes, n_shapes) ndarray
        phi^H W phi: the coordinates' covariance is its inverse (per unit weight).
    """
    w = np.asarray(weights, dtype=float)
    if phi.ndim == 1:
        info = float(np.sum(w * np.abs(phi) ** 2))
        return w * np.conj(phi) / info, np.asarray(info)
    a = np.conj(phi.T) * w                                         # (n_shapes, n_sensors)
    info_m = a @ phi
    return np.linalg.solve(info_m, a), info_m


def generalized_coordinates(model: SpatialModel, rig: Rig, sensors: HarmonicFit,
                            run_name: str = "<run>") -> Coordinates:
    """Q_n of every harmonic of the model from the sensors' harmonic fit.

    Parameters
    ----------
    model : SpatialModel
    rig : Rig
    sensors : HarmonicFit
        Harmonic fit of the sensor channels, phasors (n_sensors, H+1) [m].
    run_name : str
        Named in messages.

    Returns
    -------
    Coordinates

    Raises
    ------
    ConditioningError
        When the sensors sit at a node of a harmonic's shape.
    """
    qs, stds, gains, chi2 = [], [], [], []
    at_sensors = rig.structure.coordinates(rig.sensor_points)
    for k, n in enumerate(model.harmonics):
        gains.append(check_sensor_gain(model, rig, int(n), f"run '{run_name}'"))
        phi = sensor_rows(model, rig, int(n))
        s = sensors.phasors[:, n]
        w = sensor_weights(sensors.phasor_std[:, n])
        gain, info = coordinate_map(phi, w)
        q = complex(gain @ s)
        resid = s - phi * q
        dof = 2 * (len(s) - 1)
        # the residual's variance: the probes' noise and the fitted shape's own uncertainty
        # there (the latter is propagated as the shape term, not as a contradiction)
        var = 1.0 / w + (model.shapes[k].std(at_sensors) * abs(q)) ** 2
        red = float(np.sum(np.abs(resid) ** 2 / var) / dof) if dof > 0 else np.nan
        chi2.append(red)
        qs.append(q)
        # the shape misses the sensors by more than their noise and its own uncertainty (1 %
        # significance): the mismatch is real, and Q is only known to within the residual's
        # scatter about the fit's weights (Birge ratio)
        contradicts = dof > 0 and red > scipy.stats.chi2.ppf(MISFIT_LEVEL, dof) / dof
        misfit = float(np.sum(w * np.abs(resid) ** 2) / dof) if contradicts else 1.0
        stds.append(float(np.sqrt(misfit / float(info))))
    return Coordinates(harmonics=model.harmonics.copy(), q=np.array(qs), q_std=np.array(stds),
                       gain=np.array(gains), chi2=np.array(chi2))

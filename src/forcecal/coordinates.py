"""Sensors -> generalized coordinates (METHOD.md section 3, step 4; eq. 15, 16).

Per harmonic n the probe phasors obey S_n(l_j) = phi_n(l_j) Q_n + noise. Q_n follows by least
squares weighted by each probe's noise (estimated from its own fit residuals). The problem
needs no more coordinates than sensors (the corrected eq. 16: Nq <= NS) and sensors away from
the nodes of phi_n: the gain of the sensor set on each shape is reported, and a set that sees
a shape too faintly is refused.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.stats

from .errors import ConditioningError
from .harmonics import HarmonicFit
from .rig import Rig
from .spatial import SpatialModel, structure_coordinates, structure_grid

__all__ = ["MIN_SENSOR_GAIN", "Coordinates", "generalized_coordinates", "sensor_gain"]

MIN_SENSOR_GAIN = 0.05
"""Smallest RMS of |phi_n| at the sensors, relative to its maximum over the structure."""


@dataclass(frozen=True)
class Coordinates:
    """Generalized coordinates of one run.

    Attributes
    ----------
    harmonics : (n_h,) int
    q : (n_h,) complex [1]: w(x) at harmonic n is phi_n(x) Q_n
    q_std : (n_h,) [1] standard uncertainty of Re Q_n and of Im Q_n, scaled by the reduced
        chi-square when the sensors disagree with the shape beyond their noise
    gain : (n_h,) [1] RMS |phi_n| at the sensors / max |phi_n| on the structure
    chi2 : (n_h,) [1] reduced chi-square of the sensor fit (about 1 when the shape fits;
        NaN with a single sensor)
    """

    harmonics: np.ndarray
    q: np.ndarray
    q_std: np.ndarray
    gain: np.ndarray
    chi2: np.ndarray


def sensor_gain(model: SpatialModel, rig: Rig, n: int) -> float:
    """RMS |phi_n| at the sensors relative to its maximum along the structure [1]."""
    peak = np.max(np.abs(model.shape_values(n, structure_grid(rig))))
    at = sensor_rows(model, rig, n)
    return float(np.sqrt(np.mean(np.abs(at) ** 2)) / peak)


def sensor_rows(model: SpatialModel, rig: Rig, n: int) -> np.ndarray:
    """phi_n at the sensors, (n_sensors,) complex [m]."""
    return model.shape_values(n, structure_coordinates(rig, rig.sensor_points))


def generalized_coordinates(model: SpatialModel, rig: Rig, sensors: HarmonicFit,
                            run_name: str = "<run>") -> Coordinates:
    """Q_n of every harmonic of the model from the sensors' harmonic fit.

    Parameters
    ----------
    sensors : harmonic fit of the sensor channels, phasors (n_sensors, H+1) [m]

    Raises
    ------
    ConditioningError
        When the sensors sit at a node of a harmonic's shape.
    """
    qs, stds, gains, chi2 = [], [], [], []
    for n in model.harmonics:
        phi = sensor_rows(model, rig, int(n))
        s = sensors.phasors[:, n]
        sig = sensors.phasor_std[:, n]
        gain = sensor_gain(model, rig, int(n))
        if gain < MIN_SENSOR_GAIN:
            raise ConditioningError(
                f"run '{run_name}': sensors {', '.join(rig.sensor_names)} sit near a node of the "
                f"harmonic-{n} shape (they see {gain:.1%} of its peak; at least "
                f"{MIN_SENSOR_GAIN:.0%} is needed): move a sensor")
        w = 1.0 / np.maximum(sig, 1e-150) ** 2             # noise-free data: finite weights
        info = np.sum(w * np.abs(phi) ** 2)
        q = np.sum(w * np.conj(phi) * s) / info
        resid = s - phi * q
        dof = 2 * (len(s) - 1)
        red = float(np.sum(w * np.abs(resid) ** 2) / dof) if dof > 0 else np.nan
        chi2.append(red)
        qs.append(q)
        # the shape misses the sensors by more than their noise (1 % significance): the model
        # error is real, and Q is only known to within it (Birge ratio)
        misfit = red if dof > 0 and red > scipy.stats.chi2.ppf(0.99, dof) / dof else 1.0
        stds.append(float(np.sqrt(misfit / info)))
        gains.append(gain)
    return Coordinates(harmonics=model.harmonics.copy(), q=np.array(qs), q_std=np.array(stds),
                       gain=np.array(gains), chi2=np.array(chi2))

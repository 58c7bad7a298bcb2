"""Sensors -> generalized coordinates (METHOD.md section 3, step 4; eq. 15, 16).

Per harmonic n the probe phasors obey S_n(l_j) = phi_n(l_j) Q_n + noise. Q_n follows by least
squares weighted by each probe's noise: Q_n = G_n S_n with the weighted least-squares map
G_n = (phi^H W phi)^-1 phi^H W (:func:`coordinate_map`, the one implementation used by the
batch estimate, the streaming estimator and the uncertainty propagation). The problem needs no
more coordinates than sensors (the corrected eq. 16: Nq <= NS) and sensors away from the nodes
of phi_n: the gain of the sensor set on each shape is reported, and a set that sees a shape too
faintly is refused (:func:`check_sensor_gain`).

A model built from several scans holds a span of shapes per harmonic
(:mod:`forcecal.model.spatial`); the run's deflection is then w_n = sum_j phi_n^(j) Q_n,j over
the members that the probes need, chosen by :func:`choose_members`: every subset of at most NS
members (METHOD.md eq. 16) that the sensors can tell apart is fitted, and the one with the
least Akaike information criterion AIC = chi^2 + 2 (2 Nq) wins (chi^2 of the probes' residuals
against their noise and the shapes' uncertainty; 2 Nq real parameters). One member is the
one-scan case, unchanged.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from ..errors import ConditioningError
from ..model.spatial import SpatialModel
from ..rig import Rig
from ..signals.harmonics import HarmonicFit

__all__ = [
    "check_sensor_gain",
    "choose_members",
    "coordinate_map",
    "deflection",
    "member_fit",
    "sensor_weights",
]

MIN_SENSOR_GAIN = 0.05
"""Smallest RMS of |phi_n| at the sensors, relative to its maximum over the structure."""
MISFIT_LEVEL = 0.99
"""Chi-square quantile above which the sensors contradict the shape and Q's uncertainty is
inflated by the reduced chi-square (the Birge ratio)."""
MIN_SEPARATION = 1e-6
"""Smallest eigenvalue of the sensors' normalized information matrix on a set of members:
below it the sensors cannot tell the members apart and the set is not tried."""


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
        shape's uncertainty at the probes (about 1 when the shape fits; NaN with as many
        coordinates as sensors).
    members : tuple of tuple of int
        Per harmonic, the members of the model's span used (:meth:`SpatialModel.members`);
        ``(0,)`` with one scan.
    q_span : tuple of (n_q,) complex ndarray
        Per harmonic, the coordinates on those members (``q[k]`` is the first).
    q_cov : tuple of (n_q, n_q) complex ndarray
        Per harmonic, the covariance of Re and of Im of ``q_span`` (Hermitian; the real
        part's covariance is its real part), Birge-inflated like ``q_std``.
    """

    harmonics: np.ndarray
    q: np.ndarray
    q_std: np.ndarray
    gain: np.ndarray
    chi2: np.ndarray
    members: tuple[tuple[int, ...], ...] = ()
    q_span: tuple[np.ndarray, ...] = ()
    q_cov: tuple[np.ndarray, ...] = ()

    def span(self, k: int) -> tuple[tuple[int, ...], np.ndarray, np.ndarray]:
        """(members, coordinates, covariance) of harmonic k (one member without a span)."""
        if self.members:
            return self.members[k], self.q_span[k], self.q_cov[k]
        return (0,), self.q[k:k + 1], np.array([[self.q_std[k] ** 2]], dtype=complex)


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


@dataclass(frozen=True)
class MemberFit:
    """The probes' fit on one set of members of a harmonic's span.

    Attributes
    ----------
    members : tuple of int
    q : (n_q,) complex ndarray [1]
    info : (n_q, n_q) complex ndarray
        phi^H W phi (per unit weight).
    chi2 : float
        Sum of the squared residuals over their variances [1].
    dof : int
        2 (NS - n_q) real degrees of freedom.
    """

    members: tuple[int, ...]
    q: np.ndarray
    info: np.ndarray
    chi2: float
    dof: int

    @property
    def aic(self) -> float:
        """chi^2 + 2 k with k = 2 n_q real parameters."""
        return self.chi2 + 4.0 * len(self.members)

    @property
    def reduced(self) -> float:
        """chi^2 / dof (NaN without degrees of freedom)."""
        return self.chi2 / self.dof if self.dof > 0 else float("nan")

    def covariance(self, weights: np.ndarray, s: np.ndarray, phi: np.ndarray) -> np.ndarray:
        """Covariance of Re and of Im of q: (phi^H W phi)^-1, inflated by the Birge ratio when
        the probes contradict the shapes beyond their noise and the shapes' uncertainty (1 %
        significance)."""
        from scipy.special import gammaincinv  # on use: a steady stream starts without it

        cov: np.ndarray = np.linalg.inv(self.info)
        # the chi-square quantile, 2 P^-1(dof / 2, level) (scipy.special: lighter than .stats)
        if self.dof > 0 and self.reduced > 2 * gammaincinv(self.dof / 2, MISFIT_LEVEL) / self.dof:
            resid = s - phi[:, list(self.members)] @ self.q
            cov = cov * float(np.sum(weights * np.abs(resid) ** 2) / self.dof)
        return cov


def choose_members(phi: np.ndarray, phi_std: np.ndarray, s: np.ndarray,
                   weights: np.ndarray, scale_std: float = 0.0) -> MemberFit:
    """The set of a harmonic's span members that explains the probes best (least AIC).

    Parameters
    ----------
    phi : (n_sensors, n_members) complex ndarray
        [m] the span's shapes at the sensors.
    phi_std : (n_sensors, n_members) ndarray
        [m] their standard uncertainties there.
    s : (n_sensors,) complex ndarray
        [m] the probes' phasors.
    weights : (n_sensors,) ndarray
        Inverse noise variances of the probes' phasors.
    scale_std : float
        [1] the probes' relative sensitivity uncertainty (type B, the rig's
        ``uncertainty.probe_scale``): a probe whose scale is off by it misses the shapes by that
        fraction of its phasor, which is no contradiction of the shapes.

    Returns
    -------
    MemberFit
        Of every subset of at most n_sensors members that the sensors tell apart
        (``MIN_SEPARATION``), the one with the least AIC; the smaller set on a tie.
    """
    n_s, n_m = phi.shape
    best: MemberFit | None = None
    for size in range(1, min(n_s, n_m) + 1):
        for members in itertools.combinations(range(n_m), size):
            fit = member_fit(phi, phi_std, s, weights, members, scale_std=scale_std)
            if fit is not None and (best is None or fit.aic < best.aic - 1e-12):
                best = fit
    if best is None:   # no subset separable: the first member alone (always separable)
        best = member_fit(phi, phi_std, s, weights, (0,), check=False, scale_std=scale_std)
        assert best is not None
    return best


def member_fit(phi: np.ndarray, phi_std: np.ndarray, s: np.ndarray, weights: np.ndarray,
               members: tuple[int, ...], check: bool = True,
               scale_std: float = 0.0) -> MemberFit | None:
    """The probes' fit on the given members of a harmonic's span (arguments as
    :func:`choose_members`); None when ``check`` and the sensors cannot tell them apart."""
    cols = list(members)
    p = phi[:, cols]
    if check and len(cols) > 1:
        info = (np.conj(p.T) * weights) @ p
        d = np.sqrt(np.real(np.diag(info)))
        if not np.all(d > 0) or np.linalg.eigvalsh(info / np.outer(d, d))[0] < MIN_SEPARATION:
            return None
    gain, info = coordinate_map(p, weights)
    info = np.atleast_2d(info)
    q = np.atleast_1d(gain @ s)
    resid = s - p @ q
    var = (1.0 / weights + np.sum((phi_std[:, cols] * np.abs(q)) ** 2, axis=1)
           + (scale_std * np.abs(s)) ** 2)
    chi2 = float(np.sum(np.abs(resid) ** 2 / var))
    return MemberFit(members=members, q=q, info=info, chi2=chi2, dof=2 * (len(s) - len(cols)))


def deflection(model: SpatialModel, coords: Coordinates, k: int,
               points: np.ndarray) -> np.ndarray:
    """w_n at points: harmonic k's members used, times their coordinates.

    Parameters
    ----------
    model : SpatialModel
    coords : Coordinates
    k : int
        Position of the harmonic in ``model.harmonics``.
    points : ndarray
        Structure coordinates.

    Returns
    -------
    (n_points,) complex ndarray [m]
    """
    members, q, _ = coords.span(k)
    fits = model.members(k)
    out: np.ndarray = sum((fits[j].evaluate(points) * qj for j, qj in zip(members, q,
                                                                          strict=True)),
                          start=np.zeros(len(points), dtype=complex))
    return out


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
    at_sensors = rig.structure.coordinates(rig.sensor_points)
    fits, covs, gains = [], [], []
    for k, n in enumerate(model.harmonics):
        gains.append(check_sensor_gain(model, rig, int(n), f"run '{run_name}'"))
        s = sensors.phasors[:, n]
        w = sensor_weights(sensors.phasor_std[:, n])
        phi = model.member_values(k, at_sensors)
        fit = choose_members(phi, model.member_std(k, at_sensors), s, w,
                             scale_std=rig.type_b.probe_scale)
        fits.append(fit)
        covs.append(fit.covariance(w, s, phi))
    return Coordinates(
        harmonics=model.harmonics.copy(), q=np.array([f.q[0] for f in fits]),
        q_std=np.sqrt(np.array([c[0, 0].real for c in covs])), gain=np.array(gains),
        chi2=np.array([f.reduced for f in fits]), members=tuple(f.members for f in fits),
        q_span=tuple(f.q for f in fits), q_cov=tuple(covs))

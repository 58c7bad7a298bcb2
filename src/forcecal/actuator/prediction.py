"""The product of a calibration: the :class:`Calibration` file and the force it predicts.

A :class:`Calibration` predicts the total actuator force, with its standard uncertainty, from
(current, gap) (:func:`predict`) or from the flux (:func:`predict_flux`); it is written to and
read from JSON exactly. A calibration may carry a law over frequency
(:class:`~forcecal.actuator.frequency.FrequencyLaw`, the file's ``frequency_law``): then
:func:`predict` also takes the drive's frequency.

Shapes: ``n`` predictions, ``n_poles`` poles, ``n_params`` parameters of a law. SI units
throughout.
"""

from __future__ import annotations

import json
import math
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .._atomic import write_text_atomic
from ..errors import DimensionError, InputError
from ..schema.calibration_file import check_calibration_document
from ..schema.json_files import MAX_DOCUMENT_BYTES, object_pairs, reject_constant
from .frequency import MATCHED, FrequencyLaw
from .laws import Law, get_law

if TYPE_CHECKING:
    from .fitting import LawFit

__all__ = ["Calibration", "ExtrapolationWarning", "check_current_and_gaps", "predict",
           "predict_flux"]

_CALIBRATION_FORMAT = "forcecal-calibration"
_CALIBRATION_VERSION = 1
MAX_CURRENT_A = 1e5
"""Largest coil current accepted by :func:`predict` [A]."""
MAX_GAP_M = 0.1
"""Largest air gap accepted by :func:`predict` [m]; a gap in mm (0.8 for 0.8 mm) is beyond."""
MAX_FLUX_WB = 10.0
"""Largest pole flux accepted by :func:`predict_flux` [Wb]."""
_REQUIRED_KEYS = ("law", "params", "covariance", "n_poles", "current_range", "gap_range")
EXTRAPOLATION = 10.0
"""A current or gap more than this many times outside the calibrated range is refused by
:func:`predict` (and ``forcecal predict``); within it, a prediction extrapolates with a
warning."""
FREQUENCY_EXTRAPOLATION = 10.0
"""A frequency above this many times the highest calibrated one is refused: the law's frequency
model (a first-order lag, a solid core's half order) is fitted to the calibrated band of the
eddy currents, not to be carried that far."""


class ExtrapolationWarning(UserWarning):
    """A prediction was asked for outside the currents, gaps or fluxes of the calibration."""


def _pair(value: Any, what: str) -> tuple[float, float]:
    """``value`` as two finite floats ``(lo, hi)``; InputError naming ``what`` otherwise."""
    arr = np.asarray(value, dtype=float)
    if arr.shape != (2,) or not np.all(np.isfinite(arr)):
        raise InputError(f"{what} must be two finite numbers [lo, hi]; found {value!r}")
    return float(arr[0]), float(arr[1])


def _params_from_json(params: Any, law: Law) -> np.ndarray:
    """The parameter vector of ``law`` from the JSON map of names to values."""
    if not isinstance(params, dict):
        raise InputError("key 'params' must map parameter names to values")
    missing = [n for n in law.param_names if n not in params]
    if missing:
        raise InputError(f"key 'params' lacks {', '.join(missing)} for law '{law.name}'")
    return np.array([float(params[n]) for n in law.param_names])


@dataclass(frozen=True, eq=False)
class Calibration:
    """A calibrated actuator law: what predicts force from (current, gap) or from flux.

    Attributes
    ----------
    law : str
        Name of the law (see :data:`forcecal.actuator.LAWS`).
    params : (n_params,) array
        Parameters, units as the law's ``param_units``.
    covariance : (n_params, n_params) array
        Parameter covariance.
    n_poles : int
        Number of poles the total force sums over.
    current_range : (float, float) [A]
        Currents the law was fitted on; predictions outside warn, and more than
        :data:`EXTRAPOLATION` times beyond are refused.
    gap_range : (float, float) [m]
        Pole gaps the law was fitted on (a campaign's: its runs' instantaneous and static
        gaps); predictions outside warn, and more than :data:`EXTRAPOLATION` times outside are
        refused.
    flux_range : (float, float) [Wb] or None
        Fluxes the law was fitted on, when measured.
    candidates : tuple of dict
        The selection table (one JSON-ready row per law, skipped laws with their reason).
    frequency_law : FrequencyLaw or None
        The law over frequency, from a stepped-sine campaign; None: calibrated at one
        frequency.
    source : str
        The file the calibration was read from ('' when built in memory), for the messages;
        not written.
    """

    law: str
    params: np.ndarray
    covariance: np.ndarray
    n_poles: int
    current_range: tuple[float, float]
    gap_range: tuple[float, float]
    flux_range: tuple[float, float] | None = None
    candidates: tuple[dict[str, Any], ...] = field(default_factory=tuple)
    frequency_law: FrequencyLaw | None = None
    source: str = ""

    def __post_init__(self) -> None:
        law = get_law(self.law)
        params = np.asarray(self.params, dtype=float)
        cov = np.asarray(self.covariance, dtype=float)
        p = law.n_params
        if params.shape != (p,) or cov.shape != (p, p):
            raise DimensionError(
                f"calibration '{self.law}': params {params.shape} and covariance {cov.shape}; "
                f"expected ({p},) and ({p}, {p})"
            )
        if not (np.all(np.isfinite(params)) and np.all(np.isfinite(cov))):
            raise InputError(f"calibration '{self.law}': parameters or covariance not finite")
        if int(self.n_poles) < 1:
            raise InputError(f"calibration '{self.law}': n_poles = {self.n_poles} < 1")
        object.__setattr__(self, "params", params)
        object.__setattr__(self, "covariance", cov)
        object.__setattr__(self, "n_poles", int(self.n_poles))
        object.__setattr__(self, "candidates", tuple(self.candidates))
        fl = self.frequency_law
        if fl is not None and fl.n_poles != self.n_poles:
            raise InputError(f"calibration '{self.law}': the frequency law sums {fl.n_poles} "
                             f"poles, the calibration {self.n_poles}")

    def with_frequency_law(self, frequency_law: FrequencyLaw) -> Calibration:
        """This calibration carrying a law over frequency.

        Parameters
        ----------
        frequency_law : FrequencyLaw
            From :func:`forcecal.actuator.fit_frequency_law`.

        Returns
        -------
        Calibration
            A copy with ``frequency_law`` set.
        """
        return replace(self, frequency_law=frequency_law)

    @classmethod
    def from_fit(cls, fit: LawFit, candidates: tuple[dict[str, Any], ...] = ()) -> Calibration:
        """The calibration of a fitted law.

        Parameters
        ----------
        fit : LawFit
            The fitted law.
        candidates : tuple of dict
            The selection table to carry.

        Returns
        -------
        Calibration
            The fitted law's parameters, covariance and ranges.
        """
        return cls(
            law=fit.law.name,
            params=fit.params.copy(),
            covariance=fit.covariance.copy(),
            n_poles=fit.n_poles,
            current_range=fit.current_range,
            gap_range=fit.gap_range,
            flux_range=fit.flux_range,
            candidates=candidates,
        )

    @property
    def law_object(self) -> Law:
        """The :class:`Law` called :attr:`law`."""
        return get_law(self.law)

    @property
    def stderr(self) -> np.ndarray:
        """Standard uncertainties of the parameters (n_params,)."""
        return np.sqrt(np.diag(self.covariance))

    def _param_rows(self) -> list[tuple[str, str, str, str]]:
        """(name, value, standard uncertainty, unit) of every parameter, formatted."""
        law = self.law_object
        return [(n, f"{v:.6g}", f"{e:.2g}", u) for n, v, e, u in
                zip(law.param_names, self.params, self.stderr, law.param_units, strict=True)]

    def __repr__(self) -> str:
        """One line: the law and its parameters with their standard uncertainties."""
        params = ", ".join(f"{n} = {v} ± {e} {u}" for n, v, e, u in self._param_rows())
        over = "" if self.frequency_law is None else \
            f"; tau = {self.frequency_law.tau:.4g} ± {self.frequency_law.stderr[2]:.2g} s"
        return (f"Calibration(law '{self.law}': {self.law_object.formula}; {params}; "
                f"{self.n_poles} pole(s){over})")

    def _repr_html_(self) -> str:
        """A small table for notebooks: the law and its parameters."""
        from html import escape

        rows = "".join("<tr>" + "".join(f"<td>{escape(c)}</td>" for c in row) + "</tr>"
                       for row in self._param_rows())
        return (f"<p><b>Calibration</b>, law '{escape(self.law)}': "
                f"{escape(self.law_object.formula)}, {self.n_poles} pole(s)</p><table><tr>"
                f"<th>parameter</th><th>value</th><th>std</th><th>unit</th></tr>{rows}</table>")

    def to_json(self) -> dict[str, Any]:
        """The calibration as a JSON-ready dict.

        Returns
        -------
        dict
            What :meth:`from_json` reads back exactly.
        """
        law = self.law_object
        doc = {
            "format": _CALIBRATION_FORMAT,
            "version": _CALIBRATION_VERSION,
            "law": law.name,
            "formula": law.formula,
            "param_names": list(law.param_names),
            "param_units": list(law.param_units),
            "params": {n: float(v) for n, v in zip(law.param_names, self.params, strict=True)},
            "stderr": {n: float(v) for n, v in zip(law.param_names, self.stderr, strict=True)},
            "covariance": self.covariance.tolist(),
            "n_poles": self.n_poles,
            "current_range": list(self.current_range),
            "gap_range": list(self.gap_range),
            "flux_range": None if self.flux_range is None else list(self.flux_range),
            "candidates": [dict(row) for row in self.candidates],
        }
        if self.frequency_law is not None:
            doc["frequency_law"] = self.frequency_law.to_json()
        return doc

    @classmethod
    def from_json(cls, obj: dict[str, Any], source: str = "<dict>") -> Calibration:
        """Read a calibration from :meth:`to_json`'s dict.

        Parameters
        ----------
        obj : dict
            The decoded JSON object.
        source : str
            Where it comes from, for the messages.

        Returns
        -------
        Calibration
            The calibration the dict describes.

        Raises
        ------
        InputError
            Naming ``source`` and the key at fault.
        """
        check_calibration_document(obj, source, get_law)  # format, version, types, finite numbers
        fl = obj.get("frequency_law")
        frequency_law = None if fl is None else FrequencyLaw.from_json(fl, source)
        for key in _REQUIRED_KEYS:
            if key not in obj:
                raise InputError(f"calibration '{source}': missing key '{key}'")
        try:
            law = get_law(obj["law"])
            params = _params_from_json(obj["params"], law)
            flux_range = obj.get("flux_range")
            return cls(
                law=law.name,
                params=params,
                covariance=np.array(obj["covariance"], dtype=float),
                n_poles=int(obj["n_poles"]),
                current_range=_pair(obj["current_range"], "key 'current_range'"),
                gap_range=_pair(obj["gap_range"], "key 'gap_range'"),
                flux_range=None if flux_range is None else _pair(flux_range, "key 'flux_range'"),
                candidates=tuple(dict(row) for row in obj.get("candidates", [])),
                frequency_law=frequency_law,
                source=source,
            )
        except (InputError, DimensionError, TypeError, ValueError) as exc:
            raise InputError(f"calibration '{source}': {exc}") from exc

    def save(self, path: str | Path) -> Path:
        """Write the calibration as JSON, atomically.

        Parameters
        ----------
        path : str or Path
            The file to write.

        Returns
        -------
        Path
            The path written.
        """
        text = json.dumps(self.to_json(), indent=2, allow_nan=False)
        return write_text_atomic(path, text + "\n")

    @classmethod
    def load(cls, path: str | Path) -> Calibration:
        """Read a calibration written by :meth:`save`.

        Parameters
        ----------
        path : str or Path
            The JSON file.

        Returns
        -------
        Calibration
            The calibration the file holds.

        Raises
        ------
        InputError
            Naming the file, when it is missing, not JSON, or lacks a key.
        """
        path = Path(path)
        if path.is_file() and path.stat().st_size > MAX_DOCUMENT_BYTES:
            raise InputError(f"calibration file '{path}' holds {path.stat().st_size} bytes; "
                             f"at most {MAX_DOCUMENT_BYTES} are read")
        try:
            text = path.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise InputError(f"calibration file '{path}' not found") from None
        except (OSError, UnicodeDecodeError) as exc:
            raise InputError(f"calibration file '{path}' cannot be read: {exc}") from None
        try:
            obj = json.loads(text, parse_constant=reject_constant, object_pairs_hook=object_pairs)
        except json.JSONDecodeError as exc:
            raise InputError(
                f"calibration file '{path}' is not valid JSON: {exc.msg} at line {exc.lineno}"
            ) from None
        except RecursionError:
            raise InputError(f"calibration file '{path}' is not a calibration (JSON nested too "
                             "deeply)") from None
        except ValueError as exc:  # NaN/Infinity, an integer beyond the digit limit
            raise InputError(f"calibration file '{path}' is not valid JSON ({exc})") from None
        return cls.from_json(obj, source=str(path))


_Values = Any
"""An (n,) array of the n predictions, or a float (``numpy.float64``) where the inputs were
scalars."""


@dataclass(frozen=True)
class Prediction:
    """Predicted actuator force.

    As NumPy does: scalar inputs (a current and a gap, or a gap per pole) give floats, arrays
    give arrays (a current of shape (1,) gives arrays of one value).

    Attributes
    ----------
    total : (n,) array or float [N]
        Total force, summed over the poles.
    per_pole : (n, n_poles) array, or (n_poles,) for scalar inputs [N]
        Force of each pole.
    std : (n,) array or float [N]
        Standard uncertainty of ``total`` from the parameter covariance (delta method).
    frequency : (n,) array or float [Hz], or None
        The drive's frequency, when the prediction was asked at one (then ``total`` is the
        force with K replaced by K(f), and ``std`` from the frequency law's covariance).
    k_frequency, k_frequency_std : (n,) arrays or floats [N m^2/A^2], or None
        K(f) and its standard uncertainty.
    lag_deg, lag_deg_std : (n,) arrays or floats [deg], or None
        The force's lag behind i^2 at that frequency, and its standard uncertainty.
    """

    total: _Values
    per_pole: np.ndarray
    std: _Values
    frequency: _Values | None = None
    k_frequency: _Values | None = None
    k_frequency_std: _Values | None = None
    lag_deg: _Values | None = None
    lag_deg_std: _Values | None = None

    def __repr__(self) -> str:
        """One line: how many predictions, the total (its range over many) and its std."""
        total, std = np.ravel(self.total), np.ravel(self.std)
        if total.size == 1:
            what = f"total {total[0]:.6g} N ± {std[0]:.2g}"
        else:
            what = (f"{total.size} predictions, total {total.min():.6g} to {total.max():.6g} N, "
                    f"std up to {std.max():.2g}")
        at = "" if self.frequency is None else \
            f" at {np.min(self.frequency):g}-{np.max(self.frequency):g} Hz"
        return f"Prediction({what}{at}, {np.shape(self.per_pole)[-1]} pole(s))"


def _scalar(pred: Prediction) -> Prediction:
    """The prediction of one (current, gaps) or flux as floats (``per_pole`` (n_poles,))."""
    def one(values: np.ndarray | None) -> Any:
        return None if values is None else np.float64(np.ravel(values)[0])

    return replace(pred, total=one(pred.total), per_pole=pred.per_pole[0], std=one(pred.std),
                   frequency=one(pred.frequency), k_frequency=one(pred.k_frequency),
                   k_frequency_std=one(pred.k_frequency_std), lag_deg=one(pred.lag_deg),
                   lag_deg_std=one(pred.lag_deg_std))


def _is_scalar(current: Any, gaps: Any, frequency: Any = None) -> bool:
    """Whether the inputs are one prediction's scalars: a 0-d current, a gap that is a scalar
    or one per pole, no frequency or a 0-d one."""
    return (np.ndim(current) == 0 and np.ndim(gaps) <= 1
            and (frequency is None or np.ndim(frequency) == 0))


def _warn_unmatched(fl: FrequencyLaw, frequency: np.ndarray) -> None:
    """Warn (ExtrapolationWarning) where a frequency's nearest step (in log frequency) is one
    the law does not match within their uncertainties (:meth:`FrequencyLaw.departures`),
    stating the departure there."""
    off = fl.departures()
    if not off or not fl.steps:
        return
    steps = np.array([st.frequency for st in fl.steps])
    nearest = steps[np.argmin(np.abs(np.log(np.maximum(frequency[:, None], 1e-9))
                                     - np.log(steps[None, :])), axis=1)]
    for st, dg, dl, chi2 in off:
        if np.any(nearest == st.frequency):
            warnings.warn(
                f"frequency {st.frequency:.4g} Hz: the {fl.model} law departs from the step "
                f"measured there by {100 * dg / st.gain:+.3g} % in K(f) and {dl:+.3g} degrees "
                f"in lag (chi-square {chi2:.3g}, chance exceeds {MATCHED:g} at a 1e-3 rate): "
                "outside the domain where the law matched the data",
                ExtrapolationWarning, stacklevel=3)


def _warn_outside(
    values: np.ndarray, bounds: tuple[float, float], what: str, unit: str, factor: float
) -> None:
    """Warn (ExtrapolationWarning, at the caller of the public function) when ``values`` leave
    ``bounds``, stating by how much (in ``unit`` and in % of the range's width); ``factor``
    converts both to ``unit`` for the message."""
    lo, hi = bounds
    slack = 1e-9 * max(abs(lo), abs(hi))
    vmin, vmax = float(values.min()), float(values.max())
    if vmin < lo - slack or vmax > hi + slack:
        beyond = max(lo - vmin, vmax - hi)
        width = hi - lo if hi > lo else max(abs(lo), abs(hi))
        pct = 100 * beyond / width if width > 0 else math.nan
        share = "" if not width > 0 else f" ({pct:.3g} % of the range)" if pct < 1e3 else \
            f" ({pct:.0f} % of the range)"
        warnings.warn(
            f"{what} from {factor * vmin:.4g} to {factor * vmax:.4g} {unit} lies outside the "
            f"calibrated range {factor * lo:.4g} to {factor * hi:.4g} {unit}, by up to "
            f"{factor * beyond:.4g} {unit}{share}; extrapolating",
            ExtrapolationWarning,
            stacklevel=3,
        )


def _propagate(
    law: Law, cal: Calibration, i: np.ndarray, s: np.ndarray, phi: np.ndarray | None
) -> Prediction:
    """The prediction of the law with its standard uncertainty by the delta method."""
    per_pole, jac = law._value_and_jacobian(cal.params, i, s, phi)
    grad = jac.sum(axis=1)
    var = np.einsum("np,pq,nq->n", grad, cal.covariance, grad)
    return Prediction(
        total=per_pole.sum(axis=1), per_pole=per_pole, std=np.sqrt(np.maximum(var, 0.0))
    )


def _current_and_gaps(
    calibration: Calibration, current: Any, gaps: Any
) -> tuple[np.ndarray, np.ndarray]:
    """Current (n,) [A] and gaps (n, n_poles) [m] broadcast to one another, and within the
    limits of :func:`check_current_and_gaps`."""
    i = np.atleast_1d(np.asarray(current, dtype=float))
    g = np.asarray(gaps, dtype=float)
    if i.ndim != 1:
        raise DimensionError(f"current has shape {i.shape}; expected a scalar or (n,)")
    n = max(i.size, g.shape[0] if g.ndim == 2 else 1)
    try:
        i = np.broadcast_to(i, (n,))
        s = np.broadcast_to(g, (n, calibration.n_poles))
    except ValueError:
        raise DimensionError(
            f"current {i.shape} and gaps {g.shape} do not fit {calibration.n_poles} poles; "
            "expected gaps as a scalar, (n_poles,), (n, 1) or (n, n_poles)"
        ) from None
    check_current_and_gaps(calibration, i, s)
    return i, s


def _named(calibration: Calibration) -> str:
    """The calibration as the messages name it: its file, else its law."""
    return (f"calibration '{calibration.source}'" if calibration.source
            else f"calibration (law '{calibration.law}')")


def check_current_and_gaps(calibration: Calibration, current: Any, gaps: Any,
                           names: tuple[str, str] = ("current", "gaps")) -> None:
    """Refuse the currents and gaps :func:`predict` does not extrapolate to.

    The one place of these checks, for :func:`predict` and ``forcecal predict``.

    Parameters
    ----------
    calibration : Calibration
        Its ``current_range`` and ``gap_range`` bound the extrapolation.
    current : float or array [A]
        Coil currents.
    gaps : float or array [m]
        Air gaps.
    names : (str, str)
        How the messages name the currents and the gaps: the API's parameters (default), or
        the command line's options (``"argument --current:"``).

    Raises
    ------
    InputError
        Naming the parameter and the value: a current not finite or beyond
        :data:`MAX_CURRENT_A` in magnitude; a gap not finite, not positive or beyond
        :data:`MAX_GAP_M` (a gap in mm); a current more than :data:`EXTRAPOLATION` times the
        largest calibrated one, or a gap more than :data:`EXTRAPOLATION` times below or above
        the calibrated gaps (naming the calibration's file).
    """
    i = np.asarray(current, dtype=float).ravel()
    s = np.asarray(gaps, dtype=float).ravel()
    bad = ~(np.isfinite(i) & (np.abs(i) <= MAX_CURRENT_A))
    if np.any(bad):
        raise InputError(f"{names[0]} {float(i[bad][0])!r} A is not a finite current within "
                         f"{MAX_CURRENT_A:g} A")
    bad = ~(np.isfinite(s) & (s > 0) & (s <= MAX_GAP_M))
    if np.any(bad):
        raise InputError(f"{names[1]} {float(s[bad][0])!r} m is not an air gap between 0 and "
                         f"{MAX_GAP_M:g} m (0.0008 for 0.8 mm)")
    _refuse_far(calibration, i, calibration.current_range, names[0], "A", "current")
    lo, hi = calibration.gap_range
    bad = (s < lo / EXTRAPOLATION) | (s > hi * EXTRAPOLATION)
    if np.any(bad):
        raise InputError(f"{names[1]} {float(s[bad][0]):g} m is more than {EXTRAPOLATION:g} "
                         f"times outside the calibrated gaps {lo:.4g} to {hi:.4g} m "
                         f"({_named(calibration)})")


def predict(calibration: Calibration, current: Any, gaps: Any,
            frequency: Any = None) -> Prediction:
    """Total and per-pole force from coil current and air gaps, with its uncertainty.

    Parameters
    ----------
    calibration : Calibration
        A calibration of a (current, gap) law.
    current : float or (n,) array [A]
        Coil current.
    gaps : float, (n_poles,), (n, 1) or (n, n_poles) array [m]
        Air gap at each pole; a scalar means every pole at that gap.
    frequency : float, (n,) array or None [Hz]
        The drive's frequency, for a calibration with a frequency law: the force is then the
        frequency law's ``K(f) i^2 / (s + s_fe)^2`` (its own K, s_fe and tau), the amplitude
        of a steady drive at f; it lags i^2 by ``lag_deg``. None: the calibration's law.

    Returns
    -------
    Prediction
        Arrays over the n predictions, floats for scalar inputs (a scalar current, a scalar
        gap or one per pole, and a scalar frequency or none); ``std`` propagates the parameter
        covariance through the gradient of the total (delta method); with a frequency also
        K(f) and the lag.

    Raises
    ------
    InputError
        When the law predicts from flux; when a current or gap is not finite, beyond
        :data:`MAX_CURRENT_A` or :data:`MAX_GAP_M`, or more than :data:`EXTRAPOLATION` times
        outside the calibrated range (:func:`check_current_and_gaps`, naming ``current`` or
        ``gaps`` and the calibration's file); when a gap plus ``s_fe`` is not positive; when a
        frequency is given to a calibration without a frequency law, or
        is negative or above :data:`FREQUENCY_EXTRAPOLATION` times the highest calibrated
        one.
    DimensionError
        When the shapes of current and gaps do not fit.

    Warns
    -----
    ExtrapolationWarning
        When a current, gap or frequency lies outside the calibrated range (within
        :data:`EXTRAPOLATION` times it for a current or gap).
    """
    law = calibration.law_object
    if law.needs_flux:
        raise InputError(f"calibration law '{law.name}' predicts from flux; use predict_flux")
    i, s = _current_and_gaps(calibration, current, gaps)
    if frequency is not None:
        fl, f = _frequency(calibration, frequency, i.size)
        _warn_outside(i, fl.current_range, "current", "A", 1.0)
        _warn_outside(s, fl.gap_range, "gap", "mm", 1e3)
        _warn_outside(f, fl.frequency_range, "frequency", "Hz", 1.0)
        _warn_unmatched(fl, f)
        with np.errstate(all="ignore"):
            total, per_pole, std = fl.forces(i, s, f)
        k, k_std = fl.k_at(f)
        lag, lag_std = fl.lag_deg(f)
        pred = Prediction(total=total, per_pole=per_pole, std=std, frequency=f, k_frequency=k,
                          k_frequency_std=k_std, lag_deg=lag, lag_deg_std=lag_std)
        _check_finite_prediction(pred)
    else:
        law.check_gap_offset(calibration.params, s)
        _warn_outside(i, calibration.current_range, "current", "A", 1.0)
        _warn_outside(s, calibration.gap_range, "gap", "mm", 1e3)
        with np.errstate(all="ignore"):
            pred = _propagate(law, calibration, i, s, None)
        _check_finite_prediction(pred)
    return _scalar(pred) if _is_scalar(current, gaps, frequency) else pred


def _frequency(calibration: Calibration, frequency: Any, n: int
               ) -> tuple[FrequencyLaw, np.ndarray]:
    """The calibration's frequency law and the frequency broadcast to (n,) [Hz]; InputError
    without a law, for a frequency that is not finite, negative or far above the range."""
    fl = calibration.frequency_law
    if fl is None:
        raise InputError(f"{_named(calibration)} was calibrated at one frequency and has no "
                         "frequency law; predict without a frequency, or calibrate a "
                         "stepped-sine campaign")
    f = np.asarray(frequency, dtype=float)
    try:
        f = np.array(np.broadcast_to(f, (n,)), dtype=float)
    except ValueError:
        raise DimensionError(f"frequency {f.shape} does not fit {n} predictions; expected a "
                             "scalar or (n,)") from None
    if not np.all(np.isfinite(f)) or np.any(f < 0):
        raise InputError("frequency must be finite and not negative [Hz]")
    top = FREQUENCY_EXTRAPOLATION * fl.frequency_range[1]
    if np.any(f > top):
        raise InputError(f"frequency {float(f.max()):.4g} Hz is more than "
                         f"{FREQUENCY_EXTRAPOLATION:g} times the highest calibrated frequency "
                         f"{fl.frequency_range[1]:.4g} Hz; the {fl.model} law is not "
                         "extrapolated that far")
    return fl, f


def _check_finite_prediction(pred: Prediction) -> None:
    """InputError when the law gives a non-finite force (a gap at the law's pole)."""
    if not (np.all(np.isfinite(pred.total)) and np.all(np.isfinite(pred.std))):
        raise InputError("the calibrated law gives no finite force at these inputs (a gap at "
                         "or near zero?)")


def check_flux(calibration: Calibration, flux: Any, name: str = "flux") -> np.ndarray:
    """The fluxes (n,) [Wb] :func:`predict_flux` predicts from, refusing (InputError, naming
    ``name``) one not finite, beyond :data:`MAX_FLUX_WB`, or more than
    :data:`EXTRAPOLATION` times the largest calibrated flux."""
    phi = np.atleast_1d(np.asarray(flux, dtype=float))
    if phi.ndim != 1:
        raise InputError(f"{name} must be a scalar or (n,); got shape {phi.shape}")
    bad = ~(np.isfinite(phi) & (np.abs(phi) <= MAX_FLUX_WB))
    if np.any(bad):
        raise InputError(f"{name} {float(phi[bad][0])!r} Wb is not a finite flux through a pole "
                         f"within {MAX_FLUX_WB:g} Wb")
    if calibration.flux_range is not None:
        _refuse_far(calibration, phi, calibration.flux_range, name, "Wb", "flux")
    return phi


def _refuse_far(calibration: Calibration, values: np.ndarray, bounds: tuple[float, float],
                name: str, unit: str, what: str) -> None:
    """InputError, naming ``name`` and the calibration, for a value more than
    :data:`EXTRAPOLATION` times the largest calibrated one in magnitude."""
    top = max(abs(v) for v in bounds)
    bad = np.abs(values) > EXTRAPOLATION * top
    if np.any(bad):
        raise InputError(f"{name} {float(values[bad][0]):g} {unit} is more than "
                         f"{EXTRAPOLATION:g} times the largest calibrated {what} {top:.4g} "
                         f"{unit} ({_named(calibration)})")


def predict_flux(calibration: Calibration, flux: Any) -> Prediction:
    """Total and per-pole force from the flux through one pole, for the flux law.

    Parameters
    ----------
    calibration : Calibration
        A calibration of the flux law.
    flux : float or (n,) array [Wb]
        Flux through one pole.

    Returns
    -------
    Prediction
        ``total = n_poles * per-pole``; ``std`` by the delta method; floats for a scalar flux.

    Raises
    ------
    InputError
        When the law predicts from current and gap, or a flux is not finite, beyond
        :data:`MAX_FLUX_WB`, or more than :data:`EXTRAPOLATION` times the largest calibrated
        one (:func:`check_flux`).

    Warns
    -----
    ExtrapolationWarning
        When a flux lies outside the calibrated range.
    """
    law = calibration.law_object
    if not law.needs_flux:
        raise InputError(f"calibration law '{law.name}' predicts from current and gap; use predict")
    phi = check_flux(calibration, flux)
    if calibration.flux_range is not None:
        _warn_outside(phi, calibration.flux_range, "flux", "Wb", 1.0)
    s = np.ones((phi.size, calibration.n_poles))
    with np.errstate(all="ignore"):
        pred = _propagate(law, calibration, np.zeros(phi.size), s, phi)
    _check_finite_prediction(pred)
    return _scalar(pred) if np.ndim(flux) == 0 else pred

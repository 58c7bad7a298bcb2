"""Output files of ``reconstruct`` (INTERFACES.md section 5)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .._atomic import write_text_atomic
from ..errors import DataError
from ..forces import SPLIT_CONDITION, ForceEstimate
from .run_files import write_table_csv

__all__ = ["MAX_FORCE_N", "estimate_summary", "write_estimate"]


_HarmonicRows = list[dict[str, int | float | bool]]
"""One JSON object per harmonic the data support, in harmonic order."""


def estimate_summary(est: ForceEstimate) -> dict:
    """The JSON document of one run's forces.

    Parameters
    ----------
    est : ForceEstimate
        The run's estimate.

    Returns
    -------
    dict
        Fundamental, per-harmonic phasors with standard uncertainties (forces, total, and the
        resultant's first moments and, on a body, components), inertia share, conditioning
        figures and generalized coordinates, ready for :func:`json.dumps`.
    """
    forces = {name: _harmonic_rows(est, est.force[k], est.force_std[k], est.static[k])
              for k, name in enumerate(est.force_names)}
    forces["total"] = _harmonic_rows(est, est.total, est.total_std, est.static.sum(axis=0))
    resultant, components = _resultant_rows(est)
    c = est.coordinates
    return {
        "run": est.run_name,
        "fundamental_hz": est.f0,
        "fundamental_std_hz": est.f0_std,
        "dc_observed": est.dc_observed,
        "forces": forces,
        "resultant_moments": resultant,
        **({"resultant_components": components} if components else {}),
        "split_well_determined": bool(est.psi_condition <= SPLIT_CONDITION),
        "inertia_share": est.inertia_share,
        "waveform_std_n": est.waveform_std,
        "conditioning": {
            "psi_condition_number": est.psi_condition,
            "force_consistency_residual_n": est.consistency.tolist(),
            "sensor_gain": {str(int(n)): float(g)
                            for n, g in zip(c.harmonics, c.gain, strict=True)},
            "sensor_chi2": {str(int(n)): (None if not np.isfinite(x) else float(x))
                            for n, x in zip(c.harmonics, c.chi2, strict=True)},
        },
        "generalized_coordinates": [
            {"harmonic": int(n), "re": float(q.real), "im": float(q.imag), "std": float(s)}
            for n, q, s in zip(c.harmonics, c.q, c.q_std, strict=True)
        ],
        "notes": list(est.notes),
    }


def _harmonic_rows(est: ForceEstimate, ph: np.ndarray, std: np.ndarray,
                   static: np.ndarray | None) -> _HarmonicRows:
    """Rows of one force's phasors ``ph`` (H+1,) [N] and their uncertainties ``std`` (H+1,)
    [N], with the reactions-only amplitude when ``static`` (H+1,) [N] is given."""
    rows: _HarmonicRows = []
    for n in est.harmonics:
        if not est.kept[n]:
            continue
        row: dict[str, int | float | bool] = {
            "harmonic": int(n),
            "frequency_hz": float(n * est.f0),
            "amplitude_n": float(abs(ph[n])),
            "phase_rad": float(np.angle(ph[n])),
            "std_n": float(std[n]),
            "inertia_compensated": bool(est.with_inertia[n]),
        }
        if static is not None:
            row["static_amplitude_n"] = float(abs(static[n]))
        rows.append(row)
    return rows


def _resultant_rows(est: ForceEstimate) -> tuple[dict[str, _HarmonicRows],
                                                   dict[str, _HarmonicRows]]:
    """Rows of the resultant's first moments [N m] and of a body's resultant vector [N]."""
    resultant: dict[str, _HarmonicRows] = {}
    components: dict[str, _HarmonicRows] = {}
    if est.combination is None or est.combination_std is None:
        return resultant, components
    for k, name in enumerate(est.combination_names):
        if name.startswith(("moment", "resultant")):
            target = resultant if name.startswith("moment") else components
            target[name] = _harmonic_rows(est, est.combination[k], est.combination_std[k], None)
    return resultant, components


MAX_FORCE_N = 1e8
"""Largest force written [N]; an estimate beyond comes from inputs that are not what they
claim, and is refused rather than written."""


def write_estimate(est: ForceEstimate, out_dir: str | Path,
                   source: str | None = None) -> tuple[Path, Path]:
    """Write ``OUT/NAME.forces.csv`` and ``OUT/NAME.json`` atomically.

    Nothing is written when a value is not finite or a force exceeds :data:`MAX_FORCE_N`
    (DataError naming the run and the column); the JSON is strict (no NaN or Infinity).

    Parameters
    ----------
    est : ForceEstimate
        The run's estimate.
    out_dir : str or Path
        The output folder OUT, created when missing.
    source : str, optional
        The run file, for messages (default: the run's name).

    Returns
    -------
    csv : Path
        The force series: every force, the total and their reactions-only counterparts [N].
    json : Path
        The summary of :func:`estimate_summary`.
    """
    out_dir = Path(out_dir)
    cols = {name: est.series[k] for k, name in enumerate(est.force_names)}
    cols["total"] = est.total_series
    for k, name in enumerate(est.force_names):
        cols[f"{name}_static"] = est.static_series[k]
    cols["total_static"] = est.static_series.sum(axis=0)
    where = f"run '{source or est.run_name}'"
    for name, values in {"time": est.time, **cols}.items():
        v = np.asarray(values, dtype=float)
        bad = ~np.isfinite(v) | ((np.abs(v) > MAX_FORCE_N) if name != "time" else False)
        if np.any(bad):
            k = int(np.argmax(bad))
            raise DataError(f"{where}: the estimate's {name!r} is {v[k]:.4g} at sample {k}, not "
                            f"a finite force within {MAX_FORCE_N:g} N; nothing written (are the "
                            "inputs what they claim?)")
    try:
        text = json.dumps(estimate_summary(est), indent=1, allow_nan=False)
    except ValueError:
        raise DataError(f"{where}: the estimate's summary holds non-finite values; nothing "
                        "written") from None
    csv = write_table_csv(out_dir / f"{est.run_name}.forces.csv", est.time, cols)
    js = write_text_atomic(out_dir / f"{est.run_name}.json", text)
    return csv, js

"""Output files of ``reconstruct`` (INTERFACES.md section 5)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .._atomic import atomic_path
from ..errors import DataError, InputError
from ..forces.budget import MONTE_CARLO_SOURCES
from ..forces.steady import SPLIT_CONDITION, ForceEstimate
from .result_formats import (
    SERIES_FORMATS,
    SERIES_SUFFIXES,
    series_columns,
    series_json,
    write_series,
)

__all__ = ["MAX_FORCE_N", "SERIES_FORMATS", "estimate_summary", "write_estimate"]


_HarmonicRows = list[dict[str, int | float | bool | dict[str, float]]]
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
    forces = {name: _harmonic_rows(est, est.force[k], est.force_std[k], est.static[k],
                                   _budget(est, name), _re_im(est, name))
              for k, name in enumerate(est.force_names)}
    forces["total"] = _harmonic_rows(est, est.total, est.total_std, est.static.sum(axis=0),
                                     _budget(est, "total"), _re_im(est, "total"))
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
        "uncertainty": {
            "coverage_factor": 2,
            "budget_sources": list(est.budget),
            **({} if est.monte_carlo_std is None else {"monte_carlo": {
                "draws": est.monte_carlo_draws, "sources": list(MONTE_CARLO_SOURCES),
                "linear_same_sources": "budget_std_n of those sources, root sum of squares"}}),
            **({} if est.type_b is None else {
                "type_b": {k: getattr(est.type_b, k) for k in type(est.type_b).KEYS},
                "type_b_declared": est.type_b.declared,
                "type_b_text": est.type_b.describe()}),
        },
        "conditioning": {
            "psi_condition_number": est.psi_condition,
            "force_consistency_residual_n": est.consistency.tolist(),
            "sensor_gain": {str(int(n)): float(g)
                            for n, g in zip(c.harmonics, c.gain, strict=True)},
            "sensor_chi2": {str(int(n)): (None if not np.isfinite(x) else float(x))
                            for n, x in zip(c.harmonics, c.chi2, strict=True)},
        },
        "generalized_coordinates": [
            {"harmonic": int(n), "re": float(q.real), "im": float(q.imag), "std": float(s),
             **({} if not c.members or c.members[k] == (0,) else {
                 "shapes": [int(j) for j in c.members[k]],
                 "span": [{"re": float(v.real), "im": float(v.imag),
                           "std": float(np.sqrt(c.q_cov[k][i, i].real))}
                          for i, v in enumerate(c.q_span[k])]})}
            for k, (n, q, s) in enumerate(zip(c.harmonics, c.q, c.q_std, strict=True))
        ],
        "notes": list(est.notes),
    }


def _budget(est: ForceEstimate, name: str) -> dict[str, np.ndarray]:
    """Each uncertainty source's (H+1,) standard uncertainty of combination ``name`` (and the
    Monte Carlo's, under ``monte carlo``, when one was run)."""
    if not est.budget or name not in est.combination_names:
        return {}
    k = est.combination_names.index(name)
    out = {source: std[k] for source, std in est.budget.items()}
    if est.monte_carlo_std is not None:
        out["monte carlo"] = est.monte_carlo_std[k]
    return out


def _re_im(est: ForceEstimate, name: str) -> np.ndarray | None:
    """(H+1, 2) standard uncertainties of Re and of Im of combination ``name``, if known."""
    if est.combination_std_re_im is None or name not in est.combination_names:
        return None
    out: np.ndarray = est.combination_std_re_im[est.combination_names.index(name)]
    return out


def _harmonic_rows(est: ForceEstimate, ph: np.ndarray, std: np.ndarray,
                   static: np.ndarray | None,
                   budget: dict[str, np.ndarray] | None = None,
                   re_im: np.ndarray | None = None) -> _HarmonicRows:
    """Rows of one force's phasors ``ph`` (H+1,) [N] and their uncertainties ``std`` (H+1,)
    [N] (expanded, k = 2, beside; each source's part when ``budget`` is given), with the
    reactions-only amplitude when ``static`` (H+1,) [N] is given."""
    rows: _HarmonicRows = []
    for n in est.harmonics:
        if not est.kept[n]:
            continue
        row: dict[str, int | float | bool | dict[str, float]] = {
            "harmonic": int(n),
            "frequency_hz": float(n * est.f0),
            "amplitude_n": float(abs(ph[n])),
            "phase_rad": float(np.angle(ph[n])),
            "std_n": float(std[n]),
            "expanded_k2_n": float(2 * std[n]),
            "inertia_compensated": bool(est.with_inertia[n]),
        }
        if re_im is not None and n > 0:
            row["std_re_n"], row["std_im_n"] = float(re_im[n, 0]), float(re_im[n, 1])
        if budget:
            row["budget_std_n"] = {src: float(b[n]) for src, b in budget.items()
                                   if src != "monte carlo"}
            if "monte carlo" in budget:
                row["monte_carlo_std_n"] = float(budget["monte carlo"][n])
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
            target[name] = _harmonic_rows(est, est.combination[k], est.combination_std[k], None,
                                          _budget(est, name))
    return resultant, components


MAX_FORCE_N = 1e8
"""Largest force written [N]; an estimate beyond comes from inputs that are not what they
claim, and is refused rather than written."""


def write_estimate(est: ForceEstimate, out_dir: str | Path, source: str | None = None,
                   fmt: str = "csv", provenance: dict | None = None) -> tuple[Path, Path]:
    """Write the force series ``OUT/NAME.forces.<ext>`` and ``OUT/NAME.json``, atomically.

    The series (:func:`forcecal.io.result_formats.series_columns`): ``time`` [s]; every force
    and ``total``; the same with suffix ``_static`` (reactions only); the same with suffix
    ``_std`` (standard uncertainty at each instant), all in N. Both files appear together or
    neither: nothing is written when a value is not finite or a force exceeds
    :data:`MAX_FORCE_N` (DataError naming the run and the column), or when writing fails; the
    JSON is strict (no NaN or Infinity) and names the series file and its columns' units
    (``series``).

    Parameters
    ----------
    est : ForceEstimate
        The run's estimate.
    out_dir : str or Path
        The output folder OUT, created when missing.
    source : str, optional
        The run file, for messages (default: the run's name).
    fmt : {"csv", "hdf5", "mat", "uff"}
        Format of the series: ``NAME.forces.csv``, ``.h5``, ``.mat`` (MATLAB) or ``.uff``
        (dataset-58 time records); see :mod:`forcecal.io.result_formats`.
    provenance : dict, optional
        Written as the JSON's ``provenance``: version, date, command line, input digests.

    Returns
    -------
    series : Path
        The force series.
    json : Path
        The summary of :func:`estimate_summary`, with the ``series`` entry and, when given,
        the ``provenance`` (:func:`forcecal.provenance.provenance`).

    Raises
    ------
    InputError
        An unknown format, or force names the format cannot hold.
    DataError
        A value that is not finite or a force beyond :data:`MAX_FORCE_N`.
    """
    if fmt not in SERIES_SUFFIXES:
        raise InputError(f"run '{source or est.run_name}': output format {fmt!r} is not one of "
                         f"{', '.join(SERIES_FORMATS)}")
    out_dir = Path(out_dir)
    cols = series_columns(est)
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
        doc = estimate_summary(est)
        doc["series"] = series_json(est, fmt, cols)
        if provenance is not None:
            doc["provenance"] = provenance
        text = json.dumps(doc, indent=1, allow_nan=False)
    except ValueError:
        raise DataError(f"{where}: the estimate's summary holds non-finite values; nothing "
                        "written") from None
    series = out_dir / f"{est.run_name}{SERIES_SUFFIXES[fmt]}"
    js = out_dir / f"{est.run_name}.json"
    with atomic_path(js) as tmp_js, atomic_path(series) as tmp_series:  # series moved first
        write_series(est, tmp_series, fmt, cols)
        tmp_js.write_text(text, encoding="utf-8")
    return series, js

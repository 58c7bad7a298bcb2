"""What ``reconstruct`` writes for a run under any drive (:mod:`forcecal.forces.transient`).

``OUT/NAME.forces.csv``: ``time`` [s], every force and ``total``, the same with suffix
``_static`` (reactions only) and with suffix ``_std`` (the standard uncertainty of one sample),
in N, at the run's time stamps: the columns of a steady run's series. ``OUT/NAME.json``: the
band, the RMS of every force and of the total (AC part) with the standard uncertainty of a
sample, the inertia share, the estimator (smoother or filter) and the notes.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .._atomic import atomic_path
from ..errors import DataError, InputError
from ..forces.transient import TransientEstimate, reconstruct_any
from ..model.broadband import BroadbandModel
from ..records import Run
from ..rig import Rig
from .results import MAX_FORCE_N
from .run_files import write_table_csv
from .staging import staged_folder

__all__ = ["reconstruct_any_runs", "transient_summary", "write_transient"]


def _columns(est: TransientEstimate) -> dict[str, np.ndarray]:
    names = [*est.force_names, "total"]
    series = [*est.force, est.total]
    static = [*est.static, est.static.sum(axis=0)]
    std: list[np.ndarray] = [*est.force_std, est.total_std]
    cols = dict(zip(names, series, strict=True))
    cols.update({f"{n}_static": s for n, s in zip(names, static, strict=True)})
    cols.update({f"{n}_std": s for n, s in zip(names, std, strict=True)})
    return cols


def transient_summary(est: TransientEstimate) -> dict:
    """The JSON summary of a run under any drive."""
    def rms(x: np.ndarray) -> float:
        return float(np.sqrt(np.mean((x - x.mean()) ** 2)))

    def quad(s: np.ndarray | float) -> float:
        return float(np.sqrt(np.mean(s**2)))

    return {
        "run": est.run_name, "drive": "any", "band_hz": list(est.band),
        "estimator": ("Kalman smoother, short-time Wiener gains" if est.smoothed
                      else "Kalman filter"),
        "forces": {n: {"mean_n": float(f.mean()), "ac_rms_n": rms(f), "std_n": quad(s)}
                   for n, f, s in zip(est.force_names, est.force, est.force_std, strict=True)},
        "total": {"mean_n": float(est.total.mean()), "ac_rms_n": rms(est.total),
                  "std_n": quad(est.total_std)},
        "static_total_ac_rms_n": rms(est.static.sum(axis=0)),
        "inertia_share": est.inertia_share, "notes": list(est.notes)}


def write_transient(est: TransientEstimate, out_dir: str | Path,
                    source: str | None = None, provenance: dict | None = None
                    ) -> tuple[Path, Path]:
    """Write ``OUT/NAME.forces.csv`` and ``OUT/NAME.json`` together, atomically.

    Raises
    ------
    DataError
        A value that is not finite or beyond :data:`forcecal.io.results.MAX_FORCE_N`; nothing
        is written.
    """
    out_dir = Path(out_dir)
    cols = _columns(est)
    where = f"run '{source or est.run_name}'"
    for name, v in cols.items():
        bad = ~np.isfinite(v) | (np.abs(v) > MAX_FORCE_N)
        if np.any(bad):
            k = int(np.argmax(bad))
            raise DataError(f"{where}: the estimate's {name!r} is {v[k]:.4g} at sample {k}, not "
                            f"a finite force within {MAX_FORCE_N:g} N; nothing written")
    doc = transient_summary(est)
    doc["series"] = {"file": f"{est.run_name}.forces.csv", "columns": ["time", *cols],
                     "units": {"time": "s", **{c: "N" for c in cols}}}
    if provenance is not None:
        doc["provenance"] = provenance
    try:
        text = json.dumps(doc, indent=1, allow_nan=False)
    except ValueError:
        raise DataError(f"{where}: the summary holds non-finite values; nothing written") from None
    series = out_dir / f"{est.run_name}.forces.csv"
    js = out_dir / f"{est.run_name}.json"
    with atomic_path(js) as tmp_js, atomic_path(series) as tmp_series:
        write_table_csv(tmp_series, est.time, cols)
        tmp_js.write_text(text, encoding="utf-8")
    return series, js


def reconstruct_any_runs(rig: Rig, model: object, runs: list[Run], tare: Run | None,
                         output: str | Path, provenance: dict) -> list[str]:
    """``reconstruct`` under any drive (``acquisition.drive = "any"``): every run's forces
    sample by sample (:func:`forcecal.forces.transient.reconstruct_any`), written together into
    ``output``; the lines to print."""
    if not isinstance(model, BroadbandModel):
        raise InputError(f"rig '{rig.source}': acquisition.drive = 'any' needs a broadband "
                         "model (a scan under a broadband drive, with acquisition.band)")
    lines = []
    with staged_folder(output) as stage:
        for run in runs:
            est = reconstruct_any(rig, model, run, tare)
            series, _ = write_transient(est, stage, source=run.source, provenance=provenance)
            ac = float(np.std(est.total))
            quad = float(np.sqrt(np.mean(est.total_std**2)))
            lines.append(f"{Path(output) / series.name}: any drive, band {est.band[0]:g}-"
                         f"{est.band[1]:g} Hz, total AC RMS {ac:.4g} N, uncertainty of a "
                         f"sample (RMS) {quad:.3g} N (k = 2: {2 * quad:.3g} N), inertia "
                         f"share {est.inertia_share:.1%}")
            lines += [f"note: {note}" for note in est.notes]
    return lines

"""The fuzzer's oracle: whether the outputs of a command that exited 0 are sound (finite,
valid JSON without NaN or Infinity, physically bounded). :mod:`fuzz_inputs` runs the cases."""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from fuzz_inputs import Case, Lab

FORCE_FACTOR = 100.0
"""An output force beyond this many times the clean run's peak is absurd."""
PREDICT_LIMIT_N = 1e6
"""An actuator force beyond this (N) from ``predict`` is absurd."""


def _reject_constant(name: str) -> float:
    raise ValueError(f"non-JSON constant {name}")


def _json_numbers(obj: Any) -> list[float]:
    if isinstance(obj, dict):
        return [x for v in obj.values() for x in _json_numbers(v)]
    if isinstance(obj, list):
        return [x for v in obj for x in _json_numbers(v)]
    if isinstance(obj, int | float) and not isinstance(obj, bool):
        return [float(obj)]
    return []


def _check_json(path: Path, limit: float | None) -> str | None:
    try:
        doc = json.loads(path.read_text(encoding="utf-8"), parse_constant=_reject_constant)
    except (ValueError, UnicodeDecodeError) as exc:
        return f"{path.name}: not valid JSON ({exc})"
    nums = np.array(_json_numbers(doc))
    if nums.size and not np.all(np.isfinite(nums)):
        return f"{path.name}: non-finite number"
    if limit is not None and isinstance(doc, dict) and "forces" in doc:
        amps = [row.get("amplitude_n", 0.0) for rows in doc["forces"].values() for row in rows]
        if amps and max(abs(a) for a in amps) > limit:
            return f"{path.name}: force amplitude {max(amps):.3g} N is absurd"
    return None


def _check_table(path: Path, limit: float) -> str | None:
    from forcecal.io.run_files import read_run, read_table_csv

    try:
        if path.suffix in (".h5", ".hdf5"):
            run = read_run(path)
            cols = dict(run.channels)
        else:
            _, cols = read_table_csv(path)
    except Exception as exc:
        return f"{path.name}: unreadable output ({exc})"
    for name, v in cols.items():
        if not np.all(np.isfinite(v)):
            return f"{path.name}: column {name!r} not finite"
        if np.max(np.abs(v)) > limit:
            return f"{path.name}: column {name!r} reaches {np.max(np.abs(v)):.3g} N (absurd)"
    return None


def check_outputs(case: Case, lab: Lab, stdout: str) -> str | None:
    """None when every output is sound, else what is wrong."""
    limit = FORCE_FACTOR * lab.force_peak
    files: list[Path] = []
    for o in case.outputs:
        if o.is_dir():
            files += [p for p in o.rglob("*") if p.is_file()]
        elif o.is_file():
            files.append(o)
    for p in files:
        if p.name.endswith((".forces.csv", ".stream.csv")) or (
                case.command == "stream" and p.suffix in (".csv", ".h5", ".hdf5")):
            bad = _check_table(p, limit)
        elif p.suffix == ".json":
            bad = _check_json(p, limit)
            if bad is None and p.name == "calibration.json":
                bad = _check_calibration(p, lab)
            if bad is None and case.command == "scan":
                bad = _check_model(p)
        else:
            bad = None
        if bad:
            return bad
    if case.command == "predict":
        return _check_predict(stdout, "--json" in case.argv)
    return None


def _check_calibration(path: Path, lab: Lab) -> str | None:
    from forcecal.actuator import predict
    from forcecal.campaign import load_calibration

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            f = float(predict(load_calibration(path), [1.0], 0.0009).total[0])
        except Exception as exc:
            return f"{path.name}: not usable ({exc})"
    if not math.isfinite(f) or abs(f) > FORCE_FACTOR * lab.predict_force:
        return f"{path.name}: predicts {f:.3g} N at 1 A, 0.9 mm"
    return None


def _check_model(path: Path) -> str | None:
    from forcecal.model.broadband import BroadbandModel, load_any_model

    try:
        model = load_any_model(path)
    except Exception as exc:
        return f"{path.name}: the written model is not readable ({exc})"
    if isinstance(model, BroadbandModel):
        lines = model.frequencies
        if not (len(lines) >= 3 and model.band[0] - 5 <= lines[0] <= lines[-1]
                <= model.band[1] + 5):
            return f"{path.name}: lines {lines[:1]}..{lines[-1:]} Hz outside the band"
        std = model.ratio_std if model.ratio_std is not None else np.zeros(1)
        if not np.all(np.isfinite(std)) or np.max(std) > 1e6:
            return f"{path.name}: ratio uncertainty up to {np.max(std):.3g}"
        return None
    if not (0 < model.f0 < 1e6):
        return f"{path.name}: fundamental {model.f0} Hz"
    return None


def _check_predict(stdout: str, as_json: bool) -> str | None:
    text = stdout.strip()
    try:
        if as_json:
            doc = json.loads(text, parse_constant=_reject_constant)
            value = float(doc["total_n"])
            nums = _json_numbers(doc)
        else:
            value = float(text.splitlines()[-1])
            nums = [value]
    except (ValueError, KeyError, IndexError, TypeError) as exc:
        return f"stdout {text[:80]!r} is not a prediction ({exc})"
    if not all(math.isfinite(x) for x in nums):
        return f"stdout {text[:80]!r}: not finite"
    if abs(value) > PREDICT_LIMIT_N:
        return f"stdout {text[:80]!r}: {value:.3g} N is absurd"
    return None

"""Benchmark: the lab rig's stated uncertainty under any drive against its error, over seeds.

One run cannot test its statement where a systematic error dominates it: the ``lab`` rig draws
every sensor's sensitivity once, from the type-B uncertainty its rig file declares, so one
seed's error over its stated uncertainty is, for that part, |delta| / u of a single draw (on
the ``random`` preset at seed 0 the gauges' sensitivities are drawn 0.13 u from 1). Over N
seeds, every error redrawn (noise, hum, drifts, offsets, sensitivities, the scan), the RMS over
the seeds of each seed's error / stated is 1 for an honest statement, within the band
sqrt(chi2.ppf([0.0005, 0.9995], N) / N) where each seed's ratio is one Gaussian's (a
systematic error; a ratio averaged over many samples of noise scatters less).

For the ``sweep`` preset (through the beam's first mode in 4 s) and the ``random`` one, each
seed simulates the drive run and its tare alone (the sweep's stepped sines left out) with
``write_simulation(realism="lab")``; the model and the estimate are those of ``forcecal scan``
and ``forcecal reconstruct`` (the API). Reported per preset: each force's and the total's RMS
over the seeds of (the record's RMS error / its RMS stated uncertainty, the first and last
0.5 s aside) and the same for every 0.5 s window of the total; per seed, the gauges'
drawn sensitivities in units of their declared uncertainty. The same again with every drawn
sensitivity divided out of the run's and the tare's records and the rig declaring its
sensors' sensitivities exact: the statement's random part alone, seed by seed (the positions
and masses stay declared uncertain though the simulator's are exact, so the forces' own
ratios there lie below 1; the total does not depend on them). The mains hum is a draw of that
kind too: one phase per channel and record, the same tone all record long, so where it makes
most of a window's statement the window's ratio scatters from seed to seed as |e^(j a) +
e^(j b)| / sqrt(2) does (on the sweep at seed 1 the gauges' hum phases lie 169 degrees apart,
and their hum in the total is 0.16 of one gauge's).

Run:  .venv/bin/python benchmarks/lab_coverage.py [--seeds N] [--presets sweep random]
Writes benchmarks/results/lab_coverage.json.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
import scipy.stats

import forcecal
from forcecal.simulate.export import write_simulation
from forcecal.simulate.presets import get_preset

RESULTS = Path(__file__).parent / "results"
WIDTH = 0.5
"""Seconds of a window, and of the record's ends left aside."""
LEVEL = 0.999
"""Two-sided probability of the band on the RMS over seeds."""


def _band(n: int) -> tuple[float, float]:
    lo, hi = scipy.stats.chi2.ppf([(1 - LEVEL) / 2, (1 + LEVEL) / 2], n)
    return math.sqrt(lo / n), math.sqrt(hi / n)


def _preset(name: str):
    """The preset with its drive run alone (the lab rig adds the tare)."""
    preset = get_preset(name)
    return dataclasses.replace(preset, runs=tuple(r for r in preset.runs if not r.manifest))


def one_seed(tmp: Path, name: str, seed: int) -> dict:
    """One seed: simulated, scanned, reconstructed; its errors over its statement, as recorded
    and with the drawn sensitivities divided out of the records (:func:`_exact`)."""
    folder = write_simulation(tmp / f"{name}-{seed}", _preset(name), seed=seed, realism="lab")
    rig = forcecal.load_rig(folder / "rig.toml")
    model = forcecal.build_spatial_model(rig, forcecal.read_scan(folder / "scan.uff", rig))
    truth = pd.read_csv(folder / "truth" / f"{name}.forces.csv")
    drawn = json.loads((folder / "truth" / "simulator.json").read_text())["realism"]
    out = _ratios(rig, model, folder, name, "", truth)
    exact = dataclasses.replace(rig, type_b=dataclasses.replace(
        rig.type_b, gauge_scale=0.0, probe_scale=0.0, current_scale=0.0))
    for run in (name, "tare"):
        _exact(folder / "runs" / f"{run}.csv", drawn["sensitivity"])
    return {"seed": seed, **out, "exact": _ratios(exact, model, folder, name, ".exact", truth),
            "gauge_sensitivity_in_u": [(drawn["sensitivity"][g] - 1) / rig.type_b.gauge_scale
                                       for g in rig.gauge_names]}


def _exact(path: Path, sensitivity: dict[str, float]) -> None:
    """The record beside ``path`` (``.exact.csv``) with every channel's drawn sensitivity
    divided out: what its sensors would read if they were exactly as the rig declares."""
    frame = pd.read_csv(path)
    for channel, s in sensitivity.items():
        frame[channel] = frame[channel] / s
    frame.to_csv(path.with_suffix(".exact.csv"), index=False)


def _ratios(rig, model, folder: Path, name: str, suffix: str, truth: pd.DataFrame) -> dict:
    """Each force's and the total's error over its stated uncertainty inside the record, and
    every 0.5 s window's for the total."""
    run = forcecal.read_run(folder / "runs" / f"{name}{suffix}.csv", rig)
    tare = forcecal.read_run(folder / "runs" / f"tare{suffix}.csv", rig)
    est = forcecal.reconstruct(rig, model, run, tare=tare)
    m = int(round(WIDTH * run.fs))
    inner = slice(m, run.n_samples - m)
    names = [*rig.force_names, "total"]
    values = [*est.force, est.total]
    stds = [*est.force_std, est.total_std]
    ratio = {}
    for key, value, std in zip(names, values, stds, strict=True):
        err = (value - truth[key].to_numpy())[inner]
        ratio[key] = float(np.sqrt(np.mean(err**2) / np.mean(std[inner] ** 2)))
    err = est.total - truth["total"].to_numpy()
    windows = [float(np.sqrt(np.mean(err[k:k + m] ** 2) / np.mean(est.total_std[k:k + m] ** 2)))
               for k in range(m, run.n_samples - 2 * m + 1, m)]
    return {"error_to_stated": ratio, "windows": windows}


def summarise(rows: list[dict]) -> dict:
    """RMS over the seeds of every ratio, with the band an honest statement keeps."""
    keys = rows[0]["error_to_stated"].keys()
    win = np.array([r["windows"] for r in rows])
    out = {"n_seeds": len(rows), "band": _band(len(rows)),
           "error_to_stated": {k: float(np.sqrt(np.mean([r["error_to_stated"][k] ** 2
                                                         for r in rows]))) for k in keys},
           "windows": np.sqrt(np.mean(win**2, axis=0)).tolist()}
    if "exact" in rows[0]:
        out["exact"] = summarise([r["exact"] for r in rows])
    return out


def report(name: str, s: dict) -> None:
    lo, hi = s["band"]
    print(f"{name}: {s['n_seeds']} seeds; RMS over the seeds of error / stated (an honest "
          f"statement: {lo:.2f}-{hi:.2f}; target 0.8-1.25)")
    for label, r in (("as recorded", s), ("sensitivities exact", s["exact"])):
        print(f"  {label}: record " + ", ".join(
            f"{k} {v:.2f}" for k, v in r["error_to_stated"].items()) + "; the total's windows "
            + " ".join(f"{w:.2f}" for w in r["windows"]))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--presets", nargs="+", choices=("sweep", "random"),
                    default=["sweep", "random"])
    args = ap.parse_args()
    start = time.perf_counter()
    out: dict = {"benchmark": "lab_coverage", "machine": {
        "python": platform.python_version(), "cores": os.cpu_count()}, "presets": {}}
    with tempfile.TemporaryDirectory(prefix="forcecal-lab-") as tmp:
        for name in args.presets:
            rows = []
            for seed in range(args.seeds):
                rows.append(one_seed(Path(tmp), name, seed))
                print(f"  {name} seed {seed}: " + ", ".join(
                    f"{k} {v:.2f}" for k, v in rows[-1]["error_to_stated"].items())
                    + "; sensitivities exact: " + ", ".join(
                        f"{k} {v:.2f}" for k, v in rows[-1]["exact"]["error_to_stated"].items())
                    + "; the gauges' sensitivities drawn " + ", ".join(
                        f"{z:+.2f}" for z in rows[-1]["gauge_sensitivity_in_u"]) + " u",
                      flush=True)
            out["presets"][name] = {"summary": summarise(rows), "seeds": rows}
            report(name, out["presets"][name]["summary"])
    out["elapsed_s"] = time.perf_counter() - start
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "lab_coverage.json").write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Benchmark: the real cores' law over frequency over noise seeds, its scatter against its
stated standard uncertainty.

For the `solid` and `laminated` presets (the paper's magnet with its flux diffusing into a solid
2 mm core, diffusion time 5.0 ms, or into 0.35 mm laminations, 0.15 ms; a decade of stepped sines
10-100 Hz at gaps 0.8, 1.0 and 1.2 mm and a zero-current tare, scanned under a chirp), the
physics is simulated once per preset (the scan's and every run's true response: the
finite-element beam under the magnet whose flux diffuses into its core), and only the
measurement noise is redrawn over N seeds: the scan and every run, tare included, re-measured
with ``measure_scan`` / ``measure_run`` (:func:`calibration._seed_campaign`) from
``numpy.random.default_rng(BASE_SEED + seed)``, one generator per seed and nothing else random,
drawn in the order ``forcecal simulate`` draws them (``default_rng(0)`` gives its ``--seed 0``).

Each seed is calibrated as ``forcecal scan`` and ``forcecal calibrate`` do it, through the
Python API: the rig file's rig (``acquisition.band`` 5-200 Hz, ``drive = "any"``), the broadband
model of the chirp scan (``forcecal.build_spatial_model``, the command's defaults), then
``forcecal.calibrate`` on the manifest. Its law over frequency
(``Calibration.frequency_law``) chooses the core's model (first or half order), fits K, s_fe
and tau with their covariance, and gives K(f) / K and the lag at every frequency step.
``--check`` first runs seed 0 both ways (the command line on ``write_simulation(seed=0)``, by
:func:`calibration.core_campaign`, and this path on ``default_rng(0)``) and compares them.

Reported per preset, for K_total (K times the poles), s_fe and tau of the model most seeds chose
(every seed's fit of that model, a candidate of its selection, so a seed that chose the other
still counts) and for every step's K(f) / K and lag:

- the scatter over the seeds (sample standard deviation) over the mean stated standard
  uncertainty, with its sampling uncertainty, about ratio / sqrt(2 (N - 1)); target 0.8 to 1.25;
- the mean error against the simulated truth in units of the mean stated uncertainty, with its
  sampling uncertainty, ratio / sqrt(N). The truth is the magnet's own (as
  ``truth/simulator.json`` states it): K_total = mu0 N^2 A / 4, s_fe = l_fe / (2 mu_r), tau the
  diffusion time sigma mu d^2 (half order) or a third of it (first order: the lumped loop that
  matches the diffusion at low frequency), each step's K(f) / K and lag those of the simulated
  (discretised) diffusion at the step's drive frequency (``eddy.response``). Beside tau, the
  model's closest match to that response at the steps (``tau_match``: K(f) / K and lag fitted
  in the complex plane): its distance from the nominal tau is the model's own error, not the
  calibration's;
- which model each seed chose, and why.

N: 10 by default, about 4 minutes on 2 cores (the physics 2-5 s per preset, a seed's
calibration 9-13 s; 20 seeds take about 8 minutes): the ratio's sampling uncertainty is then
about 0.24 of it.

``--redraw scan`` or ``--redraw runs`` redraws only the scan's or only the runs' noise per
seed, the other held at one draw: the scatter of each part, against the part of the stated
uncertainty it makes.

Run:  .venv/bin/python benchmarks/core_seeds.py [--seeds 10] [--presets solid laminated]
          [--check] [--redraw both|scan|runs]
Writes benchmarks/results/core_seeds.json: the machine, N, the seeds, the elapsed time, and per
preset the truth, every quantity's statistics (``rows``), the other model's parameters'
(``other_model``), the models chosen, and every seed's values and stated uncertainties.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.optimize import minimize_scalar

import forcecal
from forcecal.actuator import FrequencyLaw
from forcecal.actuator.frequency_models import FREQUENCY_MODELS
from forcecal.errors import ForcecalError
from forcecal.simulate.presets import Preset, get_preset
from forcecal.simulate.virtual_rig import (
    build_model,
    public_rig,
    scan_response,
    simulate_response,
)

sys.path.insert(0, str(Path(__file__).resolve().parent))
import calibration

PRESETS = tuple(calibration.CORES)   # solid, laminated
SEEDS = 10
BASE_SEED = 1000
FIXED_SEED = 999
"""``--redraw scan`` or ``runs``: the seed of the part held at one draw."""
TARGET_RATIO = calibration.TARGET_RATIO   # seed scatter / mean stated standard uncertainty
PARAMS = ("K_total", "s_fe", "tau")
UNITS = {"K_total": ("1e-6 N m^2/A^2", 1e6), "s_fe": ("um", 1e6), "tau": ("ms", 1e3),
         "gain": ("-", 1.0), "lag": ("deg", 1.0)}

RESULTS = Path(__file__).resolve().parent / "results"


def machine() -> dict:
    """What the figures were measured on: Python, NumPy, the processor, its cores and load."""
    return {"python": platform.python_version(), "numpy": np.__version__,
            "cpu": platform.processor() or platform.machine(), "cores": os.cpu_count(),
            "load_average": os.getloadavg() if hasattr(os, "getloadavg") else None}


def user_rig(preset: Preset):
    """The rig as ``forcecal simulate`` writes its file for a broadband preset: the public rig
    with the scan's band and ``drive = "any"``."""
    return dataclasses.replace(public_rig(preset), band=preset.band, drive="any")


def simulate(preset: Preset) -> dict:
    """The physics of one preset, once: the finite-element model, the scan's and every run's
    true response."""
    t = time.perf_counter()
    fe = build_model(preset)
    scan_r = scan_response(preset, fe)
    responses = {spec.name: simulate_response(preset, spec.drives, spec.gap, spec.duration, fe,
                                              spec.gaps) for spec in preset.runs}
    return {"fe": fe, "scan": scan_r, "responses": responses,
            "seconds": time.perf_counter() - t}


def calibrate_seed(preset: Preset, physics: dict, rng: np.random.Generator,
                   runs_rng: np.random.Generator | None = None) -> FrequencyLaw:
    """One seed's noise drawn on the simulated physics, calibrated as ``forcecal scan`` and
    ``forcecal calibrate`` do it; its law over frequency (the runs' noise from ``runs_rng``
    where given)."""
    rig = user_rig(preset)
    with tempfile.TemporaryDirectory(prefix="forcecal-core-seed-") as tmp:
        scan, manifest = calibration._seed_campaign(Path(tmp), preset, physics["fe"],
                                                    physics["responses"], physics["scan"], rng,
                                                    runs_rng)
        model = forcecal.build_spatial_model(rig, scan)
        result = forcecal.calibrate(rig, model, manifest)
    law = result.calibration.frequency_law
    if law is None:
        raise ForcecalError(f"{preset.name}: the calibration has no law over frequency")
    return law


# ------------------------------------------------------------------------------- the truth


def _tau_match(model: str, freqs: np.ndarray, h_true: np.ndarray, tau0: float) -> float:
    """The model's tau closest to the simulated response at the steps (least squares of
    ``H_model - H_true`` in the complex plane)."""
    w = 2 * np.pi * freqs

    def cost(x: float) -> float:
        return float(np.sum(np.abs(FREQUENCY_MODELS[model].response(w, x * tau0)[0]
                                   - h_true) ** 2))

    return float(minimize_scalar(cost, bounds=(0.2, 5.0), method="bounded",
                                 options={"xatol": 1e-10}).x * tau0)


def truth(preset: Preset) -> dict:
    """The magnet's own parameters and, per step frequency, the simulated diffusion's K(f) / K
    and lag (as ``truth/simulator.json``'s ``eddy`` states them)."""
    magnet = preset.magnets[0]
    freqs = np.array(sorted({float(d.frequency) for r in preset.runs if not r.tare
                             for d in r.drives}))
    h = magnet.eddy_response(freqs)
    tau_d = magnet.diffusion_time
    nominal = {"half-order": tau_d, "first-order": tau_d / 3.0}
    return {
        "K_total": magnet.ideal_k, "s_fe": magnet.gap_offset, "n_poles": len(magnet.poles),
        "core": magnet.core, "diffusion_time": tau_d,
        "tau": nominal,
        "tau_match": {m: _tau_match(m, freqs, h, t) for m, t in nominal.items()},
        "steps": [{"frequency": float(f), "gain": float(abs(v)),
                   "lag": float(-np.degrees(np.angle(v)))} for f, v in zip(freqs, h,
                                                                            strict=True)],
    }


# ---------------------------------------------------------------------------- every seed


def _model_params(law: FrequencyLaw) -> dict[str, dict]:
    """Every model fitted: K_total, s_fe, tau and their stated standard uncertainties."""
    n = law.n_poles
    out = {}
    for c in law.candidates:
        if "params" in c:
            p, u = c["params"], c["stderr"]
            out[c["model"]] = {"K_total": n * p["K"], "s_fe": p["s_fe"], "tau": p["tau"],
                               "K_total_u": n * u["K"], "s_fe_u": u["s_fe"], "tau_u": u["tau"]}
    u = law.stderr
    chosen = {"K_total": n * law.k, "s_fe": law.s_fe, "tau": law.tau,
              "K_total_u": n * u[0], "s_fe_u": u[1], "tau_u": u[2]}
    if law.model in out:
        same = all(np.isclose(out[law.model][k], v, rtol=1e-9) for k, v in chosen.items())
        assert same, (out[law.model], chosen)
    out[law.model] = chosen
    return out


def seed_row(seed: int, law: FrequencyLaw, tr: dict) -> dict:
    """One seed's law: the model chosen, every model's parameters, every step's values."""
    steps = []
    for s, t in zip(law.steps, tr["steps"], strict=True):
        assert abs(s.frequency / t["frequency"] - 1) < 1e-3, (s.frequency, t["frequency"])
        steps.append({"frequency": s.frequency, "gain": s.gain, "gain_u": s.gain_std,
                      "lag": s.lag_deg, "lag_u": s.lag_deg_std})
    return {"seed": seed, "chosen": law.model, "reason": law.reason,
            "covariance_scale": law.covariance_scale, "chi2": law.chi2, "dof": law.dof,
            "models": _model_params(law), "steps": steps}


# ------------------------------------------------------------------------------ statistics


def stats(quantity: str, unit_key: str, values: list[float], stated: list[float],
          true: float, match: float | None = None) -> dict:
    """The scatter over the seeds against the mean stated uncertainty, and the mean error
    against the truth in units of it, each with its sampling uncertainty."""
    v, u = np.asarray(values), np.asarray(stated)
    n = v.size
    scatter = float(np.std(v, ddof=1))
    u_mean = float(u.mean())
    ratio = scatter / u_mean
    row = {"quantity": quantity, "unit": UNITS[unit_key][0], "scale": UNITS[unit_key][1],
           "n": n, "truth": true, "mean": float(v.mean()), "scatter": scatter,
           "stated": u_mean, "stated_spread": float(u.std(ddof=1)) / u_mean,
           "ratio": ratio, "ratio_sampling_1sigma": ratio / np.sqrt(2 * (n - 1)),
           "within_target": bool(TARGET_RATIO[0] <= ratio <= TARGET_RATIO[1]),
           "bias_over_u": (float(v.mean()) - true) / u_mean,
           "bias_sampling_1sigma": ratio / np.sqrt(n)}
    if match is not None:
        row["truth_match"] = match
        row["bias_over_u_match"] = (float(v.mean()) - match) / u_mean
    return row


def summarise(name: str, rows: list[dict], tr: dict) -> dict:
    """A preset's statistics over its seeds: the parameters of the model most seeds chose
    (and of the other), every step's K(f) / K and lag."""
    counts: dict[str, int] = {}
    for r in rows:
        counts[r["chosen"]] = counts.get(r["chosen"], 0) + 1
    model = max(counts, key=lambda m: (counts[m], m == calibration.CORES[name]))
    scales = np.array([r["covariance_scale"] for r in rows])
    out: dict = {"expected": calibration.CORES[name], "model": model, "chosen_counts": counts,
                 "reasons": sorted({r["reason"] for r in rows}),
                 "covariance_scale": {"min": float(scales.min()), "max": float(scales.max())}}

    def param_rows(m: str) -> list[dict]:
        fits = [r["models"][m] for r in rows if m in r["models"]]
        if len(fits) < 2:
            return []
        true = {"K_total": tr["K_total"], "s_fe": tr["s_fe"], "tau": tr["tau"][m]}
        return [stats(p, p, [f[p] for f in fits], [f[f"{p}_u"] for f in fits], true[p],
                      tr["tau_match"][m] if p == "tau" else None) for p in PARAMS]

    table = param_rows(model)
    for k, t in enumerate(tr["steps"]):
        f = t["frequency"]
        for q in ("gain", "lag"):
            label = f"{'K(f)/K' if q == 'gain' else 'lag'} {f:.2f} Hz"
            table.append(stats(label, q, [r["steps"][k][q] for r in rows],
                               [r["steps"][k][f"{q}_u"] for r in rows], t[q]))
    out["rows"] = table
    other = [m for m in FREQUENCY_MODELS if m != model]
    out["other_model"] = {m: param_rows(m) for m in other}
    return out


def print_table(name: str, res: dict) -> None:
    """One preset's table."""
    counts = ", ".join(f"{m} {c}" for m, c in res["chosen_counts"].items())
    print(f"\n{name} core ({res['truth']['core']}, diffusion time "
          f"{1e3 * res['truth']['diffusion_time']:.4f} ms): N = {res['n_seeds']} noise seeds, "
          f"physics simulated once ({res['seconds_simulation']:.1f} s), calibrations "
          f"{res['seconds_calibration']:.0f} s")
    print(f"  model chosen: {counts} (expected {res['expected']}); statistics of the "
          f"{res['model']} fit")
    c = res["covariance_scale"]
    how = ("below 1: weighted by the residual scatter, the runs' force uncertainty not given "
           "for every harmonic" if c["max"] < 1 else "the runs' force uncertainty")
    print(f"  covariance scale c {c['min']:.3g} to {c['max']:.3g} ({how})")
    head = (f"  {'quantity':<20}{'unit':>15}{'truth':>12}{'mean':>12}{'scatter':>10}"
            f"{'stated u':>10}{'scatter/u':>15}{'(mean-truth)/u':>16}")
    print(head)
    print("  " + "-" * (len(head) - 2))
    for r in res["rows"]:
        s = r["scale"]
        flag = "" if r["within_target"] else " !"
        print(f"  {r['quantity']:<20}{r['unit']:>15}{s * r['truth']:>12.6g}"
              f"{s * r['mean']:>12.6g}{s * r['scatter']:>10.3g}{s * r['stated']:>10.3g}"
              f"{r['ratio']:>8.2f} +/-{r['ratio_sampling_1sigma']:4.2f}"
              f"{r['bias_over_u']:>+9.2f} +/-{r['bias_sampling_1sigma']:4.2f}{flag}")
        if "truth_match" in r:
            print(f"  {'  model match':<20}{r['unit']:>15}{s * r['truth_match']:>12.6g}"
                  f"{'':>12}{'':>10}{'':>10}{'':>15}{r['bias_over_u_match']:>+9.2f}")
    print(f"  (target scatter/u {TARGET_RATIO[0]}-{TARGET_RATIO[1]}, '!' outside; +/- the "
          "sampling uncertainty, 1 sigma; 'model match': the model's tau closest to the "
          "simulated response at the steps)")


# ---------------------------------------------------------------------------------- checks


def check_seed0(name: str, preset: Preset, physics: dict, tr: dict) -> dict:
    """Seed 0 through the command line (:func:`calibration.core_campaign` on
    ``write_simulation(seed=0)``) and through this benchmark's path (``default_rng(0)``):
    the same law."""
    with tempfile.TemporaryDirectory(prefix="forcecal-core-check-") as tmp:
        cli = calibration.core_campaign(Path(tmp), name)
    law = calibrate_seed(preset, physics, np.random.default_rng(0))
    gains = [(1 + c["gain_error"]) * c["truth_gain"] for c in cli["steps"]]
    out = {"chosen_cli": cli["chosen"], "chosen_api": law.model,
           "tau_rel_diff": law.tau / cli["tau"] - 1,
           "tau_u_rel_diff": float(law.stderr[2]) / cli["tau_std"] - 1,
           "step_gain_max_abs_diff": float(max(abs(s.gain - g)
                                               for s, g in zip(law.steps, gains, strict=True)))}
    out["same"] = bool(out["chosen_cli"] == out["chosen_api"]
                       and abs(out["tau_rel_diff"]) < 1e-8
                       and abs(out["tau_u_rel_diff"]) < 1e-6
                       and out["step_gain_max_abs_diff"] < 1e-9)
    print(f"  check {name}: seed 0 by the command line and by the API: "
          f"{'the same' if out['same'] else 'DIFFERENT'} ({out})", file=sys.stderr)
    return out


# ------------------------------------------------------------------------------------ main


def _generators(seed: int, redraw: str) -> tuple[np.random.Generator, np.random.Generator | None]:
    """The scan's and the runs' generators of one seed: one for both (``both``, as
    ``forcecal simulate`` draws), or the other part's held at ``FIXED_SEED`` (``scan``: only
    the scan's noise redrawn; ``runs``: only the runs')."""
    if redraw == "both":
        return np.random.default_rng(seed), None
    fixed = np.random.default_rng(FIXED_SEED)
    drawn = np.random.default_rng(seed)
    return (drawn, fixed) if redraw == "scan" else (fixed, drawn)


def run_preset(name: str, n_seeds: int, check: bool, redraw: str = "both") -> dict:
    """One preset: its physics once, then every seed's noise and calibration."""
    preset = get_preset(name)
    tr = truth(preset)
    physics = simulate(preset)
    print(f"{name}: physics simulated in {physics['seconds']:.1f} s", file=sys.stderr)
    checked = check_seed0(name, preset, physics, tr) if check else None
    t = time.perf_counter()
    rows, failed = [], []
    for k in range(n_seeds):
        seed = BASE_SEED + k
        try:
            law = calibrate_seed(preset, physics, *_generators(seed, redraw))
        except ForcecalError as exc:
            failed.append({"seed": seed, "error": str(exc)})
            print(f"  {name} seed {k + 1}/{n_seeds}: FAILED: {exc}", file=sys.stderr)
            continue
        rows.append(seed_row(seed, law, tr))
        m = rows[-1]["models"][law.model]
        print(f"  {name} seed {k + 1}/{n_seeds}: {law.model}, K_total "
              f"{m['K_total']:.7g} +/- {m['K_total_u']:.2g}, s_fe {1e6 * m['s_fe']:.3f} +/- "
              f"{1e6 * m['s_fe_u']:.3f} um, tau {1e3 * m['tau']:.5f} +/- "
              f"{1e3 * m['tau_u']:.5f} ms ({time.perf_counter() - t:.0f} s)", file=sys.stderr)
    t_cal = time.perf_counter() - t
    if len(rows) < 2:
        raise SystemExit(f"{name}: {len(rows)} seeds calibrated; no scatter to compare")
    res = {"n_seeds": len(rows), "failed": failed, "truth": tr,
           "seconds_simulation": physics["seconds"], "seconds_calibration": t_cal,
           **summarise(name, rows, tr), "check_seed0": checked, "seeds": rows}
    return res


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=SEEDS,
                    help=f"noise seeds per preset (default {SEEDS}, at least 2)")
    ap.add_argument("--presets", nargs="+", choices=PRESETS, default=list(PRESETS),
                    help="the real-core presets (default both)")
    ap.add_argument("--check", action="store_true",
                    help="first compare seed 0 through the command line and through the API")
    ap.add_argument("--redraw", choices=("both", "scan", "runs"), default="both",
                    help="the noise redrawn per seed: both (default), only the scan's or only "
                         "the runs' (the other's held at one draw); results then go to "
                         "core_seeds_<redraw>.json")
    args = ap.parse_args()
    if args.seeds < 2:
        ap.error("--seeds: at least 2 seeds give a scatter")
    t0 = time.perf_counter()
    doc: dict = {"benchmark": "core_seeds", "machine": machine(), "n_seeds": args.seeds,
                 "base_seed": BASE_SEED, "redraw": args.redraw, "target": TARGET_RATIO,
                 "presets": {}}
    for name in args.presets:
        doc["presets"][name] = run_preset(name, args.seeds, args.check, args.redraw)
    doc["elapsed_s"] = time.perf_counter() - t0
    doc["machine"]["load_average_end"] = os.getloadavg() if hasattr(os, "getloadavg") else None
    for name, res in doc["presets"].items():
        print_table(name, res)
    print(f"\nN = {args.seeds} seeds per preset; elapsed {doc['elapsed_s']:.0f} s")
    RESULTS.mkdir(parents=True, exist_ok=True)
    out = "core_seeds.json" if args.redraw == "both" else f"core_seeds_{args.redraw}.json"
    (RESULTS / out).write_text(json.dumps(doc, indent=2, default=float) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

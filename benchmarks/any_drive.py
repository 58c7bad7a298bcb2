"""Benchmark: drives other than a steady sine, against the virtual rig's truth.

Simulates the `sweep` and `random` presets (seed 0) and runs them the way a user would
(``forcecal scan`` on the chirp scan with ``acquisition.band``, ``forcecal reconstruct`` with
``acquisition.drive = "any"``, ``forcecal calibrate`` on the stepped-sine manifest), then
compares:

- the swept-sine run (10 -> 150 Hz in 4 s through the first bending mode) and the band-limited
  random run (5-150 Hz): the total force's RMS error in every 0.5 s window as a fraction of
  the window's AC RMS, beside the reactions-only estimate's (targets: sweep <= 0.5 %, random
  <= 2 % in every window), and against the truth without its content above the scan's band
  (the force's second harmonic of a 150 Hz drive lies at 300 Hz, beyond the 200 Hz scan);
- the stepped-sine campaign (10-100 Hz, three gaps): each step's K(f) / K and lag against the
  first-order truth 1 / (1 + j 2 pi f tau) of the simulated eddy-current magnet, and the fitted
  tau (targets: 0.2 % and 0.2 degrees), at seed 0 and then under the noise of seeds 1-3;
- an oracle: the best gains any short-time filter of the same estimate could apply, taken
  from the truth's own power and the estimate's own error, bin by bin (the Wiener gain
  S / (S + N) over 0.2 s frames); what it leaves is no noise's but the estimate's own;
- the truth "as claimed": through the gauges' own smoother, the band the estimate gives
  (content above the scan's band reaches it as far as the gauges' smoother lets through); the
  stated uncertainty is compared with the error against it; the worst windows again at seeds
  1 and 2;
- ``forcecal stream`` on the same runs (real time, :mod:`forcecal.realtime.any_drive`): its
  windows beside the batch's, how far it is from the batch in units of the batch's stated
  uncertainty, and its wall time;
- the ``lab`` rig (seeds 0 and 1): the same runs with coloured noise, mains hum, sensitivities
  drawn from the declared type-B uncertainties, gravity preload and offsets (the tare given):
  windows, each force's and the total's error over its stated uncertainty, and on the sweep
  rig the stepped sines; the inertia's scale calibrated in situ (s, its uncertainty, the
  truth's s) and the windows without and with it.

``--only dwell`` runs the ``dwell`` preset alone (a 20 s sweep slowly through the first mode):
its windows beside a reference, the noisy reactions deconvolved with the structure's exact
transfer from the total force to the reactions' sum (:func:`_reference`), and their ratio.

Run:  .venv/bin/python benchmarks/any_drive.py [--only sweep|random|dwell]
      [--ratios auto|spline|modal]
Writes benchmarks/results/any_drive.json (with --only or --ratios spline,
any_drive_<preset>_<ratios>.json). ``--only`` runs one preset's drive runs (seed 0 and the
worst windows of seeds 1-2; the sweep's stepped sines at seed 0) without the stepped sines'
other seeds and the lab rig; ``--ratios spline`` keeps the splines' ratios whatever the
criterion says (:func:`forcecal.model.ratios.choose_ratios`), the estimate before the
modal model, and ``--ratios modal`` takes the modal model's wherever one is identified.
``--lab SEEDS`` runs the lab rig's drive runs alone at seeds 0..SEEDS-1
(any_drive_lab.json).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
import scipy.ndimage
import scipy.signal

import forcecal.model.ratios as ratio_model
from forcecal.cli.main import main
from forcecal.io.run_files import read_run
from forcecal.model.broadband import load_any_model
from forcecal.model.relaxation import force_matrix
from forcecal.rig import load_rig
from forcecal.simulate.export import write_simulation

RESULTS = Path(__file__).parent / "results"
MODE_HZ = 69.0
"""The sweep rig's first bending mode, closed loop at 1 mm and 0.6 A."""


def _in_band(x: np.ndarray, fs: float, top: float) -> np.ndarray:
    """``x`` without its content above ``top`` Hz."""
    spec = np.fft.rfft(x)
    spec[np.fft.rfftfreq(x.size, 1.0 / fs) > top] = 0.0
    return np.fft.irfft(spec, x.size)


def _windows(est: pd.DataFrame, truth: pd.DataFrame, column: str, width: float,
             top: float | None = None) -> list[float]:
    """Each window's RMS error over the window's AC RMS of the truth; with ``top``, the error
    against the truth with its content above ``top`` Hz removed (the scan's band)."""
    t = truth["time"].to_numpy()
    fs = 1.0 / (t[1] - t[0])
    n = int(round(width * fs))
    true = truth["total"].to_numpy()
    ref = true if top is None else _in_band(true, fs, top)
    err = est[column].to_numpy() - ref
    out = []
    for k in range(0, len(true) - n + 1, n):
        ac = np.std(true[k:k + n])
        out.append(float(np.sqrt(np.mean(err[k:k + n] ** 2)) / ac))
    return out


def _claimed(folder: Path, model: Path, run: str, truth: pd.DataFrame) -> np.ndarray:
    """The true total as the estimate claims it: through the reactions' smoother of the batch's
    setup (1 within the band, falling beyond its top as the gauges' own smoother does; content
    above the band is the gauges' and the transfer's, not the scan's), carried past the
    record's ends and with its mean passed whole, as the estimate's reactions are."""
    from forcecal.forces.any_setup import any_drive_setup
    from forcecal.forces.transient import run_channels
    from forcecal.signals.kalman import smooth_states
    from forcecal.signals.record_ends import extend

    rig = load_rig(folder / "rig.toml")
    record = read_run(folder / "runs" / f"{run}.csv", rig)
    gauges, probes, _ = run_channels(rig, record)
    setup = any_drive_setup(rig, load_any_model(model), gauges, probes, record.fs)
    total = truth["total"].to_numpy()
    level = float(total.mean())
    ext = extend((total - level)[None, :], record.fs, setup.band[1], 1)
    return level + ext.inner(smooth_states(setup.reaction_models[0], ext.values[0],
                                           states=(0,))[0])


def _stated(est: pd.DataFrame, claimed: np.ndarray) -> dict:
    """The RMS of the total's error over its stated uncertainty sample by sample, and the share
    of samples within 2 u, against the truth as the estimate claims it (:func:`_claimed`)."""
    err = est["total"].to_numpy() - claimed
    u = est["total_std"].to_numpy()
    return {"ratio": float(np.sqrt(np.mean((err / u) ** 2))),
            "within_2u": float(np.mean(np.abs(err) <= 2 * u))}


def _stated_windows(est: pd.DataFrame, claimed: np.ndarray, width: float) -> list[float]:
    """Each window's RMS error (against the truth as claimed) over its RMS stated
    uncertainty."""
    t = est["time"].to_numpy()
    n = int(round(width / (t[1] - t[0])))
    err = est["total"].to_numpy() - claimed
    u = est["total_std"].to_numpy()
    return [float(np.sqrt(np.mean(err[k:k + n] ** 2) / np.mean(u[k:k + n] ** 2)))
            for k in range(0, len(err) - n + 1, n)]


def _oracle(folder: Path, model: Path, run: str, truth: pd.DataFrame, claimed: np.ndarray
            ) -> list[float]:
    """Each 0.5 s window's error, against the truth as claimed, of the estimate before
    its short-time Wiener gains when the gains are the oracle's, S / (S + N) bin by bin: S
    the truth's power, N the estimate's own error's (averaged over 5 bins by 5 frames)."""
    from forcecal.forces.transient import reconstruct_any

    rig = load_rig(folder / "rig.toml")
    broadband = load_any_model(model)
    est = reconstruct_any(rig, broadband, read_run(folder / "runs" / f"{run}.csv", rig))
    total = np.ones(len(rig.force_names)) @ np.linalg.pinv(force_matrix(rig))
    raw = total @ (est.inertia - est.reactions)
    t = truth["time"].to_numpy()
    fs = 1.0 / (t[1] - t[0])
    true = claimed
    frame = 2 ** int(round(np.log2(0.2 * fs)))
    kw = {"fs": fs, "window": "hann", "nperseg": frame, "noverlap": 3 * frame // 4}
    z, s, e = (scipy.signal.stft(x, boundary="even", padded=True, **kw)[2]
               for x in (raw, true, raw - true))
    sig = np.abs(s) ** 2
    gain = sig / (sig + scipy.ndimage.uniform_filter(np.abs(e) ** 2, 5) + 1e-300)
    best = scipy.signal.istft(gain * z, boundary=True, **kw)[1][:raw.size]
    return _windows(pd.DataFrame({"total": best}), truth.assign(total=claimed), "total", 0.5)


def _drive_run(folder: Path, run: str) -> dict:
    model = folder / "model.json"
    if main(["scan", "-q", str(folder / "rig.toml"), str(folder / "scan.uff"), "-o",
             str(model)]) != 0:
        raise SystemExit(f"scan of {folder} failed")
    out = folder / "out"
    start = time.perf_counter()
    tare = folder / "runs" / "tare.csv"
    if main(["reconstruct", "-q", str(folder / "rig.toml"), str(model),
             str(folder / "runs" / f"{run}.csv"), *(["--tare", str(tare)] if tare.exists() else []),
             "-o", str(out)]) != 0:
        raise SystemExit(f"reconstruct of {run} failed")
    seconds = time.perf_counter() - start
    streamed = folder / f"{run}.stream.csv"
    start = time.perf_counter()
    if main(["stream", str(folder / "rig.toml"), str(model), str(folder / "runs" / f"{run}.csv"),
             *(["--tare", str(tare)] if tare.exists() else []), "-o", str(streamed)]) != 0:
        raise SystemExit(f"stream of {run} failed")
    stream_s = time.perf_counter() - start
    est = pd.read_csv(out / f"{run}.forces.csv")
    live = pd.read_csv(streamed)
    truth = pd.read_csv(folder / "truth" / f"{run}.forces.csv")
    band = json.loads(model.read_text())["band"]
    apart = live["total"].to_numpy() - est["total"].to_numpy()
    claimed = _claimed(folder, model, run, truth)
    as_claimed = truth.assign(total=claimed)
    return {"ratio_model": json.loads(model.read_text()).get("ratio_model"),
            "windows_stated": _stated_windows(est, claimed, 0.5),
            "windows_short": _windows(est, truth, "total", 0.1),
            "windows_short_stated": _stated_windows(est, claimed, 0.1),
            "windows": _windows(est, truth, "total", 0.5),
            "windows_claimed": _windows(est, as_claimed, "total", 0.5),
            "windows_in_band": _windows(est, truth, "total", 0.5, top=band[1]),
            "windows_static": _windows(est, truth, "total_static", 0.5),
            "windows_oracle": _oracle(folder, model, run, truth, claimed),
            "windows_stream": _windows(live, truth, "total", 0.5),
            "stream_vs_batch_rms_in_stated_std": float(np.sqrt(np.mean(apart**2))
                                                       / np.sqrt(np.mean(est["total_std"]**2))),
            "observed_to_stated": _stated(est, claimed),
            "observed_to_stated_stream": _stated(live, claimed),
            "reconstruct_s": seconds, "stream_s": stream_s}


def _campaign(folder: Path) -> dict:
    out = folder / "cal"
    if main(["calibrate", "-q", str(folder / "rig.toml"), str(folder / "model.json"),
             "--manifest", str(folder / "manifest.csv"), "-o", str(out), "--no-report"]) != 0:
        raise SystemExit("calibrate failed")
    doc = json.loads((out / "calibration.json").read_text())
    facts = json.loads((folder / "truth" / "simulator.json").read_text())
    tau = float(next(iter(facts["eddy"]["eddy_time_s"].values())))
    law = doc["frequency_law"]
    steps = []
    for s in law["steps"]:
        w = 2 * math.pi * s["frequency"] * tau
        steps.append({"frequency": s["frequency"],
                      "gain_error": s["gain"] * math.sqrt(1 + w * w) - 1,
                      "gain_std": s["gain_std"],
                      "lag_error_deg": s["lag_deg"] - math.degrees(math.atan(w)),
                      "lag_std_deg": s["lag_deg_std"]})
    return {"tau_true": tau, "tau": law["params"]["tau"], "tau_std": law["stderr"]["tau"],
            "steps": steps}


def _campaign_seed(tmp: Path, seed: int) -> dict:
    folder = tmp / f"sweep-{seed}"
    write_simulation(folder, "sweep", seed=seed)
    if main(["scan", "-q", str(folder / "rig.toml"), str(folder / "scan.uff"), "-o",
             str(folder / "model.json")]) != 0:
        raise SystemExit(f"scan of {folder} failed")
    return _campaign(folder)


def _reference(folder: Path, run: str, truth: pd.DataFrame) -> list[float]:
    """Every 0.5 s window of a reference: the run's noisy reactions deconvolved with the
    structure's exact transfer from the total force to the reactions' sum, over the lines that
    carry the force (the record's own: the simulator's noise-free reactions over its total at
    those lines), as the simulator knows them; the total's mean taken from the truth."""
    rig = load_rig(folder / "rig.toml")
    known = np.load(folder / "truth" / f"{run}.npz")
    clean = (known["inertia"] - force_matrix(rig) @ known["pole_force"]).sum(axis=0)
    total = truth["total"].to_numpy()
    record = read_run(folder / "runs" / f"{run}.csv", rig)
    measured = np.fft.rfft(sum(record.channel(g) for g in rig.gauge_names))
    spectrum = np.fft.rfft(total - total.mean())
    lines = np.abs(spectrum) > 1e-3 * np.abs(spectrum).max()
    kept = np.zeros_like(spectrum)
    kept[lines] = measured[lines] * spectrum[lines] / np.fft.rfft(clean)[lines]
    estimate = total.mean() + np.fft.irfft(kept, total.size)
    return _windows(pd.DataFrame({"total": estimate}), truth, "total", 0.5)


def _worst_windows(tmp: Path, preset: str, seed: int) -> dict:
    """The worst window of a drive run at another seed, against the truth and as claimed, and
    its observed / stated."""
    folder = tmp / f"{preset}-{seed}"
    write_simulation(folder, preset, seed=seed)
    r = _drive_run(folder, preset)
    return {"seed": seed, "worst": max(r["windows"]), "worst_claimed": max(r["windows_claimed"]),
            "worst_stream": max(r["windows_stream"]),
            "observed_to_stated": r["observed_to_stated"]["ratio"]}


def _lab(tmp: Path, preset: str, seed: int) -> dict:
    """A drive run of the ``lab`` rig (coloured noise, mains hum, sensitivities drawn from the
    declared type-B uncertainties, gravity preload and offsets, a walking scan drive): its
    windows against the truth, the reactions only, and each force's and the total's error over
    the stated uncertainty inside the record (the record's first and last 0.5 s aside)."""
    folder = tmp / f"{preset}-lab-{seed}"
    write_simulation(folder, preset, seed=seed, realism="lab")
    r = _drive_run(folder, preset)
    est = pd.read_csv(folder / "out" / f"{preset}.forces.csv")
    truth = pd.read_csv(folder / "truth" / f"{preset}.forces.csv")
    fs = 1.0 / (truth["time"][1] - truth["time"][0])
    inner = slice(int(0.5 * fs), -int(0.5 * fs))
    z = {}
    for name in [c for c in truth.columns if c != "time"]:
        err = (est[name] - truth[name]).to_numpy()[inner]
        z[name] = float(np.sqrt(np.mean((err / est[f"{name}_std"].to_numpy()[inner]) ** 2)))
    out = {"seed": seed, "windows": r["windows"], "windows_static": r["windows_static"],
           "error_to_stated": z, "error_to_stated_drawn": _drawn_stated(folder, preset, truth),
           "inertia_scale": _inertia_scale(folder, preset, truth)}
    if preset == "sweep":
        c = _campaign(folder)
        out["stepped_sines"] = {
            "gain_error": max(abs(s["gain_error"]) for s in c["steps"]),
            "lag_error_deg": max(abs(s["lag_error_deg"]) for s in c["steps"]),
            "tau": c["tau"], "tau_std": c["tau_std"], "tau_true": c["tau_true"]}
    return out


def _drawn_stated(folder: Path, preset: str, truth: pd.DataFrame) -> dict:
    """Each force's and the total's RMS error over its stated uncertainty inside the record,
    the uncertainty stated from the type-B sources the lab rig draws alone (its sensors'
    sensitivities): the rig file also declares positions, masses and gaps uncertain, but
    gives the simulator's own, so their share of the statement is never an error here."""
    from forcecal.forces.transient import reconstruct_any

    rig = load_rig(folder / "rig.toml")
    drawn = dataclasses.replace(rig, type_b=dataclasses.replace(rig.type_b, position=0.0,
                                                                 mass=0.0, gap=0.0))
    record = read_run(folder / "runs" / f"{preset}.csv", rig)
    est = reconstruct_any(drawn, load_any_model(folder / "model.json"), record,
                          read_run(folder / "runs" / "tare.csv", rig))
    inner = slice(int(0.5 * record.fs), -int(0.5 * record.fs))
    out = {}
    for k, name in enumerate([*rig.force_names, "total"]):
        value = est.force[k] if k < len(rig.force_names) else est.total
        std = est.force_std[k] if k < len(rig.force_names) else est.total_std
        err = (value - truth[name].to_numpy())[inner]
        out[name] = float(np.sqrt(np.mean((err / std[inner]) ** 2)))
    return out


def _inertia_scale(folder: Path, preset: str, truth: pd.DataFrame) -> dict:
    """The inertia's scale calibrated in situ (:mod:`forcecal.forces.inertia_scale`, on by
    default): s with its uncertainty and whether it was applied, the truth's s (the scale that
    takes the estimate's inertia to the simulator's, inside the record), and the windows
    without it (``reconstruct_any(..., inertia_scale=False)``) and with it."""
    from forcecal.forces.transient import reconstruct_any

    rig = load_rig(folder / "rig.toml")
    model = load_any_model(folder / "model.json")
    record = read_run(folder / "runs" / f"{preset}.csv", rig)
    tare = read_run(folder / "runs" / "tare.csv", rig)
    after = reconstruct_any(rig, model, record, tare)
    before = reconstruct_any(rig, model, record, tare, inertia_scale=False)
    sc = after.inertia_scale
    assert sc is not None
    total = np.ones(len(rig.force_names)) @ np.linalg.pinv(force_matrix(rig))
    seen = total @ before.inertia
    true = np.load(folder / "truth" / f"{preset}.npz")["inertia"].sum(axis=0)
    inner = slice(int(0.5 * record.fs), -int(0.5 * record.fs))
    s_true = float(np.dot(seen[inner], true[inner]) / np.dot(seen[inner], seen[inner]))
    frame = pd.DataFrame
    return {"s": sc.estimate, "s_std": sc.estimate_std, "applied": sc.applied,
            "misfit": sc.misfit, "s_true": s_true, "note": sc.note,
            "windows_before": _windows(frame({"total": before.total}), truth, "total", 0.5),
            "windows_after": _windows(frame({"total": after.total}), truth, "total", 0.5)}


def run(seeds: int = 4, drive_seeds: int = 3, only: str | None = None,
        lab_seeds: int | None = None) -> dict:
    results: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        if lab_seeds is not None:                 # the lab rig's drive runs alone
            results["lab"] = [_lab(Path(tmp), preset, seed) for preset in ("sweep", "random")
                              for seed in range(lab_seeds)]
            return results
        for preset, run_name in (("sweep", "sweep"), ("random", "random"), ("dwell", "dwell")):
            if only != preset and (only is not None or preset == "dwell"):
                continue
            folder = Path(tmp) / preset
            start = time.perf_counter()
            write_simulation(folder, preset, seed=0)
            sim_s = time.perf_counter() - start
            results[preset] = {"simulate_s": sim_s, **_drive_run(folder, run_name),
                               "windows_reference": _reference(
                                   folder, run_name,
                                   pd.read_csv(folder / "truth" / f"{run_name}.forces.csv"))}
            if preset == "sweep":
                results["stepped_sines"] = _campaign(folder)
            results[f"{preset}_seeds"] = [_worst_windows(Path(tmp), preset, seed)
                                          for seed in range(1, drive_seeds)]
        if only is not None:
            return results
        # the stepped sines again under other noise: the targets hold for the rig, not a draw
        results["stepped_sines_seeds"] = [results["stepped_sines"]] + [
            _campaign_seed(Path(tmp), seed) for seed in range(1, seeds)]
        results["lab"] = [_lab(Path(tmp), preset, seed) for preset in ("sweep", "random")
                          for seed in range(drive_seeds - 1)]
    return results


def report(res: dict) -> None:
    for preset, target in (("sweep", 0.005), ("random", 0.02), ("dwell", 0.005)):
        if preset not in res:
            continue
        r = res[preset]
        choice = r.get("ratio_model") or {"source": "spline (a model without the choice)"}
        print(f"{preset}: ratios from the {choice['source']}; AIC spline "
              f"{choice.get('aic_spline')}, modal {choice.get('aic_modal')}; modes "
              f"{choice.get('modes')}")
        print(f"{preset}: worst 0.5 s window {max(r['windows']):.2%} of the AC RMS (target "
              f"{target:.1%}); reactions only {max(r['windows_static']):.1%}; "
              f"reconstruct {r['reconstruct_s']:.2f} s")
        print("  windows  " + " ".join(f"{w:7.2%}" for w in r["windows"]))
        print("  claimed  " + " ".join(f"{w:7.2%}" for w in r["windows_claimed"])
              + "   (against the truth through the reactions' smoother)")
        print("  in band  " + " ".join(f"{w:7.2%}" for w in r["windows_in_band"]))
        print("  oracle   " + " ".join(f"{w:7.2%}" for w in r["windows_oracle"])
              + "   (as claimed, the best gains of the truth's own power)")
        print("  err/u    " + " ".join(f"{w:7.2f}" for w in r["windows_stated"])
              + "   (each window's error as claimed over its stated uncertainty, RMS)")
        print("  static   " + " ".join(f"{w:7.1%}" for w in r["windows_static"]))
        if "windows_reference" in r:
            print("  refer.   " + " ".join(f"{w:7.2%}" for w in r["windows_reference"])
                  + "   (the noisy reactions deconvolved with the exact transfer)")
            print("  ratio    " + " ".join(
                f"{a / b:7.2f}" for a, b in zip(r["windows"], r["windows_reference"],
                                                strict=True)))
        if preset == "sweep":                 # 10 -> 150 Hz in 4 s: the mode at 1.7 s
            mode = int((MODE_HZ - 10.0) / (140.0 / 4.0) / 0.1)
            near = slice(mode - 3, mode + 4)
            print(f"  0.1 s windows from {near.start / 10:.1f} s: "
                  + " ".join(f"{w:6.2%}" for w in r["windows_short"][near]) + "; err/u "
                  + " ".join(f"{w:.2f}" for w in r["windows_short_stated"][near]))
        print("  stream   " + " ".join(f"{w:7.2%}" for w in r["windows_stream"])
              + f"   (stream - batch: {r['stream_vs_batch_rms_in_stated_std']:.2f} of the "
              f"stated std RMS; stream {r['stream_s']:.2f} s)")
        for key, label in (("observed_to_stated", "batch"),
                           ("observed_to_stated_stream", "stream")):
            o = r[key]
            print(f"  {label}: observed / stated {o['ratio']:.2f}, {o['within_2u']:.1%} of the "
                  "samples within 2 u (against the truth as claimed)")
        for o in res[f"{preset}_seeds"]:
            print(f"  seed {o['seed']}: worst window {o['worst']:.2%} (as claimed "
                  f"{o['worst_claimed']:.2%}, stream {o['worst_stream']:.2%}), observed / "
                  f"stated {o['observed_to_stated']:.2f}")
    if "lab" in res:
        _report_lab(res["lab"])
    if "stepped_sines" not in res:
        return
    c = res["stepped_sines"]
    print(f"stepped sines: tau {c['tau'] * 1e3:.4f} +/- {c['tau_std'] * 1e3:.4f} ms (true "
          f"{c['tau_true'] * 1e3:g} ms)")
    print(f"  {'f [Hz]':>8} {'K(f) err':>9} {'u':>7} {'lag err':>9} {'u':>7}   (targets 0.2 %, "
          "0.2 deg)")
    for s in c["steps"]:
        print(f"  {s['frequency']:8.2f} {s['gain_error']:9.2%} {s['gain_std']:7.2%} "
              f"{s['lag_error_deg']:8.3f}° {s['lag_std_deg']:6.3f}°")
    if "stepped_sines_seeds" not in res:
        return
    print("stepped sines over seeds: the worst step of each (K(f), lag), tau, and the RMS of "
          "the steps' errors over their stated uncertainty")
    for seed, c in enumerate(res["stepped_sines_seeds"]):
        z = [s["gain_error"] / s["gain_std"] for s in c["steps"]]
        z += [s["lag_error_deg"] / s["lag_std_deg"] for s in c["steps"]]
        print(f"  seed {seed}: K(f) {max(abs(s['gain_error']) for s in c['steps']):.2%}, lag "
              f"{max(abs(s['lag_error_deg']) for s in c['steps']):.3f}°, tau "
              f"{c['tau'] * 1e3:.4f} +/- {c['tau_std'] * 1e3:.4f} ms, error / stated "
              f"{math.sqrt(np.mean(np.square(z))):.2f}")



def _report_lab(lab: list[dict]) -> None:
    print("the lab rig (coloured noise, hum, drawn sensitivities, preload; the tare given): "
          "windows against the truth, and error / stated inside the record")
    for o in lab:
        name = "sweep" if "stepped_sines" in o else "random"
        print(f"  {name} seed {o['seed']}: windows " + " ".join(f"{w:6.2%}" for w in o["windows"])
              + f"; reactions only up to {max(o['windows_static']):.0%}")
        print("    error / stated " + ", ".join(f"{k} {v:.2f}"
                                                for k, v in o["error_to_stated"].items()))
        print("    error / stated from the drawn sources alone " + ", ".join(
            f"{k} {v:.2f}" for k, v in o["error_to_stated_drawn"].items()))
        if "stepped_sines" in o:
            c = o["stepped_sines"]
            print(f"    stepped sines: K(f) {c['gain_error']:.2%}, lag {c['lag_error_deg']:.3f}°, "
                  f"tau {c['tau'] * 1e3:.4f} +/- {c['tau_std'] * 1e3:.4f} ms")
        s = o["inertia_scale"]
        print(f"    inertia's scale s {s['s']:.5f} +/- {s['s_std']:.2g} (the true inertia's "
              f"{s['s_true']:.5f}, "
              f"{'applied' if s['applied'] else 'not applied'}; the flux leaves "
              f"{s['misfit']:.1%})")
        print("    without it " + " ".join(f"{w:6.2%}" for w in s["windows_before"]))
        print("    with it    " + " ".join(f"{w:6.2%}" for w in s["windows_after"]))


def _keep_splines(frequencies: np.ndarray, coords: np.ndarray, cov: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, ratio_model.RatioChoice, tuple | None]:
    """:func:`forcecal.model.ratios.choose_ratios` before the modal model: the splines'."""
    _, _, choice, _ = _CHOOSE(frequencies, coords, cov)
    ratios, std, _, _, directions = ratio_model._spline_ratios(frequencies, coords, cov)
    return ratios, std, dataclasses.replace(choice, source="spline"), directions


_CHOOSE = ratio_model.choose_ratios


def _take_modal(frequencies: np.ndarray, coords: np.ndarray, cov: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, ratio_model.RatioChoice, tuple | None]:
    """The modal model's ratios wherever :func:`forcecal.model.modal.identify` finds one,
    whatever the criterion says."""
    ratios, std, choice, directions = _CHOOSE(frequencies, coords, cov)
    fit = ratio_model.identify(frequencies, coords, cov)
    if fit is None:
        return ratios, std, choice, directions
    return (*fit.ratios(frequencies), dataclasses.replace(choice, source="modal"), None)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--only", choices=("sweep", "random", "dwell"))
    parser.add_argument("--ratios", choices=("auto", "spline", "modal"), default="auto")
    parser.add_argument("--lab", type=int, metavar="SEEDS",
                        help="only the lab rig's drive runs, seeds 0..SEEDS-1")
    args = parser.parse_args()
    if args.ratios != "auto":                     # the build looks it up when it runs
        ratio_model.choose_ratios = {"spline": _keep_splines, "modal": _take_modal}[args.ratios]
    res = run(only=args.only, lab_seeds=args.lab)
    report(res)
    RESULTS.mkdir(exist_ok=True)
    name = ("any_drive.json" if args.only is None and args.ratios == "auto"
            else f"any_drive_{args.only or 'all'}_{args.ratios}.json")
    if args.lab is not None:
        name = "any_drive_lab.json"
    (RESULTS / name).write_text(json.dumps(res, indent=1))
    sys.exit(0)

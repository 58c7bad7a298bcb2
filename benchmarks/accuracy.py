"""Accuracy of the force reconstruction against the virtual rig's ground truth.

For the `paper`, `resonance` and one `campaign` run: the error of the total-force waveform and
of each force as % of the true AC RMS, beside the reactions-only error; per-harmonic errors;
and, over independent noise seeds (scan and run noise both redrawn, physics simulated once),
the ratio of the observed error to the stated standard uncertainty.

The `body` case is the 3-D block on six gauges (the mode-shape basis is not offered there).

Load changes since the scan (`two-coil`: a coil changed; `tilt`: pole gaps changed unequally):
each run's per-force error with a model from the first scan and from all the preset's scans.

Usage: python benchmarks/accuracy.py [--seeds 50] [--cases paper body ...] [--out NAME.json]
(prints a table, writes benchmarks/results/accuracy.json or NAME.json)
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from forcecal.forces.steady import reconstruct
from forcecal.model.spatial import build_spatial_model
from forcecal.signals.harmonics import fit_harmonics
from forcecal.simulate.presets import get_preset
from forcecal.simulate.virtual_rig import (
    build_model,
    measure_run,
    measure_scan,
    public_rig,
    run_truth,
    scan_response,
    simulate_response,
)

CASES = (("paper", "paper", 0.1), ("resonance", "resonance", 0.5),
         ("campaign", "g1000_dc06_ac02", None), ("plate", "plate", 0.2), ("body", "body", 1.0))


def rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


def damage_scan(scan, rng):
    """The scan with a laser dropout, a saturated record and a spike, each at its own record
    (the faults of a real SLDV scan that the screening must survive)."""
    import dataclasses

    resp = scan.response.copy()
    n = scan.n_points
    k = n // 3
    resp[k] = 1e-3 * resp[k] + 1e-3 * np.std(resp[k]) * rng.standard_normal(resp.shape[1])
    k = n // 2
    top = 0.6 * np.max(np.abs(resp[k]))
    resp[k] = np.clip(resp[k], -top, top)
    k = 2 * n // 3 + 1
    resp[k, 100:103] += 50 * np.max(np.abs(resp[k]))
    return dataclasses.replace(scan, response=resp)


def study(preset_name: str, run_name: str, seeds: int, basis: str = "polynomial",
          damaged: bool = False) -> dict:
    preset = get_preset(preset_name)
    model_fe = build_model(preset)
    spec = next(r for r in preset.runs if r.name == run_name)
    rig = public_rig(preset)
    t0 = time.perf_counter()
    scan_r = scan_response(preset, model_fe)
    run_r = simulate_response(preset, spec.drives, spec.gap, spec.duration, model_fe)
    t_sim = time.perf_counter() - t0
    truth = run_truth(preset, model_fe, run_r)
    true_total = truth.pole_force.sum(axis=0)
    ac_rms = rms(true_total - true_total.mean())
    f_true = spec.drives[0].frequency
    h = 6

    errors, stated, wave_err, wave_std, times, static_err = [], [], [], [], [], []
    force_err, set_aside = [], []
    first = None
    for seed in range(seeds):
        rng = np.random.default_rng(1000 + seed)
        t1 = time.perf_counter()
        scan = measure_scan(preset, model_fe, scan_r, rng)
        run = measure_run(preset, spec, model_fe, run_r, rng)
        if damaged:
            scan = damage_scan(scan, rng)
        if spec.gap is not None:
            import dataclasses
            rig_run = dataclasses.replace(rig, forces=tuple(
                dataclasses.replace(f, gap=spec.gap) for f in rig.forces))
        else:
            rig_run = rig
        model = build_spatial_model(rig_run, scan, basis=basis)
        est = reconstruct(rig_run, model, run)
        times.append(time.perf_counter() - t1)
        set_aside.append(len(model.set_aside))
        force_err.append([100 * rms((est.series[k] - tf) - (est.series[k] - tf).mean())
                          / rms(tf - tf.mean()) for k, tf in enumerate(truth.pole_force)])
        # the truth's phasors on the estimate's own basis (same fundamental, same window)
        true_total_ph = fit_harmonics(true_total, preset.fs, est.f0, h).phasors
        err_ph = est.total - true_total_ph
        errors.append(err_ph)
        stated.append(est.total_std)
        e = est.total_series - true_total
        wave_err.append(rms(e - e.mean()))
        wave_std.append(est.waveform_std)
        es = est.static_series.sum(axis=0) - true_total
        static_err.append(rms(es - es.mean()))
        if first is None:
            per_force = {}
            for k, name in enumerate(est.force_names):
                ef = est.series[k] - truth.pole_force[k]
                tf = truth.pole_force[k]
                sf = est.static_series[k] - tf
                per_force[name] = {
                    "error_pct": 100 * rms(ef - ef.mean()) / rms(tf - tf.mean()),
                    "static_error_pct": 100 * rms(sf - sf.mean()) / rms(tf - tf.mean()),
                }
            first = {
                "f0_est_hz": est.f0, "f0_true_hz": f_true,
                "harmonics_with_shape": [int(n) for n in model.harmonics],
                "orders": [int(f.order) for f in model.shapes],
                "one_shape": model.one_shape, "inertia_share": est.inertia_share,
                "total_error_pct": 100 * wave_err[-1] / ac_rms,
                "static_error_pct": 100 * static_err[-1] / ac_rms,
                "stated_pct": 100 * wave_std[-1] / ac_rms,
                "dc_error_n": float(e.mean()),
                "per_force": per_force,
                "per_harmonic": [
                    {"n": n, "true_amplitude_n": float(abs(true_total_ph[n])),
                     "error_n": float(abs(err_ph[n])), "std_n": float(est.total_std[n])}
                    for n in range(h + 1) if est.kept[n]],
                "notes": list(est.notes),
            }
    errors = np.array(errors)
    stated = np.array(stated)
    kept = stated.mean(axis=0) > 0
    ratios = {}
    for n in np.flatnonzero(kept):
        comp = np.concatenate([errors[:, n].real, errors[:, n].imag] if n else [errors[:, n].real])
        ratios[int(n)] = {
            "observed_rms_n": rms(comp), "observed_scatter_n": float(np.std(comp)),
            "stated_n": float(np.sqrt(np.mean(stated[:, n] ** 2))),
        }
        ratios[int(n)]["ratio_rms"] = ratios[int(n)]["observed_rms_n"] / ratios[int(n)]["stated_n"]
        ratios[int(n)]["ratio_scatter"] = (ratios[int(n)]["observed_scatter_n"]
                                           / ratios[int(n)]["stated_n"])
    wave_ratio = rms(wave_err) / rms(wave_std)
    return {
        "preset": preset_name, "run": run_name, "seeds": seeds, "basis": basis,
        "ac_rms_n": ac_rms,
        "first_seed": first,
        "over_seeds": {
            "total_error_pct_mean": 100 * float(np.mean(wave_err)) / ac_rms,
            "total_error_pct_max": 100 * float(np.max(wave_err)) / ac_rms,
            "static_error_pct_mean": 100 * float(np.mean(static_err)) / ac_rms,
            "waveform_ratio_observed_to_stated": wave_ratio,
            "per_harmonic": ratios,
            "per_force_error_pct_mean": dict(zip(rig.force_names,
                                                 np.mean(force_err, axis=0).tolist(),
                                                 strict=True)),
            "records_set_aside_mean": float(np.mean(set_aside)),
        },
        "seconds_simulation": t_sim,
        "seconds_per_estimate": float(np.median(times)),
    }


def load_study(preset_name: str, seeds: int) -> dict:
    """Runs whose load pattern differs from the scan's: each run's per-force error with a
    model from the first scan alone and with a model from all the preset's scans (a span of
    shapes per harmonic), over noise seeds (physics simulated once), and the observed / stated
    ratio of the fundamental's error with all scans."""
    preset = get_preset(preset_name)
    fe = build_model(preset)
    rig = public_rig(preset)
    scan_r = [scan_response(preset, fe, which=i) for i in range(len(preset.scans))]
    specs = [r for r in preset.runs if not r.tare]
    resp = {r.name: simulate_response(preset, r.drives, r.gap, r.duration, fe, gaps=r.gaps)
            for r in specs}
    truth = {r.name: run_truth(preset, fe, resp[r.name]) for r in specs}
    err: dict[tuple[str, str], list] = {}
    z: dict[str, list] = {}
    members: dict[str, dict[str, int]] = {}
    for seed in range(seeds):
        rng = np.random.default_rng(2000 + seed)
        scans = [measure_scan(preset, fe, r, rng, which=i) for i, r in enumerate(scan_r)]
        models = {"one": build_spatial_model(rig, scans[0]),
                  "all": build_spatial_model(rig, scans)}
        for spec in specs:
            run = measure_run(preset, spec, fe, resp[spec.name], rng)
            tf_all = truth[spec.name].pole_force
            total = tf_all.sum(axis=0)
            for label, model in models.items():
                est = reconstruct(rig, model, run)
                row = []
                for k, tf in enumerate(tf_all):
                    e = est.series[k] - tf
                    row.append((100 * rms(e - e.mean()) / rms(tf - tf.mean()),
                                100 * rms(e - e.mean()) / rms(total - total.mean())))
                err.setdefault((spec.name, label), []).append(row)
                if label == "all":
                    true_ph = fit_harmonics(tf_all, preset.fs, est.f0, 6).phasors
                    d = (est.force[:, 1] - true_ph[:, 1]) / est.force_std[:, 1]
                    z.setdefault(spec.name, []).extend([*d.real, *d.imag])
                    chosen = str(est.coordinates.members[0])
                    counts = members.setdefault(spec.name, {})
                    counts[chosen] = counts.get(chosen, 0) + 1
    runs = []
    for spec in specs:
        one = np.mean(err[(spec.name, "one")], axis=0)
        every = np.mean(err[(spec.name, "all")], axis=0)
        runs.append({"run": spec.name, "gaps": spec.gaps,
                     "members_n1": members[spec.name],
                     "one_scan_pct_own": one[:, 0].tolist(),
                     "one_scan_pct_total": one[:, 1].tolist(),
                     "all_scans_pct_own": every[:, 0].tolist(),
                     "all_scans_pct_total": every[:, 1].tolist(),
                     "n1_observed_to_stated": rms(z[spec.name])})
    return {"preset": preset_name, "seeds": seeds, "scans": len(preset.scans),
            "forces": list(rig.force_names), "runs": runs}


def stream_study(seconds: float) -> dict:
    """The streaming estimator on a long `paper` run: stationary, then with the drive drifting
    0.2 % in frequency and 0.2 % in level over a minute; each force's and the total's error
    over the record's second half, as % of the total's true AC RMS, for the default memory (2
    periods), the steady mode (100 periods) and the batch estimate of the whole record."""
    import dataclasses

    from forcecal.realtime.estimator import StreamEstimator
    from forcecal.realtime.replay import stream_forces

    preset = get_preset("paper")
    fe = build_model(preset)
    rig = public_rig(preset)
    rng = np.random.default_rng(3)
    model = build_spatial_model(rig, measure_scan(preset, fe, scan_response(preset, fe), rng))
    out = {"seconds": seconds}
    base = preset.runs[0]
    drift = 0.002 / 60.0
    for label, drives in (("stationary", base.drives),
                          ("drifting", tuple(dataclasses.replace(d, chirp=drift, drift=drift)
                                             for d in base.drives))):
        spec = dataclasses.replace(base, duration=seconds, drives=drives)
        r = simulate_response(preset, spec.drives, spec.gap, spec.duration, fe)
        run, truth = measure_run(preset, spec, fe, r, rng), run_truth(preset, fe, r)
        tot = truth.pole_force.sum(axis=0)
        ac = rms(tot - tot.mean())
        half = run.time > seconds / 2

        def err(x: np.ndarray, ac: float = ac, tot: np.ndarray = tot,
                half: np.ndarray = half) -> float:
            e = (x - tot)[half]
            return 100 * rms(e - e.mean()) / ac

        row = {}
        try:
            row["batch"] = err(reconstruct(rig, model, run).total_series)
        except Exception as exc:                        # a drifting record may be refused
            row["batch"] = f"refused: {exc}"[:120]
        for name, periods in (("stream, 2 periods", 2.0), ("stream steady, 100 periods", 100.0)):
            est = StreamEstimator(rig, model, model.f0, run.fs, t0=run.t0,
                                  forgetting=1 - model.f0 / (run.fs * periods))
            raw = np.stack([run.channel(n) for n in est.channel_names])
            _, force, _, std = next(stream_forces(est, [raw], 1024, run.t0))
            row[name] = err(force.sum(axis=0))
            row[name + " stated noise std"] = 100 * float(np.mean(std[-1, half])) / ac
        out[label] = row
    return out


def print_load_study(r: dict) -> None:
    names = r["forces"]
    print(f"\n{r['preset']}: one scan vs {r['scans']} scans ({r['seeds']} seeds; per-force "
          "error in % of its own true AC RMS, [% of the total's], mean)")
    hdr = (f"{'run':<22}" + "".join(f"{'1 scan ' + n:>18}{'all ' + n:>18}" for n in names)
           + f"{'obs/stated':>11}  n=1 shapes used (seeds)")
    print(hdr)
    print("-" * len(hdr))
    for run in r["runs"]:
        cells = "".join(
            f"{run['one_scan_pct_own'][k]:8.3f} [{run['one_scan_pct_total'][k]:6.3f}]"
            f"{run['all_scans_pct_own'][k]:9.3f} [{run['all_scans_pct_total'][k]:6.3f}]"
            for k in range(len(names)))
        used = ", ".join(f"{m}: {c}" for m, c in run["members_n1"].items())
        print(f"{run['run']:<22}{cells}{run['n1_observed_to_stated']:11.2f}  {used}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seeds", type=int, default=50)
    ap.add_argument("--basis-seeds", type=int, default=10,
                    help="noise seeds of the mode-shape basis comparison")
    ap.add_argument("--robust-seeds", type=int, default=10,
                    help="noise seeds of the clean vs damaged scan comparison")
    ap.add_argument("--load-seeds", type=int, default=5,
                    help="noise seeds of the load-change study (two-coil, tilt presets)")
    ap.add_argument("--stream-seconds", type=float, default=40.0,
                    help="length of the stream study's runs (0: skip it)")
    ap.add_argument("--cases", nargs="*", default=[c[0] for c in CASES])
    ap.add_argument("--out", default="accuracy.json", help="file name in benchmarks/results")
    args = ap.parse_args()
    results = []
    for preset, run, target in CASES:
        if preset not in args.cases:
            continue
        res = study(preset, run, args.seeds)
        res["target_pct"] = target
        results.append(res)
    comparison = []
    for preset, run, _ in CASES:
        if preset not in args.cases or preset == "body" or not args.basis_seeds:
            continue                                          # modes: beams and plates only
        for basis in ("polynomial", "modes"):
            r = study(preset, run, args.basis_seeds, basis=basis)
            comparison.append({"preset": preset, "basis": basis, "seeds": args.basis_seeds,
                               "total_error_pct_mean": r["over_seeds"]["total_error_pct_mean"],
                               "orders": r["first_seed"]["orders"],
                               "ratio": r["over_seeds"]["waveform_ratio_observed_to_stated"]})
    robust = []
    for preset, run, _ in CASES:
        if preset not in args.cases or not args.robust_seeds:
            continue
        clean = study(preset, run, args.robust_seeds)
        bad = study(preset, run, args.robust_seeds, damaged=True)
        robust.append({"preset": preset, "seeds": args.robust_seeds,
                       "clean": clean["over_seeds"], "damaged": bad["over_seeds"]})
    loads = [load_study(name, args.load_seeds) for name in ("two-coil", "tilt")
             if args.load_seeds]
    streams = stream_study(args.stream_seconds) if args.stream_seconds else None
    print(f"\nforce reconstruction vs truth ({args.seeds} noise seeds; errors in % of true AC RMS)")
    hdr = (f"{'case':<22}{'total %':>9}{'max %':>8}{'F1 %':>8}{'F2 %':>8}{'static %':>10}"
           f"{'target':>8}{'obs/stated':>11}{'inertia':>9}{'s/run':>7}")
    print(hdr)
    print("-" * len(hdr))
    for r in results:
        f, o = r["first_seed"], r["over_seeds"]
        tgt = f"{r['target_pct']:.1f}" if r["target_pct"] else "-"
        print(f"{r['preset'] + ':' + r['run']:<22}{o['total_error_pct_mean']:9.4f}"
              f"{o['total_error_pct_max']:8.4f}{f['per_force']['F1']['error_pct']:8.3f}"
              f"{f['per_force']['F2']['error_pct']:8.3f}{o['static_error_pct_mean']:10.3f}"
              f"{tgt:>8}{o['waveform_ratio_observed_to_stated']:11.2f}"
              f"{f['inertia_share']:9.1%}{r['seconds_per_estimate']:7.2f}")
    print("\nper harmonic of the total force: observed RMS error / stated uncertainty")
    for r in results:
        parts = [f"n={n}: {v['ratio_rms']:.2f} (scatter {v['ratio_scatter']:.2f})"
                 for n, v in r["over_seeds"]["per_harmonic"].items()]
        print(f"  {r['preset']:<10} " + ";  ".join(parts))
    print(f"\nshape basis: polynomials (black box) vs mode shapes ({args.basis_seeds} seeds)")
    print(f"{'case':<12}{'basis':<12}{'total %':>9}{'obs/stated':>12}  orders per harmonic")
    for c in comparison:
        print(f"{c['preset']:<12}{c['basis']:<12}{c['total_error_pct_mean']:9.4f}"
              f"{c['ratio']:12.2f}  {c['orders']}")
    print(f"\nrobust scan: clean vs a dropout, a saturated record and a spike "
          f"({args.robust_seeds} seeds; per-force error in % of its true AC RMS, mean)")
    print(f"{'case':<12}{'force':<8}{'clean %':>9}{'damaged %':>11}{'ratio':>8}"
          f"{'set aside':>11}  (target ratio <= 1.5)")
    for r in robust:
        c, d = r["clean"], r["damaged"]
        for name, e in c["per_force_error_pct_mean"].items():
            e2 = d["per_force_error_pct_mean"][name]
            print(f"{r['preset']:<12}{name:<8}{e:9.4f}{e2:11.4f}{e2 / e:8.2f}"
                  f"{d['records_set_aside_mean']:11.1f}")
    for r in loads:
        print_load_study(r)
    for r in loads:
        if r["preset"] != "tilt":
            continue
        matched = [x for x in r["runs"] if len(set(x["gaps"].values())) == 1]
        changed = [x for x in r["runs"] if len(set(x["gaps"].values())) > 1]
        base = np.mean([x["all_scans_pct_own"] for x in matched])
        for label, key in (("one scan", "one_scan_pct_own"), ("all scans", "all_scans_pct_own")):
            mean = np.mean([x[key] for x in changed])
            print(f"tilt, unequal gaps, {label}: mean per-force error {mean:.3f} % = "
                  f"{mean / base:.2f} x the equal-gap runs' {base:.3f} % (target <= 1.5 x)")
            r[f"unequal_to_matched_{label.replace(' ', '_')}"] = float(mean / base)
    if streams is not None:
        print(f"\nstream vs batch on a {streams['seconds']:g} s paper run (total-force error over "
              "the second half, % of the true AC RMS; the stream's stated std is its noise "
              "part only)")
        for label in ("stationary", "drifting"):
            row = streams[label]
            print(f"  {label:<11}" + "; ".join(
                f"{k} {v:.4f}" if isinstance(v, float) else f"{k} {v}" for k, v in row.items()))
        b = streams["stationary"]["batch"]
        if isinstance(b, float):
            ratio = streams["stationary"]["stream steady, 100 periods"] / b
            streams["steady_to_batch"] = ratio
            print(f"  steady mode / batch on the stationary run: {ratio:.2f} (target <= 1.5)")
    out = Path(__file__).resolve().parent / "results" / args.out
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps({"studies": results, "basis_comparison": comparison,
                              "robust_scan": robust, "load_change": loads,
                              "stream_steady": streams}, indent=1,
                              default=float))
    print(f"\nwritten {out}")


if __name__ == "__main__":
    main()

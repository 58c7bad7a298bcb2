"""Coverage of the stated uncertainty on the ``lab`` virtual rig, every imperfection on.

For the presets ``paper``, ``resonance``, one ``campaign`` run (g1000_dc06_ac02), ``plate`` and
``body``, each with lab realism (:class:`forcecal.simulate.realism.Realism` defaults): white,
1/f and mains-hum noise on every channel, ADC quantization, sensor sensitivity errors drawn from
the declared type-B uncertainties, gauge zero offsets, the gravity preload, a drive that walks
from scan point to scan point and drifts within each run, and a zero-current tare record.

What is drawn, per seed (``numpy.random.default_rng(BASE_SEED + seed)``, one generator per seed
and nothing else random), in the order the simulator's own ``write_simulation`` draws it:

1. the rig's errors (:func:`forcecal.simulate.lab.draw_errors`): every gauge's, probe's and
   current sensor's sensitivity (1 + e, e ~ N(0, declared type-B u)) and every gauge's zero
   offset; the scan, the run and the tare of one seed share them, as one real rig would;
2. the scan: the drive's level and frequency random walks, every acquisition's start within a
   drive period, then every record's noise (white, pink, hum) and quantization;
3. the run, then the tare: each its drive's linear level drift and chirp, then every channel's
   noise and quantization (:func:`forcecal.simulate.lab.read_channel`).

The physics is simulated once per preset (the finite-element response under the magnet): the
scan as a :class:`forcecal.simulate.lab.ScanTable` (steady states at drives spanning the walks,
interpolated quadratically to each point's drive, exactly as :func:`.lab.record_lab_scan` does,
with spans fixed per preset so that one table serves every seed), and each run as a table of
the same kind over its drift and chirp (nodes at 0, +-3 sigma of each and one cross node): the
clean channels and the pole forces at a seed's drift and chirp are the table's quadratic
interpolation. The structure is linear in its forces, so the interpolated gauges, probes and
pole forces are the exact response to the interpolated pole forces: the truth and the
measurement agree to round-off. The measurement applies the drawn errors and the noise as
:func:`.lab.measure_lab_run` does (the same formula, the same draw order: checked bit for bit
once per preset, see ``checks`` in the JSON), and the run and scan interpolations are checked
against a direct simulation at seed 0's drawn drives.

The estimate is what a user gets: the public rig file (its declared type-B uncertainties; a
campaign run's static gap) as a lab would declare it, its geometry and masses drawn about the
true ones from their declared uncertainties (:func:`forcecal.forces.budget.drawn_rig`, from a second
generator per seed, ``default_rng([BASE_SEED + seed, 1])``, so that the draws above stay those
of the simulator), then ``build_spatial_model(rig, scan)`` and ``reconstruct(rig, model, run,
tare=tare)``.

What is compared, per force and for the total, per harmonic: DC (n = 0) when the estimate
observes it, and every harmonic n = 1..H the estimate keeps. The truth's phasors are those of
the simulator's pole forces (``run_truth(...).pole_force``; the total is their sum) fitted on
the estimate's own fundamental and window (``fit_harmonics(pole_force, fs, est.f0, H)``). Each
component (the DC; Re and Im for n >= 1) is one sample: its error e against the stated
standard uncertainty u of that component (``ForceEstimate.combination_std_re_im`` of that
force or of "total": noise and type-B combined, Re and Im apart, since a sensitivity's or a
mass's error lies along the phasor). Reported: the ratio RMS(e) / RMS(u) (target 0.8-1.25),
the k = 2 coverage, the fraction of components with |e| <= 2 u (target 93-97 %), with the
Clopper-Pearson 95 % interval
of that fraction given the number of components, and the 95 % band of the ratio were the errors
normal with exactly the stated u (chi-square with as many degrees of freedom as components).
Both intervals treat the components as independent; Re and Im of one seed are not quite
(a sensitivity scales the whole phasor), so the bands are somewhat too narrow there.

Verdict: ``ok`` when both the ratio and the coverage are on target; otherwise ``under`` (stated
too small: ratio > 1.25 or coverage < 93 %) or ``over`` (stated too large), in capitals when the
deviation is significant (the ratio outside its chi-square band, or the coverage interval
excluding 95 %), with a ``?`` when it is within the sampling scatter of the seeds.

A harmonic the estimate keeps (its reactions show it) without a shape (neither the scan nor
the probes resolve its motion) carries its uncompensated inertia as a bound, not a standard
uncertainty (``forcecal.forces``: the inertia the nearest shape would give from the probes,
never below the whole mass moving at the probes' noise). Its rows are marked ``bounded`` and
judged as bounds: ``bound`` when at least 95 % of the errors lie within twice the stated value,
``BOUND EXCEEDED`` otherwise; their ratio is shown but is no target (the error is the true
inertia, which lies below what any sensor of the rig can see).

``--off NAME ...`` switches realism components off in the simulated rig only (the rig file keeps
declaring the same type-B uncertainties): pink, hum, adc, sensitivity, offset, gravity, walk,
drift, and geometry (the declared rig is the true one); for diagnosing a ratio off target.

Usage: python benchmarks/stated_vs_observed.py [--seeds 20]
       [--cases paper resonance campaign plate body] [--seeds-for body=10 ...]
       [--off pink hum ...] [--out stated_vs_observed.json]
(prints a table, writes benchmarks/results/stated_vs_observed.json or NAME.json)
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import stats

from forcecal.forces.budget import SOURCES, drawn_rig
from forcecal.forces.steady import reconstruct
from forcecal.model.spatial import build_spatial_model
from forcecal.records import Run, Scan
from forcecal.signals.harmonics import fit_harmonics
from forcecal.simulate.lab import (
    MAX_HARMONICS,
    LabErrors,
    ScanTable,
    _per_point,
    _scan_noise,
    _synthesize,
    draw_errors,
    draw_run_drift,
    measure_lab_run,
    read_channel,
    record_lab_scan,
    scan_table,
)
from forcecal.simulate.presets import Preset, RunSpec, get_preset
from forcecal.simulate.realism import Adc, AdcSpec, Realism
from forcecal.simulate.virtual_rig import (
    Model,
    _gauge_forces,
    _points,
    _rows,
    _scan_spec,
    build_model,
    public_rig,
    scan_points,
    simulate_response,
)

CASES = (("paper", "paper"), ("resonance", "resonance"), ("campaign", "g1000_dc06_ac02"),
         ("plate", "plate"), ("body", "body"))
BASE_SEED = 7000
RATIO_TARGET = (0.8, 1.25)
COVERAGE_TARGET = (0.93, 0.97)
K = 2.0
WALK_SPAN = 4.0      # scan table spans: this many sigma of the walk's end (sqrt(n_acq) steps)
DRIFT_SPAN = 3.0     # run table spans: this many sigma of the run's drift and chirp
NOISE_SOURCES = ("gauge noise", "probe noise", "scan shapes", "unresolved harmonics")


def _off_realism(lab: Realism, off: list[str]) -> Realism:
    """``lab`` with the named components switched off (the simulated rig's only)."""
    changes: dict = {}
    for name in off:
        if name == "pink":
            changes["flicker_corner"] = 0.0
        elif name == "hum":
            changes["hum"] = ()
        elif name == "adc":
            fine = {k: Adc(40, a.full_scale) for k, a in vars(lab.adc).items()}
            changes["adc"] = AdcSpec(**fine)
        elif name == "sensitivity":
            changes["type_b"] = dataclasses.replace(lab.type_b, gauge_scale=0.0,
                                                    probe_scale=0.0, current_scale=0.0)
        elif name == "offset":
            changes["gauge_offset"] = 0.0
        elif name == "gravity":
            changes["gravity"] = 0.0
        elif name == "walk":
            changes.update(scan_level_step=0.0, scan_frequency_step=0.0)
        elif name == "drift":
            changes.update(run_level_drift=0.0, run_frequency_drift=0.0)
        elif name == "geometry":
            pass                     # the declared rig is the true one (see study)
        else:
            raise SystemExit(f"--off: unknown component '{name}'")
    return dataclasses.replace(lab, **changes)


# ------------------------------------------------------------------------------ the run table


def clean_channels(preset: Preset, model: Model, r) -> dict[str, np.ndarray]:
    """The run's channels before the sensors' errors and noise, in the DAQ's order (gauges,
    probes, every magnet's current, flux, voltage), and the pole forces (key ``"pole_force"``)."""
    out: dict[str, np.ndarray] = {}
    gauges = _gauge_forces(model, preset, r.u, r.v)
    for k, (name, *_) in enumerate(_rows(preset.beam.gauges)):
        out[str(name)] = gauges[k]
    probes = model.row(_points(preset, preset.sensors)) @ r.u
    for k, (name, *_) in enumerate(_rows(preset.sensors)):
        out[str(name)] = probes[k]
    for k, mag in enumerate(preset.magnets):
        out[mag.current_channel] = r.current[k]
        out[mag.flux_channel] = r.flux[k]
        out[mag.voltage_channel] = r.voltage[k]
    out["pole_force"] = r.pole_force
    return out


def channel_kinds(preset: Preset) -> dict[str, str]:
    kinds = {str(g[0]): "gauge" for g in _rows(preset.beam.gauges)}
    kinds.update({str(s[0]): "probe" for s in _rows(preset.sensors)})
    for mag in preset.magnets:
        kinds.update({mag.current_channel: "current", mag.flux_channel: "flux",
                      mag.voltage_channel: "voltage"})
    return kinds


@dataclass(frozen=True)
class RunTable:
    """A run's clean channels at drives drifting by ``i level_span`` [1/s] in level and
    ``j chirp_span`` [1/s] in frequency, nodes (i, j) as :class:`.lab.ScanTable`'s."""

    level_span: float
    chirp_span: float
    nodes: dict[tuple[int, int], dict[str, np.ndarray]]

    def at(self, d: float, c: float) -> dict[str, np.ndarray]:
        """Quadratic in d and in c with the d c cross term (the formula of ScanTable.at)."""
        tab, ha, hb = self.nodes, self.level_span, self.chirp_span
        out = {}
        for key, p0 in tab[(0, 0)].items():
            p = p0.copy()
            if ha:
                up, down = tab[(1, 0)][key], tab[(-1, 0)][key]
                p += d * (up - down) / (2 * ha) + d**2 * (up - 2 * p0 + down) / (2 * ha**2)
            if hb:
                up, down = tab[(0, 1)][key], tab[(0, -1)][key]
                p += c * (up - down) / (2 * hb) + c**2 * (up - 2 * p0 + down) / (2 * hb**2)
            if ha and hb:
                cross = tab[(1, 1)][key] - tab[(1, 0)][key] - tab[(0, 1)][key] + p0
                p += d * c * cross / (ha * hb)
            out[key] = p
        return out


def drifting(spec: RunSpec, drift: float, chirp: float) -> tuple:
    return tuple(dataclasses.replace(d, drift=drift, chirp=chirp) for d in spec.drives)


def run_table(preset: Preset, model: Model, spec: RunSpec) -> RunTable:
    """Simulate the run at the nodes spanning its drifts (one simulation when they are off)."""
    lab = preset.realism
    assert lab is not None
    still = not any(d.dc or d.ac or d.harmonics for d in spec.drives)     # a tare: no drive
    ha = 0.0 if still else DRIFT_SPAN * lab.run_level_drift
    hb = 0.0 if still else DRIFT_SPAN * lab.run_frequency_drift
    nodes = [(0, 0)]
    if ha:
        nodes += [(1, 0), (-1, 0)]
    if hb:
        nodes += [(0, 1), (0, -1)]
    if ha and hb:
        nodes.append((1, 1))
    tab = {}
    for i, j in nodes:
        r = simulate_response(preset, drifting(spec, i * ha, j * hb), spec.gap, spec.duration,
                              model, spec.gaps)
        tab[(i, j)] = clean_channels(preset, model, r)
    return RunTable(ha, hb, tab)


def measure(preset: Preset, spec: RunSpec, clean: dict[str, np.ndarray],
            rng: np.random.Generator, errors: LabErrors) -> Run:
    """What the lab DAQ records of clean channels: :func:`.lab.measure_lab_run`'s formula
    (gain, preload and offset on the gauges, gain on probes and coil currents, then
    :func:`.lab.read_channel`), channel by channel in its order."""
    lab, noise, fs = preset.realism, preset.noise, preset.fs
    assert lab is not None
    channels = {}
    for name, kind in channel_kinds(preset).items():
        x = clean[name]
        if kind == "gauge":
            x = errors.gain(name) * (x + errors.preload[name]) + errors.offset[name]
        elif kind in ("probe", "current"):
            x = errors.gain(name) * x
        channels[name] = read_channel(x, kind, getattr(noise, kind), lab, fs, rng)
    return Run(channels=channels, fs=fs, t0=0.0, name=spec.name, source=f"{spec.name}.csv",
               labels=dict(spec.labels))


def lab_run(preset: Preset, spec: RunSpec, table: RunTable, rng: np.random.Generator,
            errors: LabErrors) -> tuple[Run, np.ndarray, tuple[float, float]]:
    """:func:`.lab.record_lab_run` from a table: the drift and chirp drawn, the record, the
    true pole forces."""
    assert preset.realism is not None
    drift, chirp = draw_run_drift(preset.realism, rng)
    clean = table.at(drift, chirp)
    return measure(preset, spec, clean, rng, errors), clean["pole_force"], (drift, chirp)


# ------------------------------------------------------------------------------ the scan


def fixed_scan_table(preset: Preset, model: Model, which: int = 0) -> ScanTable:
    """One scan table for every seed: spans of WALK_SPAN sigma of the walks' end."""
    lab = preset.realism
    assert lab is not None
    n_acq = len(scan_points(preset, which)) // _per_point(preset)
    root = math.sqrt(n_acq)
    f = _scan_spec(preset, which).drives[0].frequency
    # every node must keep as many harmonics (0.45 fs / f of them, .lab._n_harmonics): a wider
    # frequency span is capped short of where that count changes (the quadratic extrapolates
    # smoothly beyond its nodes)
    top = 0.45 * preset.fs / f
    h0 = int(top)
    room = min(top / h0 - 1, 1 - top / (h0 + 1)) if h0 < MAX_HARMONICS else 1 - top / (h0 + 1)
    return scan_table(preset, model, which, WALK_SPAN * lab.scan_level_step * root,
                      min(WALK_SPAN * lab.scan_frequency_step * root, 0.9 * room))


def lab_scan(preset: Preset, table: ScanTable, rng: np.random.Generator, errors: LabErrors,
             which: int = 0) -> Scan:
    """:func:`.lab.record_lab_scan` on a given table: the same draws in the same order (the
    walks, the starts, then the noise), the same synthesis."""
    lab = preset.realism
    assert lab is not None
    spec = _scan_spec(preset, which)
    fs, f = preset.fs, spec.drives[0].frequency
    n_rec = int(round(spec.record * fs))
    per_period = int(np.ceil(fs / f))
    per_point = _per_point(preset)
    n_acq = len(scan_points(preset, which)) // per_point
    a = np.cumsum(lab.scan_level_step * rng.standard_normal(n_acq))
    b = np.cumsum(lab.scan_frequency_step * rng.standard_normal(n_acq))
    starts = rng.integers(0, per_period, size=n_acq)
    response = np.empty((n_acq * per_point, n_rec))
    reference = np.empty((n_acq, n_rec))
    for k in range(n_acq):
        vel, cur = table.at(float(a[k]), float(b[k]))
        t = (starts[k] + np.arange(n_rec)) / fs
        fk = f * (1 + b[k])
        rows = slice(k * per_point, (k + 1) * per_point)
        response[rows] = _synthesize(vel[rows], fk, t)
        reference[k] = _synthesize(cur[spec.reference:spec.reference + 1], fk, t)[0]
    return _scan_noise(preset, which, response, reference, rng, errors)


# ------------------------------------------------------------------------------ checks


def self_checks(preset: Preset, model: Model, spec: RunSpec, table: RunTable,
                stable: ScanTable) -> dict:
    """Once per preset: (a) :func:`measure` is :func:`.lab.measure_lab_run` bit for bit; (b)
    the run table at seed 0's drawn drift and chirp against a direct simulation; (c) the scan
    from the fixed table against :func:`.lab.record_lab_scan` with the same draws."""
    out = {}
    errors = draw_errors(preset, model, np.random.default_rng(1))
    r0 = simulate_response(preset, spec.drives, spec.gap, spec.duration, model, spec.gaps)
    mine = measure(preset, spec, clean_channels(preset, model, r0), np.random.default_rng(2),
                   errors)
    theirs = measure_lab_run(preset, spec, model, r0, np.random.default_rng(2), errors)
    out["measure_bit_identical"] = bool(
        list(mine.channels) == list(theirs.channels)
        and all(np.array_equal(mine.channels[c], theirs.channels[c]) for c in mine.channels))
    assert preset.realism is not None
    rng = np.random.default_rng(BASE_SEED)
    draw_errors(preset, model, rng)
    d, c = draw_run_drift(preset.realism, rng)      # not seed 0's exact draw order: a sample
    exact = clean_channels(preset, model, simulate_response(
        preset, drifting(spec, d, c), spec.gap, spec.duration, model, spec.gaps))
    interp = table.at(d, c)
    kinds = channel_kinds(preset)
    dev = {name: float(np.max(np.abs(interp[name] - exact[name]))
                       / getattr(preset.noise, kinds[name])) for name in kinds}
    out["run_table"] = {"drift_per_s": d, "chirp_per_s": c,
                        "max_abs_dev_in_white_sigma": dev,
                        "pole_force_max_abs_dev_N": float(np.max(np.abs(
                            interp["pole_force"] - exact["pole_force"])))}
    zero = LabErrors(sensitivity={}, offset={str(g[0]): 0.0 for g in _rows(preset.beam.gauges)},
                     preload={str(g[0]): 0.0 for g in _rows(preset.beam.gauges)})
    mine_s = lab_scan(preset, stable, np.random.default_rng(3), zero)
    theirs_s, _ = record_lab_scan(preset, np.random.default_rng(3), model, errors=zero)
    step = preset.realism.adc.ldv.step
    out["scan_table"] = {
        "response_max_abs_dev_in_adc_steps": float(np.max(np.abs(
            mine_s.response - theirs_s.response)) / step),
        "response_rms_dev_in_adc_steps": float(np.sqrt(np.mean(
            (mine_s.response - theirs_s.response) ** 2)) / step),
        "reference_max_abs_dev_in_adc_steps": float(np.max(np.abs(
            mine_s.reference - theirs_s.reference)) / preset.realism.adc.current.step)}
    return out


# ------------------------------------------------------------------------------ the study


def study(name: str, run_name: str, seeds: int, off: list[str]) -> dict:
    t_start = time.perf_counter()
    declared = get_preset(name, "lab")                     # the rig file declares its type B
    assert declared.realism is not None
    preset = dataclasses.replace(declared, realism=_off_realism(declared.realism, off))
    model = build_model(preset)
    spec = next(r for r in preset.runs if r.name == run_name)
    tare_spec = next(r for r in preset.runs if r.tare)
    rig = public_rig(declared)
    if spec.gap is not None:                                 # the manifest's gap of the run
        rig = dataclasses.replace(rig, forces=tuple(
            dataclasses.replace(f, gap=spec.gap) for f in rig.forces))
    stable = fixed_scan_table(preset, model)
    rtable = run_table(preset, model, spec)
    ttable = run_table(preset, model, tare_spec)
    t_sim = time.perf_counter() - t_start
    checks = self_checks(preset, model, spec, rtable, stable)
    pole_names = tuple(p.name for m in preset.magnets for p in m.poles)
    rows = [*rig.force_names, "total"]
    per_seed = []
    times = []
    for seed in range(seeds):
        t1 = time.perf_counter()
        rng = np.random.default_rng(BASE_SEED + seed)
        errors = draw_errors(preset, model, rng)
        scan = lab_scan(preset, stable, rng, errors)
        run, pole_force, (drift, chirp) = lab_run(preset, spec, rtable, rng, errors)
        tare, _, _ = lab_run(preset, tare_spec, ttable, rng, errors)
        mine = rig if "geometry" in off else drawn_rig(
            rig, np.random.default_rng([BASE_SEED + seed, 1]))
        spatial = build_spatial_model(mine, scan)
        est = reconstruct(mine, spatial, run, tare=tare)
        h = len(est.harmonics) - 1
        truth_f = fit_harmonics(pole_force, preset.fs, est.f0, h).phasors
        truth = {n: truth_f[pole_names.index(n)] for n in rig.force_names}
        truth["total"] = truth_f.sum(axis=0)
        assert est.combination_std is not None and est.combination is not None
        record = {"seed": BASE_SEED + seed, "f0": est.f0, "H": h,
                  "kept": est.kept.astype(bool).tolist(), "dc_observed": bool(est.dc_observed),
                  "with_inertia": est.with_inertia.astype(bool).tolist(),
                  "drift_per_s": drift, "chirp_per_s": chirp,
                  "errors": errors.as_dict(), "rows": {}}
        for row in rows:
            i = list(est.combination_names).index(row)
            e = est.combination[i] - truth[row]
            record["rows"][row] = {
                "true": [[float(z.real), float(z.imag)] for z in truth[row]],
                "error": [[float(z.real), float(z.imag)] for z in e],
                "std": est.combination_std[i].tolist(),
                "std_re_im": (None if est.combination_std_re_im is None
                              else est.combination_std_re_im[i].tolist()),
                "budget": {src: b[i].tolist() for src, b in est.budget.items()}}
        record["notes"] = list(est.notes)
        per_seed.append(record)
        times.append(time.perf_counter() - t1)
        print(f"  {name} seed {seed + 1}/{seeds}: {times[-1]:.1f} s", flush=True)
    return {"preset": name, "run": run_name, "seeds": seeds, "off": off,
            "rows": summarize(per_seed, rows), "checks": checks,
            "seconds_simulation": t_sim, "seconds_per_seed": float(np.median(times)),
            "seconds_total": time.perf_counter() - t_start, "per_seed": per_seed}


def ratio_band(n: int) -> tuple[float, float]:
    """95 % band of RMS(e)/u for n independent normal components of std u."""
    return (math.sqrt(stats.chi2.ppf(0.025, n) / n), math.sqrt(stats.chi2.ppf(0.975, n) / n))


def clopper_pearson(k: int, n: int) -> tuple[float, float]:
    lo = 0.0 if k == 0 else float(stats.beta.ppf(0.025, k, n - k + 1))
    hi = 1.0 if k == n else float(stats.beta.ppf(0.975, k + 1, n - k))
    return lo, hi


def verdict(ratio: float, cov: float, band: tuple[float, float],
            ci: tuple[float, float]) -> str:
    r_ok = RATIO_TARGET[0] <= ratio <= RATIO_TARGET[1]
    c_ok = COVERAGE_TARGET[0] <= cov <= COVERAGE_TARGET[1]
    if r_ok and c_ok:
        return "ok"
    under = ratio > RATIO_TARGET[1] or cov < COVERAGE_TARGET[0]
    over = ratio < RATIO_TARGET[0] or cov > COVERAGE_TARGET[1]
    if under and over:
        return "tails?"
    significant = not (band[0] <= ratio <= band[1]) or not (ci[0] <= 0.95 <= ci[1])
    word = "under" if under else "over"
    return word.upper() if significant else word + "?"


def summarize(per_seed: list[dict], rows: list[str]) -> list[dict]:
    out = []
    h = max(r["H"] for r in per_seed)
    for row in rows:
        for n in range(h + 1):
            e, u, parts = [], [], {}
            bounded = False
            for rec in per_seed:
                if n > rec["H"] or not rec["kept"][n] or (n == 0 and not rec["dc_observed"]):
                    continue
                bounded |= n > 0 and not rec["with_inertia"][n]
                err = rec["rows"][row]["error"][n]
                std = rec["rows"][row]["std"][n]
                comps = [err[0]] if n == 0 else err
                e += comps
                re_im = rec["rows"][row].get("std_re_im")
                u += [std] if n == 0 else (list(re_im[n]) if re_im else [std, std])
                for src, b in rec["rows"][row]["budget"].items():
                    parts.setdefault(src, []).extend([b[n] ** 2] * len(comps))
            if not e:
                continue
            e_a, u_a = np.array(e), np.array(u)
            ratio = float(np.sqrt(np.mean(e_a**2)) / np.sqrt(np.mean(u_a**2)))
            inside = int(np.sum(np.abs(e_a) <= K * u_a))
            cov = inside / len(e_a)
            band, ci = ratio_band(len(e_a)), clopper_pearson(inside, len(e_a))
            true_amp = float(np.mean([math.hypot(*rec["rows"][row]["true"][n])
                                      for rec in per_seed]))
            out.append({
                "force": row, "n": n, "components": len(e_a), "ratio": ratio,
                "ratio_band_95": band, "coverage_k2": cov, "coverage_ci_95": ci,
                "bounded": bounded,
                "verdict": (("bound" if cov >= 0.95 else "BOUND EXCEEDED") if bounded
                            else verdict(ratio, cov, band, ci)),
                "rms_error_N": float(np.sqrt(np.mean(e_a**2))),
                "mean_error_N": float(np.mean(e_a)),
                "rms_stated_N": float(np.sqrt(np.mean(u_a**2))),
                "max_abs_z": float(np.max(np.abs(e_a) / u_a)),
                "true_amplitude_N": true_amp,
                "budget_rms_N": {src: float(np.sqrt(np.mean(v))) for src, v in parts.items()},
            })
    return out


def print_table(results: list[dict], args: argparse.Namespace, seconds: float) -> None:
    print("\nstated uncertainty vs observed error, lab rig with every imperfection on "
          "(" + ", ".join(f"{r['preset']} {r['seeds']}" for r in results) + " seeds"
          + (f"; switched off: {', '.join(args.off)}" if args.off else "") + ")")
    print(f"targets: obs/stated {RATIO_TARGET[0]}-{RATIO_TARGET[1]}, k=2 coverage "
          f"{100 * COVERAGE_TARGET[0]:.0f}-{100 * COVERAGE_TARGET[1]:.0f} %; [ ] 95 % bands: "
          "the ratio's were u exact (chi-square), the coverage's binomial (Clopper-Pearson)")
    hdr = (f"{'preset':<10}{'force':<7}{'n':>3}{'comp':>6}{'obs/stated':>11}{'[95 % band]':>15}"
           f"{'k=2 cov':>9}{'[95 % interval]':>17}{'largest source':>24}  verdict")
    print(hdr)
    print("-" * len(hdr))
    for r in results:
        for x in r["rows"]:
            top = max(x["budget_rms_N"].items(), key=lambda kv: kv[1])
            share = top[1] ** 2 / x["rms_stated_N"] ** 2
            b, c = x["ratio_band_95"], x["coverage_ci_95"]
            band = f"[{b[0]:.2f}, {b[1]:.2f}]"
            ci = f"[{100 * c[0]:.0f}, {100 * c[1]:.0f}] %"
            src = f"{top[0]} {100 * share:.0f}%"
            print(f"{r['preset']:<10}{x['force']:<7}{x['n']:>3}{x['components']:>6}"
                  f"{x['ratio']:11.2f}{band:>15}{100 * x['coverage_k2']:8.1f}%{ci:>17}"
                  f"{src:>24}  {x['verdict']}")
    print("(largest source: the budget's largest part and its share of the stated variance)")
    for r in results:
        ck = r["checks"]
        dev = max(ck["run_table"]["max_abs_dev_in_white_sigma"].values())
        print(f"{r['preset']}: {r['seeds']} seeds, {r['seconds_per_seed']:.1f} s per seed, "
              f"physics {r['seconds_simulation']:.1f} s once; checks: measurement = "
              f"measure_lab_run bit for bit: {ck['measure_bit_identical']}; run table vs direct "
              f"simulation: max {dev:.1e} white sigma; scan table vs record_lab_scan: max "
              f"{ck['scan_table']['response_max_abs_dev_in_adc_steps']:.1f} ADC steps")
    print(f"run time {seconds / 60:.1f} min")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--cases", nargs="*", default=[c[0] for c in CASES])
    ap.add_argument("--seeds-for", nargs="*", default=[], metavar="PRESET=N",
                    help="fewer (or more) seeds for a slow preset")
    ap.add_argument("--off", nargs="*", default=[],
                    help="realism components switched off in the simulated rig (diagnosis)")
    ap.add_argument("--out", default="stated_vs_observed.json",
                    help="file name in benchmarks/results")
    args = ap.parse_args()
    override = {k: int(v) for k, v in (s.split("=") for s in args.seeds_for)}
    t0 = time.perf_counter()
    declared = get_preset("paper", "lab").realism
    assert declared is not None
    out = Path(__file__).resolve().parent / "results" / args.out
    out.parent.mkdir(exist_ok=True)
    results: list[dict] = []

    def write(complete: bool) -> None:
        out.write_text(json.dumps({
            "description": "observed error / stated standard uncertainty and k=2 coverage per "
                           "preset, force (and total) and harmonic, lab realism, type-B errors "
                           "and noise redrawn per seed (see benchmarks/stated_vs_observed.py)",
            "complete": complete, "seeds": args.seeds, "seeds_for": override,
            "base_seed": BASE_SEED, "off": args.off, "realism": declared.describe(),
            "targets": {"ratio": RATIO_TARGET, "coverage_k2": COVERAGE_TARGET},
            "budget_sources": [*NOISE_SOURCES, *SOURCES],
            "seconds": time.perf_counter() - t0, "studies": results}, indent=1, default=float))

    for name, run_name in CASES:
        if name in args.cases:
            results.append(study(name, run_name, override.get(name, args.seeds), args.off))
            write(False)                                 # what is done survives a later failure
    write(True)
    print_table(results, args, time.perf_counter() - t0)
    if override:
        print("seeds reduced for slow presets: "
              + ", ".join(f"{k} {v} (instead of {args.seeds})" for k, v in override.items()))
    print(f"written {out}")


if __name__ == "__main__":
    main()

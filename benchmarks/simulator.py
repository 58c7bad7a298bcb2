"""Speed and accuracy of the virtual rig (issue "Foundation").

Run from the project root::

    .venv/bin/python benchmarks/simulator.py

Prints a table and writes ``benchmarks/results/simulator.json``. Measured:

- wall and CPU (``time.process_time``, every thread of this process) time to simulate 1 s at
  10 kHz on the paper preset (60 elements, its drive), median of 3, model assembly included;
  when the median wall time exceeds the 2 s target, a cProfile of one simulation is printed;
- wall and CPU time of ``write_simulation`` for every preset;
- the change of the harmonics 1..4 (pole forces, gauge reactions, probes) when the time step is
  halved, relative to each signal's fundamental;
- the residual of the rigid-body balance J = R + Psi f in the noise-free truth, relative to the
  reaction RMS, and the inertia term's share of the reaction AC RMS;
- the first three pinned-pinned eigenfrequencies against Euler-Bernoulli.

Other processes may share the CPU: the wall times then grow while the CPU times do not.
"""

from __future__ import annotations

import cProfile
import dataclasses
import io
import json
import os
import pstats
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from forcecal.signals.harmonics import fit_harmonics
from forcecal.simulate.beam import hermite_row, natural_frequencies, pinned_pinned_frequencies
from forcecal.simulate.export import write_simulation
from forcecal.simulate.integrate import integrate
from forcecal.simulate.presets import PRESETS, NoiseSpec, get_preset
from forcecal.simulate.virtual_rig import build_model, record_run

RESULTS = Path(__file__).resolve().parent / "results" / "simulator.json"
TARGET_S = 2.0          # wall time target for 1 s of simulation at 10 kHz
REPEATS = 3


def timed(fn):
    """(result, wall [s], cpu [s]) of one call."""
    wall, cpu = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - wall, time.process_time() - cpu


def simulate_one_second(preset):
    model = build_model(preset)
    return integrate(model, preset.magnets, preset.runs[0].drives, 10_000.0, 1.0)


def speed(preset) -> dict:
    walls, cpus = [], []
    for _ in range(REPEATS):
        _, wall, cpu = timed(lambda: simulate_one_second(preset))
        walls.append(wall)
        cpus.append(cpu)
    out = {"wall_s": walls, "cpu_s": cpus, "median_wall_s": statistics.median(walls),
           "median_cpu_s": statistics.median(cpus), "target_wall_s": TARGET_S,
           "n_elements": preset.beam.n_elements, "fs_Hz": 10_000.0, "duration_s": 1.0}
    if out["median_wall_s"] > TARGET_S:
        profile = cProfile.Profile()
        profile.runcall(simulate_one_second, preset)
        text = io.StringIO()
        pstats.Stats(profile, stream=text).sort_stats("tottime").print_stats(15)
        out["profile"] = text.getvalue()
    return out


def harmonics(x, t, f0, n_harm=4):
    """Complex amplitudes (n_signals, n_harm) of harmonics 1..n_harm by least squares."""
    fit = fit_harmonics(np.atleast_2d(x), 1.0 / (t[1] - t[0]), f0, n_harm, t0=t[0])
    return fit.phasors[:, 1:]


def gauge_reactions(model, preset, u, v):
    rows = hermite_row(model.nodes, np.array([x for _, x in preset.beam.gauges]))
    return -preset.beam.gauge_stiffness * (rows @ u + model.beta * (rows @ v))


def halving(preset, duration=0.5) -> dict:
    model = build_model(preset)
    drives = preset.runs[0].drives
    probes = hermite_row(model.nodes, np.array([x for _, x in preset.sensors]))
    amps = []
    for oversample in (1, 2):
        r = integrate(model, preset.magnets, drives, preset.fs, duration, oversample=oversample)
        signals = {"pole_force": r.pole_force,
                   "gauges": gauge_reactions(model, preset, r.u, r.v),
                   "probes": probes @ r.u}
        amps.append({k: harmonics(s, r.t, drives[0].frequency) for k, s in signals.items()})
    change = {k: float(np.max(np.abs(amps[0][k] - amps[1][k]) / np.abs(amps[0][k][:, :1])))
              for k in amps[0]}
    return {"duration_s": duration, "max_change_rel_fundamental": change,
            "worst": max(change.values())}


def balance(preset) -> dict:
    quiet = dataclasses.replace(preset, noise=NoiseSpec(0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
    model = build_model(preset)
    run, truth = record_run(quiet, preset.runs[0], np.random.default_rng(0), model)
    reactions = np.stack([run.channels[name] for name, _ in preset.beam.gauges])
    (_, xa), (_, xb) = preset.beam.gauges
    x = np.array([p.x for m in preset.magnets for p in m.poles])
    psi = np.stack([(xb - x) / (xb - xa), (x - xa) / (xb - xa)])
    residual = truth.inertia - reactions - psi @ truth.pole_force
    rms = np.sqrt(np.mean(reactions**2, axis=1))
    share = np.sqrt(np.mean(truth.inertia**2, axis=1)) / np.std(reactions, axis=1)
    return {"residual_rel_reaction_rms": float(np.max(np.abs(residual) / rms[:, None])),
            "inertia_share_of_reaction_ac_rms": share.tolist()}


def frequencies(preset) -> dict:
    b = preset.beam
    n = np.arange(1, 4)
    exact = (n * np.pi / b.length) ** 2 * np.sqrt(b.ei / b.mass_per_length) / (2 * np.pi)
    fe = pinned_pinned_frequencies(b.length, b.ei, b.mass_per_length, b.n_elements)
    return {"pinned_pinned_fe_Hz": fe.tolist(), "euler_bernoulli_Hz": exact.tolist(),
            "rel_error": (fe / exact - 1).tolist(),
            "rig_on_gauges_Hz": natural_frequencies(build_model(preset), 4).tolist()}


def main() -> int:
    paper = get_preset("paper")
    results: dict = {"machine": {"cpus": os.cpu_count(), "load_average_1min": os.getloadavg()[0],
                                 "python": sys.version.split()[0]}}
    results["simulate_1s"] = speed(paper)
    results["write_simulation"] = {}
    for name in PRESETS:
        with tempfile.TemporaryDirectory() as tmp:
            _, wall, cpu = timed(lambda name=name, tmp=tmp: write_simulation(tmp, name, seed=0))
        results["write_simulation"][name] = {"wall_s": wall, "cpu_s": cpu}
    results["time_step_halving"] = halving(paper)
    results["balance"] = balance(paper)
    results["frequencies"] = frequencies(paper)
    results["machine"]["load_average_1min_end"] = os.getloadavg()[0]

    s = results["simulate_1s"]
    print(f"virtual rig benchmark ({results['machine']['cpus']} CPUs, "
          f"load {results['machine']['load_average_1min']:.1f} -> "
          f"{results['machine']['load_average_1min_end']:.1f})")
    print(f"{'quantity':<52}{'value':>26}")
    print("-" * 78)
    verdict = "ok" if s["median_wall_s"] < TARGET_S else "OVER TARGET"
    print(f"{'simulate 1 s @ 10 kHz, 60 el., median of 3: wall':<52}"
          f"{s['median_wall_s']:>20.3f} s {verdict:>3}")
    print(f"{'    cpu (process time)':<52}{s['median_cpu_s']:>24.3f} s")
    runs = " ".join(f"{w:.2f}/{c:.2f}" for w, c in zip(s["wall_s"], s["cpu_s"], strict=True))
    print(f"{'    each run, wall/cpu [s]':<52}{runs:>26}")
    for name, w in results["write_simulation"].items():
        print(f"{'write_simulation ' + name + ': wall / cpu':<52}"
              f"{w['wall_s']:>12.2f} s / {w['cpu_s']:>7.2f} s")
    h = results["time_step_halving"]
    for k, v in h["max_change_rel_fundamental"].items():
        print(f"{'dt halving change, ' + k + ' (rel. fundamental)':<52}{v:>26.2e}")
    bal = results["balance"]
    print(f"{'balance residual J - R - Psi f (rel. reaction RMS)':<52}"
          f"{bal['residual_rel_reaction_rms']:>26.2e}")
    print(f"{'inertia share of reaction AC RMS':<52}"
          f"{', '.join(f'{v:.3f}' for v in bal['inertia_share_of_reaction_ac_rms']):>26}")
    f = results["frequencies"]
    for k in range(3):
        print(f"{f'pinned-pinned f{k + 1}: FE / Euler-Bernoulli [Hz]':<52}"
              f"{f['pinned_pinned_fe_Hz'][k]:>10.4f} / {f['euler_bernoulli_Hz'][k]:<10.4f}"
              f" ({f['rel_error'][k]:.1e})")
    if "profile" in s:
        print(s["profile"])
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(results, indent=2) + "\n", encoding="utf-8")
    print(f"written {RESULTS}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

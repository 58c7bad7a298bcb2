"""Benchmark: the tare against the rig's weight (``forcecal.forces.weight``): its false alarms on
clean lab rigs and what it catches.

Run from the project root::

    .venv/bin/python benchmarks/weight.py                     # 1000 / 1000 / 300 seeds
    .venv/bin/python benchmarks/weight.py --seeds 200 --body-seeds 50

For the ``paper`` beam, the ``plate`` and the ``body`` under lab realism (gravity preload, each
gauge's zero off by 0.5 N, sensitivities drawn from the declared type-B uncertainties; the rig
file declares ``[weight]`` with ``gauge_zero = 0.5``), at every seed it draws the rig's errors
and records its zero-current tare on the virtual rig (a finite-element model whose gravity
preload is the consistent mass matrix's, not forcecal's quadrature), then:

- counts the tares whose chi-square is beyond the check's limit (the false-alarm rate stated:
  1e-3 per tare), with the Clopper-Pearson 95 % interval, and the chi-square's mean against
  its degrees of freedom;
- makes each mistake of :data:`MISTAKES` on the rig or the tare and counts how often the check
  notes it, and how often the note names the mistake among the causes it lists (:data:`NAMED`).

Prints a table and writes ``benchmarks/results/weight.json``.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.stats import beta  # noqa: E402

from forcecal.forces.diagnostics import FALSE_ALARM, chi_square_limit  # noqa: E402
from forcecal.forces.weight import weight_chi_square, weight_notes  # noqa: E402
from forcecal.rig import Rig  # noqa: E402
from forcecal.simulate.lab import draw_errors  # noqa: E402
from forcecal.simulate.presets import get_preset, with_realism  # noqa: E402
from forcecal.simulate.virtual_rig import build_model, public_rig, record_run  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results" / "weight.json"
DRIVEN = 1.0
"""[A] the RMS current of the run a tare zeroes (the tares' own is their noise, a few mA)."""


def _masses(distributed: float = 1.0, drop_lumped: bool = False) -> Callable[[Rig], Rig]:
    def edit(rig: Rig) -> Rig:
        st = rig.structure.with_masses(distributed=distributed)
        if drop_lumped:
            st = dataclasses.replace(st, masses=st.masses[1:])
        return dataclasses.replace(rig, structure=st)
    return edit


def _gauges(factor: float, which: int | None) -> Callable[[Rig], Rig]:
    def edit(rig: Rig) -> Rig:
        gauges = tuple(dataclasses.replace(g, scale=g.scale * factor)
                       if which is None or k == which else g for k, g in enumerate(rig.gauges))
        return dataclasses.replace(rig, gauges=gauges)
    return edit


MISTAKES: dict[str, Callable[[Rig], Rig]] = {
    "distributed mass +10%": _masses(1.10),
    "distributed mass +20%": _masses(1.20),
    "first lumped mass forgotten": _masses(drop_lumped=True),
    "every gauge's scale +2%": _gauges(1.02, None),
    "every gauge's scale +5%": _gauges(1.05, None),
    "first gauge's scale +10%": _gauges(1.10, 0),
}
NAMED = {
    "distributed mass +10%": ("structure.mass_per_length", "structure.mass_per_area",
                              "structure.density"),
    "distributed mass +20%": ("structure.mass_per_length", "structure.mass_per_area",
                              "structure.density"),
    "first lumped mass forgotten": ("more than the rig's masses",),
    "every gauge's scale +2%": ("every gauge's scale",),
    "every gauge's scale +5%": ("every gauge's scale",),
    "first gauge's scale +10%": ("gauge '",),
}
"""What the note must say for its cause to count as named: the mistake's key among the causes
the data cannot tell apart (a forgotten lumped mass: the mass the gauges carry beyond the
rig's, which the note gives with its centre)."""


def _rate(k: int, n: int) -> dict:
    lo = float(beta.ppf(0.025, k, n - k + 1)) if k else 0.0
    hi = float(beta.ppf(0.975, k + 1, n - k)) if k < n else 1.0
    return {"count": k, "of": n, "rate": k / n, "ci95": [lo, hi]}


def survey(name: str, seeds: int) -> dict:
    """The clean tares' chi-squares and every mistake's verdicts on the preset ``name``."""
    preset = with_realism(get_preset(name), "lab")
    model, rig = build_model(preset), public_rig(preset)
    spec = next(r for r in preset.runs if r.tare)
    chi2: list[float] = []
    caught = dict.fromkeys(MISTAKES, 0)
    named = dict.fromkeys(MISTAKES, 0)
    t = time.perf_counter()
    for seed in range(seeds):
        rng = np.random.default_rng(seed)
        tare, _ = record_run(preset, spec, rng, model, draw_errors(preset, model, rng))
        chi2.append(weight_chi_square(rig, tare)[0])
        for mistake, edit in MISTAKES.items():
            notes = weight_notes(edit(rig), tare, DRIVEN, "run")
            caught[mistake] += bool(notes)
            named[mistake] += bool(notes) and any(p in notes[0] for p in NAMED[mistake])
    dof = len(rig.gauges)
    limit = chi_square_limit(dof, FALSE_ALARM)
    return {"preset": name, "seeds": seeds, "dof": dof, "limit": limit,
            "weight_N": float(rig.structure.total_mass * rig.weight.gravity),
            "gauge_zero_N": rig.weight.gauge_zero,
            "chi_square_mean": float(np.mean(chi2)),
            "false_alarms": _rate(int(np.sum(np.array(chi2) > limit)), seeds),
            "mistakes": {m: {"noted": _rate(caught[m], seeds),
                             "cause_named": _rate(named[m], seeds)} for m in MISTAKES},
            "seconds": time.perf_counter() - t}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=1000)
    ap.add_argument("--body-seeds", type=int, default=300)
    args = ap.parse_args()
    rows = [survey(name, args.body_seeds if name == "body" else args.seeds)
            for name in ("paper", "plate", "body")]
    print(f"{'preset':8} {'seeds':>6} {'weight N':>9} {'mean chi2 / dof':>16} "
          f"{'false alarms (stated 1e-3)':>30}")
    for r in rows:
        fa = r["false_alarms"]
        print(f"{r['preset']:8} {r['seeds']:6d} {r['weight_N']:9.3g} "
              f"{r['chi_square_mean']:7.3g} / {r['dof']:<6d} "
              f"{fa['count']:5d} = {fa['rate']:.2g} [{fa['ci95'][0]:.2g}, {fa['ci95'][1]:.2g}]")
    print(f"\n{'mistake':30}" + "".join(f"{r['preset'] + ' noted / named':>24}" for r in rows))
    for m in MISTAKES:
        print(f"{m:30}" + "".join(f"{r['mistakes'][m]['noted']['rate']:>15.0%} / "
                                  f"{r['mistakes'][m]['cause_named']['rate']:<6.0%}"
                                  for r in rows))
    RESULTS.write_text(json.dumps({"false_alarm_stated": FALSE_ALARM, "presets": rows},
                                  indent=1), encoding="utf-8")
    print(f"\nwrote {RESULTS}")


if __name__ == "__main__":
    main()

"""Guards of the uncertainty propagation that the coverage suite (test_uncertainty.py) leaves
open, found by a mutation campaign: each test here fails when one term of the stated standard
uncertainty is broken, and passes on the method as it is.

- The floor of a harmonic kept without a shape (``unresolved_inertia_bound``: the whole mass
  moving with the probes' RMS motion, or their noise). On the 'paper' rig the nearest shape's
  proxy (``unresolved_inertia``) alone already covers the error, so a zero floor went unnoticed
  by every other test. Where the probes barely see the harmonic, the proxy is made of their
  noise and may fall far below the uncompensated inertia; the floor keeps the single forces'
  stated std a bound.

Statistics as in test_uncertainty.py: z = (estimate - truth) / stated std for Re and Im, the
truth fitted at the estimate's own fundamental. Achieved values are stated beside every bound.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from forcecal.forces.steady import reconstruct
from forcecal.forces.uncertainty import combinations
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

UNRESOLVED = 3          # the resonance rig's scan resolves n = 1, 2; the reactions show n = 3
RUN_SEEDS = 20          # run-noise draws on one scan (40 Re/Im values per combination)
SCAN_SEED = 100


@pytest.fixture(scope="module")
def unresolved_z() -> dict[str, np.ndarray]:
    """z (RUN_SEEDS, 2) of every combination at the unresolved harmonic of the 'resonance' rig.

    The 36 Hz drive puts n = 2 just above the first bending mode, so the harmonics' shapes
    differ; with a 31-point scan of 0.3 s per point and three times the LDV noise the scan
    resolves n = 1, 2 only (n = 3's shape rises 1.1-2.2 times above its noise, 3 needed; at the
    preset's LDV noise it rises above 3 and is resolved), and at n = 3 probe s2 sits near a
    node (|S_3| about its noise, s1 about 5 times it): the nearest shape's proxy for the
    inertia is then mostly the probes' noise.
    """
    p = get_preset("resonance")
    p = dataclasses.replace(p, scan=dataclasses.replace(p.scan, n_points=31, record=0.3),
                            runs=(dataclasses.replace(p.runs[0], duration=0.5),),
                            noise=dataclasses.replace(p.noise, ldv=3 * p.noise.ldv))
    fe = build_model(p)
    spec = p.runs[0]
    rig = public_rig(p)
    run_r = simulate_response(p, spec.drives, spec.gap, spec.duration, fe)
    true_force = run_truth(p, fe, run_r).pole_force
    model = build_spatial_model(rig, measure_scan(p, fe, scan_response(p, fe),
                                                  np.random.default_rng(SCAN_SEED)))
    names, combo = combinations(rig)
    z = []
    for seed in range(RUN_SEEDS):
        est = reconstruct(rig, model, measure_run(p, spec, fe, run_r,
                                                  np.random.default_rng(seed)))
        assert est.kept[UNRESOLVED] and not est.with_inertia[UNRESOLVED]
        assert est.combination is not None and est.combination_std is not None
        truth = combo @ fit_harmonics(true_force, p.fs, est.f0, len(est.harmonics) - 1).phasors
        err = (est.combination - truth)[:, UNRESOLVED]
        std = est.combination_std[:, UNRESOLVED]
        z.append(np.stack([err.real / std, err.imag / std], axis=-1))
    zs = np.array(z)                                                   # (seeds, n_c, 2)
    return {c: zs[:, k] for k, c in enumerate(names)}


def test_unresolved_harmonic_bound_holds_where_the_probes_barely_see_it(unresolved_z):
    """The error of a harmonic without a shape is its uncompensated inertia, a bias, not
    noise; the stated std is a bound on it. For the single forces, whose split depends on where
    the mass moves (unknown without the shape), the whole-mass floor makes it one: RMS(z) well
    below 1. Without the floor only the noisy proxy is left and RMS(z) rises to about 1 with
    draws beyond |z| = 3."""
    single = np.concatenate([unresolved_z["F1"], unresolved_z["F2"]]).ravel()
    rms = float(np.sqrt(np.mean(single**2)))
    # achieved 0.17 over 80 values (F1 0.18, F2 0.16); with unresolved_inertia_bound = 0:
    # 1.05 (F1 1.11, F2 1.00, largest |z| 3.1)
    assert rms <= 0.5, f"F1, F2 at n = {UNRESOLVED}: RMS(z) = {rms:.3f} (observed/stated)"
    # every combination is still covered; achieved RMS(z): total 0.93, moment_x 0.70
    for c, z in unresolved_z.items():
        r = float(np.sqrt(np.mean(z**2)))
        assert r <= 1.38, f"{c} at n = {UNRESOLVED}: RMS(z) = {r:.3f} over {z.size} values"


def test_a_weak_harmonic_over_many_records_is_resolved():
    """A harmonic is kept when its fitted shape rises 3 times above its noise, not each record:
    on the resonance rig's 31-point scan n = 3 has a signal-to-noise ratio of 2.4 per record
    (below 3) yet its shape over 31 records rises above 3; noise alone (n = 5, 6) does not."""
    p = get_preset("resonance")
    p = dataclasses.replace(p, scan=dataclasses.replace(p.scan, n_points=31, record=0.3))
    fe = build_model(p)
    model = build_spatial_model(public_rig(p), measure_scan(p, fe, scan_response(p, fe),
                                                            np.random.default_rng(SCAN_SEED)))
    assert 3 in model.harmonics.tolist() and model.snr[2] < 3.0, (model.snr, model.dropped)
    for n in (5, 6):
        assert n in model.dropped and ("rises" in model.dropped[n]
                                       or "noise alone" in model.dropped[n]), model.dropped

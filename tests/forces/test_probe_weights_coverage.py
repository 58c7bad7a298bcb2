"""End to end: one probe ten times noisier than the other. The probes' phasors are weighted by
their noise, which the estimate reads from the data (each channel's harmonic-fit residual,
:func:`forcecal.forces.coordinates.sensor_weights`), so that the stated uncertainty covers the
truth as often as it claims AND the error stays at the noise floor of the weighted fit.

The ``paper`` rig (beam on gauges at 0 and 0.6 m, poles at 0.25 and 0.35 m, probes s1 at
0.1 m and s2 at 0.5 m; the session's model from its seed-0 scan) runs its noise-free 1 s
record (``paper_noise_free``, 20 Hz) with white noise of fixed seeds added here: gauges
0.01 N, current 1 mA, s1 0.2 um and s2 2 um (ten times s1's). Each run is reconstructed
(``forcecal.reconstruct``) and its force phasors are compared with the simulator's true pole
forces, fitted at the run's own estimated f0, at every harmonic whose inertia comes from the
model (1, 2, 3), Re and Im apart, for F1 and F2, over 20 seeds (240 components).

- Coverage: |error| <= 2 u in 95.8 % of the components (230 of 240; claimed 95.45 %; test
  91.4-99.5 %, the binomial 3-sigma band on 240 draws, 3 sqrt(0.9545 x 0.0455 / 240) =
  4.0 %, capped below 100 %); RMS of error / u 1.00 (test 0.75-1.3).
- Error: its RMS over the noise floor of the weighted least squares is 1.05 over all
  components (test < 1.4) and 1.06 at the third harmonic, where the probes matter most
  (test < 1.5). The floor is computed here, independently of the package, from METHOD.md
  section 6: var(Re) = 2 sigma^2 / N of every phasor, Q_n from the probes weighted by
  1 / sigma_j^2, F_n = Psi^-1 (m_n (n w0)^2 Q_n - R_n) (up to sign) propagated linearly.

Uniform weights (the same weight on s1 and s2) leave the stated uncertainty near-right at
the average variance, but triple the error: RMS over the floor 3.07 overall, 4.49 at the
third harmonic (RMS error / u 1.03, coverage 95.0 %: only the error test sees it); unit
weights also state the uncertainty as if the probes had 1 m of noise (RMS error / u 3e-8,
coverage 100 %), which the coverage test catches as well.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import forcecal
from forcecal.model.relaxation import force_matrix
from forcecal.signals.harmonics import fit_harmonics

SEEDS = range(20)
NOISE = {"R1": 0.01, "R2": 0.01, "i": 1e-3, "s1": 0.2e-6, "s2": 2e-6}     # [N, A, m]
CLAIMED = 0.9545                    # P(|z| <= 2) of a normal error
HARMONICS = (1, 2, 3)               # the harmonics whose inertia comes from the model


def noisy(run, seed):
    """The noise-free run with white noise of ``NOISE`` on its channels, seeded."""
    rng = np.random.default_rng(seed)
    return dataclasses.replace(run, channels={
        c: v + NOISE[c] * rng.standard_normal(v.size) if c in NOISE else v
        for c, v in run.channels.items()})


def noise_floor(rig, model, f0, n_samples, n):
    """(n_forces,) [N]: the std of Re (and of Im) of each force's harmonic-n phasor that
    white noise leaves after the noise-weighted fit, propagated linearly."""
    pinv = np.linalg.pinv(force_matrix(rig))                          # (n_f, n_g)
    k = [int(h) for h in model.harmonics].index(n)
    phi = model.shape_values(n, rig.structure.coordinates(rig.sensor_points))
    sigma_s = np.array([NOISE[s] for s in rig.sensor_names])
    info = np.sum(np.abs(phi) ** 2 / sigma_s**2)        # Q_n's weighted information
    c = pinv @ model.couplings[k] * (2 * np.pi * n * f0) ** 2          # d F / d Q
    sigma_g = np.array([NOISE[g] for g in rig.gauge_names])
    var = (2.0 / n_samples) * (np.abs(pinv) ** 2 @ sigma_g**2 + np.abs(c) ** 2 / info)
    return np.sqrt(var)


@pytest.fixture(scope="module")
def errors(paper, paper_noise_free):
    """(z, e): every component's error over its stated uncertainty and over the noise floor,
    each (n_seeds, n_forces, n_harmonics, 2 (Re, Im))."""
    rig, _, model, _ = paper
    run, truth = paper_noise_free
    assert list(rig.sensor_names) == ["s1", "s2"] and list(rig.force_names) == ["F1", "F2"]
    z, e = [], []
    for seed in SEEDS:
        est = forcecal.reconstruct(rig, model, noisy(run, seed))
        assert all(est.with_inertia[n] for n in HARMONICS), est.with_inertia
        want = fit_harmonics(truth.pole_force, run.fs, est.f0, len(est.harmonics) - 1,
                             t0=run.t0).phasors
        h = list(HARMONICS)
        err = est.force[:, h] - want[:, h]
        err = np.stack([err.real, err.imag], axis=-1)                  # (n_f, n_h, 2)
        floor = np.stack([noise_floor(rig, model, est.f0, run.n_samples, n) for n in h],
                         axis=1)
        z.append(err / est.force_std[:, h, None])
        e.append(err / floor[..., None])
    return np.array(z), np.array(e)


def test_the_noisier_probe_is_ten_times_noisier(paper):
    rig = paper[0]
    sigma = [NOISE[s] for s in rig.sensor_names]
    assert max(sigma) == pytest.approx(10 * min(sigma))


def test_stated_uncertainty_covers_the_truth_as_claimed(errors):
    z, _ = errors
    n = z.size
    assert n == 240
    covered = float(np.mean(np.abs(z) <= 2.0))
    band = 3 * np.sqrt(CLAIMED * (1 - CLAIMED) / n)                    # 0.040
    # achieved 0.958 (230 of 240)
    assert CLAIMED - band < covered < min(CLAIMED + band, 0.995), covered
    # achieved 1.00: the stated u is the error's size, neither inflated nor shrunk
    rms_z = float(np.sqrt(np.mean(z**2)))
    assert 0.75 < rms_z < 1.3, rms_z


def test_error_stays_at_the_weighted_noise_floor(errors):
    _, e = errors
    overall = float(np.sqrt(np.mean(e**2)))
    third = float(np.sqrt(np.mean(e[:, :, HARMONICS.index(3)] ** 2)))
    # achieved 1.05 overall, 1.06 at n = 3 (uniform weights: 3.07 and 4.49)
    assert overall < 1.4, overall
    assert third < 1.5, third

"""The noise a steady run of a campaign over frequency hands to the law's fit: the harmonics its
reconstruction holds, under a broadband model whose band ends below some of them.

The broadband model is the finite-element beam's (session fixtures in ``tests/conftest.py``).
"""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
from fe_beam import FS, record_run

from forcecal.actuator.frequency import SteadyRecord
from forcecal.campaign.noise import run_noise
from forcecal.forces.steady import reconstruct
from forcecal.model.broadband import steady_model

F0 = 46.0  # [Hz]: harmonics 5 and 6 (230, 276 Hz) lie above the model's band (5-200 Hz)


def test_harmonics_above_the_band_are_not_measured_and_get_no_weight(beam, bb_model):
    """A steady run at 46 Hz, 6 N + 1.5 N a pole and 0.6 A + 0.1 A: its reconstruction holds
    no estimate above 200 Hz (no shape, and the gauges show nothing there), and its noise
    says so; the record built from it leaves those harmonics out of the fit (``inf``) and
    weights the others by their stated noise instead of falling back on the scatter."""
    wave = np.sin(2 * np.pi * F0 * np.arange(int(2.0 * FS)) / FS)
    run, _ = record_run(beam, np.random.default_rng(3), 6.0 + 1.5 * wave, 0.6 + 0.1 * wave,
                        "steady")
    rig = dataclasses.replace(beam[3], frequency=F0, drive="steady")
    model = steady_model(bb_model, rig, F0, 6)
    est = reconstruct(rig, model, run, n_harmonics=6)
    assert list(model.harmonics) == [1, 2, 3, 4]
    assert not est.kept[5] and not est.kept[6]
    noise = run_noise(rig, model, run, est, None)
    np.testing.assert_array_equal(noise.estimated, est.kept)
    n = 64
    t = run.t0 + np.arange(n) / (n * est.f0)
    zero = np.zeros(n)
    samples = SimpleNamespace(time=t, current=0.6 + 0.1 * np.sin(2 * np.pi * est.f0 * t),
                              gaps=np.full((n, 2), 1e-3), force=zero, noise=noise)
    rec = SteadyRecord.from_samples(samples, f0=est.f0)
    assert rec.force_std is not None
    std = np.asarray(rec.force_std)
    assert np.all(np.isinf(std[5:])) and np.all(np.isfinite(std[:5])) and np.all(std[:5] > 0)
    # the stated noise of the harmonics it holds, unchanged
    var = sum(np.asarray(s) ** 2 for s in noise.force_std.values())[:5]
    assert np.all(std[:5] ** 2 >= var * (1 - 1e-12))

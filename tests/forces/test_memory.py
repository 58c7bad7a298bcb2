"""Memory of the batch estimate on a long record: :func:`forcecal.forces.steady.reconstruct`
holds the run's records in SI only while it fits them, and makes the series over the record
once they are freed, so that a 10-minute run at 10 kHz stays well within 1 GB."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from forcecal.forces.steady import reconstruct
from forcecal.records import Run
from forcecal.signals.fourier_sums import grid_series
from forcecal.signals.harmonics import fit_harmonics

N_LONG = 100_000
"""Samples of the long run (10 s at 10 kHz): beyond LONG_RECORD, fitted chunk by chunk."""
HELD = 10.0
"""Most channel lengths the estimate may allocate at once: its series over the record (time,
the forces and the reactions-only forces: 5 for two forces) and the records in SI while they
are fitted (4) are about 7; each copy of a record's channel or series adds one."""


@pytest.fixture(scope="module")
def long_run(paper):
    """(rig, model, run): every channel of the 'paper' run as its Fourier series at the
    estimate's fundamental plus white noise of its residual's level, N_LONG samples."""
    rig, _, model, run = paper
    est = reconstruct(rig, model, run)
    h = len(est.harmonics) - 1
    rng = np.random.default_rng(7)
    channels = {}
    for name in run.channels:
        fit = fit_harmonics(run.channel(name), run.fs, est.f0, h, t0=run.t0)
        channels[name] = (grid_series(fit.phasors, est.f0, run.fs, 0.0, N_LONG)
                          + float(fit.residual_std) * rng.standard_normal(N_LONG))
    return rig, model, Run(channels=channels, fs=run.fs, name="long")


def test_the_estimate_of_a_long_run_copies_its_records_no_more_than_it_must(long_run):
    """The peak of the memory the estimate allocates (its result included), in channel
    lengths: about 7 (before the records were freed ahead of the series and the reactions-only
    series made a block at a time, 15)."""
    rig, model, run = long_run
    tracemalloc.start()
    try:
        start = tracemalloc.get_traced_memory()[0]
        est = reconstruct(rig, model, run)
        peak = tracemalloc.get_traced_memory()[1] - start
    finally:
        tracemalloc.stop()
    assert est.series.shape == (len(rig.forces), N_LONG)
    assert peak / (8 * N_LONG) < HELD, peak / (8 * N_LONG)

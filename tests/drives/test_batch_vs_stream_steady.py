"""Under a steady drive the batch estimate (``forcecal.reconstruct``) and the real-time one
(``forcecal.stream``) of one stationary run agree sample by sample (METHOD.md section 3,
step 7), each force and the total, once the recursive estimator has settled.

Both are linear least-squares estimates of the same harmonics from the same samples: the batch
over the whole record, the stream over its exponential window. The batch is the best of the
two, so the stream's error is the batch's plus an independent part, and their difference has
variance u_stream^2 - u_batch^2, each as the estimates state it. Measured on the session's
``paper`` run (seed 0, 1 s, f0 = 20 Hz), after 5 latencies (0.5 s):

=======  ======================  ======================  =================  ===============
force    RMS z (test 0.55-1.35)  max |z| (test < 5.5)    max |d| / AC amp   RMS d / inertia
                                                         (test < 0.5 %)     (test < 2.5 %)
=======  ======================  ======================  =================  ===============
F1       0.81                    2.8                     0.18 %             0.68 %
F2       0.90                    3.7                     0.23 %             0.75 %
total    1.07                    3.9                     0.11 %             0.40 %
=======  ======================  ======================  =================  ===============

with z = d / sqrt(u_stream^2 - u_batch^2), d = stream - batch, the AC amplitude
sqrt(2) x the batch series' AC RMS, and "inertia" the RMS of the batch's inertia part
(the series less its reactions-only one: 7.5 % of the AC amplitude). In units of the batch's
own stated uncertainty the difference has RMS 1.5-2.0 u_batch (test < 3): the stream's
window holds about a tenth of the record, so it states ~2.1 times the batch's uncertainty
(test 1.5-4).

Checked against breakage: the stream's inertia 1 % too large (its readout) or the batch's 1 %
too small fails F1 and the total in units of u_batch (3.07 and 5.55) and F2's RMS z (1.40).
"""

from __future__ import annotations

import numpy as np
import pytest

import forcecal
from forcecal.realtime.estimator import StreamEstimator

SETTLE_LATENCIES = 5
"""The stream's warm-up left out: this many of its latencies (group delays)."""


@pytest.fixture(scope="module")
def both(paper):
    rig, _, model, run = paper
    batch = forcecal.reconstruct(rig, model, run)
    live = forcecal.stream(rig, model, run)
    latency = StreamEstimator(rig, model, model.f0, run.fs).latency_periods
    skip = int(round(SETTLE_LATENCIES * latency * run.fs / batch.f0))
    return batch, live, skip


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


def test_same_instants_and_enough_settled_record(both, paper):
    batch, live, skip = both
    run = paper[3]
    np.testing.assert_array_equal(live.time, batch.time)
    assert live.force_names == batch.force_names
    # 5 latencies of ~2 periods = 0.5 s: half the 1 s run is left to compare (10 periods)
    assert 0.25 * run.n_samples < skip < 0.75 * run.n_samples, skip


@pytest.mark.parametrize("name", ["F1", "F2", "total"])
def test_stream_agrees_with_batch_sample_by_sample(both, name):
    batch, live, skip = both
    f_b, u_b = (a[skip:] for a in batch.force_over_time(name))
    f_s, u_s = (a[skip:] for a in live.force_over_time(name))
    static = batch.columns()[f"{name}_static"][skip:]
    d = f_s - f_b

    # the stream states the larger uncertainty (achieved: 2.10-2.16 times, median)
    ratio = np.median(u_s / u_b)
    assert 1.5 < ratio < 4.0, ratio
    assert np.all(u_s > u_b)

    # in units of the batch's stated uncertainty (achieved RMS 1.53, 1.73, 1.98)
    assert _rms(d / u_b) < 3.0, _rms(d / u_b)

    # in units of the difference's own stated std (achieved RMS 0.81, 0.90, 1.07; max 2.8,
    # 3.7, 3.9 for F1, F2, total)
    z = d / np.sqrt(u_s**2 - u_b**2)
    assert 0.55 < _rms(z) < 1.35, (name, _rms(z))
    assert np.max(np.abs(z)) < 5.5, (name, np.max(np.abs(z)))

    # relative to the AC amplitude (achieved max 0.18 %, 0.23 %, 0.11 %)
    amplitude = np.sqrt(2.0) * np.std(batch.force_over_time(name)[0])
    assert np.max(np.abs(d)) < 5e-3 * amplitude, (name, np.max(np.abs(d)) / amplitude)

    # relative to the inertia term's part, which both must carry (achieved 0.68 %, 0.75 %,
    # 0.40 %; without the inertia in one of them this is 100 %)
    inertia = _rms(f_b - static)
    assert inertia > 0.05 * amplitude         # the inertia matters here (achieved 0.075)
    assert _rms(d) < 0.025 * inertia, (name, _rms(d) / inertia)

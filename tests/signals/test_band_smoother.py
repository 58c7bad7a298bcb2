"""The band-limited Kalman smoother and the smoothing spline of the broadband path
(:mod:`forcecal.signals.kalman`, :mod:`forcecal.signals.spline_smoother`).

Split from the broadband tests; the finite-element beam's fixtures are in ``tests/conftest.py``
and its helpers in ``tests/fe_beam.py``.
"""

from __future__ import annotations

import numpy as np
from fe_beam import FS, band_noise

from forcecal.signals.kalman import band_model, filter_states, smooth_states


def test_smoother_acceleration_unbiased_and_stated(beam):
    """A band-limited signal's second derivative: no gain error (achieved 0.9994-1.0005 over
    cutoffs 48-200 Hz; test 0.995-1.005) and an error whose RMS the steady covariance states
    (achieved 0.84-0.88 of it in the record's interior; test 0.65-1.15, which a halved or a doubled
    variance leaves)."""
    rng = np.random.default_rng(3)
    n = 40_000
    x = 1e-5 * band_noise(rng, n, 5.0, 40.0)
    f = np.fft.rfftfreq(n, 1 / FS)
    acc = np.fft.irfft(-(2 * np.pi * f) ** 2 * np.fft.rfft(x), n)
    noise = 2e-8
    for cutoff in (48.0, 200.0):
        bm = band_model(FS, cutoff, 1e-12, noise**2)
        a = smooth_states(bm, x + noise * rng.standard_normal(n), (2,))[0]
        inner = slice(2000, -2000)
        gain = np.dot(a[inner], acc[inner]) / np.dot(acc[inner], acc[inner])
        assert 0.9988 < gain < 1.0012
        ratio = np.std(a[inner] - acc[inner]) / np.sqrt(bm.smoothed_cov[2, 2])
        assert 0.65 < ratio < 1.15, ratio


def test_filter_is_the_kalman_recursion():
    """The compiled steady-gain filter is the textbook predict/update recursion."""
    rng = np.random.default_rng(4)
    z = np.cumsum(rng.standard_normal(3000)) * 1e-3
    bm = band_model(FS, 100.0, 1e-6, 1e-6)
    got = filter_states(bm, z, (0, 2))
    x = np.zeros(bm.phi.shape[0])
    want = np.empty((2, z.size))
    warm = np.concatenate([np.full(bm.settle, z[0]), z])
    for k, zk in enumerate(warm):
        xp = bm.phi @ x
        x = xp + bm.gain * (zk - xp[0])
        if k >= bm.settle:
            want[:, k - bm.settle] = x[[0, 2]] * bm.scale[[0, 2]]
    for row in range(2):
        np.testing.assert_allclose(got[row], want[row], rtol=1e-9,
                                   atol=1e-9 * np.abs(want[row]).max())


def test_the_spline_family_is_scipys_smoothing_spline():
    """:class:`forcecal.signals.spline_smoother.SplineFamily`'s map at any penalty gives the
    values of :func:`scipy.interpolate.make_smoothing_spline` (achieved 1e-15 of their size,
    8e-13 at the largest penalty; test 1e-9), its limit the weighted straight line, and the
    penalty of least C_p is none for values with no smooth part and, for a line, within the
    noise (1e-3; achieved 4e-4) of the straight line."""
    import scipy.interpolate

    from forcecal.signals.spline_smoother import SplineFamily

    rng = np.random.default_rng(41)
    x = np.arange(8.0, 201.0, 4.0)                         # a chirp's lines, a few dropped
    x = np.delete(x, rng.choice(x.size, 5, replace=False))
    w = rng.uniform(0.5, 2.0, x.size) * 1e6                 # inverse variances: sigma 1e-3
    y = np.sin(x / 30.0) + 1e-3 * rng.standard_normal(x.size)
    family = SplineFamily.over(x, w)
    for lam in (1e-2, 1.0, 1e3, 1e6):
        spline = scipy.interpolate.make_smoothing_spline(x, y, w=w, lam=lam)(x)
        np.testing.assert_allclose(family.matrix(lam) @ y, spline, atol=1e-9)
    design = np.column_stack([np.ones_like(x), x])
    line = design @ np.linalg.lstsq(design * np.sqrt(w)[:, None], y * np.sqrt(w), rcond=None)[0]
    np.testing.assert_allclose(family.matrix(np.inf) @ y, line, atol=1e-9)
    assert 0.0 < family.least_risk(y) < np.inf
    straight = 0.3 + 0.01 * x + 1e-3 * rng.standard_normal(x.size)
    np.testing.assert_allclose(family.matrix(family.least_risk(straight)) @ straight,
                               family.matrix(np.inf) @ straight, atol=1e-3)
    assert family.least_risk(rng.standard_normal(x.size) * 10.0) == 0.0

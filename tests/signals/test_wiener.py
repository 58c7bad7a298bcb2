"""Short-time Wiener gains on an estimate whose noise spectrum is known."""

from __future__ import annotations

import numpy as np
import scipy.signal

from forcecal.signals.wiener import stft_frame, wiener_smooth

FS = 10_000.0


def _sweep(seed, sigma):
    rng = np.random.default_rng(seed)
    t = np.arange(int(4 * FS)) / FS
    clean = scipy.signal.chirp(t, 20.0, 4.0, 150.0) + 0.2 * scipy.signal.chirp(t, 40.0, 4.0,
                                                                               300.0)
    return clean, clean + sigma * rng.standard_normal(t.size)


def test_wiener_keeps_a_sweep_and_sets_its_noise_aside():
    """A swept tone and its second harmonic in white noise: the gains keep the tone (gain
    achieved 0.99988, test 0.998-1.002), cut the noise's RMS (achieved to 0.15 of it, test
    < 0.3) and state the error (observed / stated achieved 0.86 over the noise they let
    through and the signal they take, 0.83-0.86 over three seeds, test 0.7-1.05; without what
    they take, 1.14). Stating the noise half as large gives 1.58 and twice as large 0.49."""
    sigma = 0.05
    clean, x = _sweep(0, sigma)
    frame = stft_frame(FS, x.size)
    noise = np.full((1, 1, frame // 2 + 1), sigma, complex)
    out = wiener_smooth(x[None, :], noise, FS, frame)
    inner = slice(2000, -2000)
    got = out.values[0, inner]
    gain = np.dot(got, clean[inner]) / np.dot(clean[inner], clean[inner])
    err = np.sqrt(np.mean((got - clean[inner]) ** 2))
    ratio = err / np.sqrt(np.mean(out.std[0, inner] ** 2))
    assert 0.998 < gain < 1.002
    assert err / sigma < 0.3
    assert 0.7 < ratio < 1.05, ratio
    np.testing.assert_allclose(out.total, out.values.sum(axis=0))


def test_combinations_of_the_smoothed_signals():
    """Three noisy sweeps (noise 1, 2.5 and 0.5 times sigma) smoothed in an orthonormal basis
    whose first row is their sum's (as the forces are, :mod:`forcecal.forces.transient`) and
    combined back: each signal and their sum within 0.3 of its own noise (achieved 0.14-0.21;
    with the sum's row taken from the basis's columns instead of its rows, 29); every
    combination's error over its stated uncertainty 0.6-1.05 (achieved 0.68-0.88), each
    source's parts in the components added with their phases (their powers added instead:
    0.48)."""
    sigma = 0.05
    rng = np.random.default_rng(3)
    clean = np.stack([_sweep(k, 0.0)[0] * a for k, a in enumerate((1.0, -0.6, 0.3))])
    level = np.array([1.0, 2.5, 0.5])
    noise = sigma * level[:, None] * rng.standard_normal(clean.shape)
    start = np.eye(3)
    start[:, 0] = 1.0
    basis = np.linalg.qr(start)[0].T
    assert not np.allclose(basis.sum(axis=0), basis.sum(axis=1))   # a basis that can tell
    frame = stft_frame(FS, clean.shape[1])
    own = np.zeros((3, 3, frame // 2 + 1), complex)               # each signal its own noise
    own[np.arange(3), np.arange(3)] = sigma * level[:, None]
    out = wiener_smooth(basis @ (clean + noise), np.einsum("jk,ksb->jsb", basis, own), FS,
                        frame, np.vstack([basis.T, basis.sum(axis=1)]))
    inner = slice(2000, -2000)
    truth = np.vstack([clean, clean.sum(axis=0)])[:, inner]
    got = np.vstack([out.values[:-1], out.total])[:, inner]
    std = np.vstack([out.std[:-1], out.total_std])[:, inner]
    err = np.sqrt(np.mean((got - truth) ** 2, axis=1))
    own_noise = sigma * np.append(level, np.sqrt(np.sum(level**2)))
    assert np.all(err / own_noise < 0.3), err / own_noise
    ratio = err / np.sqrt(np.mean(std**2, axis=1))
    assert np.all((0.6 < ratio) & (ratio < 1.05)), ratio

"""The real-time estimator (forcecal.realtime) against exact RLS, the batch estimate and known
synthetic truths (a step in drive amplitude, a drifting drive frequency)."""

from __future__ import annotations

import dataclasses
import sys
import tracemalloc
import types

import numpy as np
import pytest

from forcecal.errors import DataError, DimensionError, InputError
from forcecal.forces.solve import force_solve
from forcecal.forces.steady import channels_si, implied_phasors, reconstruct
from forcecal.io.run_files import read_run, read_table_csv
from forcecal.model.inertia import inertia_term
from forcecal.model.relaxation import force_matrix
from forcecal.realtime import (
    StreamEstimator,
    harmonic_start,
    harmonic_update,
    replay,
    rls_start,
    rls_update,
    steady_count,
    write_stream_csv,
)
from forcecal.realtime.replay import stream_steady
from forcecal.records import Run
from forcecal.signals.harmonics import design_matrix, fit_harmonics
from forcecal.simulate.presets import NoiseSpec

NOISE = NoiseSpec()
NOISE_STD = {"R1": NOISE.gauge, "R2": NOISE.gauge, "s1": NOISE.probe, "s2": NOISE.probe,
             "i": NOISE.current}
NOISE_FACTOR = 4.0
"""Streamed forces stay within this many times their predicted noise std of the reference."""


# ------------------------------------------------------------------------------ fixtures


@pytest.fixture(scope="module")
def batch(paper):
    rig, _, model, run = paper
    return reconstruct(rig, model, run)


@pytest.fixture(scope="module")
def phasors(paper, batch):
    """Channel phasors consistent with the batch estimate (SI), probes exactly phi_n Q_n."""
    rig, _, model, run = paper
    return implied_phasors(rig, model, run, batch)


def synthetic_run(rig, model, batch, phasors, duration, f_start, f_end, seed, gain=None):
    """Channels sum_n Re(X_n e^{j n theta(t)}) + the preset's noise, the drive frequency
    moving linearly from f_start to f_end; the true forces F_n(w(t)) of the same phasors.

    gain : optional callable t -> (n,) scaling every channel (and so every force).
    """
    fs = 10_000.0
    t = np.arange(round(duration * fs)) / fs
    cycles = f_start * t + (f_end - f_start) * t**2 / (2 * duration)
    w = 2 * np.pi * (f_start + (f_end - f_start) * t / duration)
    h = len(batch.harmonics) - 1
    rot = np.exp(2j * np.pi * np.mod(np.outer(np.arange(h + 1), cycles), 1.0))
    g = np.ones_like(t) if gain is None else gain(t)
    rng = np.random.default_rng(seed)
    channels = {name: g * (x @ rot).real + NOISE_STD[name] * rng.standard_normal(t.size)
                for name, x in phasors.items()}
    pinv = np.linalg.pinv(force_matrix(rig))
    r = np.stack([phasors[name] for name in rig.gauge_names])
    force = np.repeat(-(pinv @ r[:, :1]).real, t.size, axis=1)
    for k, n in enumerate(model.harmonics):
        n = int(n)
        inertia = inertia_term(model.couplings[k], batch.coordinates.q[k], n * w)
        force += (force_solve(pinv, inertia, r[:, n:n + 1]) * rot[n]).real
    return Run(channels=channels, fs=fs, name="synthetic"), g * force


def stacked(forces):
    return np.stack(list(forces.values()))


def rms(x, axis=None):
    return np.sqrt(np.mean(np.square(x), axis=axis))


def periods_to_samples(periods, f0, fs):
    return int(round(periods * fs / f0))


# ------------------------------------------------------------------------------ exactness


def test_harmonic_update_is_exact_rls_with_forgetting():
    """The demodulated block form equals information-form RLS on the design matrix, through
    the start-up (per-sample M_k) and the stationary stretch, for any block split."""
    rng = np.random.default_rng(1)
    fs, f0, h, lam, t0 = 2000.0, 13.7, 3, 0.99, 0.37
    n = steady_count(lam) + 1500
    t = t0 + np.arange(n) / fs
    x = rng.normal(size=(4, h + 1)) + 1j * rng.normal(size=(4, h + 1))
    x[:, 0] = x[:, 0].real
    y = (x @ np.exp(2j * np.pi * f0 * np.outer(np.arange(h + 1), t))).real
    y += 0.1 * rng.standard_normal(y.shape)
    _, theta = rls_update(rls_start(2 * h + 1, 4), y, design_matrix(t, f0, h).T, lam)
    reference = np.concatenate([theta[:, :1], theta[:, 1::2] + 1j * theta[:, 2::2]], axis=1)

    state, pieces = harmonic_start(4, h, f0, fs, t0), []
    for start in range(0, n, 777):
        state, out = harmonic_update(state, y[:, start:start + 777], lam)
        pieces.append(out)
    fast = np.concatenate(pieces, axis=-1)
    settled = int(fs / f0)            # the first period is ill-conditioned for both forms
    np.testing.assert_allclose(fast[..., settled:], reference[..., settled:], rtol=0,
                               atol=1e-11 * np.abs(reference).max())
    assert steady_count(lam) < n - 1000                  # both regimes were compared


def test_force_readout_equals_the_phasor_path(paper):
    """Mixing the readout into the demodulation (stationary fast path) changes nothing; the
    estimator is the pure function plus its set-up (filterpy style)."""
    rig, _, model, run = paper
    est = StreamEstimator(rig, model, model.f0, run.fs, forgetting=1 - 1 / 200,
                          track_frequency=False, t0=run.t0)
    raw = np.stack([run.channel(name) for name in est.channel_names])
    y = raw * np.array([1.0] * len(est.channel_names))[:, None]      # the paper rig: scale 1
    readout = est._force_readout(2 * np.pi * model.f0)
    state, phasor_path = harmonic_start(len(y), est.n_harmonics, model.f0, run.fs, run.t0), []
    for start in range(0, y.shape[1], 500):
        state, x = harmonic_update(state, y[:, start:start + 500], est.lam)
        u_complex = x * np.exp(2j * np.pi * model.f0 * np.outer(
            np.arange(est.n_harmonics + 1), run.t0 + np.arange(start, start + x.shape[-1])
            / run.fs))
        u = np.concatenate([u_complex[:, :1].real, np.stack(
            [u_complex[:, 1:].real, u_complex[:, 1:].imag], axis=2).reshape(
            len(y), -1, x.shape[-1])], axis=1)
        phasor_path.append(np.einsum("ocp,cpj->oj", readout, u))
    expected = np.concatenate(phasor_path, axis=-1)
    force = np.concatenate([est.process(raw[:, s:s + 256])[0]
                            for s in range(0, raw.shape[1], 256)], axis=-1)
    assert est.state.count > steady_count(est.lam)                  # fast path was used
    settled = int(run.fs / model.f0)        # the first period is ill-conditioned for both
    np.testing.assert_allclose(force[:, settled:], expected[:, settled:], rtol=0, atol=1e-9)


def test_block_size_does_not_change_the_result(paper):
    """Blocks of 1, 7, 256 and 4096 samples: identical forces (start-up, stationary fast
    path and frequency tracking all crossed)."""
    rig, _, model, run = paper
    options = {"forgetting": 1 - 1 / 200, "f0_guess": rig.frequency}
    results = {b: replay(rig, model, run, b, **options) for b in (4096, 256, 7, 1)}
    ref_time, ref_force, ref_static = results[4096]
    assert steady_count(options["forgetting"]) < run.n_samples
    scale = np.abs(stacked(ref_force)).max()
    for b, (time, force, static) in results.items():
        np.testing.assert_array_equal(time, ref_time)
        np.testing.assert_allclose(stacked(force), stacked(ref_force), rtol=0,
                                   atol=1e-12 * scale, err_msg=f"block {b}")
        np.testing.assert_allclose(stacked(static), stacked(ref_static), rtol=0,
                                   atol=1e-12 * scale)


# ------------------------------------------------------------------------------ accuracy


def test_stationary_run_agrees_with_batch_reconstruct(paper, batch):
    """After 5 latencies the streamed forces agree sample by sample with the batch forces
    within NOISE_FACTOR times the stream's own noise (its window holds ~ (1+lam)/(1-lam)
    samples against the batch's N), and far inside the reactions-only error."""
    rig, _, model, run = paper
    time, force, static = replay(rig, model, run, block=256)
    est = StreamEstimator(rig, model, model.f0, run.fs)
    skip = periods_to_samples(5 * est.latency_periods, batch.f0, run.fs)
    sig = channels_si(rig, run)
    sigma = fit_harmonics(np.stack([sig[c] for c in est.channel_names]), run.fs, batch.f0,
                          len(batch.harmonics) - 1, t0=run.t0).residual_std
    predicted = est.noise_std(sigma)
    # the window's noise vs the batch's: var ratio ~ N (1 - lam) / (1 + lam) per harmonic
    assert 1.5 < predicted.min() / batch.force_std[:, 1:4].max() < 10
    error = rms(stacked(force)[:, skip:] - batch.series[:, skip:], axis=1)
    static_error = rms(stacked(static)[:, skip:] - batch.series[:, skip:], axis=1)
    assert np.all(error < NOISE_FACTOR * predicted), (error, predicted)
    assert np.all(error < 0.05 * static_error)
    np.testing.assert_allclose(stacked(static), batch.static_series, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(time, batch.time)


def test_stream_readout_is_the_batch_force_solve(paper, batch):
    """The stream's readout (the map it applies at every sample) gives, from the channel
    phasors the batch estimate implies, exactly the batch's force phasors: both estimators
    use one coordinate map, one inertia term, one force solve and one harmonic policy."""
    rig, _, model, run = paper
    unshaped = [int(n) for n in np.flatnonzero(batch.kept & ~batch.with_inertia) if n > 0]
    est = StreamEstimator(rig, model, batch.f0, run.fs, extra_harmonics=unshaped,
                          n_harmonics=len(batch.harmonics) - 1)
    implied = implied_phasors(rig, model, run, batch)
    x = np.stack([implied[c] for c in est.channel_names])
    x[:, ~batch.kept] = 0.0
    got = est.force_phasors(x)
    np.testing.assert_allclose(got, batch.force, rtol=0, atol=1e-12 * np.abs(batch.force).max())
    # a broken copy shows: without the inertia the readout is the reactions-only estimate
    assert np.abs(got - batch.static)[:, 1:].max() > 1e3 * 1e-12 * np.abs(batch.force).max()


def test_stream_keeps_the_harmonics_the_batch_keeps(paper):
    """A harmonic the reactions show but the model has no shape for enters the batch forces
    (uncompensated); the stream, started without it, takes it in once its window shows it:
    the same policy (forces.kept_harmonics) decides both."""
    import dataclasses

    rig, _, model, run = paper
    last = len(model.harmonics) - 1
    fewer = dataclasses.replace(model, harmonics=model.harmonics[:last],
                                shapes=model.shapes[:last], couplings=model.couplings[:last],
                                similarity=model.similarity[:last, :last])
    batch = reconstruct(rig, fewer, run)
    dropped = int(model.harmonics[last])
    assert batch.kept[dropped] and not batch.with_inertia[dropped]
    est = StreamEstimator(rig, fewer, batch.f0, run.fs, n_harmonics=len(batch.harmonics) - 1)
    assert not est.kept[dropped]
    est.process(np.stack([run.channel(c) for c in est.channel_names]))
    np.testing.assert_array_equal(est.kept, batch.kept)
    # the significance rests on each channel's noise, followed from its second differences
    # (achieved: within 3 % of the simulated noise)
    expected = np.array([NOISE_STD[c] for c in est.channel_names])
    np.testing.assert_allclose(est.noise_level, expected, rtol=0.1)


def test_phasor_noise_matches_the_forgetting_prediction():
    """White noise: var(Re X_n) = var(Im X_n) = (1-lam)/(1+lam) 2 sigma^2 (n >= 1) and
    (1-lam)/(1+lam) sigma^2 for the mean."""
    rng = np.random.default_rng(7)
    lam, sigma, h = 0.99, 0.3, 2
    y = sigma * rng.standard_normal((1, 120_000))
    _, x = harmonic_update(harmonic_start(1, h, 50.0, 5000.0), y, lam)
    x = x[0, :, steady_count(lam):]
    factor = (1 - lam) / (1 + lam)
    np.testing.assert_allclose(np.var(x[0].real), factor * sigma**2, rtol=0.15)
    for n in (1, 2):
        np.testing.assert_allclose(np.var(x[n].real), 2 * factor * sigma**2, rtol=0.15)
        np.testing.assert_allclose(np.var(x[n].imag), 2 * factor * sigma**2, rtol=0.15)


def test_step_in_drive_amplitude_settles_as_stated(paper, batch, phasors):
    """Every channel (so every force) jumps by half at t = 1 s. The estimate lags at first,
    and within settling_periods(1e-3) periods the error is back to the noise plus 1e-3 of
    the step."""
    rig, _, model, _ = paper
    t_step, jump = 1.0, 1.5
    run, truth = synthetic_run(rig, model, batch, phasors, 2.5, batch.f0, batch.f0, seed=3,
                               gain=lambda t: np.where(t < t_step, 1.0, jump))
    _, force, _ = replay(rig, model, run, 256, f0_guess=batch.f0)
    est = StreamEstimator(rig, model, batch.f0, run.fs)
    sigma = np.array([NOISE_STD[c] for c in est.channel_names])
    noise = NOISE_FACTOR * est.noise_std(sigma)[:, None]
    err = np.abs(stacked(force) - truth)
    k_step = round(t_step * run.fs)
    period = periods_to_samples(1, batch.f0, run.fs)
    settle = periods_to_samples(est.settling_periods(1e-3), batch.f0, run.fs)
    assert 10 < est.settling_periods(1e-3) < 20          # 6.9 memories of 2 periods
    step_size = rms((jump - 1) * truth[:, :k_step] , axis=1)[:, None] / (jump - 1) * 0.5
    before = slice(periods_to_samples(10, batch.f0, run.fs), k_step)
    assert np.all(rms(err[:, before], axis=1)[:, None] < noise)
    assert np.all(rms(err[:, k_step:k_step + period], axis=1)[:, None] > 0.1 * step_size)
    after = slice(k_step + settle, None)
    assert np.all(rms(err[:, after], axis=1)[:, None] < noise + 1e-3 * step_size)


def test_frequency_drift_is_tracked(paper, batch, phasors):
    """The drive frequency rises by 0.2 % over a 2 s record: with tracking the forces stay at
    the noise level after 10 periods and the frequency is followed; a fixed frequency lags
    more and more."""
    rig, _, model, _ = paper
    f_end = batch.f0 * 1.002
    run, truth = synthetic_run(rig, model, batch, phasors, 2.0, batch.f0, f_end, seed=5)
    est = StreamEstimator(rig, model, batch.f0, run.fs)
    raw = np.stack([run.channels[c] for c in est.channel_names])
    tracked = np.concatenate([est.process(raw[:, s:s + 256])[0]
                              for s in range(0, raw.shape[1], 256)], axis=-1)
    _, fixed, _ = replay(rig, model, run, 256, f0_guess=batch.f0, track_frequency=False)
    sigma = np.array([NOISE_STD[c] for c in est.channel_names])
    noise = NOISE_FACTOR * est.noise_std(sigma)
    settled = slice(periods_to_samples(10, batch.f0, run.fs), None)
    last = slice(-periods_to_samples(5, batch.f0, run.fs), None)
    assert np.all(rms(tracked[:, settled] - truth[:, settled], axis=1) < noise)
    assert np.all(rms(stacked(fixed)[:, last] - truth[:, last], axis=1) > 3 * noise)
    assert abs(est.frequency / f_end - 1) < 5e-5


# ------------------------------------------------------------------------------ interface


def test_memory_stays_flat(paper, batch, phasors):
    """The state is of fixed size: thousands more blocks allocate nothing that stays."""
    rig, _, model, _ = paper
    f0 = 20.0                               # 500 samples a period: 5 periods repeat smoothly
    run, _ = synthetic_run(rig, model, batch, phasors, 0.25, f0, f0, seed=9)
    est = StreamEstimator(rig, model, f0, run.fs, forgetting=1 - 1 / 100)
    raw = np.stack([run.channels[c] for c in est.channel_names])
    blocks = [raw[:, s:s + 250] for s in range(0, raw.shape[1], 250)]

    def feed(n_blocks):
        for k in range(n_blocks):
            est.process(blocks[k % len(blocks)])

    feed(300)                                           # past start-up, caches filled
    tracemalloc.start()
    try:
        feed(100)
        first, _ = tracemalloc.get_traced_memory()
        feed(1500)
        second, _ = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert second - first < 64_000
    assert est.state.demod.shape == (len(est.channel_names), est.n_harmonics + 1)


def test_dict_and_array_blocks_agree_and_channels_are_checked(paper):
    rig, _, model, run = paper
    a = StreamEstimator(rig, model, model.f0, run.fs, t0=run.t0)
    b = StreamEstimator(rig, model, model.f0, run.fs, t0=run.t0)
    block = {name: run.channel(name)[:300] for name in run.channels}   # extra 'phi', 'v'
    fa, sa = a.process(block)
    fb, sb = b.process(np.stack([block[name] for name in b.channel_names]))
    np.testing.assert_array_equal(fa, fb)
    np.testing.assert_array_equal(sa, sb)
    assert fa.shape == (len(rig.forces), 300)
    with pytest.raises(DataError, match="'s2'"):
        a.process({k: v for k, v in block.items() if k != "s2"})
    with pytest.raises(DimensionError, match=r"\(5, n\)"):
        a.process(np.zeros((4, 10)))
    bad = dict(block)
    bad["R1"] = block["R1"].copy()
    bad["R1"][17] = np.nan
    with pytest.raises(DataError, match="channel 'R1' has 1 NaN"):
        a.process(bad)


def test_bad_options_are_refused(paper):
    rig, _, model, run = paper
    with pytest.raises(InputError, match="forgetting factor"):
        StreamEstimator(rig, model, model.f0, run.fs, forgetting=1.0)
    with pytest.raises(InputError, match="memory"):
        StreamEstimator(rig, model, model.f0, run.fs, forgetting=0.9)
    with pytest.raises(DataError, match="Nyquist"):
        StreamEstimator(rig, model, model.f0, run.fs, n_harmonics=300)
    with pytest.raises(InputError, match="block"):
        replay(rig, model, run, block=0)


def test_tare_and_ac_coupling_remove_the_dc(paper, batch):
    """A tare equal to the run removes the DC force; AC-coupled gauges give no DC at all;
    after the start-up both leave the same AC force, and the AC-coupled static estimate has
    the tracked DC removed."""
    rig, _, model, run = paper
    _, tared, _ = replay(rig, model, run, 512, tare=run)
    _, ac, ac_static = replay(rig, model, run, 512, ac_coupled=True)
    skip = periods_to_samples(10, batch.f0, run.fs)
    dc = np.abs(batch.force[:, 0])
    assert np.all(dc > 5.0)                                          # a DC worth removing
    for f in (stacked(tared), stacked(ac)):
        assert np.all(np.abs(f[:, skip:].mean(axis=1)) < 1e-3 * dc)
    np.testing.assert_allclose(stacked(tared)[:, skip:], stacked(ac)[:, skip:], rtol=0,
                               atol=0.01)
    assert np.all(np.abs(stacked(ac_static)[:, skip:].mean(axis=1)) < 1e-2 * dc)


def test_latency_is_stated_in_periods(paper):
    rig, _, model, run = paper
    est = StreamEstimator(rig, model, model.f0, run.fs)
    assert est.memory == pytest.approx(2 * run.fs / model.f0)       # the default: 2 periods
    assert est.latency_periods == pytest.approx((est.memory - 1) * model.f0 / run.fs)
    assert est.settling_periods(np.exp(-1)) == pytest.approx(2.0, rel=1e-3)


def test_stream_csv_has_the_reconstruct_columns(paper, tmp_path):
    rig, _, model, run = paper
    time, force, static = replay(rig, model, run, block=1024)
    path = write_stream_csv(tmp_path / "paper.forces.csv", time, force, static)
    t, cols = read_table_csv(path)
    assert list(cols) == ["F1", "F2", "total", "F1_static", "F2_static", "total_static"]
    np.testing.assert_array_equal(t, time)
    np.testing.assert_array_equal(cols["F2"], force["F2"])
    np.testing.assert_allclose(cols["total_static"], static["F1"] + static["F2"], rtol=1e-15)


# ------------------------------------------------------------------------------ compiled, files


def _stream_file(paper, source, target, block=256, **kwargs):
    """``forcecal stream``'s path: the run opened in blocks, checked, streamed to a table."""
    from forcecal.io.blocks import check_run_blocks, open_run_blocks
    from forcecal.realtime.replay import stream_table

    rig, _, model, _ = paper
    blocks = check_run_blocks(rig, open_run_blocks(source, rig, **kwargs))
    with blocks:
        stream_table(rig, model, blocks, target, block=block)
    return blocks


@pytest.mark.parametrize("block", [1, 37, 500, 4096])
def test_compiled_kernel_equals_the_numpy_reference(block):
    """Random channels, a random readout: the compiled loops give NumPy's results to rounding,
    through the start-up (per-sample solve) and the stationary fast path, for any split."""
    rng = np.random.default_rng(11)
    fs, f0, h, lam, n_ch = 3000.0, 17.3, 4, 0.985, 3
    n = steady_count(lam) + 900
    y = rng.standard_normal((n_ch, n)) + np.sin(2 * np.pi * f0 * np.arange(n) / fs)
    readout = rng.standard_normal((2, n_ch, 2 * h + 1))
    for out in (readout, None):
        results = []
        for compiled in (True, False):
            state, pieces = harmonic_start(n_ch, h, f0, fs, 0.2), []
            for s in range(0, n, block):
                state, x = harmonic_update(state, y[:, s:s + block], lam, out,
                                           compiled=compiled)
                pieces.append(x)
            results.append((state, np.concatenate(pieces, axis=-1)))
        (fast_state, fast), (ref_state, ref) = results
        scale = np.abs(ref).max()
        np.testing.assert_allclose(fast, ref, rtol=0, atol=1e-12 * scale)
        np.testing.assert_allclose(fast_state.demod, ref_state.demod, rtol=1e-13)
        np.testing.assert_allclose(fast_state.energy, ref_state.energy, rtol=1e-13)
        assert fast_state.count == ref_state.count == n


def test_csv_numbers_are_printf_g():
    """The compiled formatter writes what C's '%.{P}g' writes; 17 digits, or P = 0 (15 when
    they suffice), read back exactly."""
    from forcecal.io.text_format import format_rows

    rng = np.random.default_rng(5)
    values = np.concatenate([
        rng.standard_normal(3000) * 10.0 ** rng.integers(-30, 30, 3000),
        [0.0, -0.0, 0.5, 0.125, 2.5, 1e-5, 9.99999999995e-5, 999999999.5, 1e16, 1e22, 0.1,
         1 / 3, 5e-324, 1.7976931348623157e308, -1e-300, 123456789.0]])
    for digits in (1, 6, 9, 17):
        lines = format_rows(values[:, None], [digits]).decode().splitlines()
        assert lines == [f"{v:.{digits}g}" for v in values]
    lines = format_rows(values.reshape(-1, 4), [17, 9, 0, 3]).decode().splitlines()
    assert [float(c) for c in lines[5].split(",")[::2]] == list(values.reshape(-1, 4)[5, ::2])
    stamps = np.concatenate([np.arange(3000) / 10240.0, 0.37 + np.arange(3000) / 1e4, values])
    short = format_rows(stamps[:, None], [0]).decode().splitlines()
    assert [float(text) for text in short] == list(stamps)               # exact, and short:
    assert all(text in (f"{v:.15g}", f"{v:.17g}") for text, v in zip(short, stamps, strict=True))
    assert short[1] == "9.765625e-05"


@pytest.mark.parametrize("fmt", ["csv", "h5"])
def test_chunked_reading_gives_the_forces_of_a_whole_read(paper, paper_dir, tmp_path,
                                                          monkeypatch, fmt):
    """The run read in small blocks (and checked in windows) streams to the very table a whole
    read streams to; and to replay's forces."""
    import forcecal.io.blocks as blocks_module
    from forcecal.io.run_files import write_run_hdf5

    source = paper_dir / "runs" / "paper.csv"
    if fmt == "h5":
        source = write_run_hdf5(read_run(source), tmp_path / "paper.h5")
    whole = _stream_file(paper, source, tmp_path / "whole.csv", whole=True)
    assert whole.run is not None
    monkeypatch.setattr(blocks_module, "READ_BLOCK", 1000)
    monkeypatch.setattr(blocks_module, "CHECK_WINDOW", 3000)
    chunked = _stream_file(paper, source, tmp_path / "chunked.csv")
    assert chunked.run is None                                   # really read in blocks
    assert (tmp_path / "chunked.csv").read_bytes() == (tmp_path / "whole.csv").read_bytes()
    rig, _, model, run = paper
    time, force, _ = replay(rig, model, run, 256)
    t, cols = read_table_csv(tmp_path / "chunked.csv")
    np.testing.assert_array_equal(t, time)
    np.testing.assert_allclose(cols["F1"], force["F1"], rtol=1e-8, atol=1e-9)


def test_streamed_table_is_the_same_whatever_the_block(paper, paper_dir, tmp_path):
    """Blocks of 7, 256 and 1024 samples: the same table (CSV to 9 digits, HDF5 to 1e-12)."""
    source = paper_dir / "runs" / "paper.csv"
    tables = {}
    for block in (1024, 256, 7):
        _stream_file(paper, source, tmp_path / f"b{block}.csv", block)
        _stream_file(paper, source, tmp_path / f"b{block}.h5", block)
        tables[block] = read_table_csv(tmp_path / f"b{block}.csv")
        h5 = read_run(tmp_path / f"b{block}.h5")
        assert h5.fs == read_run(source).fs
        np.testing.assert_allclose(h5.channels["F2"], tables[block][1]["F2"], rtol=1e-8)
        if block != 1024:
            ref = read_run(tmp_path / "b1024.h5")
            for name, values in h5.channels.items():
                np.testing.assert_allclose(values, ref.channels[name], rtol=0, atol=1e-11)
    for block in (256, 7):
        np.testing.assert_array_equal(tables[block][0], tables[1024][0])
        for name, values in tables[block][1].items():
            np.testing.assert_allclose(values, tables[1024][1][name], rtol=2e-9, atol=1e-12)


def test_stream_writes_csv_to_stdout_and_nothing_on_error(paper, paper_dir, tmp_path,
                                                          capsysbinary, monkeypatch):
    """``-o -`` writes the CSV table to stdout; an error in the middle of a stream to a file
    leaves no file and no temporary beside it."""
    from forcecal.cli.main import main
    from forcecal.io.blocks import check_run_blocks, open_run_blocks
    from forcecal.realtime.replay import stream_table

    rig, _, model, _ = paper
    path = tmp_path / "model.json"
    model.save(path)
    run = paper_dir / "runs" / "paper.csv"
    args = ["stream", str(paper_dir / "rig.toml"), str(path), str(run)]
    assert main([*args, "-o", "-"]) == 0
    out = capsysbinary.readouterr().out.decode()
    assert out.splitlines()[0] == ("time,F1,F2,total,F1_static,F2_static,total_static,"
                                   "F1_std,F2_std,total_std")
    assert len(out.splitlines()) == 1 + read_run(run).n_samples
    assert main([*args, "-o", str(tmp_path / "s.csv")]) == 0
    capsysbinary.readouterr()
    assert (tmp_path / "s.csv").read_text() == out

    class ClosedPipe:                       # stdout whose reader has gone (`... | head`)
        def write(self, data):
            raise BrokenPipeError(32, "Broken pipe")

        def flush(self):
            pass

    monkeypatch.setattr(sys, "stdout", types.SimpleNamespace(buffer=ClosedPipe(),
                                                             write=ClosedPipe().write,
                                                             flush=ClosedPipe().flush))
    assert main([*args, "-o", "-"]) == 2
    monkeypatch.undo()
    err = capsysbinary.readouterr().err.decode().strip()
    assert err == ("forcecal: stdout: its reader closed the pipe; the table written there is "
                   "cut short"), err

    calls = []

    def failing(time, forces, static):
        calls.append(time.size)
        if len(calls) == 2:
            raise DataError("stop")

    replay_module = sys.modules["forcecal.realtime.replay"]   # the package's `replay` shadows it
    monkeypatch.setattr(replay_module, "STREAM_READ", 2000)
    blocks = check_run_blocks(rig, open_run_blocks(run, rig))
    with blocks, pytest.raises(DataError, match="stop"):
        stream_table(rig, model, blocks, tmp_path / "half.csv", block=64, check=failing)
    assert len(calls) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.json", "s.csv"]


# seed 0 paper run, after 0.3 s: RMS(error / stated std) F1 1.09, F2 1.07, total 1.24 on a
# 3 s run of seed 5; here on the 1 s file run (bounds 0.7-1.6: the short-memory window's own
# scatter over 0.7 s is few independent draws)
def test_the_streamed_std_describes_the_streamed_error(paper, paper_dir):
    """The stream's per-sample standard uncertainty against its error from the truth."""
    from forcecal.io.run_files import read_table_csv
    from forcecal.realtime.replay import stream_forces

    rig, _, model, run = paper
    _, truth = read_table_csv(paper_dir / "truth" / "paper.forces.csv")
    est = StreamEstimator(rig, model, model.f0, run.fs, t0=run.t0)
    raw = np.stack([run.channel(n) for n in est.channel_names])
    t, force, _, std = next(stream_forces(est, [raw], 256, run.t0))
    assert np.all(np.isfinite(std)) and np.all(std > 0)
    settled = t > 0.3
    for k, name in enumerate([*est.force_names, "total"]):
        f = force[k] if k < len(est.force_names) else force.sum(axis=0)
        z = ((f - truth[name]) / std[k])[settled]
        assert 0.7 < np.sqrt(np.mean(z**2)) < 1.6, (name, np.sqrt(np.mean(z**2)))
    # the window's start is far less certain than its steady state
    assert np.all(std[:, 0] > 100 * np.median(std[:, settled], axis=1))


def test_memory_and_steady_mode_options(paper, paper_dir, tmp_path):
    """--memory PERIODS sets the estimator's memory; --steady is 100 periods; nonsense is
    refused with exit status 2 and nothing written."""
    from forcecal.cli.main import STEADY_MEMORY_PERIODS, _forgetting, main

    rig, _, model, run = paper
    args = [str(paper_dir / "rig.toml"), str(paper_dir / "scan.uff"),
            str(paper_dir / "runs" / "paper.csv")]
    out = tmp_path / "steady.csv"
    assert main(["stream", *args, "-o", str(out), "--steady"]) == 0
    assert out.read_text().splitlines()[0].endswith("total_std")
    assert main(["stream", *args, "-o", str(tmp_path / "x.csv"), "--memory", "0.5"]) == 2
    assert not (tmp_path / "x.csv").exists()

    class Args:
        steady, memory = True, None

    lam = _forgetting(Args, model, run.fs)
    est = StreamEstimator(rig, model, model.f0, run.fs, forgetting=lam)
    assert est.memory == pytest.approx(STEADY_MEMORY_PERIODS * run.fs / model.f0)


@pytest.mark.parametrize("kind", ["csv", "tdms"])
def test_stream_takes_a_tare(paper, paper_dir, tmp_path, kind):
    """``stream --tare`` takes the zero-current record's gauge means off every block (of a run
    read in blocks, CSV, or whole, TDMS), as
    ``reconstruct --tare`` does: gauges read 0.3 N and -0.1 N high in both files leave the
    streamed forces where they are without the offsets (to 1e-9 N RMS), where, without the
    tare, the total moves by their sum (-0.2 N: -0.2000002 N once the recursive estimate has
    settled, test within 1e-6 N)."""
    import pandas as pd

    from forcecal.cli.main import main
    from forcecal.io.run_files import write_run_csv, write_run_tdms

    rig, _, model, run = paper
    path = tmp_path / "model.json"
    model.save(path)
    scale = {g.name: g.scale for g in rig.gauges}
    high = {rig.gauge_names[0]: 0.3, rig.gauge_names[1]: -0.1}          # [N]
    raw = {c: v + high[c] / scale[c] if c in high else v for c, v in run.channels.items()}
    high_run = tmp_path / f"high.{kind}"
    (write_run_csv if kind == "csv" else write_run_tdms)(
        dataclasses.replace(run, channels=raw), high_run)
    n = 2000
    zero = {c: np.full(n, high[c] / scale[c]) if c in high else np.zeros(n)
            for c in run.channels}
    write_run_csv(dataclasses.replace(run, channels=zero, name="tare"), tmp_path / "tare.csv")
    rig_file, source = str(paper_dir / "rig.toml"), paper_dir / "runs" / "paper.csv"
    assert main(["stream", rig_file, str(path), str(source), "-o", str(tmp_path / "a.csv")]) == 0
    assert main(["stream", rig_file, str(path), str(high_run), "-o",
                 str(tmp_path / "b.csv"), "--tare", str(tmp_path / "tare.csv")]) == 0
    assert main(["stream", rig_file, str(path), str(high_run), "-o",
                 str(tmp_path / "c.csv")]) == 0
    a, b, c = (pd.read_csv(tmp_path / f"{k}.csv") for k in "abc")
    for col in ("F1", "F2", "total", "total_static"):
        assert np.sqrt(np.mean((b[col] - a[col]) ** 2)) < 1e-9, col
    late = slice(len(a) // 2, None)                 # once the recursive estimate has settled
    shift = (c["total"] - a["total"]).to_numpy()[late]
    np.testing.assert_allclose(np.mean(shift), -0.2, atol=1e-6)


def test_the_streamed_forces_carry_the_notes_of_their_first_seconds(paper):
    # the in-memory stream says what ``reconstruct`` says of the run's first 10 periods (at
    # least 0.5 s): a gauge's scale 10 % off in the rig is named from the force against the flux;
    # the clean run draws no note
    from forcecal.realtime.end_segments import MIN_SECONDS, PERIODS

    rig, _, model, run = paper
    slipped = dataclasses.replace(rig, gauges=(
        dataclasses.replace(rig.gauges[0], scale=1.1 * rig.gauges[0].scale), *rig.gauges[1:]))
    n = int(np.ceil(max(MIN_SECONDS, PERIODS / model.f0) * run.fs))
    first = Run(channels={k: v[:n] for k, v in run.channels.items()}, fs=run.fs, t0=run.t0,
                source=run.source)
    head = f"run '{run.source}'"
    batch = tuple(head + " (its first 0.5 s, as reconstruct checks it)" + text[len(head):]
                  for text in reconstruct(slipped, model, first).notes)
    notes = stream_steady(slipped, model, run).notes
    assert notes == batch and any("gauge 'R1' scale" in text for text in notes), notes
    assert stream_steady(rig, model, run).notes == ()


def test_a_gauge_that_slips_mid_run_is_named_from_the_streams_last_seconds(paper):
    # R1 reads 10 % high from 0.5 s on (a gauge that slips): the first 0.5 s draw no note, the
    # last 0.5 s name R1's scale (achieved +10.1 %), the note saying which seconds it judged
    rig, _, model, run = paper
    n = run.time.size // 2
    slipped = dict(run.channels)
    slipped["R1"] = np.concatenate([run.channel("R1")[:n], 1.1 * run.channel("R1")[n:]])
    notes = stream_steady(rig, model, dataclasses.replace(run, channels=slipped)).notes
    assert notes and all("(its last 0.5 s, as reconstruct checks it)" in t for t in notes), notes
    assert any("gauge 'R1' scale" in t for t in notes), notes

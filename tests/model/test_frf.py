"""A broadband scan's frequency responses: leakage-free on a periodic drive's lines."""

from __future__ import annotations

import numpy as np

from forcecal.model.frf import periods_in_record, scan_response
from forcecal.records import Scan

FS = 2_000.0


def _records(rng, periodic: bool, n_points: int = 5, noise: float = 1e-3):
    """Responses of a one-pole system (10 Hz corner) to a reference, per point a gain."""
    n = int(FS)
    f = np.fft.rfftfreq(n if not periodic else n // 4, 1 / FS)
    spec = np.where((f >= 5) & (f <= 200), np.exp(2j * np.pi * rng.random(f.size)), 0)
    base = np.fft.irfft(spec, n // 4 if periodic else n)
    ref = np.tile(base, 4) if periodic else base
    ref = np.tile(ref / ref.std(), (n_points, 1))
    fr = np.fft.rfftfreq(n, 1 / FS)
    h = 1.0 / (1.0 + 1j * fr / 10.0)
    gains = np.linspace(1.0, 2.0, n_points)
    resp = np.array([g * np.fft.irfft(np.fft.rfft(r) * h, n) for g, r in zip(gains, ref,
                                                                               strict=True)])
    resp += noise * rng.standard_normal(resp.shape)
    scan = Scan(points=np.linspace(0, 1, n_points), response=resp, reference=ref, fs=FS,
                quantity="displacement", source="s.uff")
    return scan, gains


def test_periodic_drive_is_found_and_its_lines_are_exact():
    """Four periods per record: found; H on the drive's lines equals the system's own within
    its stated noise (observed / stated achieved 1.01, test 0.7-1.3: a halved or doubled
    noise fails); a random drive is not
    periodic and goes through Welch's H1."""
    rng = np.random.default_rng(2)
    scan, gains = _records(rng, periodic=True)
    assert periods_in_record(scan.reference, FS, (5.0, 200.0)) == 4
    r = scan_response(scan, (5.0, 200.0))
    assert r.periods == 4 and np.allclose(np.diff(r.frequencies), 4.0)
    want = gains[:, None] / (1.0 + 1j * r.frequencies / 10.0)
    z = np.concatenate([((r.values - want) / r.std).real.ravel(),
                        ((r.values - want) / r.std).imag.ravel()])
    assert 0.7 < np.std(z) < 1.3
    scan, _ = _records(rng, periodic=False)
    assert periods_in_record(scan.reference, FS, (5.0, 200.0)) == 0
    r = scan_response(scan, (5.0, 200.0))
    assert r.periods == 0 and np.median(r.coherence) > 0.9


def test_exported_frfs_state_their_noise_from_coherence_and_averages():
    """A periodic drive's FRFs as SLDV software exports them (H1 and its coherence over the
    four periods of every record, :func:`forcecal.simulate.sldv_frf.frf_export`): the noise
    stated from the coherence and the 4 averages is unbiased, the observed error's variance
    over the stated 1.04 in 10 draws (test 0.85-1.18; Bendat and Piersol's n for the
    coherence's n - 1 states 3/4 of it: 1.39, red). One average, or none declared, is refused."""
    import pytest

    from forcecal.errors import InputError
    from forcecal.simulate.sldv_frf import frf_export

    observed = stated = 0.0
    for seed in range(10):
        rng = np.random.default_rng(seed)
        scan, gains = _records(rng, periodic=True, noise=1e-2)
        frfs, averages = frf_export(scan, (5.0, 200.0), 400.0)
        assert averages == 4 and np.allclose(np.diff(frfs.frequencies), 4.0)
        r = scan_response(frfs, (5.0, 200.0), averages)
        assert r.periods == 0 and r.frequencies[0] == 8.0 and r.frequencies[-1] == 200.0
        want = gains[:, None] / (1.0 + 1j * r.frequencies / 10.0)
        observed += np.sum(np.abs(r.values - want) ** 2)
        stated += np.sum(2.0 * r.std**2)
    assert 0.85 < observed / stated < 1.18, observed / stated
    for averages in (None, 1):
        with pytest.raises(InputError, match="number of averages"):
            scan_response(frfs, (5.0, 200.0), averages)


def test_the_references_noise_is_stated_where_the_response_is_strong(monkeypatch):
    """The coil current measured with noise (the structure driven by the clean current): H =
    X / R errs by -H n_R / R, in proportion to the response, which the response's own noise
    does not tell. With 1 % of noise on the reference and next to none on the response, the
    observed error over the stated one is 1.02 (test 0.8-1.25); with the response's noise alone
    stated (the reference's lines between the drive's read as empty) it is 3220 (the dwell
    rig's points at its mode read 13.9 so; test above 5)."""
    import dataclasses

    import forcecal.model.frf as frf

    rng = np.random.default_rng(4)
    scan, gains = _records(rng, periodic=True, noise=1e-6)
    scan = dataclasses.replace(scan, reference=scan.reference
                               + 0.01 * rng.standard_normal(scan.reference.shape))

    def observed_over_stated() -> float:
        r = scan_response(scan, (5.0, 200.0))
        want = gains[:, None] / (1.0 + 1j * r.frequencies / 10.0)
        z = (r.values - want) / r.std
        return float(np.sqrt(np.mean(np.concatenate([z.real.ravel(), z.imag.ravel()]) ** 2)))

    stated = observed_over_stated()
    real = frf._periodic

    def response_noise_alone(f, lines, x, r, band, m, source):
        f_on, h, _, coh = real(f, lines, x, r, band, m, source)
        quiet = np.where((lines % m == 0)[None, :], r, 0.0)     # no noise between the lines
        return f_on, h, real(f, lines, x, quiet, band, m, source)[2], coh

    monkeypatch.setattr(frf, "_periodic", response_noise_alone)
    alone = observed_over_stated()
    assert 0.8 < stated < 1.25 and alone > 5.0, (stated, alone)

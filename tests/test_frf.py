"""A broadband scan's frequency responses: leakage-free on a periodic drive's lines."""

from __future__ import annotations

import numpy as np

from forcecal.frf import periods_in_record, scan_response
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

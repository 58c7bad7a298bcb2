"""The structure's transfer from its reactions to its motion, fitted over a record."""

from __future__ import annotations

import numpy as np

from forcecal.forces.reaction_transfer import ReactionTransfer, filtered, fit_reaction_transfer

FS = 5_000.0
BAND = (5.0, 200.0)
TRUE = ReactionTransfer(num=np.array([2.0e-5]), den=np.array([1.0, 0.05, -1.3]),
                        scale=2 * np.pi * BAND[1], cov=np.zeros((3, 3)), chi2=1.0)
"""Two real poles at +/- 175 Hz and a little damping: the beam's, whose reactions vanish for a
force above its first bending mode."""
VAR_Q = (2.0e-7) ** 2


def _record(seed: int, seconds: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """A reactions-only force over 5-150 Hz and the coordinate it ties, with white noise on
    the coordinate: cut from the middle of a record three times as long, so that the ends do
    not wrap."""
    rng = np.random.default_rng(seed)
    n = int(seconds * FS)
    f = np.fft.rfftfreq(3 * n, 1 / FS)
    spec = np.where((f >= 5.0) & (f <= 150.0), np.exp(2j * np.pi * rng.random(f.size)), 0)
    u = np.fft.irfft(spec, 3 * n)
    u *= 1.5 / u.std()
    q = np.fft.irfft(TRUE.response(f) * np.fft.rfft(u), 3 * n)
    cut = slice(n, 2 * n)
    return q[cut] + np.sqrt(VAR_Q) * rng.standard_normal(n), 6.0 + u[cut]


def _params(t: ReactionTransfer) -> np.ndarray:
    return np.r_[t.num, t.den[1:]]


def test_a_known_transfer_is_recovered_with_its_covariance():
    """Over 40 records cut from longer ones, every parameter's error over its stated standard
    uncertainty has an RMS of 0.75-1.3 (achieved 0.96-1.01; with the covariance halved
    1.36-1.43), and the residual's chi-square per degree of freedom is 0.85-1.15 in every
    record (achieved 0.86-1.11): the record's ends' term takes what the cut leaves (without it
    the parameters' errors reach 0.9-2.1 of the stated)."""
    z, chi2 = [], []
    for seed in range(40):
        q, u = _record(seed)
        fit = fit_reaction_transfer(q, u, FS, BAND, VAR_Q)
        assert fit is not None
        z.append((_params(fit) - _params(TRUE)) / np.sqrt(np.diag(fit.cov)))
        chi2.append(fit.chi2)
    rms = np.sqrt(np.mean(np.square(z), axis=0))
    assert np.all((0.75 < rms) & (rms < 1.3)), rms
    assert 0.85 < min(chi2) and max(chi2) < 1.15, (min(chi2), max(chi2))


def test_the_transfer_carries_a_record_through_its_response():
    """``filtered`` applies the fitted G to the reactions-only force: the coordinate it makes
    differs from the measured one by the measurement's noise alone away from the record's
    ends (0.9-1.1 of its standard deviation; achieved 0.99)."""
    q, u = _record(3)
    fit = fit_reaction_transfer(q, u, FS, BAND, VAR_Q)
    assert fit is not None
    made = filtered(u[None, :], FS, fit.response)[0]
    inner = slice(int(0.1 * FS), -int(0.1 * FS))
    ratio = np.std((made - q)[inner]) / np.sqrt(VAR_Q)
    assert 0.9 < ratio < 1.1, ratio


def test_a_band_with_too_few_lines_has_no_transfer():
    """Fewer than MIN_BINS lines in the band, or no noise to weigh them by: no transfer."""
    q, u = _record(1, seconds=0.05)
    assert fit_reaction_transfer(q, u, FS, BAND, VAR_Q) is None
    q, u = _record(1)
    assert fit_reaction_transfer(q, u, FS, BAND, 0.0) is None


def test_a_transfer_with_a_pole_at_a_real_frequency_is_refused():
    """A fit whose denominator vanishes at some frequency (an undamped pole at 160 Hz: its
    response there infinite) gives no transfer, and the probes alone carry the inertia."""
    undamped = ReactionTransfer(num=np.array([2.0e-5]), den=np.array([1.0, 0.0, 1.5625]),
                                scale=TRUE.scale, cov=np.zeros((3, 3)), chi2=1.0)
    rng = np.random.default_rng(4)
    n = int(2.0 * FS)
    f = np.fft.rfftfreq(n, 1 / FS)
    spec = np.where((f >= 5.0) & (f <= 150.0), np.exp(2j * np.pi * rng.random(f.size)), 0)
    u = np.fft.irfft(spec, n)
    u *= 1.5 / u.std()
    q = np.fft.irfft(undamped.response(f) * np.fft.rfft(u), n)
    q += np.sqrt(VAR_Q) * rng.standard_normal(n)
    assert abs(undamped.response(np.array([160.0]))[0]) > 1e10
    assert fit_reaction_transfer(q, u, FS, BAND, VAR_Q) is None


def _narrow(seed: int, seconds: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """A sweep's first seconds: the reactions-only force swept slowly over 40-45 Hz, the
    coordinate it ties with white noise, cut from a record three times as long."""
    rng = np.random.default_rng(seed)
    n = int(seconds * FS)
    t = np.arange(3 * n) / FS
    u = 1.5 * np.sin(2 * np.pi * np.cumsum(40.0 + 5.0 * np.clip(t / seconds - 1, 0, 1)) / FS)
    f = np.fft.rfftfreq(3 * n, 1 / FS)
    q = np.fft.irfft(TRUE.response(f) * np.fft.rfft(u), 3 * n)
    cut = slice(n, 2 * n)
    return q[cut] + np.sqrt(VAR_Q) * rng.standard_normal(n), 6.0 + u[cut]


def test_a_narrow_band_finds_the_output_errors_minimum():
    """On a drive that holds 40-45 Hz the Sanathanan-Koerner iterations settle away from the
    output error's minimum (a_2 13-18 % low, the static gain 0.7-1.0 % low over five records);
    the fit goes on to the minimum: the static gain within 0.5 % (achieved 0.19 % at most),
    a_2 within 10 % (achieved 3.4 %), the chi-square per degree of freedom 0.9-1.15
    (achieved 0.95-1.09)."""
    for seed in range(5):
        q, u = _narrow(seed)
        fit = fit_reaction_transfer(q, u, FS, BAND, VAR_Q)
        assert fit is not None
        ratio = _params(fit) / _params(TRUE)
        assert abs(ratio[0] - 1) < 0.005 and abs(ratio[2] - 1) < 0.10, (seed, ratio)
        assert 0.9 < fit.chi2 < 1.15, (seed, fit.chi2)

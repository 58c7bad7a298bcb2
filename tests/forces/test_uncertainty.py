"""The stated standard uncertainty of every force phasor against the virtual rig (METHOD.md
sections 6 and 7: "its stated uncertainty covers the truth as often as it claims").

The physics of a small 'paper' rig (scan of 31 points x 0.3 s, run of 0.5 s) is simulated once
per module; for every seed the scan noise and the run noise are redrawn, the spatial model is
rebuilt and the forces reconstructed. With the truth's phasors fitted at the estimate's own
fundamental, z = (estimate - truth) / stated std, for Re and Im separately, is standard normal
when the stated std is right. Over the draws of one cell (combination of forces x harmonic):

- RMS(z): sum(z^2) is chi-square with as many degrees of freedom as draws, so RMS(z) lies in
  sqrt(chi2.ppf([0.0005, 0.9995], n) / n) (99.9 % two-sided);
- the fraction with |z| <= 2 is binomial(n, 95.45 %) / n, inside binom.ppf([0.0005, 0.9995]).

Cases, each aimed at one term of the propagation (:mod:`forcecal.forces.uncertainty`):

- "nominal": the preset's noise. Gauge noise dominates the DC and F1, F2 at n = 1; the
  coordinate's noise dominates the total at n = 2, 3.
- "noisy scan": LDV noise x 10, so the shape coefficients' covariance dominates the total and
  the moment at n = 1, 2; the scan no longer resolves n = 3, which the reactions still show: its
  inertia is uncompensated and only bounded (``unresolved_inertia_bound``).
- "contradicting probe": probe s2 reads 5 % high; the sensors contradict the shape far beyond
  their noise at n = 1, 2, and only the Birge-ratio inflation of Q's uncertainty covers it.
- "quiet run": gauge and probe noise / 10, so the scan's shape error dominates even n = 3.

Then the linear propagation of one seed against a Monte Carlo of its inputs.

Achieved statistics (seeds 0..39) are written beside every bound; they were measured with
``python tests/forces/test_uncertainty.py``, which prints them all.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
import pytest
import scipy.stats

from forcecal.forces.coordinates import MISFIT_LEVEL, coordinate_map, sensor_weights
from forcecal.forces.solve import force_solve
from forcecal.forces.steady import ForceEstimate, channels_si, reconstruct
from forcecal.forces.uncertainty import combinations, shape_operators
from forcecal.model.inertia import inertia_term
from forcecal.model.relaxation import force_matrix
from forcecal.model.spatial import SpatialModel, build_spatial_model
from forcecal.records import Run
from forcecal.rig import Rig
from forcecal.signals.harmonics import fit_harmonics
from forcecal.simulate.presets import Preset, get_preset
from forcecal.simulate.virtual_rig import (
    build_model,
    measure_run,
    measure_scan,
    public_rig,
    run_truth,
    scan_response,
    simulate_response,
)

SEEDS = 40
"""Noise draws of the nominal and noisy-scan cases (80 draws per cell, 40 for the DC)."""
GAIN_SEEDS = 15
"""Draws of the contradicting-probe case (its errors are far from the noise without the
inflation)."""
QUIET_SEEDS = 20
"""Draws of the quiet-run case."""
LEVEL = 0.999
"""Two-sided probability of every chi-square and binomial bound."""
TWO_SIGMA = scipy.stats.norm.cdf(2) - scipy.stats.norm.cdf(-2)      # 95.45 %

HARMONICS = 3           # the run's harmonics the scan resolves (0..3 are kept)
COMBINATIONS = ("F1", "F2", "total", "moment_x")
LDV_FACTOR = 10.0       # the noisy scan: n = 3 rises 1.0-2.1 times above its noise (3 needed)
PROBE_GAIN = 1.05       # the contradicting probe s2
QUIET_FACTOR = 0.1      # gauge and probe noise of the quiet run
MC_DRAWS = 1000
MC_RTOL = 0.08          # achieved: largest |MC / stated - 1| = 0.044 (nominal, DC of F1; 0.034
                        # at n >= 1), 0.043 (noisy scan); MC sampling error 1/sqrt(2 N): 2.2 %
                        # (DC, N = 1000 draws), 1.6 % (n >= 1, Re and Im pooled)


# --------------------------------------------------------------------------- statistics

def rms_bounds(n: int) -> tuple[float, float]:
    """99.9 % two-sided bounds of RMS(z) over n standard normal draws."""
    lo, hi = scipy.stats.chi2.ppf([(1 - LEVEL) / 2, (1 + LEVEL) / 2], n)
    return float(np.sqrt(lo / n)), float(np.sqrt(hi / n))


def coverage_bounds(n: int) -> tuple[float, float]:
    """99.9 % two-sided bounds of the fraction of n standard normal draws with |z| <= 2."""
    lo, hi = scipy.stats.binom.ppf([(1 - LEVEL) / 2, (1 + LEVEL) / 2], n, TWO_SIGMA)
    return float(lo / n), float(hi / n)


def statistics(z: np.ndarray) -> tuple[float, float]:
    """RMS(z) and the fraction with |z| <= 2."""
    return float(np.sqrt(np.mean(z**2))), float(np.mean(np.abs(z) <= 2))


def check_two_sided(z: np.ndarray, what: str) -> None:
    """The stated std is right: RMS(z) and the 2-sigma coverage both inside their bounds."""
    rms, cov = statistics(z)
    r_lo, r_hi = rms_bounds(z.size)
    c_lo, c_hi = coverage_bounds(z.size)
    assert r_lo <= rms <= r_hi, (f"{what}: RMS(z) = {rms:.3f} over {z.size} draws, outside "
                                 f"[{r_lo:.3f}, {r_hi:.3f}] (observed/stated)")
    assert c_lo <= cov <= c_hi, (f"{what}: {cov:.1%} of {z.size} draws have |z| <= 2, outside "
                                 f"[{c_lo:.1%}, {c_hi:.1%}]")


def check_covers(z: np.ndarray, what: str) -> None:
    """The stated std covers the error (it may be conservative: a bound, a Birge ratio)."""
    rms, cov = statistics(z)
    r_hi = rms_bounds(z.size)[1]
    c_lo = coverage_bounds(z.size)[0]
    assert rms <= r_hi, (f"{what}: RMS(z) = {rms:.3f} over {z.size} draws, above {r_hi:.3f} "
                         "(observed/stated)")
    assert cov >= c_lo, (f"{what}: only {cov:.1%} of {z.size} draws have |z| <= 2, below "
                         f"{c_lo:.1%}")


# --------------------------------------------------------------------------- the virtual rig

def small_paper() -> Preset:
    """The 'paper' rig with a coarser, shorter scan and a shorter run."""
    p = get_preset("paper")
    return dataclasses.replace(
        p, scan=dataclasses.replace(p.scan, n_points=31, record=0.3),
        runs=(dataclasses.replace(p.runs[0], duration=0.5),))


def with_noise(preset: Preset, **factors: float) -> Preset:
    """``preset`` with some noise stds scaled (``ldv=5`` multiplies the LDV noise by 5)."""
    noise = preset.noise
    return dataclasses.replace(preset, noise=dataclasses.replace(
        noise, **{k: getattr(noise, k) * f for k, f in factors.items()}))


@dataclass
class Case:
    """Normalized errors of one case over its seeds."""

    z: list[np.ndarray] = field(default_factory=list)        # each (n_c, H+1, 2)
    with_inertia: list[np.ndarray] = field(default_factory=list)
    kept: list[np.ndarray] = field(default_factory=list)
    chi2: list[np.ndarray] = field(default_factory=list)
    inputs: list[tuple[SpatialModel, Run, ForceEstimate]] = field(default_factory=list)

    def add(self, z: np.ndarray, est: ForceEstimate, model: SpatialModel, run: Run,
            keep_inputs: bool = False) -> None:
        self.z.append(z)
        self.with_inertia.append(est.with_inertia)
        self.kept.append(est.kept)
        self.chi2.append(est.coordinates.chi2)
        if keep_inputs:
            self.inputs.append((model, run, est))

    def cell(self, c: str, n: int) -> np.ndarray:
        """The draws of combination ``c`` at harmonic n: Re and Im (Re only for the DC)."""
        z = np.array(self.z)[:, COMBINATIONS.index(c), n, : 1 if n == 0 else 2].ravel()
        assert np.all(np.isfinite(z)), f"{c} at n = {n} is not estimated in every draw"
        return z


@dataclass
class Draws:
    rig: Rig
    nominal: Case
    noisy_scan: Case
    gain: Case
    quiet: Case


def normalized_errors(rig: Rig, est: ForceEstimate, true_force: np.ndarray,
                      fs: float) -> np.ndarray:
    """(n_c, H+1, 2) z of Re and Im of every combination; NaN where nothing is estimated.

    The truth is fitted on the estimate's own basis: the same fundamental, the same window.
    """
    names, combo = combinations(rig)
    assert names == COMBINATIONS
    h = len(est.harmonics) - 1
    truth = combo @ fit_harmonics(true_force, fs, est.f0, h).phasors
    assert est.combination is not None and est.combination_std is not None
    err = est.combination - truth
    std = np.where(est.combination_std > 0, est.combination_std, np.nan)
    return np.stack([err.real / std, err.imag / std], axis=-1)


def simulate_draws() -> Draws:
    """Simulate the physics once, then redraw the noise of scan and run for every seed."""
    preset = small_paper()
    noisy_scan, quiet = with_noise(preset, ldv=LDV_FACTOR), with_noise(
        preset, gauge=QUIET_FACTOR, probe=QUIET_FACTOR)
    fe = build_model(preset)
    spec = preset.runs[0]
    rig = public_rig(preset)
    scan_r = scan_response(preset, fe)
    run_r = simulate_response(preset, spec.drives, spec.gap, spec.duration, fe)
    true_force = run_truth(preset, fe, run_r).pole_force
    draws = Draws(rig, Case(), Case(), Case(), Case())

    def add(case: Case, model: SpatialModel, run: Run, keep: bool = False) -> None:
        est = reconstruct(rig, model, run)
        case.add(normalized_errors(rig, est, true_force, preset.fs), est, model, run, keep)

    for seed in range(SEEDS):
        rng = np.random.default_rng(seed)
        model = build_spatial_model(rig, measure_scan(preset, fe, scan_r, rng))
        run = measure_run(preset, spec, fe, run_r, rng)
        add(draws.nominal, model, run, keep=seed == 0)
        noisy_model = build_spatial_model(rig, measure_scan(noisy_scan, fe, scan_r, rng))
        add(draws.noisy_scan, noisy_model, run, keep=True)
        if seed < GAIN_SEEDS:
            channels = dict(run.channels)
            channels["s2"] = PROBE_GAIN * channels["s2"]
            add(draws.gain, model, dataclasses.replace(run, channels=channels))
        if seed < QUIET_SEEDS:
            add(draws.quiet, model, measure_run(quiet, spec, fe, run_r, rng))
    return draws


@pytest.fixture(scope="module")
def draws() -> Draws:
    return simulate_draws()


# --------------------------------------------------------------------------- coverage

# Achieved RMS(z) / fraction |z| <= 2 of the nominal case, seeds 0..39 (bounds: DC, 40 draws:
# RMS in [0.65, 1.38], fraction >= 82.5 %; n >= 1, 80 draws: RMS in [0.75, 1.27], fraction
# >= 86.2 %):
#            n = 0        n = 1        n = 2        n = 3
# F1         0.86/98 %    0.98/96 %    0.97/96 %    1.02/94 %
# F2         0.82/98 %    1.04/96 %    1.12/94 %    0.98/95 %
# total      0.80/98 %    1.17/91 %    1.07/95 %    0.98/95 %
# moment_x   0.77/98 %    1.16/88 %    1.12/94 %    0.98/95 %
NOMINAL_CELLS = [(c, n) for c in COMBINATIONS for n in range(HARMONICS + 1)]


@pytest.mark.parametrize(("c", "n"), NOMINAL_CELLS, ids=[f"{c}-n{n}" for c, n in NOMINAL_CELLS])
def test_coverage_nominal(draws, c, n):
    """Every force, the total and the moment at every kept harmonic: the stated std is the
    scatter (gauge noise: DC, F1/F2 at n = 1; coordinate noise: total at n = 2, 3)."""
    assert all(k[: HARMONICS + 1].all() and not k[HARMONICS + 1:].any()
               for k in draws.nominal.kept)
    check_two_sided(draws.nominal.cell(c, n), f"nominal {c} at n = {n}")


# Pooled over n = 0..3 (280 draws: RMS in [0.86, 1.14], fraction in [90.7 %, 98.9 %]);
# achieved: F1 0.97/96 %, F2 1.02/95 %, total 1.04/94 %, moment_x 1.05/93 %
@pytest.mark.parametrize("c", COMBINATIONS)
def test_coverage_nominal_pooled(draws, c):
    """The same, pooled over the harmonics of one combination (the harmonics' errors are
    independent: different noise frequencies, separate shape fits), with tighter bounds."""
    z = np.concatenate([draws.nominal.cell(c, n) for n in range(HARMONICS + 1)])
    check_two_sided(z, f"nominal {c}, n = 0..{HARMONICS} pooled")


# Noisy scan, shape term about 90 % of the variance of the total and the moment; achieved
# (80 draws: RMS in [0.75, 1.27], fraction >= 86.2 %); the inflation for contradicting
# sensors fires in half of these seeds and lowers the total's and the moment's RMS (see
# test_birge_inflation_is_rare_for_sound_sensors):
#            n = 1        n = 2
# F1         1.00/94 %    1.05/95 %
# F2         1.07/90 %    0.89/99 %
# total      0.90/96 %    0.87/99 %
# moment_x   0.94/94 %    0.84/98 %
SHAPE_CELLS = [(c, n) for c in COMBINATIONS for n in (1, 2)]


@pytest.mark.parametrize(("c", "n"), SHAPE_CELLS, ids=[f"{c}-n{n}" for c, n in SHAPE_CELLS])
def test_coverage_shape_dominated(draws, c, n):
    """With a noisy scan the shape coefficients' covariance, propagated through
    ``shape_jacobian``, is what the total's and the moment's stated std are made of."""
    assert all(w[n] for w in draws.noisy_scan.with_inertia)
    check_two_sided(draws.noisy_scan.cell(c, n), f"noisy scan {c} at n = {n}")


# Achieved (80 draws: RMS <= 1.27, fraction >= 86.2 %): F1 0.23/100 %, F2 0.23/100 % (the
# floor, the whole mass at the probes' noise, dominates the single forces), moment_x
# 0.97/100 %, total 1.01/100 % (the total was at 1.36 while the bound was the whole mass moving
# with the probes' RMS motion; it is now the nearest shape's inertia from the probes' own
# phasors)
@pytest.mark.parametrize("c", ["F1", "F2", "moment_x", "total"])
def test_unresolved_harmonic_is_covered(draws, c):
    """n = 3 shows in the reactions but the noisy scan does not resolve it: its inertia is left
    in the forces and only its bound enters the stated std, which must cover the error."""
    n = HARMONICS
    case = draws.noisy_scan
    assert all(k[n] and not w[n] for k, w in zip(case.kept, case.with_inertia, strict=True))
    check_covers(case.cell(c, n), f"unresolved harmonic {n}: {c}")


# Probe s2 reads 5 % high (15 seeds, n = 1, 2 pooled, 60 draws: RMS <= 1.28, fraction
# >= 85.0 %); achieved: F1 0.89/100 %, F2 1.03/100 %, total 0.96/100 %, moment_x
# 0.97/100 %
@pytest.mark.parametrize("c", COMBINATIONS)
def test_contradicting_probe_is_covered(draws, c):
    """When the probes contradict the shape beyond their noise, Q is only known to within
    that misfit (Birge ratio), and the stated std must say so."""
    dof = 2 * (len(draws.rig.sensors) - 1)
    threshold = scipy.stats.chi2.ppf(MISFIT_LEVEL, dof) / dof
    assert all(w[1] and w[2] for w in draws.gain.with_inertia)    # chi2 columns are n = 1, 2
    assert np.all(np.array(draws.gain.chi2)[:, :2] > threshold)   # both contradict the shape
    z = np.concatenate([draws.gain.cell(c, n) for n in (1, 2)])
    check_covers(z, f"probe s2 x {PROBE_GAIN}: {c}")


# Achieved: Q inflated at n = 1 in 0 of 40 nominal seeds and 0 of 40 with the noisy scan (9
# and 33 of 40 while the misfit test left out the fitted shape's own uncertainty at the
# sensors); bound (binomial, 1 %, 99.9 %): 4
def test_birge_inflation_is_rare_for_sound_sensors(draws):
    """The nominal probes measure the true motion: the inflation for contradicting sensors
    should fire about as often as its significance level says (1 - MISFIT_LEVEL)."""
    dof = 2 * (len(draws.rig.sensors) - 1)
    threshold = scipy.stats.chi2.ppf(MISFIT_LEVEL, dof) / dof
    assert all(w[1] for w in draws.nominal.with_inertia)           # chi2 column 0 is n = 1
    fired = np.sum(np.array(draws.nominal.chi2)[:, 0] > threshold)
    most = scipy.stats.binom.ppf((1 + LEVEL) / 2, SEEDS, 1 - MISFIT_LEVEL)
    assert fired <= most, f"Q inflated at n = 1 in {fired} of {SEEDS} seeds (at most {most:g})"


# Quiet run, 20 seeds (40 draws: RMS in [0.65, 1.38], fraction >= 82.5 %); achieved: total
# at n = 3 1.14/95 % (moment 1.09/95 %, F1 1.27/90 %, F2 1.04/98 %). Before the weak harmonic
# was given the strongest one's order and the covariance the choice of order, the total was
# 2.07/75 %: GCV picked order 3 or 4 at n = 3 (scan signal-to-noise about 8), whose truncated
# shape put the coupling-to-probe ratio 7 % low, a bias no conditional covariance holds.
def test_shape_term_at_weakest_harmonic(draws):
    """When the run is quiet, the scan's shape error dominates even the weakest resolved
    harmonic; there the stated std is still the scatter."""
    assert all(w[HARMONICS] for w in draws.quiet.with_inertia)
    check_two_sided(draws.quiet.cell("total", HARMONICS), "quiet run total at n = 3")


# --------------------------------------------------------------------------- Monte Carlo

def monte_carlo(rig: Rig, model: SpatialModel, run: Run, est: ForceEstimate, n_draws: int,
                rng: np.random.Generator) -> np.ndarray:
    """(n_draws + 1, n_c, H+1) complex: the combinations recomputed from perturbed inputs
    (draw 0 unperturbed), for the DC and every harmonic with a shape.

    Shape coefficients (Re and Im) are drawn from their covariance, sensor and gauge phasors
    from their stds; every draw goes through the estimate's own formulas: the coordinate map,
    the inertia term, the force solve.
    """
    _, combo = combinations(rig)
    h = len(est.harmonics) - 1
    sig = channels_si(rig, run)
    gauges = fit_harmonics(np.stack([sig[g] for g in rig.gauge_names]), run.fs, est.f0, h,
                           t0=run.t0)
    sensors = fit_harmonics(np.stack([sig[s] for s in rig.sensor_names]), run.fs, est.f0, h,
                            t0=run.t0)
    pinv = np.linalg.pinv(force_matrix(rig))
    ops = shape_operators(model, rig)
    w0 = 2 * np.pi * est.f0
    n_g, n_s = len(rig.gauges), len(rig.sensors)
    out = np.zeros((n_draws + 1, len(combo), h + 1), dtype=complex)

    def noise(std: np.ndarray, real: bool = False) -> np.ndarray:
        d = rng.standard_normal((n_draws, len(std)))
        if not real:
            d = d + 1j * rng.standard_normal((n_draws, len(std)))
        return np.vstack([np.zeros(len(std)), std * d])

    r0 = gauges.phasors[:, 0].real + noise(gauges.phasor_std[:, 0], real=True)
    out[:, :, 0] = (combo @ force_solve(pinv, np.zeros((n_g, n_draws + 1)), r0.T)).T
    for k, n in enumerate(model.harmonics):
        n = int(n)
        fit = model.shapes[k]
        nf = len(fit.coefficients)
        cov = fit.coefficient_covariance
        dp = (rng.multivariate_normal(np.zeros(nf), cov, n_draws, method="eigh")
              + 1j * rng.multivariate_normal(np.zeros(nf), cov, n_draws, method="eigh"))
        p = fit.coefficients + np.vstack([np.zeros(nf), dp])
        s = sensors.phasors[:, n] + noise(sensors.phasor_std[:, n])
        r = gauges.phasors[:, n] + noise(gauges.phasor_std[:, n])
        w = sensor_weights(sensors.phasor_std[:, n])
        assert s.shape == (n_draws + 1, n_s) and r.shape == (n_draws + 1, n_g)
        for d in range(n_draws + 1):
            gain, _ = coordinate_map(ops.at_sensors[k][0] @ p[d], w)
            j = inertia_term(ops.couplings[k][0] @ p[d], complex(gain @ s[d]), n * w0)
            out[d, :, n] = combo @ force_solve(pinv, j, r[d])
    return out


def birge_free(rig: Rig, est: ForceEstimate) -> bool:
    """Whether no harmonic's Q uncertainty was inflated for contradicting sensors."""
    dof = 2 * (len(rig.sensors) - 1)
    return bool(np.all(est.coordinates.chi2 <= scipy.stats.chi2.ppf(MISFIT_LEVEL, dof) / dof))


@pytest.mark.parametrize("case", ["nominal", "noisy_scan"])
def test_propagation_matches_monte_carlo(draws, case):
    """The linear propagation of one seed against a Monte Carlo of its inputs (GUM S1):
    MC_DRAWS draws, std of Re and Im pooled as the stated std is (Re only for the DC)."""
    rig = draws.rig
    model, run, est = next(i for i in getattr(draws, case).inputs if birge_free(rig, i[2]))
    mc = monte_carlo(rig, model, run, est, MC_DRAWS, np.random.default_rng(7))
    shaped = [0, *(int(n) for n in model.harmonics)]
    assert est.combination is not None and est.combination_std is not None
    np.testing.assert_allclose(mc[0][:, shaped], est.combination[:, shaped], rtol=1e-9,
                               atol=1e-12)
    var = 0.5 * (mc[1:].real.var(axis=0) + mc[1:].imag.var(axis=0))
    var[:, 0] = mc[1:, :, 0].real.var(axis=0)
    ratio = np.sqrt(var[:, shaped]) / est.combination_std[:, shaped]
    assert np.all(np.abs(ratio - 1) <= MC_RTOL), (
        f"{case}: Monte Carlo std / stated std per combination (rows {COMBINATIONS}) and "
        f"harmonic {shaped}:\n{np.array2string(ratio, precision=3)}")


# --------------------------------------------------------------------------- report

def main() -> None:
    """Print every statistic the tests check (``python tests/forces/test_uncertainty.py``)."""
    d = simulate_draws()

    def line(label: str, z: np.ndarray) -> str:
        rms, cov = statistics(z)
        return f"{label}: {rms:.2f}/{cov:.0%} ({z.size} draws)"

    for name, case, cells in (("nominal", d.nominal, NOMINAL_CELLS),
                              ("noisy scan", d.noisy_scan, SHAPE_CELLS)):
        print(name)
        for c in COMBINATIONS:
            print("  ", c, "; ".join(line(f"n={n}", case.cell(c, n))
                                     for cc, n in cells if cc == c))
    print("nominal pooled", "; ".join(line(c, np.concatenate(
        [d.nominal.cell(c, n) for n in range(HARMONICS + 1)])) for c in COMBINATIONS))
    print("unresolved n=3", "; ".join(line(c, d.noisy_scan.cell(c, HARMONICS))
                                      for c in COMBINATIONS))
    print("probe gain", "; ".join(line(c, np.concatenate([d.gain.cell(c, n) for n in (1, 2)]))
                                  for c in COMBINATIONS))
    print("quiet n=3", "; ".join(line(c, d.quiet.cell(c, HARMONICS)) for c in COMBINATIONS))
    for case in ("nominal", "noisy_scan"):
        model, run, est = next(i for i in getattr(d, case).inputs if birge_free(d.rig, i[2]))
        mc = monte_carlo(d.rig, model, run, est, MC_DRAWS, np.random.default_rng(7))
        shaped = [0, *(int(n) for n in model.harmonics)]
        var = 0.5 * (mc[1:].real.var(axis=0) + mc[1:].imag.var(axis=0))
        var[:, 0] = mc[1:, :, 0].real.var(axis=0)
        assert est.combination_std is not None
        print("MC", case, np.round(np.sqrt(var[:, shaped]) / est.combination_std[:, shaped], 3))
    for n in (1, 80, 40, 60, 280):
        print(n, "rms", np.round(rms_bounds(n), 3), "cov", np.round(coverage_bounds(n), 3))


if __name__ == "__main__":
    main()

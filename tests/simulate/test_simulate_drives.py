"""Broadband drives, the lagging magnet, the cores whose flux diffuses, and the rigs that use them.

The waveforms against their own definitions (instantaneous frequency, lines, band, RMS), the
steady drives against records computed before broadband drives existed, the eddy-current lag
against 1 / (1 + j w tau), a solid core's discretised diffusion against the slab's
tanh(sqrt(s tau)) / sqrt(s tau) and its simulated force against that diffusion's response, a
broadband record against a longer lead and against the periodic steady state, and the swept
rig's truth against its balance law and its files.
"""

from __future__ import annotations

import dataclasses
import json
import math
import tomllib

import numpy as np
import pytest
import scipy.signal

from forcecal.errors import InputError
from forcecal.io.uff import read_scan_uff
from forcecal.simulate import presets
from forcecal.simulate.beam import hermite_row
from forcecal.simulate.core import diffusion_response, diffusion_step
from forcecal.simulate.export import _diffusion_facts, write_simulation
from forcecal.simulate.integrate import _Stepper, integrate, lead_time
from forcecal.simulate.magnet import KNEE, Drive
from forcecal.simulate.physics import _magnets_at
from forcecal.simulate.presets import BeamSpec, NoiseSpec, RunSpec, ScanSpec, get_preset
from forcecal.simulate.virtual_rig import build_model, record_run, scan_offsets, scan_response
from forcecal.simulate.waveforms import BandLimitedRandom, MultiTone, PeriodicChirp, SweptSine

FS = 10_000.0
SWEEP_FREQ_ATOL = 0.3      # Hz, Hilbert instantaneous frequency vs the linear law
LINE_RTOL = 1e-9           # multi-tone lines vs their amplitudes (exact DFT bins)
RANDOM_FLAT_RTOL = 1e-3    # random lines' magnitudes (linear interpolation droop: 2e-5)
RMS_RTOL = 1e-3            # random RMS vs requested
EDDY_GAIN_RTOL = 1.5e-3    # trapezoidal lag vs 1/(1 + j w tau): warping (w dt / 2)^2 / 3
EDDY_PHASE_ATOL = 1.5e-3   # rad
SLAB_RTOL = 5e-4           # 20 linear elements vs the slab's closed form up to w tau_d = 5
SETTLED_RTOL = 2e-3        # a broadband record vs the same with a doubled lead / steady state
BALANCE_RTOL = 1e-6        # rigid-body balance residual relative to the reaction RMS


def quiet(preset):
    """The preset without measurement noise."""
    return dataclasses.replace(preset, noise=NoiseSpec(0.0, 0.0, 0.0, 0.0, 0.0, 0.0))


def lines(x: np.ndarray, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """(frequencies [Hz], complex amplitudes) of a record of whole periods: X_k = A e^{j phi}
    for a term A cos(2 pi f t + phi)."""
    spec = np.fft.rfft(x) * 2 / len(x)
    return np.fft.rfftfreq(len(x), 1 / fs), spec


@pytest.fixture(scope="module")
def sweep_rig():
    preset = get_preset("sweep")
    return preset, build_model(preset)


# --------------------------------------------------------------------------------------------
# the waveforms


def test_sweep_follows_its_linear_frequency_law():
    wave = SweptSine(1.0, 20.0, 120.0, 2.0, lead_in=0.5)
    fs = 5000.0
    t = np.arange(int(-0.6 * fs), int(2.6 * fs)) / fs
    x = wave.value(t)
    assert np.all(x[t < -0.5] == 0.0)                        # silent before the lead-in
    phase = np.unwrap(np.angle(scipy.signal.hilbert(x)))
    f_inst = np.gradient(phase, t) / (2 * np.pi)
    inside = (t > 0.1) & (t < 1.9)
    np.testing.assert_allclose(f_inst[inside], 20.0 + 50.0 * t[inside], atol=SWEEP_FREQ_ATOL)
    # held at f_stop after the sweep, at f_start during the lead-in (rising zero crossings)
    for lo, hi, f in ((2.1, 2.5, 120.0), (-0.25, 0.0, 20.0)):
        seg, ts = x[(t > lo) & (t < hi)], t[(t > lo) & (t < hi)]
        k = np.flatnonzero((seg[:-1] < 0) & (seg[1:] >= 0))
        crossings = ts[k] - seg[k] * (ts[k + 1] - ts[k]) / (seg[k + 1] - seg[k])
        np.testing.assert_allclose(1 / np.diff(crossings), f, rtol=1e-3)
    np.testing.assert_allclose(np.abs(x[(t > -0.25) & (t < 2.5)]).max(), 1.0, rtol=1e-3)
    stopped = dataclasses.replace(wave, after="stop").value(t)
    assert np.all(stopped[t > 2.0] == 0.0) and np.array_equal(stopped[t <= 2.0], x[t <= 2.0])
    np.testing.assert_allclose(wave.instantaneous_frequency([-1.0, 1.0, 3.0]), [20, 70, 120])


def test_periodic_chirp_repeats_without_leakage_and_without_a_jump():
    wave = PeriodicChirp(0.3, 5.0, 200.0, 0.25)
    fs = 10_000.0
    t = np.arange(int(4 * 0.25 * fs)) / fs + 0.37
    x = wave.value(t)
    np.testing.assert_allclose(wave.value(t + 0.25), x, atol=1e-9)
    freqs, amps = lines(x, fs)
    power = np.abs(amps) ** 2
    on_lines = np.isclose(freqs * 0.25, np.round(freqs * 0.25), atol=1e-9)
    assert power[~on_lines].sum() < 1e-20 * power.sum()          # leakage: rounding only
    band = (freqs >= 4.0) & (freqs <= 205.0)
    assert power[band].sum() > 0.98 * power.sum()
    # continuous where one sweep ends and the next begins (only the frequency jumps)
    ends = wave.value(np.array([0.25 - 1e-7, 0.25]))
    assert abs(ends[0] - ends[1]) < 1e-4


def test_multi_tone_lines():
    wave = MultiTone((7.0, 31.0, 113.0), (0.2, 0.05, 0.1), (0.3, -1.2, 2.0))
    fs = 4000.0
    t = np.arange(int(fs)) / fs
    freqs, amps = lines(wave.value(t), fs)
    for f, a, ph in zip(wave.frequencies, wave.amplitudes, wave.phases, strict=True):
        k = int(np.argmin(np.abs(freqs - f)))
        np.testing.assert_allclose(amps[k], a * np.exp(1j * (ph - np.pi / 2)), atol=LINE_RTOL)
    others = np.delete(np.abs(amps), [7, 31, 113])
    assert others.max() < LINE_RTOL


def test_band_limited_random_band_rms_and_gaussian():
    wave = BandLimitedRandom(0.07, 5.0, 150.0, period=2.0, seed=3)
    fs = 2000.0
    t = np.arange(int(2.0 * fs)) / fs
    x = wave.value(t)
    np.testing.assert_allclose(np.sqrt(np.mean(x**2)), 0.07, rtol=RMS_RTOL)
    freqs, amps = lines(x, fs)
    band = (freqs >= 5.0) & (freqs <= 150.0)
    assert band.sum() == len(wave.lines) == 291
    mags = np.abs(amps[band])
    np.testing.assert_allclose(mags, np.mean(mags), rtol=RANDOM_FLAT_RTOL)   # flat
    assert np.sum(np.abs(amps[~band]) ** 2) < 1e-8 * np.sum(mags**2)
    z = x / x.std()
    assert abs(np.mean(z**4) - 3.0) < 0.3 and abs(np.mean(z**3)) < 0.2      # Gaussian
    again = BandLimitedRandom(0.07, 5.0, 150.0, period=2.0, seed=3).value(t)
    assert np.array_equal(again, x)                                          # deterministic
    assert not np.allclose(BandLimitedRandom(0.07, 5.0, 150.0, 2.0, seed=4).value(t), x)
    np.testing.assert_allclose(wave.value(t + 2.0), x, atol=1e-12)           # periodic


def _stepper_case(name: str) -> tuple[presets.Preset, tuple[Drive, ...]]:
    """The preset and the drives of a compiled-stepper case: its first run's, or on the
    saturating magnet its most saturated run's; ``paper-saturating`` is the paper's voltage
    drive on that magnet (the saturated iron in the voltage branch)."""
    if name == "paper-saturating":
        preset = get_preset("paper")
        magnet = dataclasses.replace(preset.magnets[0],
                                     saturation=get_preset("saturation").magnets[0].saturation)
        return dataclasses.replace(preset, magnets=(magnet,)), preset.runs[0].drives
    preset = get_preset(name)
    if name == "saturation":
        return preset, max(preset.runs, key=lambda r: r.drives[0].dc / r.gap).drives
    return preset, preset.runs[0].drives


@pytest.mark.parametrize("name", ["sweep", "two-coil", "plate", "solid", "saturation",
                                  "paper-saturating"])
def test_the_compiled_stepper_keeps_newmark_and_the_magnetic_circuit(name):
    """Every kept step of the compiled time loop satisfies the modal equations of motion, the
    trapezoidal rule, and each coil's circuit (an imposed current, through the core's eddy lag
    on the sweep rig or its diffusion on the solid one, or an imposed voltage on the
    plate's; the iron's reluctance at the step's flux where it saturates)."""
    preset, drives = _stepper_case(name)       # a sweep, steady currents, a steady voltage
    model = build_model(preset)
    dt = 1e-4
    st = _Stepper(model, preset.magnets, drives, dt, model.beta)
    state = st.static_state(-0.1)
    _, forces, rec = st.run(-0.1, 2000, *state, keep_every=1)
    assert rec is not None
    np.testing.assert_array_equal(rec["f"], forces)
    lhs = rec["qdd"] + st.c[:, None] * rec["qd"] + st.w2[:, None] * rec["q"]
    rhs = st.modal_force @ rec["f"]
    scale = np.abs(rhs).max()
    assert np.abs(lhs - rhs).max() < 1e-9 * scale                     # equations of motion
    for x, dx in (("q", "qd"), ("qd", "qdd")):
        step = np.diff(rec[x], axis=1) - dt / 2 * (rec[dx][:, 1:] + rec[dx][:, :-1])
        assert np.abs(step).max() < 1e-9 * np.abs(rec[x]).max()       # trapezoidal rule
    np.testing.assert_allclose(rec["f"], rec["lam"] ** 2 * np.array(st.fscale)[:, None],
                               rtol=1e-12)
    gaps = st.S @ (st.static_gap[:, None] - st.pole_modal @ rec["q"])
    # the B-H curve of the magnet's docstring, |B| / B_s = |lambda| / (N A B_s)
    iron = np.array(st.iron)[:, None] * (1 + (np.abs(rec["lam"]) * np.array(st.sat)[:, None])
                                         ** KNEE)
    if "satur" in name:
        assert iron.max() > 1.5 * max(st.iron)                       # well into saturation
    rel = (gaps + iron) / np.array(st.mu_a)[:, None]
    magnetising = rec["lam"] * rel / np.array(st.turns2)[:, None]
    for m, d in enumerate(drives):
        if d.voltage_driven:                                          # lam' = v - R i
            np.testing.assert_allclose(magnetising[m], rec["i"][m], rtol=1e-9)
            dlam = np.diff(rec["lam"][m])
            emf = dt / 2 * ((rec["d"][m, 1:] + rec["d"][m, :-1])
                            - st.res[m] * (rec["i"][m, 1:] + rec["i"][m, :-1]))
            np.testing.assert_allclose(dlam, emf, atol=1e-9 * np.abs(rec["lam"][m]).max())
            continue
        np.testing.assert_allclose(rec["i"][m], rec["d"][m], rtol=1e-15)
        tau = st.eddy[m]
        if preset.magnets[m].core != "lag":
            np.testing.assert_allclose(magnetising[m], diffused(preset.magnets[m], dt,
                                                                d.value(-0.1), rec["d"][m]),
                                       rtol=1e-9)
            assert np.abs(magnetising[m] - rec["i"][m]).max() > 1e-2 * np.abs(
                rec["i"][m] - d.dc).max()
        elif tau == 0:
            np.testing.assert_allclose(magnetising[m], rec["i"][m], rtol=1e-9)
        else:                               # tau i_m' + i_m = i by the trapezoidal rule
            im = magnetising[m]
            lag = tau * np.diff(im) / dt + (im[1:] + im[:-1]) / 2
            np.testing.assert_allclose(lag, (rec["i"][m, 1:] + rec["i"][m, :-1]) / 2,
                                       rtol=1e-9)
            assert np.abs(im - rec["i"][m]).max() > 1e-3 * np.abs(rec["i"][m] - d.dc).max()


def diffused(magnet, dt, start, drive):
    """The magnetising current of a diffusing core, its nodes stepped here from rest at the
    current ``start`` through the coil currents ``drive`` (one per step)."""
    a, b_old, b_new, c, c_new = diffusion_step(magnet.core_nodes, magnet.diffusion_time, dt)
    u = np.full(magnet.core_nodes, start)
    out, last = [], start
    for i in drive:
        u = a @ u + b_old * last + b_new * i
        out.append(c @ u + c_new * i)
        last = i
    return np.array(out)


def test_a_waveform_replaces_the_sine():
    with pytest.raises(ValueError, match="ac = 0"):
        Drive("current", 0.6, 0.1, 10.0, waveform=MultiTone((10.0,), (0.1,)))
    drive = Drive("current", 0.6, 0.0, 10.0, waveform=MultiTone((10.0,), (0.1,)))
    assert drive.scaled(2.0).waveform == MultiTone((10.0,), (0.2,))


# --------------------------------------------------------------------------------------------
# steady drives are computed as they always were

# (sample, pole force F1 [N], u at DOF 60 [m], last coil's current [A]) of the first 0.05 s of
# each preset's first run, computed before broadband drives and eddy currents existed
BEFORE = {
    "paper": [(0, 7.2526848202556815, 5.000700717456577e-05, 0.8509058138714282),
              (123, 11.740167294944598, 8.389643716007791e-05, 1.0473016064001188),
              (499, 7.2445536948877205, 4.9949489303414395e-05, 0.850475759114253)],
    "two-coil": [(0, 8.718694390648825, 2.8571166033276206e-05, 0.2),
                 (123, 21.62441602797313, 8.513483937178539e-05, 0.2999710794010704),
                 (499, 8.643693425221366, 2.8309202882593622e-05, 0.1991823153762411)],
}


@pytest.mark.parametrize("name", sorted(BEFORE))
def test_steady_records_are_unchanged(name):
    """The values a steady preset gave before the new drives, to rounding: the modal model's
    products and eigensolutions round differently from one BLAS build, thread count or
    NumPy/SciPy release to another (one unit in the last place was seen on one build, 6e-9
    relative after a library update), far below a change of the physics: a time step 0.1 %
    shorter moves them by up to 8.6e-4, a damping ratio 1 % higher by up to 2.3e-5."""
    preset = get_preset(name)
    r = integrate(build_model(preset), preset.magnets, preset.runs[0].drives, preset.fs, 0.05)
    now = np.array([(k, float(r.pole_force[0, k]), float(r.u[60, k]), float(r.current[-1, k]))
                    for k, *_ in BEFORE[name]])
    np.testing.assert_allclose(now, np.array(BEFORE[name]), rtol=1e-7, atol=0)


def test_the_existing_presets_have_no_lagging_core_and_no_waveform():
    for name in ("paper", "resonance", "campaign", "plate", "body", "two-coil", "tilt"):
        preset = get_preset(name)
        assert all(m.eddy_time == 0.0 for m in preset.magnets)
        drives = [d for s in preset.scans for d in s.drives]
        drives += [d for r in preset.runs for d in r.drives]
        assert all(d.waveform is None for d in drives) and preset.band is None


# --------------------------------------------------------------------------------------------
# the eddy-current lag


def fundamental(x: np.ndarray, t: np.ndarray, f: float) -> np.ndarray:
    """Complex amplitude at f of every row of x (least squares on DC and 3 harmonics)."""
    w = 2 * np.pi * f * t
    basis = np.column_stack([np.ones_like(t)] + [g(n * w) for n in (1, 2, 3)
                                                 for g in (np.cos, np.sin)])
    coef = np.linalg.lstsq(basis, np.atleast_2d(x).T, rcond=None)[0]
    return coef[1] - 1j * coef[2]


@pytest.fixture(scope="module")
def stiff_rig(sweep_rig):
    """The sweep rig on a beam and gauges 10^4 times stiffer: the gaps stay put."""
    preset, _ = sweep_rig
    stiff = dataclasses.replace(preset, beam=BeamSpec(youngs_modulus=210e13,
                                                      gauge_stiffness=2e13))
    return stiff, build_model(stiff)


@pytest.mark.parametrize("f", [40.0, 160.0])
def test_eddy_currents_lag_the_force_by_the_first_order_law(stiff_rig, f):
    preset, model = stiff_rig
    (magnet,) = _magnets_at(preset, 1.0e-3)
    tau = magnet.eddy_time
    assert tau == 0.5e-3
    ratios = []
    for m in (dataclasses.replace(magnet, eddy_time=0.0), magnet):
        r = integrate(model, (m,), (Drive("current", 0.6, 0.1, f),), FS, 0.25)
        force, i2 = fundamental(np.vstack([r.pole_force.sum(0), r.current[0] ** 2]), r.t, f)
        ratios.append(force / i2)
    assert np.ptp(r.gap) < 1e-5 * 1.0e-3                     # a fixed gap
    h = ratios[1] / ratios[0]
    expected = 1 / (1 + 2j * np.pi * f * tau)
    np.testing.assert_allclose(abs(h), abs(expected), rtol=EDDY_GAIN_RTOL)
    np.testing.assert_allclose(np.angle(h), -math.atan(2 * np.pi * f * tau),
                               atol=EDDY_PHASE_ATOL)
    np.testing.assert_allclose(magnet.eddy_response(f), expected)
    assert -np.angle(h) > 0.1                                 # the lag matters


def test_eddy_currents_need_a_current_drive(sweep_rig):
    preset, model = sweep_rig
    with pytest.raises(ValueError, match="current drive"):
        integrate(model, preset.magnets, (Drive("voltage", 2.0, 1.0, 20.0),), FS, 0.01)
    with pytest.raises(ValueError, match="eddy_time"):
        dataclasses.replace(preset.magnets[0], eddy_time=-1e-3)


def slab(z):
    """``tanh(sqrt(z)) / sqrt(z)``: the field's mean in a slab, its faces driven (z != 0)."""
    r = np.sqrt(np.asarray(z, dtype=complex))
    return np.tanh(r) / r


def test_the_core_diffusion_converges_to_the_slab():
    """The discretised diffusion's response against the slab's closed form up to
    w tau_d = 5: within SLAB_RTOL at 20 elements, its error falling with the square of the
    element (a quarter at 40), 1 at 0 Hz."""
    tau_d = 5e-3
    f = np.geomspace(0.2, 5.0, 9) / (2 * np.pi * tau_d)
    exact = slab(2j * np.pi * f * tau_d)
    err = {n: np.max(np.abs(diffusion_response(f, tau_d, n) / exact - 1)) for n in (20, 40)}
    assert err[20] < SLAB_RTOL
    assert 3.5 < err[20] / err[40] < 4.5, err
    assert diffusion_response(0.0, tau_d, 20) == pytest.approx(1.0, abs=1e-14)


def test_a_solid_core_lags_the_force_by_its_diffusion(stiff_rig):
    """At a fixed gap the simulated force's fundamental over that of i^2 is the discretised
    diffusion's response (to the time step's warping), half order: far from the first-order
    lag with the same low-frequency slope; a laminated core is near it."""
    preset, model = stiff_rig
    (magnet,) = _magnets_at(preset, 1.0e-3)
    solid = get_preset("solid").magnets[0]
    solid = dataclasses.replace(magnet, eddy_time=0.0, core=solid.core,
                                conductivity=solid.conductivity,
                                core_thickness=solid.core_thickness)
    f = 100.0
    ratios = []
    for m in (dataclasses.replace(magnet, eddy_time=0.0), solid):
        r = integrate(model, (m,), (Drive("current", 0.6, 0.1, f),), FS, 0.1)
        force, i2 = fundamental(np.vstack([r.pole_force.sum(0), r.current[0] ** 2]), r.t, f)
        ratios.append(force / i2)
    h = ratios[1] / ratios[0]
    expected = solid.eddy_response(f)
    np.testing.assert_allclose(abs(h), abs(expected), rtol=EDDY_GAIN_RTOL)
    np.testing.assert_allclose(np.angle(h), np.angle(expected), atol=EDDY_PHASE_ATOL)
    np.testing.assert_allclose(expected, slab(2j * np.pi * f * solid.diffusion_time),
                               rtol=SLAB_RTOL)
    first = 1 / (1 + 2j * np.pi * f * solid.diffusion_time / 3)
    assert abs(expected / first - 1) > 0.05                   # not first order
    lam = get_preset("laminated").magnets[0]
    near = 1 / (1 + 2j * np.pi * f * lam.diffusion_time / 3)
    assert abs(lam.eddy_response(f) / near - 1) < 1e-3


def test_a_diffusing_core_is_described_and_checked():
    facts = _diffusion_facts(get_preset("solid"))["eddy"]
    rows = facts["response"]["i"]
    assert facts["core"] == {"i": "solid"} and len(rows) == 7
    magnet = get_preset("solid").magnets[0]
    assert facts["diffusion_time_s"]["i"] == pytest.approx(5.0265e-3, rel=1e-4)
    h = magnet.eddy_response([r["frequency_Hz"] for r in rows])
    np.testing.assert_allclose([r["gain"] for r in rows], np.abs(h), rtol=1e-12)
    np.testing.assert_allclose([r["lag_deg"] for r in rows], -np.degrees(np.angle(h)))
    with pytest.raises(ValueError, match="conductivity > 0"):
        dataclasses.replace(magnet, conductivity=0.0)
    with pytest.raises(ValueError, match="core is one of lag, solid, laminated"):
        dataclasses.replace(magnet, core="ferrite")
    model = build_model(get_preset("solid"))
    with pytest.raises(ValueError, match="a solid core needs a current drive"):
        integrate(model, (magnet,), (Drive("voltage", 2.0, 1.0, 20.0),), FS, 0.01)


# --------------------------------------------------------------------------------------------
# a broadband record starts settled


def probe(model, x: float, r) -> np.ndarray:
    return (hermite_row(model.nodes, np.array([x])) @ r.u)[0]


def test_random_record_starts_settled(sweep_rig):
    preset, model = sweep_rig
    noise = BandLimitedRandom(0.05, 10.0, 150.0, period=0.1, seed=5)   # repeats every 0.1 s
    drives = (Drive("current", 0.6, 0.0, 10.0, waveform=noise),)
    w = probe(model, 0.3, integrate(model, preset.magnets, drives, FS, 0.5))
    w = w - w.mean()
    first, last = w[:1000], w[-1000:]
    rms = np.sqrt(np.mean(last**2))
    assert abs(np.sqrt(np.mean(first**2)) / rms - 1) < SETTLED_RTOL
    assert np.max(np.abs(first - last)) < SETTLED_RTOL * np.max(np.abs(last))
    # the same from rest at t = 0: the start-up transient is there
    w0 = probe(model, 0.3, integrate(model, preset.magnets, drives, FS, 0.5, lead=0.0))
    w0 = w0 - w0.mean()
    assert np.max(np.abs(w0[:1000] - w0[-1000:])) > 0.1 * np.max(np.abs(last))


def test_broadband_lead_is_long_enough(sweep_rig):
    preset, model = sweep_rig
    lead = lead_time(model)
    assert 1.5 < lead < 3.0                           # 10 / (zeta omega_1), 70.7 Hz, 1 %
    drives = (Drive("current", 0.6, 0.0, 10.0,
                    waveform=BandLimitedRandom(0.07, 5.0, 150.0, period=4.0, seed=7)),)
    a = probe(model, 0.3, integrate(model, preset.magnets, drives, FS, 0.2))
    b = probe(model, 0.3, integrate(model, preset.magnets, drives, FS, 0.2, lead=2 * lead))
    assert np.max(np.abs(a - b)) < SETTLED_RTOL * np.std(b)


def test_one_tone_stepped_through_is_the_periodic_steady_state(sweep_rig):
    preset, model = sweep_rig
    f = 31.0
    steady = integrate(model, preset.magnets, (Drive("current", 0.6, 0.2, f),), FS, 0.1)
    tone = Drive("current", 0.6, 0.0, f, waveform=MultiTone((f,), (0.2,)))
    stepped = integrate(model, preset.magnets, (tone,), FS, 0.1)
    np.testing.assert_allclose(stepped.current, steady.current, rtol=1e-12)
    ac = np.ptp(steady.pole_force)
    assert np.max(np.abs(stepped.pole_force - steady.pole_force)) < SETTLED_RTOL * ac
    gap_ac = np.ptp(steady.gap)
    assert np.max(np.abs(stepped.gap - steady.gap)) < SETTLED_RTOL * gap_ac


# --------------------------------------------------------------------------------------------
# the swept rig: truth, steps, files


def test_sweep_truth_balances_reactions_inertia_and_forces(sweep_rig):
    preset, model = sweep_rig
    p0 = quiet(preset)
    spec = RunSpec("short", drives=(Drive("current", 0.6, 0.0, 40.0,
                                          waveform=SweptSine(0.1, 40.0, 100.0, 0.3)),),
                   gap=1.0e-3, duration=0.3)
    run, truth = record_run(p0, spec, np.random.default_rng(1), model)
    (_, xa), (_, xb) = preset.beam.gauges
    xs = np.array([p.x for m in preset.magnets for p in m.poles])
    psi = np.stack([(xb - xs) / (xb - xa), (xs - xa) / (xb - xa)])
    reactions = np.stack([run.channels[name] for name, _ in preset.beam.gauges])
    rms = np.sqrt(np.mean(reactions**2, axis=1))
    residual = truth.inertia - reactions - psi @ truth.pole_force
    assert np.max(np.abs(residual) / rms[:, None]) < BALANCE_RTOL
    share = np.sqrt(np.mean(truth.inertia**2, axis=1)) / np.std(reactions, axis=1)
    assert np.all(share > 0.05)                        # the inertia term matters
    np.testing.assert_allclose(truth.current[0], 0.6 + spec.drives[0].waveform.value(truth.t))


def test_the_closest_step_stays_clear_of_the_gap(sweep_rig):
    preset, model = sweep_rig
    spec = next(r for r in preset.runs if r.name == "g0800_f60p00")
    r = integrate(model, _magnets_at(preset, spec.gap), spec.drives, FS, 0.2)
    dynamic = np.max(np.abs(r.gap - r.gap.mean(axis=1, keepdims=True)))
    assert 0.05 * 0.8e-3 < dynamic < 0.15 * 0.8e-3


def test_sweep_and_random_presets():
    sweep, rand = get_preset("sweep"), get_preset("random")
    steps = [r for r in sweep.runs if r.manifest and not r.tare]
    assert len(steps) == 21 and {r.gap for r in steps} == {0.8e-3, 1.0e-3, 1.2e-3}
    assert all(r.duration * r.drives[0].frequency >= 5 for r in steps)
    assert [r.name for r in sweep.runs if not r.manifest] == ["sweep"]
    assert sweep.magnets[0].eddy_time == rand.magnets[0].eddy_time == 0.5e-3
    assert sweep.scan == rand.scan and sweep.band == rand.band == (5.0, 200.0)
    noise = rand.runs[0].drives[0].waveform
    assert isinstance(noise, BandLimitedRandom) and noise.band == (5.0, 150.0)
    with pytest.raises(InputError, match="unknown"):
        get_preset("sweep", "bench")


def test_a_lab_sweep_rig(tmp_path, monkeypatch):
    """The ``lab`` realism under broadband drives: the rig declares its type-B uncertainties
    and its mains, every gauge reads its preload and offset (the tare's mean), every channel
    its hum (50 Hz on the tare's gauges: 3 times their white noise's sigma, 0.03 N), and each
    chirp record's reference current follows its drive's walking level (its mean over whole
    periods times the level and the current sensor's sensitivity, to 2e-4)."""
    small = _small_sweep()
    monkeypatch.setitem(presets.PRESETS, "sweep", lambda: dataclasses.replace(
        small, runs=(small.runs[0], small.runs[-1])))
    out = write_simulation(tmp_path / "lab", "sweep", seed=0, realism="lab")
    rig = tomllib.loads((out / "rig.toml").read_text())
    assert rig["acquisition"]["mains"] == 50.0 and rig["uncertainty"]["gauge_scale"] == 0.005
    tare = np.loadtxt(out / "runs" / "tare.csv", delimiter=",", skiprows=1)
    header = (out / "runs" / "tare.csv").read_text().splitlines()[0].split(",")
    r1 = tare[:, header.index("R1")]
    assert abs(r1.mean()) > 1.0                                   # the beam's weight
    t = np.arange(r1.size) / 10_000.0
    hum = 2 * abs(np.mean((r1 - r1.mean()) * np.exp(-2j * np.pi * 50.0 * t)))
    assert 0.02 < hum < 0.04, hum
    facts = json.loads((out / "truth" / "simulator.json").read_text())
    level = np.array(facts["realism"]["scans"][0]["drive_level"])
    assert level.shape == (5,) and 0 < np.max(np.abs(level - 1)) < 0.01
    scan = read_scan_uff(out / "scan.uff")
    gain = facts["realism"]["sensitivity"]["i"]
    chirp = small.scan.drives[0]                     # whole periods: any start's mean
    mean = chirp.dc + np.mean(chirp.waveform.value(np.arange(2500) / 10_000.0))
    np.testing.assert_allclose(scan.reference.mean(axis=1), mean * gain * level, rtol=2e-4)
    assert not np.allclose(scan.reference.mean(axis=1), mean * gain, rtol=2e-4)


def _small_sweep():
    full = presets._sweep()
    scan = dataclasses.replace(full.scan, n_points=5, record=0.5)
    return dataclasses.replace(full, scan=scan, runs=(
        dataclasses.replace(full.runs[0], duration=0.2), full.runs[1], full.runs[-1]))


def test_sweep_files(tmp_path, monkeypatch):
    monkeypatch.setitem(presets.PRESETS, "sweep", _small_sweep)
    out = write_simulation(tmp_path / "sweep", "sweep", seed=0)
    rig = tomllib.loads((out / "rig.toml").read_text())
    assert rig["acquisition"]["band"] == [5.0, 200.0]
    assert rig["acquisition"]["drive"] == "any"
    manifest = (out / "manifest.csv").read_text().splitlines()
    assert manifest[0] == "run,gap,tare,dc,ac,frequency"
    assert [row.split(",")[0] for row in manifest[1:]] == ["runs/g0800_f10p00.csv",
                                                           "runs/tare.csv"]
    assert manifest[1].endswith(",10.0")
    for name in ("sweep", "g0800_f10p00", "tare"):
        assert (out / "runs" / f"{name}.csv").exists()
        assert (out / "truth" / f"{name}.forces.csv").exists()
        assert (out / "truth" / f"{name}.npz").exists()
    forces = np.loadtxt(out / "truth" / "sweep.forces.csv", delimiter=",", skiprows=1)
    assert forces.shape == (2000, 4)                  # time, F1, F2, total
    np.testing.assert_allclose(forces[:, 3], forces[:, 1] + forces[:, 2], rtol=1e-12)
    facts = json.loads((out / "truth" / "simulator.json").read_text())
    assert facts["eddy"]["eddy_time_s"] == {"i": 0.5e-3}
    assert "atan(2 pi f tau)" in facts["eddy"]["law"]
    assert facts["runs"]["sweep"]["drives"][0]["waveform"]["f_stop_Hz"] == 150.0
    # every scan window holds whole chirp periods: its lines at multiples of 4 Hz only
    scan = read_scan_uff(out / "scan.uff")
    assert scan.response.shape == (5, 5000)
    spec = np.abs(np.fft.rfft(scan.reference - scan.reference.mean(1, keepdims=True))) ** 2
    freqs = np.fft.rfftfreq(5000, 1 / scan.fs)
    on = np.isclose(freqs / 4, np.round(freqs / 4))
    assert np.all(spec[:, ~on].sum(1) < 1e-3 * spec[:, on].sum(1))


def test_a_random_scan_windows_whole_periods(sweep_rig):
    preset, model = sweep_rig
    noise = BandLimitedRandom(0.05, 5.0, 200.0, period=0.5, seed=2)
    scan = ScanSpec(drives=(Drive("current", 0.6, 0.0, 5.0, waveform=noise),), n_points=3,
                    record=0.5)
    rig = dataclasses.replace(quiet(preset), scan=scan)
    assert scan_offsets(rig) == 5000
    r = scan_response(rig, model)
    assert len(r.t) == 10_000
    np.testing.assert_allclose(r.current[0], 0.6 + noise.value(r.t), rtol=1e-12)


def test_the_dwell_preset_lingers_at_the_mode_longer_than_the_scan_does():
    """The ``dwell`` run sweeps through the closed-loop first mode (about 69 Hz at 1 mm) at
    3 Hz/s: within the mode's half-power band (2 zeta f, 1.4 Hz at 1 % damping) for 0.46 s,
    against the chirp scan's 1.8 ms a period (7 ms over its 1 s record, four periods); its
    run uses the broadband scan of the ``sweep`` preset, whose lines lie 4 Hz apart."""
    dwell, sweep = get_preset("dwell"), get_preset("sweep")
    assert dwell.scan == sweep.scan and dwell.band == sweep.band
    run = dwell.runs[0]
    wave = run.drives[0].waveform
    assert wave.f_start < 69.0 < wave.f_stop and run.duration == wave.duration
    bandwidth = 2 * dwell.beam.damping_ratio * 69.0
    in_run = bandwidth / ((wave.f_stop - wave.f_start) / wave.duration)
    chirp = dwell.scan.drives[0].waveform
    per_record = (dwell.scan.record / chirp.period) * bandwidth / (
        (chirp.f_stop - chirp.f_start) / chirp.period)
    assert in_run > 0.4 and in_run > 50 * per_record, (in_run, per_record)
    assert 1.0 / chirp.period > 2 * bandwidth                       # lines 4 Hz apart

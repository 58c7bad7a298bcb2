"""Shared fixtures, made once per test session (per worker): the simulated 'paper' rig, and
the finite-element beam under broadband drives with its scans and model (the broadband tests
of model/, forces/, realtime/, signals/ and campaign/; their helpers are in fe_beam.py)."""

# ruff: noqa: E402 (the imports follow the BLAS threads' setting)

from __future__ import annotations

import os

# One BLAS thread per test process: the two xdist workers are the parallelism, and BLAS threads
# in each would oversubscribe the cores (the coverage study of forces/test_uncertainty.py took
# 300 s of CPU instead of 17 s). The command line and the API set their threads themselves
# (forcecal.cluster.threads), but most tests call the stages' modules directly, which do not:
# so set here, before numpy is imported.
for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

import dataclasses

import numpy as np
import pytest
from fe_beam import FS, band_noise, random_force_run

from forcecal.io.run_files import read_run
from forcecal.io.uff import read_scan_uff
from forcecal.model.broadband import build_broadband_model
from forcecal.model.spatial import build_spatial_model
from forcecal.records import Scan
from forcecal.rig import load_rig
from forcecal.simulate.export import write_simulation
from forcecal.simulate.presets import NoiseSpec, get_preset
from forcecal.simulate.virtual_rig import build_model, public_rig, record_run


@pytest.fixture(scope="session")
def paper_dir(tmp_path_factory):
    """The 'paper' preset written in the public formats (seed 0)."""
    out = tmp_path_factory.mktemp("paper")
    write_simulation(out, "paper", seed=0)
    return out


@pytest.fixture(scope="session")
def campaign_dir(tmp_path_factory):
    """The 'campaign' preset written in the public formats (seed 0), and beside its manifest
    ``manifest_small.csv``: its runs at 0.6 A DC and 0.2 A AC, one per static gap (0.8, 1.0
    and 1.2 mm), and its tare (a campaign of three runs, calibrated in seconds)."""
    out = tmp_path_factory.mktemp("campaign")
    write_simulation(out, "campaign", seed=0)
    header, *rows = (out / "manifest.csv").read_text(encoding="utf-8").splitlines()
    keep = [r for r in rows if r.split(",")[0].endswith("_dc06_ac02.csv") or "runs/tare" in r]
    (out / "manifest_small.csv").write_text("\n".join([header, *keep]) + "\n", encoding="utf-8")
    return out


@pytest.fixture(scope="session")
def random_lab(tmp_path_factory):
    """(rig, model, run, tare, folder) of the 'random' preset's lab rig (seed 0: coloured
    noise, hum, sensitivities drawn from the declared type-B uncertainties), its model built
    as ``forcecal scan`` builds it."""
    from forcecal.cli.main import main
    from forcecal.model.broadband import load_any_model

    out = tmp_path_factory.mktemp("random_lab")
    write_simulation(out, "random", seed=0, realism="lab")
    assert main(["scan", "-q", str(out / "rig.toml"), str(out / "scan.uff"), "-o",
                 str(out / "model.json")]) == 0
    rig = load_rig(out / "rig.toml")
    return (rig, load_any_model(out / "model.json"), read_run(out / "runs" / "random.csv", rig),
            read_run(out / "runs" / "tare.csv", rig), out)


@pytest.fixture(scope="session")
def paper(paper_dir):
    """(rig, scan, model, run) of the simulated 'paper' rig."""
    rig = load_rig(paper_dir / "rig.toml")
    scan = read_scan_uff(paper_dir / "scan.uff")
    model = build_spatial_model(rig, scan)
    run = read_run(paper_dir / "runs" / "paper.csv")
    return rig, scan, model, run


@pytest.fixture(scope="session")
def paper_noise_free():
    """A noise-free 'paper' run with its truth (no file round trip)."""
    preset = get_preset("paper")
    quiet = dataclasses.replace(preset, noise=NoiseSpec(0, 0, 0, 0, 0, 0))
    return record_run(quiet, quiet.runs[0], np.random.default_rng(0), build_model(quiet))


# --------------------------------------------------------------------------------------------
# the finite-element beam under broadband drives


@pytest.fixture(scope="session")
def beam():
    """The 'paper' preset's finite-element beam: (preset, FE model, its mode shapes, the public
    rig with ``acquisition.band`` 5-200 Hz and ``drive = "any"``, ``modal(f, force_spectrum)``:
    the modes' response to forces at the poles)."""
    preset = get_preset("paper")
    model = build_model(preset)
    w2, phi = model.modes
    poles = phi.T @ model.row(np.array([0.25, 0.35])).T               # (n_modes, 2)
    rig = dataclasses.replace(public_rig(preset), band=(5.0, 200.0), drive="any")

    def modal(f, force_spectrum):
        """(n_f, n_modes): the modes' response to a force spectrum (n_f,) at both poles, or
        (n_f, 2) at each."""
        w = 2 * np.pi * f
        den = w2[None, :] - w[:, None] ** 2 + 1j * w[:, None] * model.beta * w2[None, :]
        at = force_spectrum if force_spectrum.ndim == 2 else force_spectrum[:, None] * [1, 1]
        return at @ poles.T / den

    return preset, model, phi, rig, modal


@pytest.fixture(scope="session")
def bb_scan(beam):
    """A broadband scan of the beam: 41 points, four periods of a 3-250 Hz random drive a
    record (lines every 4 Hz), 50 um/s of noise on every velocity and 1 mA on every current."""
    _preset, model, phi, _rig, modal = beam
    rng = np.random.default_rng(11)
    n, x = int(FS), np.linspace(0.0, 0.6, 41)
    f = np.fft.rfftfreq(n, 1 / FS)
    rows = model.row(x) @ phi
    resp, ref = [], []
    for _ in x:
        r = np.tile(0.1 * band_noise(rng, n // 4, 3.0, 250.0), 4)     # periodic, 4 Hz lines
        qv = modal(f, 2j * np.pi * f * np.fft.rfft(r) * 10.0)        # velocity, 10 N/A
        resp.append(np.fft.irfft(qv, n, axis=0) @ rows.T)
        ref.append(r + 1e-3 * rng.standard_normal(n))
    resp = np.array([rp[:, k] for k, rp in enumerate(resp)])
    resp += 50e-6 * rng.standard_normal(resp.shape)
    return Scan(points=x, response=resp, reference=np.array(ref), fs=FS, quantity="velocity",
                source="broadband.uff")


@pytest.fixture(scope="session")
def bb_model(beam, bb_scan):
    """The broadband model of ``bb_scan``."""
    return build_broadband_model(beam[3], bb_scan)


@pytest.fixture(scope="session")
def random_run(beam):
    """(run, force at each pole, noise-free gauges): 4 s of a 5-40 Hz random force (seed 5)."""
    return random_force_run(beam, np.random.default_rng(5), 40.0)


@pytest.fixture(scope="session")
def chirp(beam):
    """A chirp scan like the fixture's (41 points, four periods of 3-250 Hz a record, its
    drives drawn afresh) without noise: every point's velocity and reference."""
    _preset, model, phi, _rig, modal = beam
    rng = np.random.default_rng(11)
    n, x = int(FS), np.linspace(0.0, 0.6, 41)
    f = np.fft.rfftfreq(n, 1 / FS)
    rows = model.row(x) @ phi
    ref = np.array([np.tile(0.1 * band_noise(rng, n // 4, 3.0, 250.0), 4) for _ in x])
    resp = np.array([np.fft.irfft(modal(f, 2j * np.pi * f * np.fft.rfft(r) * 10.0), n,
                                  axis=0) @ rows[k] for k, r in enumerate(ref)])
    return x, resp, ref


@pytest.fixture(scope="session")
def random_scan(beam):
    """41 points under a band-limited random drive (3-250 Hz), one record of it a point (not
    periodic: Welch's H1), with the fixture's noise (50 um/s, 1 mA)."""
    _preset, model, phi, _rig, modal = beam
    rng = np.random.default_rng(21)
    n, x = int(FS), np.linspace(0.0, 0.6, 41)
    f = np.fft.rfftfreq(n, 1 / FS)
    rows = model.row(x) @ phi
    ref = np.array([0.1 * band_noise(rng, n, 3.0, 250.0) for _ in x])
    resp = np.array([np.fft.irfft(modal(f, 2j * np.pi * f * np.fft.rfft(r) * 10.0), n,
                                  axis=0) @ rows[k] for k, r in enumerate(ref)])
    return Scan(points=x, response=resp + 50e-6 * rng.standard_normal(resp.shape),
                reference=ref + 1e-3 * rng.standard_normal(ref.shape), fs=FS,
                quantity="velocity", source="random.uff")

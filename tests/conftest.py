"""Shared fixtures: one simulated 'paper' rig per test session."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from forcecal.io.run_files import read_run
from forcecal.io.uff import read_scan_uff
from forcecal.model.spatial import build_spatial_model
from forcecal.rig import load_rig
from forcecal.simulate.export import write_simulation
from forcecal.simulate.presets import NoiseSpec, get_preset
from forcecal.simulate.virtual_rig import build_model, record_run


@pytest.fixture(scope="session")
def paper_dir(tmp_path_factory):
    """The 'paper' preset written in the public formats (seed 0)."""
    out = tmp_path_factory.mktemp("paper")
    write_simulation(out, "paper", seed=0)
    return out


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

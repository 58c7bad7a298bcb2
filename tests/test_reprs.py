"""What a user sees of forcecal at a prompt: the package's names (``dir(forcecal)``, what
``forcecal.<TAB>`` completes to) and the one-line reprs of the records and results, which
summarise (name, channels, rate, duration, sizes) rather than print arrays."""

from __future__ import annotations

import types

import numpy as np
import pytest

import forcecal
from forcecal.actuator import Calibration
from forcecal.records import ScanFRF, ScanSpectra

MAX_REPR = 300
"""A repr longer than this is a dump, not a summary."""


def short(obj: object) -> str:
    """``repr(obj)``, checked to be one short line without an array's dump."""
    text = repr(obj)
    assert len(text) < MAX_REPR, text
    assert "array(" not in text and "\n" not in text, text
    return text


def test_dir_of_the_package_is_its_public_names():
    public = {name for name in dir(forcecal) if not name.startswith("_")}
    assert public == set(forcecal.__all__) - {"__version__"}
    held = {name for name, value in vars(forcecal).items()     # no stray import either
            if not name.startswith("_") and not isinstance(value, types.ModuleType)}
    assert held <= set(forcecal.__all__), held - set(forcecal.__all__)
    assert {"Any", "TYPE_CHECKING", "annotations"}.isdisjoint(dir(forcecal))
    assert "__version__" in dir(forcecal) and "__doc__" in dir(forcecal)
    assert len(forcecal.__all__) == len(set(forcecal.__all__))
    for name in forcecal.__all__:                              # every listed name resolves
        getattr(forcecal, name)


def test_rig_scan_and_run_print_a_summary(paper):
    rig, scan, _model, run = paper
    text = short(rig)
    assert f"'{rig.name}'" in text and "Beam" in text and "2 gauges (R1, R2)" in text
    assert "steady drive at 20 Hz" in text
    text = short(scan)
    assert f"{scan.n_points} points x {scan.n_samples} samples at {scan.fs:g} Hz" in text
    assert f"({scan.n_samples / scan.fs:g} s a record), velocity" in text
    text = short(run)
    assert f"Run('{run.name}', {len(run.channels)} channels (R1, R2, s1" in text
    assert f"{run.n_samples} samples at {run.fs:g} Hz ({run.n_samples / run.fs:g} s" in text


def test_a_run_of_many_channels_counts_the_rest():
    run = forcecal.Run({f"ch{k}": np.zeros(4000) for k in range(40)}, fs=2000.0, name="wide")
    text = short(run)
    assert "40 channels (ch0, ch1" in text and "ch7, ... (32 more)" in text and "ch8" not in text
    assert "4000 samples at 2000 Hz (2 s from t0 = 0 s)" in text


def test_spectra_and_frf_scans_print_a_summary():
    f = np.arange(0.0, 2001.0)                                # 2001 lines, 1 Hz apart
    spectra = ScanSpectra(points=np.linspace(0, 0.6, 500), frequencies=f,
                          response=np.ones((500, f.size)), reference=np.ones((500, f.size)),
                          source="s.uff")
    assert short(spectra) == ("ScanSpectra('s.uff', 500 points x 2001 lines 0-2000 Hz, "
                              "velocity, peak)")
    frf = ScanFRF(points=np.linspace(0, 0.6, 500), frequencies=f[5:],
                  values=np.ones((500, f.size - 5)), coherence=np.ones((500, f.size - 5)),
                  source="f.uff")
    assert short(frf) == "ScanFRF('f.uff', 500 points x 1996 lines 5-2000 Hz, velocity per A)"


def test_a_broadband_model_prints_a_summary(bb_model):
    text = short(bb_model)
    assert f"band {bb_model.band[0]:g}-{bb_model.band[1]:g} Hz" in text
    assert f"{bb_model.n_shapes} shape(s)" in text and f"{bb_model.n_points} points" in text


@pytest.mark.parametrize("current", [0.9, np.linspace(0.8, 1.2, 10_000)], ids=["one", "many"])
def test_a_prediction_prints_a_summary(current):
    cal = Calibration(law="k_i2_s2", params=np.array([9e-6]), covariance=np.array([[1e-18]]),
                      n_poles=2, current_range=(0.8, 1.2), gap_range=(0.0008, 0.001))
    pred = forcecal.predict(cal, current, 0.0009)
    text = short(pred)
    if np.ndim(current) == 0:
        assert text == f"Prediction(total {pred.total:.6g} N ± {pred.std:.2g}, 2 pole(s))"
    else:
        assert f"10000 predictions, total {pred.total.min():.6g} to" in text

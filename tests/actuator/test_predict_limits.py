"""What ``forcecal.predict`` refuses, and where it extrapolates.

The API and ``forcecal predict`` refuse the same currents and gaps with the same words (one
check, :func:`forcecal.actuator.prediction.check_current_and_gaps`): not finite, beyond the
hard limits (a current in mA, a gap in mm), or more than ``EXTRAPOLATION`` times outside the
calibrated range. A campaign's calibrated range holds every static gap of its manifest, so
that none of its own gaps warns.
"""

from __future__ import annotations

import dataclasses
import warnings
from types import SimpleNamespace

import numpy as np
import pytest

import forcecal
from forcecal.actuator import Calibration, ExtrapolationWarning, FrequencyLaw
from forcecal.actuator.prediction import EXTRAPOLATION
from forcecal.campaign.calibrate import _with_static_gaps
from forcecal.cli.main import main
from forcecal.errors import ForcecalError, InputError
from forcecal.io.manifest import read_manifest

CURRENT_RANGE = (0.2, 1.0)  # [A]
GAP_RANGE = (0.6e-3, 1.2e-3)  # [m]


def _calibration() -> Calibration:
    return Calibration(law="k_i2_s2", params=np.array([9e-6]), covariance=np.array([[1e-18]]),
                       n_poles=2, current_range=CURRENT_RANGE, gap_range=GAP_RANGE)


@pytest.fixture
def saved(tmp_path):
    return _calibration().save(tmp_path / "calibration.json")


REFUSED = [  # (current, gap, the parameter named, what the message says)
    (600.0, 1e-3, "current", "600 A is more than 10 times the largest calibrated current 1 A"),
    (-11.0, 1e-3, "current", "-11 A is more than 10 times the largest calibrated current"),
    (float("nan"), 1e-3, "current", "nan A is not a finite current within 100000 A"),
    (2e5, 1e-3, "current", "200000.0 A is not a finite current within 100000 A"),
    (1.0, 0.8, "gap", "0.8 m is not an air gap between 0 and 0.1 m (0.0008 for 0.8 mm)"),
    (1.0, 0.0, "gap", "0.0 m is not an air gap between 0 and 0.1 m"),
    (1.0, -1e-3, "gap", "-0.001 m is not an air gap"),
    (1.0, float("inf"), "gap", "inf m is not an air gap"),
    (1.0, 5e-5, "gap", "5e-05 m is more than 10 times outside the calibrated gaps 0.0006 to "
                       "0.0012 m"),
    (1.0, 0.013, "gap", "0.013 m is more than 10 times outside the calibrated gaps"),
]
IDS = ["mA", "negative", "nan", "beyond-limit", "mm", "zero-gap", "negative-gap", "inf-gap",
       "gap-far-below", "gap-far-above"]
API_NAME = {"current": "current", "gap": "gaps"}


@pytest.mark.parametrize(("current", "gap", "parameter", "says"), REFUSED, ids=IDS)
def test_the_api_refuses(current, gap, parameter, says):
    with pytest.raises(InputError) as caught:
        forcecal.predict(_calibration(), current, gap)
    message = str(caught.value)
    assert isinstance(caught.value, ForcecalError)
    assert message.startswith(f"{API_NAME[parameter]} {says}"), message
    if "calibrated" in says:           # the calibration is named: here by its law
        assert message.endswith("(calibration (law 'k_i2_s2'))"), message


def test_the_refusal_names_the_calibration_file(saved):
    cal = forcecal.load_calibration(saved)
    with pytest.raises(InputError, match=rf"current 600 A .* \(calibration '{saved}'\)"):
        forcecal.predict(cal, 600, 1e-3)
    with pytest.raises(InputError, match=rf"gaps 0\.013 m .* \(calibration '{saved}'\)"):
        forcecal.predict(cal, 1.0, 0.013)


def test_arrays_are_refused_naming_a_value_at_fault():
    cal = _calibration()
    with pytest.raises(InputError, match=r"^current 600 A is more than 10 times"):
        forcecal.predict(cal, [0.5, 600.0], 1e-3)
    with pytest.raises(InputError, match=r"^gaps 0\.8 m is not an air gap"):
        forcecal.predict(cal, [0.5, 0.6], [[1e-3, 1e-3], [1e-3, 0.8]])


def test_within_the_factor_a_prediction_extrapolates_with_a_warning():
    cal = _calibration()
    with pytest.warns(ExtrapolationWarning, match="current from 9.9 to 9.9 A") as said:
        pred = forcecal.predict(cal, 0.99 * EXTRAPOLATION * CURRENT_RANGE[1], 1e-3)
    assert np.isfinite(pred.total).all()
    assert "by up to 8.9 A (1112 % of the range)" in str(said[0].message)   # 8.9 A / 0.8 A
    with pytest.warns(ExtrapolationWarning, match="gap from 11 to 11 mm") as said:
        forcecal.predict(cal, 1.0, 11e-3)
    assert "by up to 9.8 mm (1633 % of the range)" in str(said[0].message)   # 9.8 / 0.6 mm
    with pytest.warns(ExtrapolationWarning, match=r"by up to 0\.1 A \(12\.5 % of the range\)"):
        forcecal.predict(cal, 1.1, 1e-3)


@pytest.mark.parametrize(("current", "gap", "parameter", "says"), REFUSED, ids=IDS)
def test_the_command_line_refuses_the_same_in_the_same_words(saved, capsys, current, gap,
                                                             parameter, says):
    with pytest.raises(InputError) as caught:
        forcecal.predict(forcecal.load_calibration(saved), current, gap)
    api = str(caught.value).removeprefix(f"{API_NAME[parameter]} ")
    assert main(["predict", str(saved), "--current", repr(current), "--gap", repr(gap)]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert err.splitlines() == [f"forcecal predict: argument --{parameter}: {api} "
                                "(see 'forcecal predict --help')"]
    assert sorted(p.name for p in saved.parent.iterdir()) == ["calibration.json"]


# --------------------------------------------------------------------------------------------
# the calibrated range of a campaign


@pytest.fixture(scope="module")
def small(campaign_dir, tmp_path_factory):
    """(manifest, result, calibration file) of the small campaign, calibrated serially."""
    rig = forcecal.load_rig(campaign_dir / "rig.toml")
    scan = forcecal.read_scan(campaign_dir / "scan.uff", rig=rig)
    manifest = campaign_dir / "manifest_small.csv"
    result = forcecal.calibrate(rig, scan, manifest)
    path = result.calibration.save(tmp_path_factory.mktemp("small") / "calibration.json")
    return manifest, result, path


def test_the_calibrated_gaps_span_the_static_and_the_instantaneous_gaps(small):
    manifest, result, _ = small
    static = sorted({float(e.gap) for e in read_manifest(manifest) if e.gap and not e.tare})
    assert static == pytest.approx([0.8e-3, 1.0e-3, 1.2e-3])
    for r in result.runs:
        assert float(r.samples.motion.static_gap.max()) in static
    lo, hi = result.calibration.gap_range
    instantaneous = np.concatenate([r.samples.gaps.ravel() for r in result.runs])
    assert lo == instantaneous.min() < static[0]
    assert instantaneous.max() < static[-1] == hi      # the attracted beam closes the gaps


def test_a_campaigns_own_gaps_do_not_warn(small, capsys):
    manifest, _, path = small
    cal = forcecal.load_calibration(path)
    gaps = sorted({float(e.gap) for e in read_manifest(manifest) if e.gap and not e.tare})
    assert gaps == pytest.approx([0.8e-3, 1.0e-3, 1.2e-3])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for gap in gaps:
            assert np.isfinite(forcecal.predict(cal, 0.6, gap).total).all()
    for gap in gaps:
        assert main(["predict", str(path), "--current", "0.6", "--gap", repr(gap)]) == 0
        out, err = capsys.readouterr()
        assert err == "" and float(out) > 0


def test_the_frequency_law_spans_the_static_gaps_too():
    law = FrequencyLaw(k=9e-6, s_fe=5e-5, tau=1e-3, covariance=np.eye(3) * 1e-20, n_poles=2,
                       frequency_range=(10.0, 100.0), current_range=CURRENT_RANGE,
                       gap_range=(0.7e-3, 1.1e-3))
    cal = dataclasses.replace(_calibration(), gap_range=(0.7e-3, 1.1e-3), frequency_law=law)
    runs = [SimpleNamespace(samples=SimpleNamespace(motion=SimpleNamespace(
        static_gap=np.array(gaps)))) for gaps in ([0.8e-3, 0.8e-3], [1.2e-3, 1.25e-3])]
    wider = _with_static_gaps(cal, runs)
    assert wider.gap_range == (0.7e-3, 1.25e-3)
    assert wider.frequency_law is not None and wider.frequency_law.gap_range == (0.7e-3, 1.25e-3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        forcecal.predict(wider, 0.5, 1.25e-3, frequency=50.0)

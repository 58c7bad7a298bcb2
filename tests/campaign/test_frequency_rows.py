"""A campaign over frequency under a broadband model: each manifest row's drive frequency.

The broadband model is the finite-element beam's (session fixtures in ``tests/conftest.py``).
"""

from __future__ import annotations

import pytest

from forcecal.errors import InputError


def test_campaign_row_takes_its_frequency_from_the_manifest(beam, bb_model, tmp_path):
    """A stepped-sine row is reconstructed at its ``frequency`` column's harmonics; a column
    that is not a frequency is refused naming the row; three fundamentals make a campaign over
    frequency, two do not."""
    from types import SimpleNamespace

    from forcecal.campaign.calibrate import _frequency_steps
    from forcecal.campaign.runs import _entry_model, _Task
    from forcecal.io.manifest import ManifestEntry

    rig = beam[3]

    def task(label):
        entry = ManifestEntry(run=tmp_path / "r.csv", gap=None, gaps={}, tare=False,
                              labels={"frequency": label}, row=3)
        return _Task(index=0, rig=rig, model=bb_model, entry=entry, tare=None,
                     ac_coupled=False, samples_per_period=64)

    row_rig, model = _entry_model(task("46.42"))
    assert row_rig.frequency == 46.42 and model.f0 == 46.42
    assert list(model.harmonics) == [1, 2, 3, 4]          # 5 x 46.42 Hz lies above 200 Hz
    for bad in ("fast", "-5"):
        with pytest.raises(InputError, match="row 3"):
            _entry_model(task(bad))

    def runs(*f0):
        return [SimpleNamespace(estimate=SimpleNamespace(f0=f)) for f in f0]

    assert _frequency_steps(runs(10.0, 10.05, 14.7, 14.7)) == 2
    assert _frequency_steps(runs(10.0, 14.7, 21.5, 21.52)) == 3

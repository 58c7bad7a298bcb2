"""Tests of the calibration certificate (``forcecal.report.certificate``, ``calibration_report``).

A small campaign is simulated and calibrated once per module: three static gaps at one DC
current (AC 0.2 A, 0.3 s records), one repeat and a zero-current tare, on a rig file whose
``[uncertainty]`` table declares two type-B keys (the others take the documented defaults).
The certificate is checked against ``calibration.json`` and the campaign's runs, never against
the code that formats it.
"""

from __future__ import annotations

import dataclasses
import hashlib
import html
import json
import re
from dataclasses import dataclass
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
import tomli_w
from matplotlib.figure import Figure

from forcecal.actuator import FrequencyLaw
from forcecal.campaign import (
    CampaignResult,
    calibrate_runs,
    reconstruct_campaign,
    write_calibration,
)
from forcecal.errors import RigError
from forcecal.io.manifest import write_manifest
from forcecal.io.run_files import write_run_csv
from forcecal.model.spatial import SpatialModel, build_spatial_model
from forcecal.provenance import provenance
from forcecal.report.certificate import calibration_certificate
from forcecal.report.pipeline import calibration_report
from forcecal.rig import Rig, load_rig, rig_to_dict
from forcecal.simulate.magnet import Drive
from forcecal.simulate.presets import Preset, RunSpec, get_preset
from forcecal.simulate.virtual_rig import build_model, public_rig, record_run, record_scan

GAPS = (0.8e-3, 1.0e-3, 1.2e-3)  # [m]
DC = 0.6  # [A]
AC = 0.2  # [A]
DURATION = 0.3  # [s]
DECLARED = {"current_scale": 0.002, "gap": 5e-6}  # the rig's [uncertainty] table
HOSTILE = "<script>alert('x')</script>&\"r\""

RANGE_RTOL = 5e-6  # the certificate's ranges carry six significant digits
FREQUENCY_ATOL = 1e-6  # [Hz] its frequencies eight (20.014123)
CORRELATION_ATOL = 5e-5  # its correlations four decimals
VALUE_ROUNDING = 0.06  # a value is rounded to the digit of u's second significant one


@dataclass(frozen=True)
class Certified:
    folder: Path
    rig: Rig
    model: SpatialModel
    result: CampaignResult
    page: str
    doc: dict


def _preset() -> Preset:
    base = get_preset("campaign")
    f = base.runs[0].drives[0].frequency
    runs = [RunSpec("tare", drives=(Drive("current", 0.0, 0.0, f),), gap=1.0e-3,
                    duration=DURATION, tare=True, labels={"repeat": "1"})]
    runs += [RunSpec(f"g{gap * 1e6:04.0f}", drives=(Drive("current", DC, AC, f),), gap=gap,
                     duration=DURATION, labels={"repeat": "1"}) for gap in GAPS]
    runs.append(RunSpec("g1000_r2", drives=(Drive("current", DC, AC, f, phase=1.3),),
                        gap=1.0e-3, duration=DURATION, labels={"repeat": "2"}))
    return dataclasses.replace(base, name="certificate campaign", runs=tuple(runs),
                               scan=dataclasses.replace(base.scan, n_points=41, record=0.3))


def _rig_file(path: Path, rig: Rig, acquisition: dict | None = None,
              uncertainty: dict | None = None) -> Rig:
    """The rig written as a lab would, with the given extra keys, and read back."""
    doc = rig_to_dict(rig)
    doc.pop("uncertainty", None)
    if uncertainty is not None:
        doc["uncertainty"] = uncertainty
    doc["acquisition"] = {**doc.get("acquisition", {}), **(acquisition or {})}
    path.write_text(tomli_w.dumps(doc), encoding="utf-8")
    return load_rig(path)


@pytest.fixture(scope="module")
def certified(tmp_path_factory) -> Certified:
    folder = tmp_path_factory.mktemp("certificate")
    preset = _preset()
    rng = np.random.default_rng(3)
    beam = build_model(preset)
    rig = _rig_file(folder / "rig.toml", public_rig(preset), uncertainty=DECLARED)
    model = build_spatial_model(rig, record_scan(preset, rng, beam))
    rows = []
    for spec in preset.runs:
        run, _ = record_run(preset, spec, rng, beam)
        write_run_csv(run, folder / "runs" / f"{spec.name}.csv")
        rows.append({"run": f"runs/{spec.name}.csv", "gap": spec.gap, "tare": spec.tare,
                     **spec.labels})
    manifest = write_manifest(folder / "manifest.csv", rows)
    results = reconstruct_campaign(rig, model, manifest, workers=1)
    result = calibrate_runs(rig, results, manifest=str(manifest))
    out = folder / "out"
    write_calibration(result, out)
    page = calibration_report(rig, model, result, out).read_text(encoding="utf-8")
    doc = json.loads((out / "calibration.json").read_text(encoding="utf-8"))
    return Certified(folder, rig, model, result, page, doc)


class _Tables(HTMLParser):
    """Every table of a page by caption: rows of cell texts (a cell's lines joined by \\n)."""

    def __init__(self) -> None:
        super().__init__()
        self.tables: dict[str, list[list[str]]] = {}
        self._rows: list[list[str]] | None = None
        self._text: list[str] | None = None
        self._caption = ""

    def handle_starttag(self, tag: str, attrs: list) -> None:
        if tag == "table":
            self._rows, self._caption = [], ""
        elif tag == "tr" and self._rows is not None:
            self._rows.append([])
        elif tag in ("td", "th", "caption"):
            self._text = []
        elif tag == "span" and self._text:
            self._text.append("\n")

    def handle_endtag(self, tag: str) -> None:
        if tag in ("td", "th") and self._rows is not None and self._text is not None:
            self._rows[-1].append("".join(self._text).strip())
            self._text = None
        elif tag == "caption" and self._text is not None:
            self._caption, self._text = "".join(self._text).strip(), None
        elif tag == "table" and self._rows is not None:
            self.tables[self._caption] = self._rows
            self._rows = None

    def handle_data(self, data: str) -> None:
        if self._text is not None:
            self._text.append(data)


def _tables(page: str) -> dict[str, list[list[str]]]:
    parser = _Tables()
    parser.feed(page)
    return parser.tables


def _table(page: str, caption: str) -> list[list[str]]:
    """The table whose caption starts with ``caption``: header row first."""
    found = [rows for cap, rows in _tables(page).items() if cap.startswith(caption)]
    assert len(found) == 1, f"one table '{caption}...' expected, found {len(found)}"
    return found[0]


def _by_first(rows: list[list[str]]) -> dict[str, list[str]]:
    return {row[0]: row for row in rows[1:]}


def _numbers(cells: list[str]) -> list[float]:
    return [float(c) for c in cells]


def _two_digits(values: list[float]) -> list[float]:
    """What an uncertainty shows: two significant digits."""
    return [float(f"{v:.2g}") for v in values]


# --------------------------------------------------------------------------------------------
# the law and its uncertainties


def _si(unit: str) -> float:
    """The factor from a unit the certificate writes to SI."""
    return {"µm": 1e-6, "mm": 1e-3, "µA": 1e-6, "mA": 1e-3, "µWb": 1e-6, "mWb": 1e-3}.get(
        unit, 1.0)


def test_parameters_state_u_and_u_expanded_with_k2_in_lab_units(certified):
    doc = certified.doc
    rows = _table(certified.page, "Calibrated parameters")
    header, params = rows[0], _by_first(rows)
    assert doc["uncertainty"]["coverage_factor"] == 2
    u_col, big_u_col = header.index("std. uncertainty u"), header.index("expanded U (k = 2)")
    assert set(doc["param_names"]) <= set(params)
    for name in doc["param_names"]:
        row = params[name]
        f = _si(row[2])
        u = doc["stderr"][name]
        assert f * float(row[1]) == pytest.approx(doc["params"][name], abs=VALUE_ROUNDING * u)
        assert f * float(row[u_col]) == pytest.approx(float(f"{u:.2g}"), rel=1e-12)
        assert f * float(row[big_u_col]) == pytest.approx(float(f"{2 * u:.2g}"), rel=1e-12)
        assert float(row[big_u_col]) == pytest.approx(2 * float(row[u_col]), rel=0.06)
    assert params["s_fe"][2] == "µm"          # 4.97e-05 m as a laboratory writes it
    kt = params["K_total = 2 K"]
    assert float(kt[u_col]) == float(f"{doc['k_total']['stderr']:.2g}")
    assert float(kt[big_u_col]) == float(f"{doc['k_total']['expanded']:.2g}")
    assert "coverage factor k = 2" in certified.page
    assert "f = K i² / (s + s_fe)²" in certified.page


def test_correlation_matrix_is_the_calibrations(certified):
    rows = _table(certified.page, "Correlation matrix")
    names = certified.doc["uncertainty"]["param_names"]
    corr = np.array(certified.doc["uncertainty"]["correlation"])
    assert rows[0][1:] == names
    assert 0 < abs(corr[0, 1]) < 1
    for i, row in enumerate(rows[1:]):
        assert row[0] == names[i]
        np.testing.assert_allclose([float(c) for c in row[1:]], corr[i], atol=CORRELATION_ATOL)


def test_calibrated_range_is_the_campaigns_min_and_max(certified):
    runs = certified.doc["runs"]
    rows = _by_first(_table(certified.page, "Calibrated range"))
    expected = {
        "coil current i": (min(r["current_range"][0] for r in runs),
                           max(r["current_range"][1] for r in runs)),
        "static air gap (every pole)": (min(min(r["static_gap"]) for r in runs),
                                        max(max(r["static_gap"]) for r in runs)),
        "instantaneous air gap s": (min(r["gap_range"][0] for r in runs),
                                    max(r["gap_range"][1] for r in runs)),
        "drive frequency (refined, every run)": (min(r["f0_hz"] for r in runs),
                                                 max(r["f0_hz"] for r in runs)),
        "total actuator force": (min(r["force_range"][0] for r in runs),
                                 max(r["force_range"][1] for r in runs)),
    }
    assert expected["static air gap (every pole)"] == pytest.approx((min(GAPS), max(GAPS)))
    for label, (lo, hi) in expected.items():
        tol = {"abs": FREQUENCY_ATOL} if "frequency" in label else {"rel": RANGE_RTOL}
        f = _si(rows[label][3])
        assert f * float(rows[label][1]) == pytest.approx(lo, **tol), label
        assert f * float(rows[label][2]) == pytest.approx(hi, **tol), label
    assert rows["instantaneous air gap s"][3] == rows["static air gap (every pole)"][3] == "mm"
    assert tuple(certified.doc["current_range"]) == pytest.approx(
        expected["coil current i"], rel=RANGE_RTOL)


def test_budget_rows_are_the_sources_of_calibration_json(certified):
    unc = certified.doc["uncertainty"]
    names = unc["param_names"]
    rows = _table(certified.page, "Uncertainty budget")
    body = _by_first(rows)
    heads = [next(h for h in rows[0] if h.startswith(f"u({n})")) for n in names]
    cols = [rows[0].index(h) for h in heads]
    factors = np.array([_si(h[h.index("[") + 1:h.index("]")]) for h in heads])
    assert len(unc["budget"]) >= 6
    assert {k["kind"] for k in unc["budget"].values()} == {"statistical", "type B"}

    def shown(row: list[str]) -> np.ndarray:
        return factors * np.array(_numbers([row[c] for c in cols]))

    for source, entry in unc["budget"].items():
        row = body[source]
        assert row[1].startswith(entry["kind"]), source
        np.testing.assert_allclose(shown(row), _two_digits([entry[n] for n in names]),
                                   rtol=1e-12, err_msg=source)
    for label, part in (("statistical, combined", unc["statistical"]["stderr"]),
                        ("type B, combined", unc["type_b"]["stderr"]),
                        ("combined standard uncertainty u", unc["stderr"]),
                        ("expanded uncertainty U = k u (k = 2)", unc["expanded"])):
        np.testing.assert_allclose(shown(body[label]), _two_digits([part[n] for n in names]),
                                   rtol=1e-12, err_msg=label)


def test_budget_says_which_type_b_inputs_are_defaults(certified):
    body = _by_first(_table(certified.page, "Uncertainty budget"))
    assert body["current scale"][2:4] == ["0.2 % (relative)", "declared by the rig"]
    assert body["static gaps"][2:4] == ["5 µm", "declared by the rig"]
    assert body["gauge sensitivity"][2:4] == ["0.5 % (relative)", "documented default"]
    assert body["masses"][3] == "documented default"
    assert ("declares current_scale, gap; forcecal's documented defaults are used for "
            "gauge_scale, probe_scale, position, mass.") in html.unescape(certified.page)


def test_budget_without_an_uncertainty_table_says_every_input_is_a_default(certified, tmp_path):
    rig = _rig_file(tmp_path / "rig.toml", certified.rig)
    assert not rig.type_b.declared
    unc = dataclasses.replace(certified.result.uncertainty, type_b_used=rig.type_b)
    page = calibration_certificate(rig, dataclasses.replace(certified.result, uncertainty=unc),
                                   provenance([]))
    body = _by_first(_table(page, "Uncertainty budget"))
    origins = {body[s][3] for s in ("current scale", "static gaps", "gauge sensitivity",
                                    "probe sensitivity", "positions", "masses")}
    assert origins == {"documented default"}
    assert "every type-B input above is forcecal's documented default" in html.unescape(page)


# --------------------------------------------------------------------------------------------
# the rest of the page


def test_candidate_laws_are_a_table_and_nothing_is_preformatted(certified):
    page = certified.page
    assert "<pre" not in page
    rows = _table(page, "Candidate laws fitted to the reconstructed force")
    laws = {row["law"] for row in certified.doc["candidates"] if "skipped" not in row}
    assert {row[0] for row in rows[1:]} == laws
    chosen = [row[0] for row in rows[1:] if row[-1] == "chosen"]
    assert chosen == [certified.doc["chosen"]["law"]]
    assert _table(page, "Reactions only (inertia ignored)")[1][2] == (
        certified.doc["reactions_only"]["chosen"])
    assert _table(page, "Repeated setpoints")[1][1].split("\n") == ["g1000", "g1000_r2"]
    assert not re.search(r'(src|href)="(?!data:)', page)  # self-contained
    assert page.count('src="data:image/png;base64,') == 1  # fig. 9


def test_validity_domain_states_the_ranges_of_the_samples(certified):
    rows = _by_first(_table(certified.page, "Domain checked"))
    runs = certified.result.runs
    gaps = np.concatenate([r.samples.gaps for r in runs])          # (n_obs, n_poles) [m]
    expected = {"coil current i": (certified.doc["current_range"], 1.0, "A")}
    for p in range(gaps.shape[1]):
        expected[f"air gap of pole {p + 1} s{p + 1}"] = (
            (gaps[:, p].min(), gaps[:, p].max()), 1e3, "mm")
    assert set(rows) == set(expected)   # one frequency, a (current, gap) law: no f, no flux
    for label, ((lo, hi), factor, unit) in expected.items():
        assert rows[label][3] == unit
        assert float(rows[label][1]) == pytest.approx(factor * lo, rel=RANGE_RTOL), label
        assert float(rows[label][2]) == pytest.approx(factor * hi, rel=RANGE_RTOL), label
    assert rows["coil current i"][4].startswith("warns; refuses beyond 10 ×")


def test_validity_domain_states_the_departure_at_the_edges(certified):
    rows = _table(certified.page, "Departure of the law from the data at the domain's edges")
    body = _by_first(rows)
    run_res = certified.result.run_residual
    n_obs = sum(r.samples.n for r in certified.result.runs)
    every = body["every calibration sample"]
    assert int(every[2]) == n_obs
    # the runs hold as many samples each: the RMS over all is that of the runs' own RMS
    assert float(every[3].rstrip(" %")) == pytest.approx(
        100 * np.sqrt(np.mean(run_res ** 2)), abs=5e-4)
    edges = [name for name in body if "tenth" in name]
    assert edges == ["lowest tenth of coil current", "highest tenth of coil current",
                     "lowest tenth of air gap of pole 1", "highest tenth of air gap of pole 1",
                     "lowest tenth of air gap of pole 2", "highest tenth of air gap of pole 2"]
    currents = np.concatenate([r.samples.current for r in certified.result.runs])
    low, high = body["lowest tenth of coil current"], body["highest tenth of coil current"]
    assert int(low[2]) == int(high[2]) == int(np.ceil(0.1 * n_obs))
    assert float(low[1].split()[1]) == pytest.approx(currents.min(), rel=RANGE_RTOL)
    assert float(high[1].split()[3]) == pytest.approx(currents.max(), rel=RANGE_RTOL)
    for name in edges:   # an edge's RMS is no more than its largest residual
        rms, top = float(body[name][3].rstrip(" %")), abs(float(body[name][4].rstrip(" %")))
        assert 0 < rms <= top + 1e-3, name


def test_validity_domain_says_why_each_candidate_was_not_chosen(certified):
    rows = _by_first(_table(certified.page, "Candidates not chosen, and why"))
    doc = certified.doc
    chosen = doc["chosen"]["law"]
    others = {row["law"]: row for row in doc["candidates"] if row["law"] != chosen}
    assert set(rows) == set(others) and chosen not in rows
    for name, row in others.items():
        why = rows[name][3]
        if "skipped" in row:
            assert why.startswith("not fitted: ")
        else:
            assert float(rows[name][2].rstrip(" %")) == pytest.approx(
                100 * row["held_out"], abs=5e-4)
            assert why.startswith(("held-out error above", "held-out error within",
                                   "as simple and as good")), why


def test_validity_domain_with_a_frequency_law_states_its_band_and_models(certified):
    result = certified.result
    cal = result.calibration
    band = (12.5, 80.0)                                                  # [Hz]
    fl = FrequencyLaw(
        k=1e-5, s_fe=5e-5, tau=1e-3, covariance=np.eye(3) * 1e-12, n_poles=cal.n_poles,
        frequency_range=band, current_range=cal.current_range, gap_range=cal.gap_range,
        model="first-order", reason="'first-order' is the simplest model",
        candidates=({"model": "first-order", "held_out": 0.010, "bic": -50.0},
                    {"model": "half-order", "held_out": 0.040, "bic": -40.0},
                    {"model": "lumped", "skipped": "too few steps"}))
    page = calibration_certificate(
        certified.rig, dataclasses.replace(result, calibration=cal.with_frequency_law(fl)),
        provenance([]))
    ranges = _by_first(_table(page, "Domain checked"))
    assert _numbers(ranges["drive frequency f"][1:3]) == list(band)
    assert ranges["drive frequency f"][3] == "Hz"
    edges = _by_first(_table(page, "Departure of the law"))
    assert {"lowest tenth of drive frequency", "highest tenth of drive frequency"} <= set(edges)
    why = _by_first(_table(page, "Candidates not chosen, and why"))
    assert "frequency model 'first-order'" not in why
    assert why["frequency model 'half-order'"][2] == "4.000 %"
    assert why["frequency model 'half-order'"][3].startswith("held-out error above the best's "
                                                             "(1.000 %)")
    assert why["frequency model 'lumped'"][3] == "not fitted: too few steps"
    assert "Frequency steps the" not in page                   # no step: nothing unmatched


def test_validity_domain_names_the_frequency_steps_the_law_misses(certified):
    """A step 5 % below the first-order law's K(f) at 40 Hz (0.1 % uncertainty), another on it:
    the first is named with its departure, the second not."""
    from forcecal.actuator.frequency import FrequencyStep

    result = certified.result
    cal = result.calibration
    fl = FrequencyLaw(k=1e-5, s_fe=5e-5, tau=1e-3, covariance=np.eye(3) * 1e-14,
                      n_poles=cal.n_poles, frequency_range=(10.0, 40.0),
                      current_range=cal.current_range, gap_range=cal.gap_range)
    steps = []
    for f, off in ((10.0, 0.0), (40.0, -0.05)):
        g, lag = float(fl.gain(f)[0]), float(fl.lag_deg(f)[0])
        steps.append(FrequencyStep(frequency=f, n_runs=3, gain=g + off, gain_std=1e-3,
                                   k=1e-5 * (g + off), k_std=1e-8, lag_deg=lag,
                                   lag_deg_std=0.05))
    fl = dataclasses.replace(fl, steps=tuple(steps))
    page = calibration_certificate(
        certified.rig, dataclasses.replace(result, calibration=cal.with_frequency_law(fl)),
        provenance([]))
    missed = _by_first(_table(page, "Frequency steps the first-order law does not match"))
    assert list(missed) == ["40 Hz"], missed
    assert missed["40 Hz"][1] == f"{100 * 0.05 / steps[1].gain:+.3f} %"


def test_provenance_gives_the_sha256_of_every_input(certified):
    inputs = _by_first(_table(certified.page, "Input files"))
    files = [certified.folder / "rig.toml", certified.folder / "manifest.csv",
             *sorted((certified.folder / "runs").glob("*.csv"))]
    assert len(files) == 2 + 1 + len(GAPS) + 1  # the tare and the repeat too
    digests = {row[2] for row in inputs.values()}
    for f in files:
        assert hashlib.sha256(f.read_bytes()).hexdigest() in digests, f.name
    own = hashlib.sha256((certified.folder / "out" / "calibration.json").read_bytes())
    assert own.hexdigest() in certified.page
    assert "Command" in certified.page and "forcecal" in certified.page


def test_a_hostile_run_name_and_label_are_escaped(certified):
    result = certified.result
    first = result.runs[0]
    hostile = dataclasses.replace(
        first, estimate=dataclasses.replace(first.estimate, run_name=HOSTILE),
        entry=dataclasses.replace(first.entry, labels={"operator": HOSTILE}))
    page = calibration_certificate(
        certified.rig, dataclasses.replace(result, runs=(hostile, *result.runs[1:])),
        provenance([]))
    assert "<script>" not in page
    assert "&lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt;&amp;&#34;r&#34;" in page
    runs = _by_first(_table(page, "The campaign's runs"))
    assert HOSTILE in runs
    assert runs[HOSTILE][-1] == f"operator = {HOSTILE}"


def test_temperature_is_stated_when_the_rig_gives_it(certified, tmp_path):
    warm = _rig_file(tmp_path / "warm.toml", certified.rig, acquisition={"temperature": 23.4},
                     uncertainty=DECLARED)
    assert warm.temperature == 23.4
    page = calibration_certificate(warm, certified.result, provenance([]))
    conditions = _by_first([[], *_table(page, "Conditions of the measurements")])
    assert conditions["ambient temperature"][1].startswith("23.4 °C")
    assert conditions["nominal drive frequency"][1].startswith(f"{certified.rig.frequency:g} Hz")
    assert certified.rig.temperature is None
    plain = _by_first([[], *_table(certified.page, "Conditions of the measurements")])
    assert "ambient temperature" not in plain
    assert "°C" not in certified.page


def test_rig_temperature_is_read_checked_and_written_back(certified, tmp_path):
    warm = _rig_file(tmp_path / "warm.toml", certified.rig, acquisition={"temperature": -5})
    assert warm.temperature == -5.0
    assert rig_to_dict(warm)["acquisition"]["temperature"] == -5.0
    assert "temperature" not in rig_to_dict(certified.rig)["acquisition"]
    with pytest.raises(RigError, match=r"key 'acquisition.temperature' = 296.15 °C .*kelvin"):
        _rig_file(tmp_path / "kelvin.toml", certified.rig, acquisition={"temperature": 296.15})
    with pytest.raises(RigError, match=r"acquisition\.temperature' must be a number"):
        _rig_file(tmp_path / "text.toml", certified.rig, acquisition={"temperature": "warm"})


# --------------------------------------------------------------------------------------------
# presentation: lab units, paths, the figure's format


def test_runs_state_gaps_in_mm_and_digits_by_their_uncertainty(certified):
    rows = _table(certified.page, "The campaign's runs")
    header, runs = rows[0], _by_first(rows)
    assert header[1] == "static gap [mm]"
    assert {runs[r.name][1] for r in certified.result.runs} == {"0.800", "1.000", "1.200"}
    for r in certified.result.runs:
        mean, u = r.estimate.total[0].real, r.estimate.total_std[0]
        shown = runs[r.name][header.index("mean force [N]")]
        assert float(shown) == pytest.approx(mean, abs=VALUE_ROUNDING * u)
        # the last digit shown is that of u's second significant one
        assert 10 ** -len(shown.split(".")[1]) == pytest.approx(
            10 ** (np.floor(np.log10(float(f"{u:.2g}"))) - 1))


def test_every_input_path_is_relative_to_the_stated_root(certified):
    page = html.unescape(certified.page)
    root = str(certified.folder)
    assert f"<code>{root}</code>" in page
    inputs = _table(certified.page, "Input files")[1:]
    assert {row[0] for row in inputs} >= {"rig.toml", "manifest.csv", "runs/tare.csv"}
    assert not [row[0] for row in inputs if row[0].startswith("/")]
    assert "<dt>Rig file</dt><dd><code>rig.toml</code>" in page
    assert "<dt>Campaign manifest</dt><dd><code>manifest.csv</code>" in page


@pytest.mark.parametrize("fmt", ["svg", "pdf"])
def test_the_figure_is_written_in_the_format_asked_for(certified, tmp_path, fmt, monkeypatch):
    drawn = []

    def small(points, law):                   # fig. 9 is tested apart; a cheap stand-in here
        drawn.append(points.n_runs)
        fig = Figure(figsize=(12.0, 3.0))
        fig.add_subplot().plot([0, 1], [1, 0])
        return fig

    monkeypatch.setattr("forcecal.report.pipeline.fig_calibration", small)
    out = tmp_path / "out"
    page = calibration_report(certified.rig, certified.model, certified.result, out,
                              figure_format=fmt).read_text(encoding="utf-8")
    assert drawn == [len(certified.result.runs)]
    assert [p.name for p in (out / "figures").iterdir()] == [f"calibration.{fmt}"]
    data = (out / "figures" / f"calibration.{fmt}").read_bytes()
    if fmt == "svg":                       # embedded as it is
        assert b"<svg" in data and page.count('src="data:image/svg+xml;base64,') == 1
    else:                                  # linked, beside an embedded PNG preview
        assert data.startswith(b"%PDF")
        assert '<a href="figures/calibration.pdf"><img src="data:image/png;base64,' in page
    # shown at the size it was drawn at: 12 inches at 96 CSS pixels each
    assert re.search(r'<img src="data:[^"]+" width="1152"', page)
    assert "Fig. 1 (after the paper&#39;s fig. 9)" in page


def test_the_runs_notes_are_stated_once_per_kind(certified):
    # the same note but for its numbers is one kind, the commonest first; without any note the
    # page says that no run drew one
    runs = certified.result.runs
    tare = "run 'a/{}.csv': the tare 'a/tare.csv' reads {:.2f} N on the gauges"
    drawn = [dataclasses.replace(r, estimate=dataclasses.replace(
        r.estimate, notes=(tare.format(r.name, 25.0 + k),
                           *(("harmonic 5: no shape in the scan model",) if k == 0 else ()))))
        for k, r in enumerate(runs)]
    noted = dataclasses.replace(certified.result, runs=tuple(drawn))
    page = calibration_certificate(certified.rig, noted, provenance({}))
    rows = _table(page, "Notes the runs drew")
    assert rows[1:] == [["the tare 'a/tare.csv' reads 25.00 N on the gauges",
                         f"{len(runs)} of {len(runs)}", runs[0].name],
                        ["harmonic 5: no shape in the scan model", f"1 of {len(runs)}",
                         runs[0].name]]
    quiet = dataclasses.replace(certified.result, runs=tuple(
        dataclasses.replace(r, estimate=dataclasses.replace(r.estimate, notes=()))
        for r in runs))
    page = calibration_certificate(certified.rig, quiet, provenance({}))
    assert "No run drew a note" in page and "Notes the runs drew" not in page

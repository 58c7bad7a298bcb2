"""Write a simulated campaign in the public formats (INTERFACES.md section 5, ``simulate``).

``OUT/rig.toml``, ``OUT/scan.uff`` (and ``OUT/scan2.uff``, ``OUT/scan3.uff``, ... when the rig
is scanned under more than one load), ``OUT/runs/*.csv``, ``OUT/manifest.csv`` for the user's
side; ``OUT/truth/NAME.forces.csv``, ``OUT/truth/NAME.npz`` and ``OUT/truth/simulator.json``
(the parameters the lab would not know, every scan's and run's drives, reference coil and static
gaps) for checking any estimate against the truth: the data sets of the virtual rig (METHOD.md
section 6) whose true forces are known.

A ``lab`` rig also states every drawn error in the truth; a rig under broadband drives writes
its band and ``drive = "any"`` in the rig file, and its scans may be written as SLDV software
exports FRFs (:func:`write_simulation` tells both).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w

from .._atomic import atomic_path, write_text_atomic
from ..errors import InputError
from ..io.manifest import write_manifest
from ..io.run_files import write_run_csv, write_table_csv
from ..io.uff import write_frf_uff, write_scan_uff
from ..records import Scan
from ..rig import rig_to_dict
from .beam import natural_frequencies
from .lab import draw_errors, record_lab_scan
from .magnet import KNEE, Drive
from .physics import Model, Truth, build_model, scan_file, static_gaps
from .presets import BodySpec, PlateSpec, Preset, get_preset, with_realism, with_tare
from .realism import Realism
from .sldv_frf import frf_export
from .virtual_rig import public_rig, record_run, record_scan

__all__ = ["check_scan_export", "write_simulation"]

SCAN_EXPORTS = ("time", "frfs")
"""How a simulation writes its scans: time records, or (a broadband rig) FRFs and coherences."""
BANDWIDTH = 2.56
"""An FRF export's top line is the sampling rate over this (the usual anti-aliased bandwidth)."""


def write_truth(out: Path, name: str, truth: Truth) -> None:
    """The truth of one run: forces as a reconstruct-style CSV, the rest as NPZ.

    Parameters
    ----------
    out : Path
        The truth folder; ``NAME.forces.csv`` and ``NAME.npz`` are written there atomically
        (the NPZ holds the time series, every pole's static gap, ``static_gap`` [m], and a
        ``lab`` rig's ``imperfections``).
    name : str
        The run's name.
    truth : Truth
        What the virtual rig did during the run.
    """
    cols = {n: truth.pole_force[k] for k, n in enumerate(truth.pole_names)}
    cols["total"] = truth.pole_force.sum(axis=0)
    write_table_csv(out / f"{name}.forces.csv", truth.t, cols)
    arrays: dict[str, Any] = dict(
        time=truth.t, pole_names=np.array(truth.pole_names), pole_force=truth.pole_force,
        gap=truth.gap, nodes=truth.nodes, w=truth.w.astype(np.float32), inertia=truth.inertia,
        current=truth.current, flux=truth.flux, static_gap=truth.static_gap,
        **truth.imperfections)
    with atomic_path(out / f"{name}.npz") as tmp:
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, **arrays)


def _structure_facts(preset: Preset) -> dict:
    s = preset.beam
    if isinstance(s, BodySpec):
        return {
            "structure": "body",
            "size_m": list(s.size), "youngs_modulus_Pa": s.youngs_modulus,
            "poisson": s.poisson, "density_kg_m3": s.density, "mesh": list(s.mesh),
            "gauge_stiffness_N_m": s.gauge_stiffness,
        }
    if isinstance(s, PlateSpec):
        return {
            "structure": "plate",
            "size_m": [s.a, s.b], "thickness_m": s.thickness,
            "youngs_modulus_Pa": s.youngs_modulus, "poisson": s.poisson,
            "flexural_rigidity_Nm": s.flexural_rigidity,
            "mass_per_area_kg_m2": s.mass_per_area,
            "mesh": list(s.mesh),
            "gauge_stiffness_N_m": s.gauge_stiffness,
        }
    return {
        "bending_stiffness_Nm2": s.ei,
        "mass_per_length_kg_m": s.mass_per_length,
        "gauge_stiffness_N_m": s.gauge_stiffness,
    }


def _drives(preset: Preset, drives: tuple[Drive, ...]) -> list[dict]:
    """Every coil's drive, named by its current channel (with its ``waveform`` when it has
    one)."""
    out = []
    for m, d in zip(preset.magnets, drives, strict=True):
        row: dict[str, Any] = {"coil": m.current_channel, "source": d.source, "dc": d.dc,
                               "ac": d.ac, "frequency_Hz": d.frequency, "phase_rad": d.phase,
                               "harmonics": [list(h) for h in d.harmonics]}
        if d.waveform is not None:
            row["waveform"] = d.waveform.describe()
        out.append(row)
    return out


def _pole_gaps(preset: Preset, gap: float | None, gaps: dict[str, float]) -> dict[str, float]:
    names = [p.name for m in preset.magnets for p in m.poles]
    return dict(zip(names, static_gaps(preset, gap, gaps).tolist(), strict=True))


def _scans_and_runs(preset: Preset) -> dict:
    """What every scan and run did: file, drives, reference coil, static gap of every pole."""
    scans = [{"file": scan_file(k), "reference": preset.magnets[s.reference].current_channel,
              "drives": _drives(preset, s.drives), "static_gap_m": _pole_gaps(preset, s.gap,
                                                                              s.gaps)}
             for k, s in enumerate(preset.scans)]
    runs = {r.name: {"drives": _drives(preset, r.drives),
                     "static_gap_m": _pole_gaps(preset, r.gap, r.gaps)} for r in preset.runs}
    return {"scans": scans, "runs": runs}


def _simulator_facts(preset: Preset) -> dict:
    model = build_model(preset)
    mag = preset.magnets[0]
    return {
        "preset": preset.name,
        "description": preset.description,
        **_structure_facts(preset),
        "damping_beta_s": model.beta,
        "natural_frequencies_Hz": natural_frequencies(model, 4).tolist(),
        "drive_frequency_Hz": preset.runs[0].drives[0].frequency,
        "nominal_frequency_Hz": preset.nominal_frequency,
        **({} if preset.band is None else {"band_Hz": list(preset.band)}),
        "magnet": {"turns": mag.turns, "pole_area_m2": mag.pole_area,
                   "iron_length_m": mag.iron_length, "mu_r": mag.mu_r,
                   "resistance_ohm": mag.resistance, "gap_offset_m": mag.gap_offset,
                   "ideal_K_total_Nm2_A2": mag.ideal_k,
                   **({"saturation_T": mag.saturation, "knee": KNEE} if mag.saturation
                      else {})},
        "noise": dict(vars(preset.noise)),
        **_eddy_facts(preset),
        **_scans_and_runs(preset),
    }


def _eddy_facts(preset: Preset) -> dict:
    """The eddy time of every magnet and the law it gives, when a core lags (else nothing);
    a solid or laminated core's diffusion and response instead (:func:`_diffusion_facts`)."""
    if any(m.core != "lag" for m in preset.magnets):
        return _diffusion_facts(preset)
    if not any(m.eddy_time > 0 for m in preset.magnets):
        return {}
    return {"eddy": {
        "eddy_time_s": {m.current_channel: m.eddy_time for m in preset.magnets},
        "model": "tau di_m/dt + i_m = i; flux and force from the magnetising current i_m",
        "law": "at a fixed gap the force's component at f over that of i^2: "
               "H(f) = 1 / (1 + j 2 pi f tau): K(f) = K / sqrt(1 + (2 pi f tau)^2), "
               "lag(f) = atan(2 pi f tau)"}}


def _diffusion_facts(preset: Preset) -> dict:
    """The cores of a rig whose flux diffuses into the iron: every magnet's core, diffusion
    time and nodes, and the truth of every run's drive frequency, ``K(f) / K`` and the lag
    [deg] of the simulated diffusion's own response (:func:`.core.diffusion_response`; a lag
    core's ``1 / (1 + j 2 pi f tau)``)."""
    mags = preset.magnets
    freqs = sorted({float(d.frequency) for r in preset.runs if not r.tare for d in r.drives})
    response = {}
    for m in mags:
        h = m.eddy_response(np.array(freqs))
        response[m.current_channel] = [
            {"frequency_Hz": f, "gain": float(abs(v)), "lag_deg": float(-np.degrees(np.angle(v)))}
            for f, v in zip(freqs, h, strict=True)]
    return {"eddy": {
        "core": {m.current_channel: m.core for m in mags},
        "eddy_time_s": {m.current_channel: m.eddy_time for m in mags},
        "conductivity_S_m": {m.current_channel: m.conductivity for m in mags},
        "core_thickness_m": {m.current_channel: m.core_thickness for m in mags},
        "diffusion_time_s": {m.current_channel: m.diffusion_time for m in mags},
        "core_nodes": {m.current_channel: m.core_nodes for m in mags},
        "model": "du/dt = (1 / tau_d) d2u/dxi2 across the core's half-thickness (xi from 0 at "
                 "the mid-plane to 1 at the face), u(1) = i, du/dxi(0) = 0, tau_d = sigma mu "
                 "d^2; i_m = mean of u; flux and force from the magnetising current i_m; "
                 "linear finite elements in depth, trapezoidal rule in time",
        "law": "at a fixed gap the force's component at f over that of i^2: the discretised "
               "diffusion's response H(f), close to tanh(sqrt(j 2 pi f tau_d)) / "
               "sqrt(j 2 pi f tau_d): K(f) = K |H(f)|, lag(f) = -angle(H(f))",
        "response": response}}


def _rig_document(preset: Preset, averages: int | None = None) -> dict:
    """The public rig file's document; a rig under broadband drives also states its scan's
    ``band`` [Hz] and ``drive = "any"`` in ``[acquisition]``, and the ``scan_averages`` behind
    an FRF export."""
    doc = rig_to_dict(public_rig(preset))
    if preset.band is not None:
        acquisition = doc.setdefault("acquisition", {})
        acquisition["band"] = [float(preset.band[0]), float(preset.band[1])]
        acquisition["drive"] = "any"
        if averages is not None:
            acquisition["scan_averages"] = averages
    return doc


def _write_scan(preset: Preset, scan: Scan, path: Path, binary: bool, export: str
                ) -> int | None:
    """One scan written as time records, or as FRFs (returning their averages)."""
    if export == "time":
        write_scan_uff(scan, path, binary=binary)
        return None
    assert preset.band is not None, "check_scan_export refuses FRFs of a steady drive's scan"
    frfs, averages = frf_export(scan, preset.band, scan.fs / BANDWIDTH)
    write_frf_uff(frfs, path, binary=binary)
    return averages


def write_simulation(out: str | Path, preset_name: str | Preset = "paper", seed: int = 0,
                     progress: Callable[[str], None] | None = None,
                     binary_uff: bool = False,
                     realism: str | Realism | None = None, scan_export: str = "time") -> Path:
    """Simulate ``preset_name`` and write every file of the public formats under ``out``.

    Parameters
    ----------
    out : str or Path
        The output folder (see the module docstring for its layout).
    preset_name : str or Preset
        A name of :data:`forcecal.simulate.presets.PRESETS`, or a preset (a built-in one with
        fewer runs: a study that redraws one run's noise over many seeds).
    seed : int
        Seed of the measurement noise.
    progress : callable, optional
        Called with a short message before each stage.
    binary_uff : bool
        Write the scans as binary (58b) records instead of ASCII.
    realism : str, Realism or None
        ``"ideal"`` (white noise only) or ``"lab"`` (:class:`.realism.Realism` defaults), or a
        Realism; None keeps the preset's own (ideal for every built-in one).
    scan_export : {"time", "frfs"}
        The scans as time records, or (a rig under broadband drives) as SLDV software exports
        FRFs with their coherence.

    Returns
    -------
    Path
        ``out``.

    Raises
    ------
    InputError
        An unknown preset or scan export, or FRFs asked of a steady drive's scan.
    SimulationError
        A pole closes its gap or the magnetic circuit does not converge.

    Notes
    -----
    The noise of the first scan is drawn first, then the runs', then any further scan's, so
    a preset's first scan and runs do not depend on how many scans it has. A ``lab`` rig's
    errors are drawn before all of them.

    A ``lab`` rig (``realism``, :class:`.realism.Realism`) adds a zero-current tare run when
    the preset has none, declares its type-B uncertainties in ``rig.toml``, and states every
    drawn error in the truth: ``simulator.json``'s ``realism`` (the settings, every channel's
    sensitivity, every gauge's preload, offset and zero-current reading, each run's drive
    drift and chirp, each scan's drive level and frequency at every acquisition), and each
    run's NPZ (its ``imperfections``, :class:`.virtual_rig.Truth`).

    A rig under broadband drives (``Preset.band``: a sweep, random) writes its scan's
    ``band = [lo, hi]`` [Hz] and ``drive = "any"`` in the rig file's ``[acquisition]``; its
    runs that are not listed (``RunSpec.manifest`` false: the swept and random ones) are
    written with their truth but left out of ``manifest.csv``. A magnet whose core lags (eddy
    currents) has its ``eddy_time_s`` and the law it gives stated in ``simulator.json``'s
    ``eddy``; a solid or laminated core its diffusion and, per run frequency, the response
    its simulation has (``eddy.response``: ``K(f) / K`` and the lag). Such a rig's scans may
    be written as SLDV software exports FRFs (``scan_export="frfs"``, :mod:`.sldv_frf`): per
    point H1 and its coherence up to the acquisition's bandwidth (fs / 2.56), the averages
    behind them stated as ``acquisition.scan_averages``.
    """
    preset = (get_preset(preset_name, realism) if isinstance(preset_name, str)
              else with_realism(preset_name, realism))
    check_scan_export(preset, scan_export)
    if preset.realism is not None:
        preset = with_tare(preset)
    out = Path(out)
    rng = np.random.default_rng(seed)
    model = build_model(preset)
    say = progress or (lambda _msg: None)
    lab = _LabRecorder(preset, model, rng) if preset.realism is not None else None

    say("scan")
    scan = record_scan(preset, rng, model) if lab is None else lab.scan(0)
    averages = _write_scan(preset, scan, out / scan_file(0), binary_uff, scan_export)
    write_text_atomic(out / "rig.toml", tomli_w.dumps(_rig_document(preset, averages)))

    rows = []
    for k, spec in enumerate(preset.runs):
        say(f"run {k + 1}/{len(preset.runs)}: {spec.name}")
        run, truth = record_run(preset, spec, rng, model, None if lab is None else lab.errors)
        write_run_csv(run, out / "runs" / f"{spec.name}.csv")
        write_truth(out / "truth", spec.name, truth)
        if lab is not None:
            lab.note_run(spec.name, truth)
        if not spec.manifest:
            continue
        row: dict[str, object] = {"run": f"runs/{spec.name}.csv"}
        if spec.gap is not None:
            row["gap"] = spec.gap
        row.update({f"gap_{pole}": gap for pole, gap in spec.gaps.items()})
        row["tare"] = "true" if spec.tare else "false"
        row.update(spec.labels)
        rows.append(row)
    for k in range(1, len(preset.scans)):
        say(f"scan {k + 1}/{len(preset.scans)}")
        more = record_scan(preset, rng, model, which=k) if lab is None else lab.scan(k)
        _write_scan(preset, more, out / scan_file(k), binary_uff, scan_export)
    write_manifest(out / "manifest.csv", rows)
    facts = _simulator_facts(preset)
    if lab is not None:
        facts["realism"] = lab.facts()
    write_text_atomic(out / "truth" / "simulator.json", json.dumps(facts, indent=2))
    return out


def check_scan_export(preset: Preset, scan_export: str) -> None:
    """InputError for an unknown scan export, or FRFs of a steady drive's scan (their phases are
    relative to the reference at each line: no steady model can be built from them)."""
    if scan_export not in SCAN_EXPORTS:
        raise InputError(f"scan export '{scan_export}' is not one of {', '.join(SCAN_EXPORTS)}")
    if scan_export == "frfs" and preset.band is None:
        raise InputError(f"preset '{preset.name}' scans under a steady drive, whose model is "
                         "not built from FRFs; FRFs are exported for a broadband preset (sweep, "
                         "random)")


class _LabRecorder:
    """A ``lab`` rig's drawn errors, and the drifts of the runs and scans recorded with them."""

    def __init__(self, preset: Preset, model: Model, rng: np.random.Generator):
        self.preset, self.model, self.rng = preset, model, rng
        self.errors = draw_errors(preset, model, rng)
        self.walks: dict[int, dict] = {}
        self.runs: dict[str, dict] = {}

    def scan(self, which: int) -> Scan:
        """Record scan ``which``; keep its walk."""
        scan, walk = record_lab_scan(self.preset, self.rng, self.model, which, self.errors)
        self.walks[which] = {"file": scan_file(which), "drive_level": walk.level.tolist(),
                             "frequency_Hz": walk.frequency.tolist(),
                             "start_sample": walk.start.tolist()}
        return scan

    def note_run(self, name: str, truth: Truth) -> None:
        """Keep run ``name``'s drive drift and chirp."""
        self.runs[name] = {"drive_drift_per_s": float(truth.imperfections["drive_drift"]),
                           "drive_chirp_per_s": float(truth.imperfections["drive_chirp"])}

    def facts(self) -> dict:
        """The settings and every drawn error, for ``simulator.json``."""
        assert self.preset.realism is not None
        return {"settings": self.preset.realism.describe(), **self.errors.as_dict(),
                "runs": self.runs, "scans": [self.walks[k] for k in sorted(self.walks)]}

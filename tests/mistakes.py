"""The mistake campaign (issue 34): one plausible lab mistake at a time on the virtual rig, and
forcecal's verdict on each.

Shared by ``tests/forces/test_mistakes.py`` (the mistakes forcecal catches today, on one small
lab) and ``benchmarks/mistakes.py`` (every mistake on its presets, the "before" table of issue
34). A lab is simulated and scanned once (:func:`build_lab`: ``forcecal simulate``, then
``forcecal scan``); a mistake (:data:`MISTAKES`) edits a copy of the lab's rig (TOML), run
(CSV), tare or scan in a working :class:`Case`, and :func:`verdict` runs ``forcecal
reconstruct`` on it through :func:`forcecal.cli.main` (re-scanning first when the mistake
changes what the spatial model depends on: the rig's geometry and masses, the scan, the
scan's options) and judges the outcome:

- **refused**: exit status 2 (the message is kept, and whether it names the cause);
- **noted**: exit 0 and a note the clean run does not have that names the mistake's cause: one
  of its ``channels`` (the channel or key, or the kind of sensor) and one of its ``words``
  (what is wrong with it: scale, sign, skew, tare...), each matched as a whole word, any case;
- **wrong note**: exit 0, no such note, but a new note that blames a gauge or a probe;
- **harmless**: every force and the total within :data:`K_BOUND` times its stated uncertainty
  (RMS error over the RMS of the ``_std`` column), or within :data:`CLEAN_FACTOR` times the
  clean run's own error;
- **silently wrong**: anything else.

Errors are against the simulator's truth (``truth/NAME.forces.csv``) at the samples the run
kept (a skew or a truncation drops some; a time base stretches the time stamps, never the
samples), DC included, in % of the true total's AC RMS. A note is new when its shape (quoted
file names and numbers aside) is not among the clean run's notes; warnings on stderr count as
notes.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import re
import tempfile
import tomllib
import zlib
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import tomli_w

REFUSED, NOTED, WRONG_NOTE, HARMLESS, SILENT = (
    "refused", "noted", "wrong note", "harmless", "silently wrong")
VERDICTS = (REFUSED, NOTED, WRONG_NOTE, HARMLESS, SILENT)
CLEAN = "clean"
"""The verdict of the clean run (the baseline)."""
BLAME = ("wrong", "off by", "explained by", "closest", "likely")
"""What a note says of a sensor it blames (beside naming it)."""
K_BOUND = 3.0
"""A force within K_BOUND times its stated standard uncertainty is right."""
CLEAN_FACTOR = 1.5
"""...and so is one within CLEAN_FACTOR times the clean run's own error."""


# --------------------------------------------------------------------------------------------
# the lab


@dataclass(frozen=True)
class LabSpec:
    """How a lab is simulated and which of its records the campaign uses."""

    preset: str                      # forcecal simulate --preset
    realism: str                     # --realism
    run: str                         # the run's file stem
    scans: tuple[str, ...]           # the scans the model is built from
    tare: str | None = None          # the tare's file stem, passed to every reconstruct
    duration: float | None = None    # [s] the run's first part only (None: all of it)
    flux: bool = True                # False: the rig's flux channels and pole area left out
    only_run: bool = False           # the false-alarm survey takes ``run`` alone, not the folder
    zeroed: float | None = None      # [N] the gauges zeroed to within this (:func:`rezero`)


LABS = {
    "paper": LabSpec("paper", "ideal", "paper", ("scan.uff",)),
    "paper-lab": LabSpec("paper", "lab", "paper", ("scan.uff",), tare="tare"),
    "paper-lab-0.5s": LabSpec("paper", "lab", "paper", ("scan.uff",), tare="tare",
                              duration=0.5),
    "tilt": LabSpec("tilt", "ideal", "g0800_1200_dc08_ac02", ("scan.uff", "scan2.uff"),
                    tare="tare"),
    "two-coil": LabSpec("two-coil", "ideal", "b_changed", ("scan.uff", "scan2.uff")),
    "paper-noflux": LabSpec("paper", "lab", "paper", ("scan.uff",), tare="tare", flux=False),
    "campaign": LabSpec("campaign", "lab", "g1000_dc06_ac02", ("scan.uff",), tare="tare"),
    "random-lab": LabSpec("random", "lab", "random", ("scan.uff",), tare="tare", only_run=True),
    "sweep-lab": LabSpec("sweep", "lab", "sweep", ("scan.uff",), tare="tare", only_run=True),
    "paper-zeroed": LabSpec("paper", "lab", "paper", ("scan.uff",), tare="tare", zeroed=0.05),
}
"""The labs: ``paper`` (ideal sensors, poles that pull alike), ``paper-lab`` (lab realism:
coloured noise, hum, drawn sensitivities, gravity preload, gauge offsets, a tare;
``paper-lab-0.5s``: its run's first 10 periods, as long as the campaigns' runs), ``tilt`` (two
poles on one current at unequal gaps, 0.8 / 1.2 mm: F1 pulls 2.2 times F2, so swaps show;
modelled from both its scans), ``two-coil`` (two coils driven apart, both scans) and
``paper-noflux`` (``paper-lab`` without a flux channel: only the run, the scan and the tare
check the estimate), ``campaign`` (lab realism; runs at three gaps and six currents, scanned
at one: for the false alarms of the checks against the scan), and under any drive
``random-lab`` and ``sweep-lab`` (lab realism; a band-limited random run, a swept sine; for
the false alarms of the cross-checks on a spectrum's lines), ``paper-zeroed`` (``paper-lab``
whose gauges were zeroed to within 0.05 N without the beam, its rig saying so in ``[weight]``:
the tare weighs the beam to 0.1 N of its 24.6 N)."""


@dataclass
class Lab:
    """A simulated lab, scanned once, and its clean verdict (the baseline)."""

    name: str
    seed: int
    root: Path
    spec: LabSpec
    rig: dict
    run: pd.DataFrame
    truth: pd.DataFrame
    tare: pd.DataFrame | None
    scans: list[Path]
    model: Path
    clean: Result | None = None

    @property
    def names(self) -> dict[str, str]:
        """Channel and key names by role: g0, g1... (gauges), p0... (probes), f0... (forces),
        i (the current channel), phi (the flux channel)."""
        out = {f"g{k}": g["name"] for k, g in enumerate(self.rig["gauges"])}
        out |= {f"p{k}": s["name"] for k, s in enumerate(self.rig["sensors"])}
        out |= {f"f{k}": f["name"] for k, f in enumerate(self.rig["forces"])}
        out["i"] = self.rig.get("actuator", {}).get("current", "i")
        out["phi"] = self.rig.get("actuator", {}).get("flux", "flux")
        return out

    @property
    def force_names(self) -> list[str]:
        return [f["name"] for f in self.rig["forces"]]

    @property
    def sensor_terms(self) -> tuple[str, ...]:
        """What a note names when it blames a gauge or a probe."""
        return (*(g["name"] for g in self.rig["gauges"]),
                *(s["name"] for s in self.rig["sensors"]),
                "gauge", "gauges", "probe", "probes")

    @property
    def fs(self) -> float:
        t = self.run["time"].to_numpy()
        return float((len(t) - 1) / (t[-1] - t[0]))

    @property
    def f0(self) -> float:
        """[Hz] the clean run's refined fundamental."""
        assert self.clean is not None
        return self.clean.f0

    def higher_harmonics_share(self) -> float:
        """[%] the true total's harmonics above the fundamental, of its AC RMS."""
        if not math.isfinite(self.f0):
            return math.nan                      # any drive: no fundamental
        total = self.truth["total"].to_numpy()
        t = self.truth["time"].to_numpy()
        w = 2 * np.pi * self.f0 * t
        basis = np.column_stack([np.ones_like(t), np.cos(w), np.sin(w)])
        first = basis @ np.linalg.lstsq(basis, total, rcond=None)[0]
        return 100 * _rms(total - first) / _rms(total - total.mean())


def quiet_main(argv: list[str]) -> tuple[int, str]:
    """``forcecal.cli.main(argv)`` in process: its exit status and stderr."""
    from forcecal.cli.main import main

    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        code = main([str(a) for a in argv])
    return code, err.getvalue()


def build_lab(preset: str, seed: int, folder: Path, *, duration: float | None = None,
              scan_step: int = 1) -> Lab:
    """Simulate the lab ``preset`` (a key of :data:`LABS`) at ``seed`` into ``folder``, scan it
    once (``model.json``) and reconstruct its clean run (``lab.clean``).

    ``duration`` [s] (default: the lab's own) keeps the first part of the run, its truth and
    its tare; ``scan_step`` keeps every that many scan points (both for fast tests). The scans
    are kept as NPZ beside the UFF (the same records, faster to read again when a mistake
    re-scans).
    """
    from forcecal.io.scan_files import read_scan, write_scan_npz
    from forcecal.records import Scan

    spec = LABS[preset]
    duration = spec.duration if duration is None else duration
    root = Path(folder) / f"{preset}-{seed}"
    code, err = quiet_main(["simulate", root, "--preset", spec.preset, "--seed", seed,
                            "--realism", spec.realism])
    assert code == 0, err
    scans = []
    for name in spec.scans:
        scan = read_scan(root / name)
        assert isinstance(scan, Scan)
        scan = Scan(points=scan.points[::scan_step], response=scan.response[::scan_step],
                    reference=scan.reference[::scan_step], fs=scan.fs, quantity=scan.quantity)
        scans.append(write_scan_npz(scan, root / f"{Path(name).stem}.npz"))
    run, truth = (_read_csv(root / "runs" / f"{spec.run}.csv", duration),
                  _read_csv(root / "truth" / f"{spec.run}.forces.csv", duration))
    tare = None if spec.tare is None else _read_csv(root / "runs" / f"{spec.tare}.csv", duration)
    rig = tomllib.loads((root / "rig.toml").read_text(encoding="utf-8"))
    if not spec.flux:
        for key in ("flux", "pole_area"):
            rig["actuator"].pop(key, None)
        for force in rig["forces"]:
            force.pop("flux", None)
    if spec.zeroed is not None:
        assert tare is not None
        rezero(root, rig, [run, tare], spec.zeroed, np.random.default_rng([seed, 34]))
    (root / "rig.toml").write_text(tomli_w.dumps(rig), encoding="utf-8")
    model = root / "model.json"
    code, err = quiet_main(["scan", root / "rig.toml", *scans, "-o", model])
    assert code == 0, err
    lab = Lab(name=preset, seed=seed, root=root, spec=spec, rig=rig, run=run, truth=truth,
              tare=tare, scans=scans, model=model)
    lab.clean = verdict(lab)
    return lab


def rezero(root: Path, rig: dict, records: list[pd.DataFrame], level: float,
           rng: np.random.Generator) -> None:
    """The gauges of a lab zeroed again to within ``level`` [N]: the offsets the simulator
    drew (its ``truth/simulator.json``) replaced in every record by new ones of that standard
    deviation, and the rig's ``weight.gauge_zero`` set to it. The forces, every record zeroed
    by the same tare, do not change; the tare's weight is known the better."""
    drawn = json.loads((root / "truth" / "simulator.json").read_text(encoding="utf-8"))
    for gauge in rig["gauges"]:
        name = gauge["name"]
        shift = (level * rng.standard_normal() - drawn["realism"]["gauge_offset_N"][name]) \
            / gauge.get("scale", 1.0)
        for frame in records:
            frame[name] = frame[name] + shift
    rig["weight"]["gauge_zero"] = level


def _read_csv(path: Path, duration: float | None) -> pd.DataFrame:
    frame = pd.read_csv(path)
    if duration is not None:
        frame = frame[frame["time"] < frame["time"].iloc[0] + duration].reset_index(drop=True)
    return frame


# --------------------------------------------------------------------------------------------
# mistakes


@dataclass
class Case:
    """A working copy of a lab that one mistake edits."""

    lab: Lab
    folder: Path                     # where the edited files are written
    rig: dict
    run: pd.DataFrame
    tare: pd.DataFrame | None
    rows: np.ndarray                 # the truth's sample of each row of ``run``
    scans: list[Path]
    rng: np.random.Generator
    scan_args: list[str] = field(default_factory=list)

    def channel(self, role: str) -> str:
        return self.lab.names[role]


@dataclass(frozen=True)
class Mistake:
    """One plausible lab mistake: ``edit`` makes it on a :class:`Case`; ``channels`` (any of
    them: the channel or key at fault, or its kind; ``{g0}``, ``{p1}``, ``{f0}``, ``{i}`` stand
    for the lab's names) and ``words`` (any of them) are what a note naming the cause says."""

    name: str
    what: str
    presets: tuple[str, ...]
    edit: Callable[[Case], None]
    channels: tuple[str, ...] = ()
    words: tuple[str, ...] = ()

    def terms(self, lab: Lab) -> tuple[tuple[str, ...], tuple[str, ...]]:
        return tuple(c.format(**lab.names) for c in self.channels), self.words


def _scale(section: str, index: int | None, factor: float) -> Callable[[Case], None]:
    """Multiply the rig's ``section[index].scale`` (every entry's when index is None)."""
    def edit(case: Case) -> None:
        entries = case.rig[section]
        for entry in entries if index is None else [entries[index]]:
            entry["scale"] = entry.get("scale", 1.0) * factor
    return edit


def _key(path: tuple, value: object = None, *, factor: float | None = None,
         offset: float | None = None, drop: bool = False) -> Callable[[Case], None]:
    """Set (or scale, shift, drop) the rig's key at ``path`` (names and list indices)."""
    def edit(case: Case) -> None:
        node = case.rig
        for part in path[:-1]:
            node = node.setdefault(part, {}) if isinstance(part, str) else node[part]
        last = path[-1]
        if drop:
            del node[last]
        elif factor is not None:
            node[last] = node.get(last, 1.0) * factor
        elif offset is not None:
            node[last] = node[last] + offset
        else:
            node[last] = value
    return edit


def _column(roles: tuple[str, ...], factor: float = 1.0, add: float = 0.0,
            tare: bool = True) -> Callable[[Case], None]:
    """Scale and shift the run's columns of these roles (``g0``, ``p1``...), and the tare's
    when ``tare`` (recorded the same way)."""
    def edit(case: Case) -> None:
        for frame in _records(case, tare):
            for role in roles:
                name = case.channel(role)
                frame[name] = frame[name] * factor + add
    return edit


def _records(case: Case, tare: bool) -> list[pd.DataFrame]:
    """The run, and the tare when ``tare`` and there is one."""
    return [case.run, *([case.tare] if tare and case.tare is not None else [])]


def _swap_columns(a: str, b: str) -> Callable[[Case], None]:
    """Two channels swapped in the run and its tare (one wiring)."""
    def edit(case: Case) -> None:
        x, y = case.channel(a), case.channel(b)
        for frame in _records(case, True):
            frame[[x, y]] = frame[[y, x]].to_numpy()
    return edit


def _swap_forces(case: Case) -> None:
    forces = case.rig["forces"]
    forces[0]["name"], forces[1]["name"] = forces[1]["name"], forces[0]["name"]


def _skew(roles: tuple[str, ...], samples: int) -> Callable[[Case], None]:
    """The channels of ``roles`` recorded ``samples`` late against the others (and the
    time column), the first rows dropped."""
    def edit(case: Case) -> None:
        late = {case.channel(r) for r in roles}
        shifted = case.run.iloc[samples:].reset_index(drop=True)
        for name in late:
            shifted[name] = case.run[name].to_numpy()[:-samples]
        case.run, case.rows = shifted, case.rows[samples:]
    return edit


def _time_scale(factor: float) -> Callable[[Case], None]:
    def edit(case: Case) -> None:
        case.run["time"] = case.run["time"] * factor
    return edit


def _truncate(periods: float) -> Callable[[Case], None]:
    def edit(case: Case) -> None:
        keep = round(periods * case.lab.fs / case.lab.f0)
        case.run, case.rows = case.run.iloc[:keep].copy(), case.rows[:keep]
    return edit


def _hum(role: str, amplitude: float, mains: float = 50.0) -> Callable[[Case], None]:
    def edit(case: Case) -> None:
        t = case.run["time"].to_numpy()
        phase = case.rng.uniform(0, 2 * np.pi)
        name = case.channel(role)
        case.run[name] = case.run[name] + amplitude * np.sin(2 * np.pi * mains * t + phase)
    return edit


def _tare_drifted(shifts: tuple[float, ...]) -> Callable[[Case], None]:
    """A tare of another day: every gauge's zero moved by ``shifts`` [N]."""
    def edit(case: Case) -> None:
        assert case.tare is not None
        for k, shift in enumerate(shifts):
            name = case.channel(f"g{k}")
            case.tare[name] = case.tare[name] + shift
    return edit


def _tare_with_current(case: Case) -> None:
    """The run itself given as the tare (a record with current)."""
    case.tare = case.lab.run.copy()


def _no_tare(case: Case) -> None:
    case.tare = None


def _harmonics(h: int) -> Callable[[Case], None]:
    def edit(case: Case) -> None:
        case.scan_args = ["--harmonics", str(h)]
    return edit


def _mirror_scans(case: Case) -> None:
    """Every scan point's x measured from the structure's other end."""
    from forcecal.io.scan_files import read_scan, write_scan_npz
    from forcecal.records import Scan

    length = float(case.rig["structure"]["length"])
    mirrored = []
    for path in case.scans:
        scan = read_scan(path)
        assert isinstance(scan, Scan)
        points = np.array(scan.points, dtype=float)
        points[:, 0] = length - points[:, 0]
        mirrored.append(write_scan_npz(
            Scan(points=points, response=scan.response, reference=scan.reference, fs=scan.fs,
                 quantity=scan.quantity), case.folder / f"mirrored_{path.name}"))
    case.scans = mirrored


GAUGE = ("{g0}", "gauge")
GAUGES = ("{g0}", "{g1}", "gauge", "gauges")
PROBE = ("{p0}", "probe")
PROBES = ("{p0}", "{p1}", "probe", "probes")
CURRENT = ("{i}", "current")
SCALE = ("scale", "scales", "sensitivity", "sensitivities", "gain", "gains", "unit", "units")
SIGN = ("sign", "signs", "polarity", "inverted", "reversed")
SWAP = ("swap", "swapped", "exchanged", "interchanged", "mixed up", "order")
SKEW = ("skew", "skewed", "delay", "delayed", "lag", "lags", "latency", "time shift")
POSITION = ("position", "positions", "x", "misplaced")
MASS = ("mass", "masses", "mass_per_length")
P = ("paper", "paper-lab", "paper-noflux")
PT = (*P, "tilt")
PTC = (*PT, "two-coil")
PF = ("paper", "paper-lab")
"""The labs with a flux channel."""
A = ("random-lab",)
"""A lab under any drive."""
Z = ("paper-zeroed",)
"""A lab whose tare weighs the structure (its gauges zeroed without it to within 0.05 N)."""

MISTAKES: tuple[Mistake, ...] = (
    Mistake("gauge scale +2%", "one gauge's sensitivity in the rig 2 % off", (*PT, *A),
            _scale("gauges", 0, 1.02), GAUGE, SCALE),
    Mistake("gauge scale +10%", "one gauge's sensitivity in the rig 10 % off", (*PT, *A),
            _scale("gauges", 0, 1.10), GAUGE, SCALE),
    Mistake("gauge offset 1 N", "1 N on one gauge's zero since its tare (or zeroing)", (*PT, *A),
            _column(("g0",), add=1.0, tare=False), GAUGE, ("offset", "zero", "tare", "dc")),
    Mistake("gauges both +2%", "both gauges' sensitivities 2 % high in the rig", (*PT, *A, *Z),
            _scale("gauges", None, 1.02), GAUGES, SCALE),
    Mistake("gauge sign", "one gauge reports its compression (its scale's sign flipped)", PT,
            _scale("gauges", 0, -1.0), GAUGE, SIGN),
    Mistake("probes sign both", "both probes' signs flipped in the rig", (*PT, *A),
            _scale("sensors", None, -1.0), PROBES, SIGN),
    Mistake("probe sign one", "one probe's sign flipped in the rig", PT,
            _scale("sensors", 0, -1.0), PROBE, SIGN),
    Mistake("probes mm, scale m", "probes recorded in mm, the rig's scale for m", P,
            _column(("p0", "p1"), factor=1e3), PROBES, SCALE),
    Mistake("probes m, scale mm", "probes recorded in m, the rig's scale for mm", P,
            _scale("sensors", None, 1e-3), PROBES, SCALE),
    Mistake("probes 10x", "both probes' scale 10 times too large", P,
            _scale("sensors", None, 10.0), PROBES, SCALE),
    Mistake("probe scale +10%", "one probe's sensitivity 10 % off", PT,
            _scale("sensors", 0, 1.10), PROBE, SCALE),
    Mistake("probe position 1 cm", "one probe 1 cm from where the rig says", P,
            _key(("sensors", 0, "x"), offset=0.01), PROBE, POSITION),
    Mistake("gauge position 2 cm", "one gauge 2 cm from where the rig says", P,
            _key(("gauges", 0, "x"), 0.02), GAUGE, POSITION),
    Mistake("gauges swapped", "the two gauge channels swapped (run and tare)", PTC,
            _swap_columns("g0", "g1"), GAUGES, SWAP),
    Mistake("probes swapped", "the two probe channels swapped (run and tare)", PTC,
            _swap_columns("p0", "p1"), PROBES, SWAP),
    Mistake("force names swapped", "the forces' names swapped in the rig", ("tilt", "two-coil"),
            _swap_forces, ("{f0}", "{f1}", "force", "forces"), (*SWAP, "name", "names")),
    Mistake("force point 5 cm", "one force point 5 cm from where the rig says", (*PTC, *A),
            _key(("forces", 0, "x"), offset=-0.05), ("{f0}", "force", "pole"), POSITION),
    Mistake("lumped mass forgotten", "the armature's lumped mass left out of the rig",
            (*P, *A, *Z), _key(("structure", "masses"), drop=True), (), MASS),
    Mistake("mass_per_length +10%", "the distributed mass 10 % off", (*P, *Z),
            _key(("structure", "mass_per_length"), factor=1.1), (), MASS),
    Mistake("skew gauges 4", "the gauges recorded 4 samples late (another DAQ module)",
            (*P, *A), _skew(("g0", "g1"), 4), GAUGES, SKEW),
    Mistake("skew probes 4", "the probes recorded 4 samples late", (*P, *A),
            _skew(("p0", "p1"), 4), PROBES, SKEW),
    Mistake("skew current 4", "the coil current recorded 4 samples late", P,
            _skew(("i",), 4), CURRENT, SKEW),
    Mistake("time base +0.99%", "the CSV's time column 0.99 % long (a wrong sampling rate)",
            PT, _time_scale(1.0099), ("time", "sampling"), ("frequency", "rate")),
    Mistake("time in ms", "the time column in ms, read as s", P, _time_scale(1e3),
            ("time", "sampling", "sampled"), ("frequency", "rate", "ms", "unit", "nyquist")),
    Mistake("truncated 10.5 periods", "the run cut after 10.5 periods", P,
            _truncate(10.5), ("record", "run"), ("period", "periods", "truncated", "window")),
    Mistake("hum on one gauge", "50 Hz hum of 0.2 N on one gauge (a ground loop)", P,
            _hum("g0", 0.2), GAUGE, ("hum", "mains", "50 hz", "tone")),
    Mistake("tare of another day", "a tare whose gauge zeros moved by +0.6 / -0.4 N",
            ("paper-lab",), _tare_drifted((0.6, -0.4)), ("tare",), ()),
    Mistake("tare with current", "the run itself given as the tare", ("paper-lab",),
            _tare_with_current, ("tare",), ()),
    Mistake("no tare", "the tare left out on a rig with offsets and preload", ("paper-lab",),
            _no_tare, ("tare",), ()),
    Mistake("--harmonics 1", "the model built with --harmonics 1", P, _harmonics(1),
            ("harmonic", "harmonics"), ("--harmonics", "no shape", "dropped", "not compensated")),
    Mistake("current scale +5%", "the current channel's scale 5 % off", P,
            _key(("actuator", "current_scale"), factor=1.05), CURRENT, SCALE),
    Mistake("current sign", "the current clamp the wrong way round", P,
            _key(("actuator", "current_scale"), factor=-1.0), CURRENT, SIGN),
    Mistake("nominal frequency +10%", "acquisition.frequency 10 % off the drive's",
            (*PT, "paper-lab-0.5s"),
            _key(("acquisition", "frequency"), factor=1.1), ("acquisition.frequency",
                                                            "frequency"), ()),
    Mistake("gap in mm", "one pole's static gap written in mm", P,
            _key(("forces", 0, "gap"), factor=1e3), ("gap", "forces[0].gap"), ()),
    Mistake("scan mirrored", "the scan's x measured from the other end", ("tilt",),
            _mirror_scans, ("scan", "scans"), ("mirrored", "reversed", "flipped", "other end")),
    Mistake("flux scale +5%", "the flux channel's scale 5 % off", PF,
            _key(("actuator", "flux_scale"), factor=1.05), ("{phi}", "flux"), SCALE),
    Mistake("pole area +10%", "actuator.pole_area 10 % off", PF,
            _key(("actuator", "pole_area"), factor=1.1), ("actuator.pole_area", "pole_area",
                                                          "pole area"), ()),
)
"""Every mistake of the campaign, each on the presets where it shows."""


def mistake(name: str) -> Mistake:
    """The mistake called ``name``."""
    return next(m for m in MISTAKES if m.name == name)


# --------------------------------------------------------------------------------------------
# the verdict


@dataclass
class Result:
    """One mistake's (or the clean run's) outcome."""

    mistake: str
    lab: str
    seed: int
    verdict: str
    code: int
    message: str = ""                 # a refusal's line
    cause_named: bool = False         # the refusal's or a note's text names the cause
    total_error_pct: float = math.nan
    worst_force_error_pct: float = math.nan
    error_over_stated: float = math.nan   # the worst of the forces' and the total's
    errors_pct: dict[str, float] = field(default_factory=dict)
    over_stated: dict[str, float] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)   # new ones (the baseline: all)
    all_notes: list[str] = field(default_factory=list)
    relevant_note: str = ""
    f0: float = math.nan

    def to_json(self) -> dict:
        doc = asdict(self)
        doc.pop("all_notes")
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                for k, v in doc.items()}


def verdict(lab: Lab, which: Mistake | None = None) -> Result:
    """Make the mistake ``which`` (None: none, the baseline) on a copy of ``lab``, run
    ``forcecal reconstruct`` (and ``forcecal scan`` first when needed) and judge it."""
    with tempfile.TemporaryDirectory(dir=lab.root) as tmp:
        case = _case(lab, which, Path(tmp))
        code, err, out = _run(case)
        return _judge(case, which, code, err, out)


def streamed(lab: Lab, which: Mistake | None = None) -> tuple[int, list[str]]:
    """Make the mistake ``which`` as :func:`verdict` does and run ``forcecal stream`` instead:
    its exit status and its notes (or its one line of refusal)."""
    with tempfile.TemporaryDirectory(dir=lab.root) as tmp:
        case = _case(lab, which, Path(tmp))
        code, err, _ = _run(case, "stream")
        lines = [line for line in err.splitlines() if line.strip()]
        said = [line for line in lines if line.startswith("note: ")]
        return code, said if code == 0 else lines[-1:]


def _case(lab: Lab, which: Mistake | None, folder: Path) -> Case:
    """A copy of ``lab`` in ``folder`` with the mistake ``which`` made on it."""
    name = "clean" if which is None else which.name
    case = Case(lab=lab, folder=folder, rig=json.loads(json.dumps(lab.rig)),
                run=lab.run.copy(), tare=None if lab.tare is None else lab.tare.copy(),
                rows=np.arange(len(lab.run)), scans=list(lab.scans),
                rng=np.random.default_rng([lab.seed, zlib.crc32(name.encode())]))
    if which is not None:
        which.edit(case)
    return case


def _needs_scan(case: Case) -> bool:
    """Whether the spatial model must be built again: the scan, its options or what the model
    depends on in the rig changed (forcecal refuses a model of another rig's geometry)."""
    def geometry(rig: dict) -> str:
        keep = {k: rig.get(k) for k in ("structure", "gauges", "forces", "sensors")}
        for key in ("gauges", "forces", "sensors"):
            keep[key] = [{a: v for a, v in p.items() if a not in ("scale", "gap")}
                         for p in keep[key] or []]
        return json.dumps(keep, sort_keys=True)
    return (case.scans != case.lab.scans or bool(case.scan_args)
            or geometry(case.rig) != geometry(case.lab.rig))


def _run(case: Case, command: str = "reconstruct") -> tuple[int, str, Path]:
    """Write the case's files and run the commands (``reconstruct`` or ``stream``): exit
    status, stderr, output folder."""
    folder, stem = case.folder, case.lab.spec.run
    rig = folder / "rig.toml"
    rig.write_text(tomli_w.dumps(case.rig), encoding="utf-8")
    (folder / "runs").mkdir()
    run = folder / "runs" / f"{stem}.csv"
    case.run.to_csv(run, index=False)
    model = case.lab.model
    if _needs_scan(case):
        model = folder / "model.json"
        code, err = quiet_main(["scan", rig, *case.scans, "-o", model, *case.scan_args])
        if code != 0:
            return code, err, folder / "out"
    tare: list[object] = []
    if case.tare is not None:
        case.tare.to_csv(folder / "tare_record.csv", index=False)
        tare = ["--tare", folder / "tare_record.csv"]
    out = folder / "out"
    if command == "stream":
        out.mkdir()
        code, err = quiet_main(["stream", rig, model, run, "-o", out / f"{stem}.forces.csv",
                                *tare])
        return code, err, out
    code, err = quiet_main(["reconstruct", rig, model, run, "-o", out, *tare])
    return code, err, out


def _judge(case: Case, which: Mistake | None, code: int, err: str, out: Path) -> Result:
    lab, name = case.lab, "clean" if which is None else which.name
    result = Result(mistake=name, lab=lab.name, seed=lab.seed, verdict=CLEAN, code=code)
    lines = [line for line in err.splitlines() if line.strip()]
    if code != 0:
        result.verdict = REFUSED
        result.message = _paths(lines[-1] if lines else "", case)
        result.cause_named = which is not None and names_cause(result.message, which, lab)
        return result
    doc = json.loads((out / f"{lab.spec.run}.json").read_text(encoding="utf-8"))
    result.f0 = float(doc.get("fundamental_hz", math.nan))      # none under any drive
    warned = [line for line in lines if line.startswith("forcecal: warning:")]
    result.all_notes = [_paths(n, case) for n in [*doc.get("notes", []), *warned]]
    _errors(case, out, result)
    if which is None:
        result.notes = result.all_notes
        return result
    assert lab.clean is not None
    clean_shapes = {_shape(n) for n in lab.clean.all_notes}
    result.notes = [n for n in result.all_notes if _shape(n) not in clean_shapes]
    named = [n for n in result.notes if names_cause(n, which, lab)]
    blaming = [n for n in result.notes
               if _mentions(n, lab.sensor_terms) and _mentions(n, BLAME)]
    result.relevant_note = (named or blaming or result.notes or [""])[0]
    result.cause_named = bool(named)
    if named:
        result.verdict = NOTED
    elif blaming:
        result.verdict = WRONG_NOTE
    else:
        result.verdict = HARMLESS if _harmless(result, lab.clean) else SILENT
    return result


def _paths(text: str, case: Case) -> str:
    """``text`` with the case's folder written CASE and the lab's LAB."""
    return text.replace(str(case.folder), "CASE").replace(str(case.lab.root), "LAB")


def _errors(case: Case, out: Path, result: Result) -> None:
    """Each force's and the total's error against the truth, in % of the true total's AC RMS,
    and over its stated uncertainty (RMS of the error over the RMS of the ``_std`` column)."""
    est = pd.read_csv(out / f"{case.lab.spec.run}.forces.csv")
    truth = case.lab.truth.iloc[case.rows].reset_index(drop=True)
    total = truth["total"].to_numpy()
    ac = _rms(total - total.mean())
    for name in [*case.lab.force_names, "total"]:
        e = est[name].to_numpy() - truth[name].to_numpy()
        result.errors_pct[name] = 100 * _rms(e) / ac
        result.over_stated[name] = _rms(e) / max(_rms(est[f"{name}_std"].to_numpy()), 1e-300)
    result.total_error_pct = result.errors_pct["total"]
    result.worst_force_error_pct = max(result.errors_pct[n] for n in case.lab.force_names)
    result.error_over_stated = max(result.over_stated.values())


def _harmless(result: Result, clean: Result) -> bool:
    return all(result.over_stated[k] <= K_BOUND
               or result.errors_pct[k] <= CLEAN_FACTOR * clean.errors_pct[k]
               for k in result.errors_pct)


def names_cause(text: str, which: Mistake, lab: Lab) -> bool:
    """Whether ``text`` names the mistake's cause: one of its channels and one of its words
    (either list may be empty)."""
    channels, words = which.terms(lab)
    return ((not channels or _mentions(text, channels))
            and (not words or _mentions(text, words)))


def _mentions(text: str, terms: tuple[str, ...]) -> bool:
    """Whether ``text`` holds one of ``terms`` as a whole word (any case)."""
    return any(re.search(rf"(?<![A-Za-z0-9_]){re.escape(t)}(?![A-Za-z0-9_])", text, re.I)
               for t in terms)


def _shape(note: str) -> str:
    """A note without its file names and numbers, to tell a new note from the clean run's."""
    note = re.sub(r"'[^'\s]*[/\\.][^'\s]*'", "''", note)
    return re.sub(r"(?<![A-Za-z0-9_])[-+]?\d+(\.\d+)?(e[-+]?\d+)?%?", "#", note)


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def campaign(labs: dict[str, Lab], mistakes: tuple[Mistake, ...] = MISTAKES,
             progress: Callable[[Result], None] | None = None) -> list[Result]:
    """Every mistake on each of its presets that ``labs`` holds."""
    results = []
    for which in mistakes:
        for preset in which.presets:
            if preset in labs:
                results.append(verdict(labs[preset], which))
                if progress is not None:
                    progress(results[-1])
    return results


"""The ``lab`` virtual rig's measurements (:class:`.realism.Realism`).

Once per simulated rig, :func:`draw_errors` draws what its sensors get wrong (each gauge's,
probe's and current sensor's sensitivity, each gauge's zero offset) and computes the gravity
preload of every gauge. A run (:func:`record_lab_run`) is simulated under a drive that drifts
linearly in level and frequency; a scan (:func:`record_lab_scan`) under a drive whose level and
frequency walk from point to point. Every channel then reads

    sensitivity * (truth + preload) + offset + white + pink + hum,   quantized by its ADC

(preload and offset on the gauges only). The scan's records follow from the harmonics of a few
steady-state simulations at the extremes of the walk (:class:`ScanTable`), interpolated to each
point's drive: quadratic in level and frequency, with their cross term.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..records import Run, Scan
from ..signals.harmonics import fit_harmonics
from .integrate import Response
from .physics import (
    Model,
    Truth,
    _gauge_forces,
    _points,
    _rows,
    _scan_spec,
    relaxation_modes,
    run_truth,
    scan_file,
    scan_offsets,
    scan_points,
    scan_response,
    simulate_response,
)
from .presets import Preset, RunSpec
from .realism import Realism, coloured
from .solid import SolidModel

__all__: list[str] = []

MAX_HARMONICS = 40
"""Most harmonics kept of a steady state to interpolate a scan's records from."""
TABLE_PERIODS = 4
"""Drive periods simulated per node of a :class:`ScanTable`."""


def _realism(preset: Preset) -> Realism:
    if preset.realism is None:
        raise ValueError(f"preset '{preset.name}' is ideal: it has no lab realism")
    return preset.realism


@dataclass(frozen=True)
class LabErrors:
    """What a ``lab`` rig's sensors and set-up get wrong, drawn once per simulated rig.

    Attributes
    ----------
    sensitivity : dict channel -> float
        [1] true sensitivity over the rig file's scale, ``1 + e``, of every gauge, probe and
        coil current channel (1 for the others).
    offset : dict gauge -> float
        [N] each gauge's zero offset.
    preload : dict gauge -> float
        [N] the force each gauge exerts on the structure at rest under gravity.
    """

    sensitivity: dict[str, float]
    offset: dict[str, float]
    preload: dict[str, float]

    def gain(self, channel: str) -> float:
        """The channel's true sensitivity over its rig-file scale (1 when not drawn)."""
        return self.sensitivity.get(channel, 1.0)

    def zero_reading(self, gauge: str) -> float:
        """[N] what a gauge reads at zero current: ``gain * preload + offset``."""
        return self.gain(gauge) * self.preload[gauge] + self.offset[gauge]

    def as_dict(self) -> dict:
        """Plain JSON-ready values, with every gauge's zero-current reading."""
        return {"sensitivity": dict(self.sensitivity), "gauge_offset_N": dict(self.offset),
                "gravity_preload_N": dict(self.preload),
                "gauge_zero_reading_N": {g: self.zero_reading(g) for g in self.preload}}


def gravity_preload(preset: Preset, model: Model, gravity: float) -> np.ndarray:
    """(n_gauges,) [N]: the force each gauge exerts on the structure at rest under its weight.

    Gravity acts along -w (on a body along -z); a relaxed gauge r balances the weight's virtual
    work on its relaxation shape, ``R_r = -psi_r . F_g`` with ``F_g = M (-g e_w)`` the nodal
    weight (consistent mass, lumped masses included). The gauges carry the whole weight.

    Parameters
    ----------
    preset : Preset
    model : BeamModel, PlateModel or SolidModel
        ``build_model(preset)``.
    gravity : float
        [m/s^2].

    Returns
    -------
    (n_gauges,) ndarray [N]
    """
    if isinstance(model, SolidModel):
        down = model.rigid_mode((0.0, 0.0, -gravity), (0.0, 0.0, 0.0))
    else:
        down = model.rigid_mode(-gravity, 0.0)
    out: np.ndarray = -(relaxation_modes(model, preset) @ (model.mass @ down))
    return out


def draw_errors(preset: Preset, model: Model, rng: np.random.Generator) -> LabErrors:
    """Draw a ``lab`` rig's sensor errors: gauges, then probes, then current sensors, then the
    gauge offsets.

    Parameters
    ----------
    preset : Preset
        With its ``realism``.
    model : BeamModel, PlateModel or SolidModel
        ``build_model(preset)``, for the gravity preload.
    rng : numpy.random.Generator

    Returns
    -------
    LabErrors
    """
    lab = _realism(preset)
    tb = lab.type_b
    gauges = [str(g[0]) for g in _rows(preset.beam.gauges)]
    probes = [str(s[0]) for s in _rows(preset.sensors)]
    currents = [m.current_channel for m in preset.magnets]
    sens = {}
    for names, u in ((gauges, tb.gauge_scale), (probes, tb.probe_scale),
                     (currents, tb.current_scale)):
        for name in names:
            sens[name] = float(1.0 + u * rng.standard_normal())
    offset = {g: float(lab.gauge_offset * rng.standard_normal()) for g in gauges}
    preload = dict(zip(gauges, gravity_preload(preset, model, lab.gravity).tolist(),
                       strict=True))
    return LabErrors(sensitivity=sens, offset=offset, preload=preload)


def read_channel(x: np.ndarray, kind: str, sigma: float, lab: Realism, fs: float,
                 rng: np.random.Generator) -> np.ndarray:
    """What a ``lab`` channel records of its input: white, pink and hum noise added (drawn in
    that order), quantized by its kind's ADC.

    Parameters
    ----------
    x : (..., n_samples) ndarray
        The channel's input [SI unit], sensitivity, preload and offset applied; each record
        (row) gets its own noise and hum phases.
    kind : {"gauge", "probe", "current", "flux", "voltage", "ldv"}
        The channel kind: its field of :class:`.realism.AdcSpec`.
    sigma : float
        The white noise's standard deviation [SI unit].
    lab : Realism
    fs : float
        [Hz] sampling rate.
    rng : numpy.random.Generator

    Returns
    -------
    ndarray shaped like ``x``
    """
    noisy = x + sigma * rng.standard_normal(x.shape) + coloured(x.shape, fs, sigma, lab, rng)
    quantized: np.ndarray = getattr(lab.adc, kind).quantize(noisy)
    return quantized


def draw_run_drift(lab: Realism, rng: np.random.Generator) -> tuple[float, float]:
    """A run's linear drifts of the drive: (level ``drift``, frequency ``chirp``) [1/s], normal
    with standard deviations ``run_level_drift`` and ``run_frequency_drift``.

    Parameters
    ----------
    lab : Realism
    rng : numpy.random.Generator

    Returns
    -------
    (float, float)
    """
    drift = float(lab.run_level_drift * rng.standard_normal())
    chirp = float(lab.run_frequency_drift * rng.standard_normal())
    return drift, chirp


def measure_lab_run(preset: Preset, spec: RunSpec, model: Model, r: Response,
                    rng: np.random.Generator, errors: LabErrors | None = None) -> Run:
    """What the ``lab`` DAQ records of a simulated response.

    Parameters
    ----------
    preset : Preset
        With its ``realism``.
    spec : RunSpec
        The run.
    model : BeamModel, PlateModel or SolidModel
    r : Response
        The simulated run.
    rng : numpy.random.Generator
    errors : LabErrors, optional
        The rig's errors (drawn from ``rng`` when not given: pass the same to every record of
        one rig).

    Returns
    -------
    Run
        Channels in the order of the ideal rig's: gauges, probes, then every magnet's current,
        flux and voltage.
    """
    lab, noise, fs = _realism(preset), preset.noise, preset.fs
    errors = errors or draw_errors(preset, model, rng)
    clean: list[tuple[str, str, np.ndarray]] = []
    gauges = _gauge_forces(model, preset, r.u, r.v)
    for k, (name, *_) in enumerate(_rows(preset.beam.gauges)):
        g = str(name)
        clean.append((g, "gauge", errors.gain(g) * (gauges[k] + errors.preload[g])
                      + errors.offset[g]))
    probes = model.row(_points(preset, preset.sensors)) @ r.u
    for k, (name, *_) in enumerate(_rows(preset.sensors)):
        clean.append((str(name), "probe", errors.gain(str(name)) * probes[k]))
    for k, mag in enumerate(preset.magnets):
        clean.append((mag.current_channel, "current",
                      errors.gain(mag.current_channel) * r.current[k]))
        clean.append((mag.flux_channel, "flux", r.flux[k]))
        clean.append((mag.voltage_channel, "voltage", r.voltage[k]))
    channels = {name: read_channel(x, kind, getattr(noise, kind), lab, fs, rng)
                for name, kind, x in clean}
    return Run(channels=channels, fs=fs, t0=0.0, name=spec.name, source=f"{spec.name}.csv",
               labels=dict(spec.labels))


def record_lab_run(preset: Preset, spec: RunSpec, rng: np.random.Generator, model: Model,
                   errors: LabErrors | None = None) -> tuple[Run, Truth]:
    """Simulate one run of a ``lab`` rig under its drifting drive; the DAQ's record and the
    truth.

    The drive's level drifts by ``drift`` and its frequency by ``chirp`` per second (drawn
    from ``rng``, :class:`.realism.Realism`), from the run's start. The truth's
    ``imperfections`` state both, every channel's sensitivity and every gauge's preload and
    offset.

    Parameters
    ----------
    preset : Preset
        With its ``realism``.
    spec : RunSpec
    rng : numpy.random.Generator
    model : BeamModel, PlateModel or SolidModel
    errors : LabErrors, optional
        The rig's errors (drawn from ``rng`` first when not given).

    Returns
    -------
    (Run, Truth)
    """
    lab = _realism(preset)
    errors = errors or draw_errors(preset, model, rng)
    drift, chirp = draw_run_drift(lab, rng)
    drives = tuple(dataclasses.replace(d, drift=drift, chirp=chirp) for d in spec.drives)
    r = simulate_response(preset, drives, spec.gap, spec.duration, model, spec.gaps)
    run = measure_lab_run(preset, spec, model, r, rng, errors)
    gauges = [str(g[0]) for g in _rows(preset.beam.gauges)]
    channels = list(run.channels)
    truth = dataclasses.replace(run_truth(preset, model, r, spec), imperfections={
        "drive_drift": np.array(drift), "drive_chirp": np.array(chirp),
        "sensitivity_channels": np.array(channels),
        "sensitivity": np.array([errors.gain(c) for c in channels]),
        "gauge_preload": np.array([errors.preload[g] for g in gauges]),
        "gauge_offset": np.array([errors.offset[g] for g in gauges])})
    return run, truth


# ------------------------------------------------------------------------------ scans


@dataclass(frozen=True)
class ScanWalk:
    """The drive of every acquisition of a scan (a body's three records of a point share one).

    Attributes
    ----------
    level : (n_acquisitions,) ndarray
        [1] the drive's level over the scan spec's, ``1 + a_k``.
    frequency : (n_acquisitions,) ndarray
        [Hz] the drive's true frequency.
    start : (n_acquisitions,) int ndarray
        The record's first sample within the drive's period.
    """

    level: np.ndarray
    frequency: np.ndarray
    start: np.ndarray


@dataclass(frozen=True)
class ScanTable:
    """Harmonics of a scan's steady state at a few drives, to interpolate any drive near them.

    Attributes
    ----------
    frequency : float
        [Hz] the scan spec's drive frequency.
    level_span, frequency_span : float
        [1] the relative steps of level and frequency between the nodes (0: not varied).
    velocity : dict node -> (n_records, H+1) complex ndarray
        [m/s] harmonics of the vibrometer's quantity at every record's location.
    current : dict node -> (n_magnets, H+1) complex ndarray
        [A] harmonics of every coil current. Nodes are (i, j) in {-1, 0, 1}: level
        ``1 + i level_span``, frequency ``frequency (1 + j frequency_span)``.
    """

    frequency: float
    level_span: float
    frequency_span: float
    velocity: dict[tuple[int, int], np.ndarray]
    current: dict[tuple[int, int], np.ndarray]

    def at(self, a: float, b: float) -> tuple[np.ndarray, np.ndarray]:
        """(velocity, current) harmonics at level ``1 + a`` and frequency ``f (1 + b)``:
        quadratic in a and in b, with the a b cross term."""
        out = []
        for tab in (self.velocity, self.current):
            p = tab[(0, 0)].copy()
            ha, hb = self.level_span, self.frequency_span
            if ha:
                up, down = tab[(1, 0)], tab[(-1, 0)]
                p += a * (up - down) / (2 * ha) + a**2 * (up - 2 * tab[(0, 0)] + down) / (2 * ha**2)
            if hb:
                up, down = tab[(0, 1)], tab[(0, -1)]
                p += b * (up - down) / (2 * hb) + b**2 * (up - 2 * tab[(0, 0)] + down) / (2 * hb**2)
            if ha and hb:
                p += a * b * (tab[(1, 1)] - tab[(1, 0)] - tab[(0, 1)] + tab[(0, 0)]) / (ha * hb)
            out.append(p)
        return out[0], out[1]


def _n_harmonics(preset: Preset, f: float) -> int:
    return max(1, min(MAX_HARMONICS, int(0.45 * preset.fs / f)))


def scan_table(preset: Preset, model: Model, which: int = 0, level_span: float = 0.0,
               frequency_span: float = 0.0) -> ScanTable:
    """Simulate a scan's steady state at its drive and at drives ``level_span`` and
    ``frequency_span`` (relative) away, and keep their harmonics.

    Parameters
    ----------
    preset : Preset
    model : BeamModel, PlateModel or SolidModel
    which : int
        Indexes :attr:`Preset.scans`.
    level_span, frequency_span : float
        [1] the steps between the nodes; 0 leaves that axis out (one simulation when both are).

    Returns
    -------
    ScanTable
    """
    spec = _scan_spec(preset, which)
    f = spec.drives[0].frequency
    rows = model.row(scan_points(preset, which))
    nodes = [(0, 0)]
    if level_span:
        nodes += [(1, 0), (-1, 0)]
    if frequency_span:
        nodes += [(0, 1), (0, -1)]
    if level_span and frequency_span:
        nodes.append((1, 1))
    velocity, current = {}, {}
    for i, j in nodes:
        fj = f * (1 + j * frequency_span)
        drives = tuple(d.scaled(1 + i * level_span, d.frequency * (1 + j * frequency_span))
                       for d in spec.drives)
        n = int(math.ceil(TABLE_PERIODS * preset.fs / fj))
        r = simulate_response(preset, drives, spec.gap, n / preset.fs, model, spec.gaps)
        h = _n_harmonics(preset, fj)
        velocity[(i, j)] = fit_harmonics(rows @ r.v, preset.fs, fj, h).phasors
        current[(i, j)] = fit_harmonics(r.current, preset.fs, fj, h).phasors
    return ScanTable(frequency=f, level_span=level_span, frequency_span=frequency_span,
                     velocity=velocity, current=current)


def _synthesize(phasors: np.ndarray, f: float, t: np.ndarray) -> np.ndarray:
    """``X_0 + sum_n Re(X_n exp(j n 2 pi f t))`` of (m, H+1) phasors at times t: (m, n_t)."""
    basis = np.empty((phasors.shape[-1], len(t)), dtype=complex)       # (H+1, n_t)
    basis[0] = 1.0
    if len(basis) > 1:
        basis[1] = np.exp(1j * 2 * math.pi * f * t)
    for n in range(2, len(basis)):
        basis[n] = basis[n - 1] * basis[1]
    out: np.ndarray = (phasors @ basis).real
    return out


def _per_point(preset: Preset) -> int:
    """Records per acquisition: a 3-D SLDV measures a point's three components at once."""
    return 3 if preset.is_body else 1


def _scan_noise(preset: Preset, which: int, response: np.ndarray, reference: np.ndarray,
                rng: np.random.Generator, errors: LabErrors) -> Scan:
    """The scan's records from its clean response (n_records, n) and its clean reference
    current, one per acquisition (n_acquisitions, n)."""
    lab, noise, fs = _realism(preset), preset.noise, preset.fs
    spec = _scan_spec(preset, which)
    coil = preset.magnets[spec.reference].current_channel
    resp = read_channel(response, "ldv", noise.ldv, lab, fs, rng)
    ref = read_channel(errors.gain(coil) * reference, "current", noise.current, lab, fs, rng)
    return Scan(points=scan_points(preset, which), response=resp,
                reference=np.repeat(ref, _per_point(preset), axis=0), fs=fs,
                quantity="velocity", source=scan_file(which))


def measure_lab_scan(preset: Preset, model: Model, r: Response, rng: np.random.Generator,
                     which: int = 0, errors: LabErrors | None = None) -> Scan:
    """A ``lab`` scan's records from one steady-state response (the drive does not walk: for
    that, :func:`record_lab_scan`): windows at random starts, as the ideal scan's, then the
    lab's noise, sensitivity and quantization.

    Parameters
    ----------
    preset : Preset
        With its ``realism``.
    model : BeamModel, PlateModel or SolidModel
    r : Response
        :func:`.virtual_rig.scan_response` of the scan.
    rng : numpy.random.Generator
    which : int
        Indexes :attr:`Preset.scans`.
    errors : LabErrors, optional
        The rig's errors (drawn from ``rng`` first when not given).

    Returns
    -------
    Scan
    """
    errors = errors or draw_errors(preset, model, rng)
    spec = _scan_spec(preset, which)
    n_rec = int(round(spec.record * preset.fs))
    per_period = int(np.ceil(preset.fs / spec.drives[0].frequency))
    x = scan_points(preset, which)
    n_acq = len(x) // _per_point(preset)
    starts = rng.integers(0, per_period, size=n_acq)
    idx = starts[:, None] + np.arange(n_rec)[None, :]
    velocity = model.row(x) @ r.v
    response = np.take_along_axis(velocity, np.repeat(idx, _per_point(preset), axis=0), axis=1)
    return _scan_noise(preset, which, response, r.current[spec.reference][idx], rng, errors)


def _broadband_lab_scan(preset: Preset, rng: np.random.Generator, model: Model, which: int,
                        errors: LabErrors) -> tuple[Scan, ScanWalk]:
    """A ``lab`` scan under a broadband drive (a chirp, noise): every acquisition a window of
    one steady-state response at a random start (as the ideal scan's), its response and its
    reference scaled by the level's walk, ``1 + a_k`` (to first order in the walk's steps, which
    move the magnet's bias by a few parts in 1e3 at most); the generator's frequency does not
    walk (a broadband drive's is its clock's). Then the lab's noise, sensitivity and
    quantization."""
    lab = _realism(preset)
    spec = _scan_spec(preset, which)
    n_rec = int(round(spec.record * preset.fs))
    per_point = _per_point(preset)
    x = scan_points(preset, which)
    n_acq = len(x) // per_point
    a = np.cumsum(lab.scan_level_step * rng.standard_normal(n_acq))
    starts = rng.integers(0, scan_offsets(preset, which), size=n_acq)
    r = scan_response(preset, model, which)
    idx = starts[:, None] + np.arange(n_rec)[None, :]
    level = (1.0 + a)[:, None]
    response = np.repeat(level, per_point, axis=0) * np.take_along_axis(
        model.row(x) @ r.v, np.repeat(idx, per_point, axis=0), axis=1)
    reference = level * r.current[spec.reference][idx]
    return (_scan_noise(preset, which, response, reference, rng, errors),
            ScanWalk(level=1.0 + a, frequency=np.full(n_acq, spec.drives[0].frequency),
                     start=starts))


def record_lab_scan(preset: Preset, rng: np.random.Generator, model: Model, which: int = 0,
                    errors: LabErrors | None = None) -> tuple[Scan, ScanWalk]:
    """A ``lab`` scan: the drive's level and frequency walk from point to point.

    The walks (steps ``scan_level_step`` and ``scan_frequency_step``, :class:`.realism.Realism`)
    are drawn first, then every acquisition's start within one drive period; each record is the
    steady state under its own drive, interpolated from a :class:`ScanTable` whose nodes span
    the walks; the reference records the same drive's current. Then the lab's noise,
    sensitivity and quantization.

    Parameters
    ----------
    preset : Preset
        With its ``realism``.
    rng : numpy.random.Generator
    model : BeamModel, PlateModel or SolidModel
    which : int
        Indexes :attr:`Preset.scans`.
    errors : LabErrors, optional
        The rig's errors (drawn from ``rng`` first when not given).

    Returns
    -------
    (Scan, ScanWalk)
    """
    lab = _realism(preset)
    errors = errors or draw_errors(preset, model, rng)
    spec = _scan_spec(preset, which)
    if spec.drives[0].waveform is not None:
        return _broadband_lab_scan(preset, rng, model, which, errors)
    fs, f = preset.fs, spec.drives[0].frequency
    n_rec = int(round(spec.record * fs))
    per_period = int(np.ceil(fs / f))
    per_point = _per_point(preset)
    n_acq = len(scan_points(preset, which)) // per_point
    a = np.cumsum(lab.scan_level_step * rng.standard_normal(n_acq))
    b = np.cumsum(lab.scan_frequency_step * rng.standard_normal(n_acq))
    starts = rng.integers(0, per_period, size=n_acq)
    table = scan_table(preset, model, which, float(np.max(np.abs(a), initial=0.0)),
                       float(np.max(np.abs(b), initial=0.0)))
    response = np.empty((n_acq * per_point, n_rec))
    reference = np.empty((n_acq, n_rec))
    for k in range(n_acq):
        vel, cur = table.at(float(a[k]), float(b[k]))
        t = (starts[k] + np.arange(n_rec)) / fs
        fk = f * (1 + b[k])
        rows = slice(k * per_point, (k + 1) * per_point)
        response[rows] = _synthesize(vel[rows], fk, t)
        reference[k] = _synthesize(cur[spec.reference:spec.reference + 1], fk, t)[0]
    scan = _scan_noise(preset, which, response, reference, rng, errors)
    return scan, ScanWalk(level=1 + a, frequency=f * (1 + b), start=starts)

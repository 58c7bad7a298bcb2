"""The virtual rig: builds the finite-element model of a preset and records runs and scans.

Measurements carry seeded white noise; the ground truth (pole forces, gaps, displacement field,
the inertia term of each gauge) is returned beside them.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..records import Run, Scan
from ..rig import Actuator, ForcePoint, Gauge, LumpedMass, Rig, Sensor, Structure
from .beam import BeamModel, assemble_beam, natural_frequencies
from .integrate import Response, integrate
from .magnet import Drive, Magnet
from .presets import Preset, RunSpec, first_mode_beta

__all__ = [
    "Truth",
    "build_model",
    "measure_run",
    "measure_scan",
    "public_rig",
    "record_run",
    "record_scan",
    "run_truth",
    "scan_response",
]


@dataclass(frozen=True)
class Truth:
    """Ground truth of one run.

    pole_force : (n_poles, n_samples) [N]; gap : (n_poles, n_samples) [m];
    nodes : (n_nodes,) [m]; w : (n_nodes, n_samples) [m] deflection at the FE nodes;
    inertia : (n_gauges, n_samples) [N], J_r = integral(rho psi_r w_tt) + lumped terms.
    """

    t: np.ndarray
    pole_names: tuple[str, ...]
    pole_force: np.ndarray
    gap: np.ndarray
    nodes: np.ndarray
    w: np.ndarray
    inertia: np.ndarray
    current: np.ndarray
    flux: np.ndarray


def build_model(preset: Preset) -> BeamModel:
    """The beam of ``preset`` on its gauge springs, damped at the first bending mode."""
    b = preset.beam
    springs = tuple((x, b.gauge_stiffness) for _, x in b.gauges)
    undamped = assemble_beam(b.length, b.ei, b.mass_per_length, b.n_elements, b.masses, springs)
    f1 = _first_bending(undamped)
    return assemble_beam(b.length, b.ei, b.mass_per_length, b.n_elements, b.masses, springs,
                         beta=first_mode_beta(b, f1))


def _first_bending(model: BeamModel) -> float:
    """Lowest mode that bends the beam (the bounce modes on the gauge springs are rigid)."""
    import scipy.linalg

    w2, vec = scipy.linalg.eigh(model.stiffness, model.mass)
    for k in range(len(w2)):
        strain = vec[:, k] @ model.bending_stiffness @ vec[:, k]
        if strain > 0.5 * w2[k]:
            return float(np.sqrt(w2[k]) / (2 * np.pi))
    return float(natural_frequencies(model, 1)[0])


def _magnets_at(preset: Preset, gap: float | None) -> tuple[Magnet, ...]:
    if gap is None:
        return preset.magnets
    return tuple(dataclasses.replace(m, poles=tuple(dataclasses.replace(p, gap=gap)
                                                     for p in m.poles))
                 for m in preset.magnets)


def public_rig(preset: Preset) -> Rig:
    """What the lab writes in its rig file: geometry, masses, channels; no stiffness, no truth."""
    b = preset.beam
    mag = preset.magnets[0]
    return Rig(
        name=f"virtual {preset.name} rig",
        structure=Structure(kind="beam", length=b.length, mass_per_length=b.mass_per_length,
                            masses=tuple(LumpedMass(x=x, mass=m) for x, m in b.masses)),
        gauges=tuple(Gauge(name=n, x=x) for n, x in b.gauges),
        forces=tuple(ForcePoint(name=p.name, x=p.x, gap=p.gap)
                     for m in preset.magnets for p in m.poles),
        sensors=tuple(Sensor(name=n, x=x) for n, x in preset.sensors),
        actuator=Actuator(current=mag.current_channel, flux=mag.flux_channel,
                          turns=mag.turns, pole_area=mag.pole_area),
        frequency=preset.nominal_frequency,
    )


def _gauge_forces(model: BeamModel, preset: Preset, u, v) -> np.ndarray:
    """(n_gauges, n) [N] force each gauge exerts on the structure (spring plus its dashpot)."""
    rows = model.row(np.array([x for _, x in preset.beam.gauges]))
    k = preset.beam.gauge_stiffness
    return -k * (rows @ u + model.beta * (rows @ v))


def _inertia(model: BeamModel, preset: Preset, a) -> np.ndarray:
    """(n_gauges, n) [N]: Psi_r^T M a, the inertia term of every relaxed gauge (exact)."""
    (_, xa), (_, xb) = preset.beam.gauges
    span = xb - xa
    psi = np.stack([model.rigid_mode(xb / span, -1 / span), model.rigid_mode(-xa / span, 1 / span)])
    return psi @ (model.mass @ a)


def simulate_response(preset: Preset, drives: tuple[Drive, ...], gap: float | None,
                      duration: float, model: BeamModel | None = None) -> Response:
    model = model or build_model(preset)
    return integrate(model, _magnets_at(preset, gap), drives, preset.fs, duration)


def record_run(preset: Preset, spec: RunSpec, rng: np.random.Generator,
               model: BeamModel | None = None) -> tuple[Run, Truth]:
    """Simulate one run and return what the DAQ recorded (noisy) and the truth."""
    model = model or build_model(preset)
    r = simulate_response(preset, spec.drives, spec.gap, spec.duration, model)
    return measure_run(preset, spec, model, r, rng), run_truth(preset, model, r)


def measure_run(preset: Preset, spec: RunSpec, model: BeamModel, r: Response,
                rng: np.random.Generator) -> Run:
    """What the DAQ records of a simulated response: every channel with its white noise."""
    noise = preset.noise
    n = len(r.t)
    gauges = _gauge_forces(model, preset, r.u, r.v)
    probes = model.row(np.array([x for _, x in preset.sensors])) @ r.u
    channels: dict[str, np.ndarray] = {}
    for k, (name, _) in enumerate(preset.beam.gauges):
        channels[name] = gauges[k] + noise.gauge * rng.standard_normal(n)
    for k, (name, _) in enumerate(preset.sensors):
        channels[name] = probes[k] + noise.probe * rng.standard_normal(n)
    for k, mag in enumerate(preset.magnets):
        channels[mag.current_channel] = r.current[k] + noise.current * rng.standard_normal(n)
        channels[mag.flux_channel] = r.flux[k] + noise.flux * rng.standard_normal(n)
        channels[mag.voltage_channel] = r.voltage[k] + noise.voltage * rng.standard_normal(n)
    return Run(channels=channels, fs=preset.fs, t0=0.0, name=spec.name,
               source=f"{spec.name}.csv", labels=dict(spec.labels))


def run_truth(preset: Preset, model: BeamModel, r: Response) -> Truth:
    """The ground truth of a simulated response."""
    return Truth(
        t=r.t, pole_names=tuple(p.name for m in preset.magnets for p in m.poles),
        pole_force=r.pole_force, gap=r.gap, nodes=model.nodes, w=r.u[0::2],
        inertia=_inertia(model, preset, r.a), current=r.current, flux=r.flux,
    )


def record_scan(preset: Preset, rng: np.random.Generator,
                model: BeamModel | None = None) -> Scan:
    """A sequential SLDV scan: each point a velocity record with its own random start phase.

    The rig runs on its periodic steady state; point k is recorded over its own window, which
    starts at a random time within one drive period, with the coil current of the same window
    as reference.
    """
    model = model or build_model(preset)
    return measure_scan(preset, model, scan_response(preset, model), rng)


def scan_response(preset: Preset, model: BeamModel) -> Response:
    """The steady-state response the scan samples: one record plus one drive period."""
    spec = preset.scan
    n_rec = int(round(spec.record * preset.fs))
    per_period = int(np.ceil(preset.fs / spec.drives[0].frequency))
    return simulate_response(preset, spec.drives, spec.gap, (n_rec + per_period) / preset.fs,
                             model)


def measure_scan(preset: Preset, model: BeamModel, r: Response,
                 rng: np.random.Generator) -> Scan:
    """The scan's records: a window per point at a random start within one drive period."""
    spec = preset.scan
    n_rec = int(round(spec.record * preset.fs))
    per_period = int(np.ceil(preset.fs / spec.drives[0].frequency))
    x = np.linspace(0.0, preset.beam.length, spec.n_points)
    velocity = model.row(x) @ r.v                            # (n_points, n_total)
    starts = rng.integers(0, per_period, size=spec.n_points)
    idx = starts[:, None] + np.arange(n_rec)[None, :]
    response = np.take_along_axis(velocity, idx, axis=1)
    reference = r.current[0][idx]
    response = response + preset.noise.ldv * rng.standard_normal(response.shape)
    reference = reference + preset.noise.current * rng.standard_normal(reference.shape)
    return Scan(points=x, response=response, reference=reference, fs=preset.fs,
                quantity="velocity", source="scan.uff")

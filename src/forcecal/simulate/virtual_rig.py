"""The virtual rig: builds the finite-element model of a preset and records runs and scans.

The structure is a beam (:mod:`.beam`), a rectangular plate (:mod:`.plate`) or a block
(:mod:`.solid`); a plate takes every point (gauge, pole, probe, scan point, lumped mass) as
(x, y), a block as a location (x, y, z, dx, dy, dz): a point and the direction along which a
gauge or a pole acts or a probe or the SLDV measures.

Measurements carry seeded white noise; the ground truth (pole forces, gaps, displacement field,
the inertia term of each gauge) is returned beside them. A preset may be scanned more than once,
under other loads (:attr:`Preset.scans`); ``which`` picks the scan, the first by default. A
preset with a ``realism`` (:class:`.realism.Realism`) is measured by :mod:`.lab` instead:
coloured noise, quantization, sensitivity errors, a drifting drive, gravity preload and gauge
offsets; the functions here hand it over, with the rig's drawn errors (``errors``).
"""

from __future__ import annotations

import numpy as np

from ..records import Run, Scan
from ..rig import Actuator, ForcePoint, Gauge, LumpedMass, Rig, Sensor, TypeB, Weight
from ..structures import Beam, Body, Plate
from .integrate import Response
from .lab import LabErrors, measure_lab_run, measure_lab_scan, record_lab_run, record_lab_scan
from .magnet import Magnet
from .physics import (
    Model,
    Truth,
    _gauge_forces,
    _points,
    _rows,
    _scan_spec,
    _unit,
    build_model,
    run_truth,
    scan_file,
    scan_offsets,
    scan_points,
    scan_response,
    simulate_response,
)
from .presets import BodySpec, PlateSpec, Preset, RunSpec

__all__: list[str] = []


def _own_flux(preset: Preset, magnet: Magnet) -> str | None:
    """A pole's flux channel where the preset's magnets are several (each pole on its own
    core names its own); None with one magnet, whose flux the actuator's names."""
    return magnet.flux_channel if len(preset.magnets) > 1 else None


def _core(preset: Preset, magnet: Magnet) -> str | None:
    """The core a pole names where its magnet has several poles (one flux through them all,
    :mod:`.magnet`); None for a magnet's only pole."""
    if len(magnet.poles) < 2:
        return None
    return f"magnet{preset.magnets.index(magnet) + 1}"


def public_rig(preset: Preset) -> Rig:
    """What the lab writes in its rig file: geometry, masses, channels; no stiffness, no truth.

    Its ``[uncertainty]`` declares every type-B uncertainty zero (exact sensors), or those of
    the preset's ``realism``, whose rig also declares ``[weight]``: the gauges read the weight,
    their zeros off by the realism's ``gauge_offset``.
    """
    b = preset.beam
    mag = preset.magnets[0]
    type_b = TypeB.none() if preset.realism is None else preset.realism.type_b
    mains = None if preset.realism is None or not preset.realism.hum else preset.realism.mains
    lab = preset.realism
    weight = (None if lab is None or lab.gravity == 0.0
              else Weight(gravity=lab.gravity, gauge_zero=lab.gauge_offset))
    if isinstance(b, BodySpec):
        return Rig(
            name=f"virtual {preset.name} rig",
            structure=Body(density=b.density, blocks=b.blocks,
                           masses=tuple(LumpedMass(x=x, y=y, z=z, mass=m)
                                        for x, y, z, m in _rows(b.masses))),
            gauges=tuple(Gauge(name=n, x=x, y=y, z=z, direction=_unit(d))
                         for n, x, y, z, *d in _rows(b.gauges)),
            forces=tuple(ForcePoint(name=p.name, x=p.x, y=p.y, z=p.z, gap=p.gap,
                                    direction=_unit(p.direction), flux=_own_flux(preset, m),
                                    core=_core(preset, m))
                         for m in preset.magnets for p in m.poles),
            sensors=tuple(Sensor(name=n, x=x, y=y, z=z, direction=_unit(d))
                          for n, x, y, z, *d in _rows(preset.sensors)),
            actuator=Actuator(current=mag.current_channel, flux=mag.flux_channel,
                              turns=mag.turns, pole_area=mag.pole_area),
            frequency=preset.nominal_frequency, type_b=type_b, mains=mains, weight=weight,
        )
    if isinstance(b, PlateSpec):
        return Rig(
            name=f"virtual {preset.name} rig",
            structure=Plate(mass_per_area=b.mass_per_area, outline=b.outline,
                            masses=tuple(LumpedMass(x=x, y=y, mass=m)
                                         for x, y, m in _rows(b.masses))),
            gauges=tuple(Gauge(name=n, x=x, y=y) for n, x, y in _rows(b.gauges)),
            forces=tuple(ForcePoint(name=p.name, x=p.x, y=p.y, gap=p.gap,
                                    flux=_own_flux(preset, m), core=_core(preset, m))
                         for m in preset.magnets for p in m.poles),
            sensors=tuple(Sensor(name=n, x=x, y=y) for n, x, y in _rows(preset.sensors)),
            actuator=Actuator(current=mag.current_channel, flux=mag.flux_channel,
                              turns=mag.turns, pole_area=mag.pole_area),
            frequency=preset.nominal_frequency, type_b=type_b, mains=mains, weight=weight,
        )
    return Rig(
        name=f"virtual {preset.name} rig",
        structure=Beam(length=b.length, mass_per_length=b.mass_per_length,
                       masses=tuple(LumpedMass(x=x, mass=m) for x, m in _rows(b.masses))),
        gauges=tuple(Gauge(name=n, x=x) for n, x in _rows(b.gauges)),
        forces=tuple(ForcePoint(name=p.name, x=p.x, gap=p.gap, flux=_own_flux(preset, m),
                                core=_core(preset, m))
                     for m in preset.magnets for p in m.poles),
        sensors=tuple(Sensor(name=n, x=x) for n, x in _rows(preset.sensors)),
        actuator=Actuator(current=mag.current_channel, flux=mag.flux_channel,
                          turns=mag.turns, pole_area=mag.pole_area),
        frequency=preset.nominal_frequency, type_b=type_b, mains=mains, weight=weight,
    )


def record_run(preset: Preset, spec: RunSpec, rng: np.random.Generator,
               model: Model | None = None,
               errors: LabErrors | None = None) -> tuple[Run, Truth]:
    """Simulate one run and return what the DAQ recorded (noisy) and the truth.

    A ``lab`` preset's run is simulated under its drifting drive (:func:`.lab.record_lab_run`);
    ``errors`` are its rig's (drawn from ``rng`` when not given); an ideal preset has none.
    """
    model = model or build_model(preset)
    if preset.realism is not None:
        return record_lab_run(preset, spec, rng, model, errors)
    r = simulate_response(preset, spec.drives, spec.gap, spec.duration, model, spec.gaps)
    return measure_run(preset, spec, model, r, rng), run_truth(preset, model, r, spec)


def measure_run(preset: Preset, spec: RunSpec, model: Model, r: Response,
                rng: np.random.Generator, errors: LabErrors | None = None) -> Run:
    """What the DAQ records of a simulated response: every channel with its white noise (a
    ``lab`` preset's: :func:`.lab.measure_lab_run`, with its rig's ``errors``)."""
    if preset.realism is not None:
        return measure_lab_run(preset, spec, model, r, rng, errors)
    noise = preset.noise
    n = len(r.t)
    gauges = _gauge_forces(model, preset, r.u, r.v)
    probes = model.row(_points(preset, preset.sensors)) @ r.u
    channels: dict[str, np.ndarray] = {}
    for k, (name, *_) in enumerate(_rows(preset.beam.gauges)):
        channels[str(name)] = gauges[k] + noise.gauge * rng.standard_normal(n)
    for k, (name, *_) in enumerate(_rows(preset.sensors)):
        channels[str(name)] = probes[k] + noise.probe * rng.standard_normal(n)
    for k, mag in enumerate(preset.magnets):
        channels[mag.current_channel] = r.current[k] + noise.current * rng.standard_normal(n)
        channels[mag.flux_channel] = r.flux[k] + noise.flux * rng.standard_normal(n)
        channels[mag.voltage_channel] = r.voltage[k] + noise.voltage * rng.standard_normal(n)
    return Run(channels=channels, fs=preset.fs, t0=0.0, name=spec.name,
               source=f"{spec.name}.csv", labels=dict(spec.labels))


def record_scan(preset: Preset, rng: np.random.Generator,
                model: Model | None = None, which: int = 0,
                errors: LabErrors | None = None) -> Scan:
    """A sequential SLDV scan: each point a velocity record with its own random start phase.

    The rig runs on its steady state; point k is recorded over its own window, which starts at
    a random time within one drive period (:func:`scan_offsets`), with the coil current of the
    same window (the current of the scan's ``reference`` magnet) as reference. ``which``
    indexes :attr:`Preset.scans`. A ``lab`` preset's drive walks from point to point
    (:func:`.lab.record_lab_scan`), with its rig's ``errors``.
    """
    model = model or build_model(preset)
    if preset.realism is not None:
        return record_lab_scan(preset, rng, model, which, errors)[0]
    return measure_scan(preset, model, scan_response(preset, model, which), rng, which)


def measure_scan(preset: Preset, model: Model, r: Response,
                 rng: np.random.Generator, which: int = 0,
                 errors: LabErrors | None = None) -> Scan:
    """The scan's records: a window per point at a random start within one drive period
    (:func:`scan_offsets`); the reference is the coil current of the scan's ``reference``
    magnet. ``which`` indexes :attr:`Preset.scans` (``r`` is that scan's
    :func:`scan_response`). A ``lab`` preset's records carry its noise and its rig's
    ``errors`` (:func:`.lab.measure_lab_scan`; the drive does not walk here)."""
    if preset.realism is not None:
        return measure_lab_scan(preset, model, r, rng, which, errors)
    spec = _scan_spec(preset, which)
    n_rec = int(round(spec.record * preset.fs))
    per_period = scan_offsets(preset, which)
    x = scan_points(preset, which)
    velocity = model.row(x) @ r.v                            # (n_points, n_total)
    # a 3-D SLDV measures a point's three components in one acquisition
    per_point = 3 if preset.is_body else 1
    starts = np.repeat(rng.integers(0, per_period, size=len(x) // per_point), per_point)
    idx = starts[:, None] + np.arange(n_rec)[None, :]
    response = np.take_along_axis(velocity, idx, axis=1)
    reference = r.current[spec.reference][idx]
    response = response + preset.noise.ldv * rng.standard_normal(response.shape)
    noise = rng.standard_normal((len(x) // per_point, n_rec))
    reference = reference + preset.noise.current * np.repeat(noise, per_point, axis=0)
    return Scan(points=x, response=response, reference=reference, fs=preset.fs,
                quantity="velocity", source=scan_file(which))

"""The virtual rig: builds the finite-element model of a preset and records runs and scans.

The structure is a beam (:mod:`.beam`), a rectangular plate (:mod:`.plate`) or a block
(:mod:`.solid`); a plate takes every point (gauge, pole, probe, scan point, lumped mass) as
(x, y), a block as a location (x, y, z, dx, dy, dz): a point and the direction along which a
gauge or a pole acts or a probe or the SLDV measures.

Measurements carry seeded white noise; the ground truth (pole forces, gaps, displacement field,
the inertia term of each gauge) is returned beside them.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..records import Run, Scan
from ..rig import Actuator, ForcePoint, Gauge, LumpedMass, Rig, Sensor
from ..structures import Beam, Body, Plate
from .beam import BeamModel, assemble_beam, natural_frequencies
from .integrate import Response, integrate
from .magnet import Drive, Magnet
from .plate import PlateModel, assemble_plate
from .presets import BeamSpec, BodySpec, PlateSpec, Preset, RunSpec, first_mode_beta
from .solid import SolidModel, assemble_solid

__all__ = [
    "Truth",
    "build_model",
    "measure_run",
    "measure_scan",
    "public_rig",
    "record_run",
    "record_scan",
    "relaxation_modes",
    "run_truth",
    "scan_points",
    "scan_response",
]

Model = BeamModel | PlateModel | SolidModel


@dataclass(frozen=True)
class Truth:
    """Ground truth of one run.

    pole_force : (n_poles, n_samples) [N]; gap : (n_poles, n_samples) [m];
    nodes : (n_nodes,) [m] on a beam, (n_nodes, 2) (x, y) on a plate, (n_nodes, 3) on a body;
    w : (n_nodes, n_samples) [m] deflection at the FE nodes (on a body its z component);
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


def build_model(preset: Preset) -> Model:
    """The beam or plate of ``preset`` on its gauge springs, damped at the first bending mode."""
    b = preset.beam
    if isinstance(b, PlateSpec):
        return _build_plate(b)
    if isinstance(b, BodySpec):
        return _build_body(b)
    springs = tuple((x, b.gauge_stiffness) for _, x in b.gauges)
    undamped = assemble_beam(b.length, b.ei, b.mass_per_length, b.n_elements, b.masses, springs)
    f1 = _first_bending(undamped)
    return assemble_beam(b.length, b.ei, b.mass_per_length, b.n_elements, b.masses, springs,
                         beta=first_mode_beta(b, f1))


def _build_plate(p: PlateSpec) -> PlateModel:
    springs = tuple((x, y, p.gauge_stiffness) for _, x, y in p.gauges)
    args = (p.a, p.b, p.flexural_rigidity, p.mass_per_area, p.poisson, p.mesh, p.masses, springs)
    f1 = _first_bending(assemble_plate(*args))
    return assemble_plate(*args, beta=first_mode_beta(p, f1))


def _build_body(p: BodySpec) -> SolidModel:
    springs = tuple((*g[1:], p.gauge_stiffness) for g in p.gauges)
    args = (p.size, p.youngs_modulus, p.poisson, p.density, p.mesh)
    f1 = _first_bending(assemble_solid(*args, masses=p.masses, springs=springs))
    return assemble_solid(*args, masses=p.masses, springs=springs,
                          beta=first_mode_beta(p, f1))


def _first_bending(model: Model) -> float:
    """Lowest mode that bends the structure (the bounce modes on the gauge springs are rigid)."""
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
    if isinstance(b, BodySpec):
        return Rig(
            name=f"virtual {preset.name} rig",
            structure=Body(density=b.density, blocks=b.blocks,
                           masses=tuple(LumpedMass(x=x, y=y, z=z, mass=m)
                                        for x, y, z, m in _rows(b.masses))),
            gauges=tuple(Gauge(name=n, x=x, y=y, z=z, direction=_unit(d))
                         for n, x, y, z, *d in _rows(b.gauges)),
            forces=tuple(ForcePoint(name=p.name, x=p.x, y=p.y, z=p.z, gap=p.gap,
                                    direction=_unit(p.direction))
                         for m in preset.magnets for p in m.poles),
            sensors=tuple(Sensor(name=n, x=x, y=y, z=z, direction=_unit(d))
                          for n, x, y, z, *d in _rows(preset.sensors)),
            actuator=Actuator(current=mag.current_channel, flux=mag.flux_channel,
                              turns=mag.turns, pole_area=mag.pole_area),
            frequency=preset.nominal_frequency,
        )
    if isinstance(b, PlateSpec):
        return Rig(
            name=f"virtual {preset.name} rig",
            structure=Plate(mass_per_area=b.mass_per_area, outline=b.outline,
                            masses=tuple(LumpedMass(x=x, y=y, mass=m)
                                         for x, y, m in _rows(b.masses))),
            gauges=tuple(Gauge(name=n, x=x, y=y) for n, x, y in _rows(b.gauges)),
            forces=tuple(ForcePoint(name=p.name, x=p.x, y=p.y, gap=p.gap)
                         for m in preset.magnets for p in m.poles),
            sensors=tuple(Sensor(name=n, x=x, y=y) for n, x, y in _rows(preset.sensors)),
            actuator=Actuator(current=mag.current_channel, flux=mag.flux_channel,
                              turns=mag.turns, pole_area=mag.pole_area),
            frequency=preset.nominal_frequency,
        )
    return Rig(
        name=f"virtual {preset.name} rig",
        structure=Beam(length=b.length, mass_per_length=b.mass_per_length,
                       masses=tuple(LumpedMass(x=x, mass=m) for x, m in _rows(b.masses))),
        gauges=tuple(Gauge(name=n, x=x) for n, x in _rows(b.gauges)),
        forces=tuple(ForcePoint(name=p.name, x=p.x, gap=p.gap)
                     for m in preset.magnets for p in m.poles),
        sensors=tuple(Sensor(name=n, x=x) for n, x in _rows(preset.sensors)),
        actuator=Actuator(current=mag.current_channel, flux=mag.flux_channel,
                          turns=mag.turns, pole_area=mag.pole_area),
        frequency=preset.nominal_frequency,
    )


def _rows(items: Sequence[Sequence[Any]]) -> list[tuple[Any, ...]]:
    """A preset's rows (name and coordinates, or coordinates and mass) as plain tuples."""
    return [tuple(item) for item in items]


def _unit(d: Sequence[float]) -> tuple[float, float, float]:
    v = np.asarray(d, dtype=float)
    v = v / np.linalg.norm(v)
    return (float(v[0]), float(v[1]), float(v[2]))


def _points(preset: Preset, items) -> np.ndarray:
    """Coordinates of named points ``(name, x[, y[, z, dx, dy, dz]])`` as ``model.row`` takes
    them: (n,) x on a beam, (n, 2) (x, y) on a plate, (n, 6) locations on a body."""
    if preset.is_body:
        return np.array([[x, y, z, *_unit(d)] for _, x, y, z, *d in items],
                        dtype=float).reshape(-1, 6)
    if preset.is_plate:
        return np.array([[x, y] for _, x, y in items], dtype=float).reshape(-1, 2)
    return np.array([x for _, x in items])


def _gauge_forces(model: Model, preset: Preset, u, v) -> np.ndarray:
    """(n_gauges, n) [N] force each gauge exerts on the structure (spring plus its dashpot)."""
    rows = model.row(_points(preset, preset.beam.gauges))
    k = preset.beam.gauge_stiffness
    return -k * (rows @ u + model.beta * (rows @ v))


def relaxation_modes(model: Model, preset: Preset) -> np.ndarray:
    """(n_gauges, n_dof): nodal vectors of the relaxation shapes psi_r (METHOD.md section 2).

    Beam on gauges at xa, xb: (xb - x)/(xb - xa) and (x - xa)/(xb - xa). Plate on three
    gauges: the barycentric coordinates of the gauge triangle, psi_r = c0 + c1 x + c2 y with
    psi_r(g_s) = delta_rs. Block on six gauges: the rigid motion t_r + theta_r x x whose
    component along every gauge's direction is delta_rs at that gauge. All are rigid motions,
    exact in the element bases.
    """
    spec = preset.beam
    if isinstance(spec, BodySpec):
        g = _points(preset, spec.gauges)
        # column m of a: d_s . u_m(g_s) for the translations e_m and the rotations e_m x x
        a = np.hstack([g[:, 3:], np.cross(g[:, :3], g[:, 3:])])
        coef = np.linalg.inv(a)                      # column r: psi_r's (t, theta)
        assert isinstance(model, SolidModel)
        return np.stack([model.rigid_mode(coef[:3, r], coef[3:, r]) for r in range(len(g))])
    if isinstance(spec, BeamSpec):
        (_, xa), (_, xb) = spec.gauges
        span = xb - xa
        return np.stack([model.rigid_mode(xb / span, -1 / span),
                         model.rigid_mode(-xa / span, 1 / span)])
    g = np.array([[1.0, x, y] for _, x, y in spec.gauges])
    coef = np.linalg.inv(g)                          # column r: psi_r's (c0, c1, c2)
    return np.stack([model.rigid_mode(*coef[:, r]) for r in range(len(spec.gauges))])


def _inertia(model: Model, preset: Preset, a) -> np.ndarray:
    """(n_gauges, n) [N]: Psi_r^T M a, the inertia term of every relaxed gauge (exact)."""
    return relaxation_modes(model, preset) @ (model.mass @ a)


def simulate_response(preset: Preset, drives: tuple[Drive, ...], gap: float | None,
                      duration: float, model: Model | None = None) -> Response:
    model = model or build_model(preset)
    return integrate(model, _magnets_at(preset, gap), drives, preset.fs, duration)


def record_run(preset: Preset, spec: RunSpec, rng: np.random.Generator,
               model: Model | None = None) -> tuple[Run, Truth]:
    """Simulate one run and return what the DAQ recorded (noisy) and the truth."""
    model = model or build_model(preset)
    r = simulate_response(preset, spec.drives, spec.gap, spec.duration, model)
    return measure_run(preset, spec, model, r, rng), run_truth(preset, model, r)


def measure_run(preset: Preset, spec: RunSpec, model: Model, r: Response,
                rng: np.random.Generator) -> Run:
    """What the DAQ records of a simulated response: every channel with its white noise."""
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


def run_truth(preset: Preset, model: Model, r: Response) -> Truth:
    """The ground truth of a simulated response."""
    if isinstance(model, SolidModel):
        w = r.u[2::3]                                             # u_z of every node
    else:
        w = r.u[0::4 if isinstance(model, PlateModel) else 2]     # w is the first nodal DOF
    return Truth(
        t=r.t, pole_names=tuple(p.name for m in preset.magnets for p in m.poles),
        pole_force=r.pole_force, gap=r.gap, nodes=model.nodes, w=w,
        inertia=_inertia(model, preset, r.a), current=r.current, flux=r.flux,
    )


def record_scan(preset: Preset, rng: np.random.Generator,
                model: Model | None = None) -> Scan:
    """A sequential SLDV scan: each point a velocity record with its own random start phase.

    The rig runs on its periodic steady state; point k is recorded over its own window, which
    starts at a random time within one drive period, with the coil current of the same window
    as reference.
    """
    model = model or build_model(preset)
    return measure_scan(preset, model, scan_response(preset, model), rng)


def scan_points(preset: Preset) -> np.ndarray:
    """The scan grid [m]: (n_points,) along a beam; (n_x * n_y, 2) over a plate, x fastest; on
    a body the locations (n, 6) of the records: every point of the top face's grid and of the
    side faces' rows (at ``heights`` levels strictly between bottom and top), along x, y and z
    (the three records of a point follow each other)."""
    spec = preset.scan
    b = preset.beam
    if isinstance(b, BodySpec):
        assert spec.grid is not None, "a body's scan needs its top-face grid"
        nx, ny = spec.grid
        xs, ys = np.linspace(0.0, b.a, nx), np.linspace(0.0, b.b, ny)
        zs = b.c * np.arange(1, spec.heights + 1) / (spec.heights + 1)
        gx, gy = np.meshgrid(xs, ys, indexing="xy")
        faces = [np.column_stack([gx.ravel(), gy.ravel(), np.full(gx.size, b.c)])]
        for x0 in (0.0, b.a):
            yy, zz = np.meshgrid(ys, zs, indexing="xy")
            faces.append(np.column_stack([np.full(yy.size, x0), yy.ravel(), zz.ravel()]))
        for y0 in (0.0, b.b):
            xx, zz = np.meshgrid(xs, zs, indexing="xy")
            faces.append(np.column_stack([xx.ravel(), np.full(xx.size, y0), zz.ravel()]))
        pts = np.vstack(faces)
        _, first = np.unique(pts.round(12), axis=0, return_index=True)
        pts = pts[np.sort(first)]                  # the side faces share their corner columns
        return np.hstack([np.repeat(pts, 3, axis=0), np.tile(np.eye(3), (len(pts), 1))])
    if isinstance(b, PlateSpec):
        if spec.grid is None:
            raise ValueError(f"preset '{preset.name}': a plate scan needs ScanSpec.grid (n_x, n_y)")
        nx, ny = spec.grid
        gx, gy = np.meshgrid(np.linspace(0.0, b.a, nx), np.linspace(0.0, b.b, ny), indexing="xy")
        return np.column_stack([gx.ravel(), gy.ravel()])
    return np.linspace(0.0, b.length, spec.n_points)


def scan_response(preset: Preset, model: Model) -> Response:
    """The steady-state response the scan samples: one record plus one drive period."""
    spec = preset.scan
    n_rec = int(round(spec.record * preset.fs))
    per_period = int(np.ceil(preset.fs / spec.drives[0].frequency))
    return simulate_response(preset, spec.drives, spec.gap, (n_rec + per_period) / preset.fs,
                             model)


def measure_scan(preset: Preset, model: Model, r: Response,
                 rng: np.random.Generator) -> Scan:
    """The scan's records: a window per point at a random start within one drive period."""
    spec = preset.scan
    n_rec = int(round(spec.record * preset.fs))
    per_period = int(np.ceil(preset.fs / spec.drives[0].frequency))
    x = scan_points(preset)
    velocity = model.row(x) @ r.v                            # (n_points, n_total)
    # a 3-D SLDV measures a point's three components in one acquisition
    per_point = 3 if preset.is_body else 1
    starts = np.repeat(rng.integers(0, per_period, size=len(x) // per_point), per_point)
    idx = starts[:, None] + np.arange(n_rec)[None, :]
    response = np.take_along_axis(velocity, idx, axis=1)
    reference = r.current[0][idx]
    response = response + preset.noise.ldv * rng.standard_normal(response.shape)
    noise = rng.standard_normal((len(x) // per_point, n_rec))
    reference = reference + preset.noise.current * np.repeat(noise, per_point, axis=0)
    return Scan(points=x, response=response, reference=reference, fs=preset.fs,
                quantity="velocity", source="scan.uff")

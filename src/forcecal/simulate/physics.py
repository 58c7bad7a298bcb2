"""The virtual rig's physics: the finite-element model of a preset (a beam, :mod:`.beam`; a
rectangular plate, :mod:`.plate`; a block, :mod:`.solid`), its response to the drives, the
ground truth (pole forces, gaps, displacement field, each gauge's inertia term) and the scan's
points. A plate takes every point as (x, y), a block as a location (x, y, z, dx, dy, dz).
What the instruments record of it is :mod:`.virtual_rig`'s (ideal) and :mod:`.lab`'s.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .beam import BeamModel, assemble_beam, natural_frequencies
from .integrate import Response, integrate
from .magnet import Drive, Magnet, Pole
from .plate import PlateModel, assemble_plate
from .presets import BeamSpec, BodySpec, PlateSpec, Preset, RunSpec, ScanSpec, first_mode_beta
from .solid import SolidModel, assemble_solid

__all__: list[str] = []

Model = BeamModel | PlateModel | SolidModel


@dataclass(frozen=True)
class Truth:
    """Ground truth of one run.

    pole_force : (n_poles, n_samples) [N]; gap : (n_poles, n_samples) [m];
    nodes : (n_nodes,) [m] on a beam, (n_nodes, 2) (x, y) on a plate, (n_nodes, 3) on a body;
    w : (n_nodes, n_samples) [m] deflection at the FE nodes (on a body its z component);
    inertia : (n_gauges, n_samples) [N], J_r = integral(rho psi_r w_tt) + lumped terms;
    static_gap : (n_poles,) [m], each pole's gap at zero deflection during the run;
    imperfections : what a ``lab`` rig drew for the run (empty for an ideal one): the drive's
    ``drive_drift`` and ``drive_chirp`` [1/s], every channel's ``sensitivity`` (named by
    ``sensitivity_channels``), each gauge's ``gauge_preload`` and ``gauge_offset`` [N].
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
    static_gap: np.ndarray
    imperfections: dict[str, np.ndarray] = field(default_factory=dict)


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


def _magnets_at(preset: Preset, gap: float | None,
                gaps: Mapping[str, float] | None = None) -> tuple[Magnet, ...]:
    """The preset's magnets with every pole at ``gap``, then single poles at ``gaps``."""
    gaps = dict(gaps or {})
    names = [p.name for m in preset.magnets for p in m.poles]
    unknown = sorted(set(gaps) - set(names))
    if unknown:
        raise ValueError(f"preset '{preset.name}': no pole {unknown[0]!r} to set the gap of "
                         f"(poles: {', '.join(names)})")
    if gap is None and not gaps:
        return preset.magnets

    def at(p: Pole) -> Pole:
        return dataclasses.replace(p, gap=gaps.get(p.name, p.gap if gap is None else gap))

    return tuple(dataclasses.replace(m, poles=tuple(at(p) for p in m.poles))
                 for m in preset.magnets)


def static_gaps(preset: Preset, gap: float | None = None,
                gaps: Mapping[str, float] | None = None) -> np.ndarray:
    """Every pole's gap at zero deflection [m], in the order of the magnets' poles.

    Parameters
    ----------
    preset : Preset
        The virtual rig.
    gap : float or None [m]
        Overrides every pole's static gap.
    gaps : mapping pole name -> float [m], optional
        Overrides single poles' static gaps, after ``gap``.

    Returns
    -------
    (n_poles,) ndarray [m]
    """
    return np.array([p.gap for m in _magnets_at(preset, gap, gaps) for p in m.poles])


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
                      duration: float, model: Model | None = None,
                      gaps: Mapping[str, float] | None = None) -> Response:
    """The rig's steady-state response to ``drives`` with every pole at ``gap`` (None: the
    preset's gaps), then single poles at ``gaps`` (pole name -> m)."""
    model = model or build_model(preset)
    return integrate(model, _magnets_at(preset, gap, gaps), drives, preset.fs, duration)


def run_truth(preset: Preset, model: Model, r: Response, spec: RunSpec | None = None) -> Truth:
    """The ground truth of a simulated response; ``spec`` (the run) gives its static gaps
    (without it, the preset's)."""
    static = static_gaps(preset) if spec is None else static_gaps(preset, spec.gap, spec.gaps)
    if isinstance(model, SolidModel):
        w = r.u[2::3]                                             # u_z of every node
    else:
        w = r.u[0::4 if isinstance(model, PlateModel) else 2]     # w is the first nodal DOF
    return Truth(
        t=r.t, pole_names=tuple(p.name for m in preset.magnets for p in m.poles),
        pole_force=r.pole_force, gap=r.gap, nodes=model.nodes, w=w,
        inertia=_inertia(model, preset, r.a), current=r.current, flux=r.flux,
        static_gap=static,
    )


def _scan_spec(preset: Preset, which: int) -> ScanSpec:
    scans = preset.scans
    if not 0 <= which < len(scans):
        raise IndexError(f"preset '{preset.name}' has {len(scans)} scan(s), not a scan {which}")
    return scans[which]


def scan_file(which: int = 0) -> str:
    """The file a scan is written to: ``scan.uff`` for the first, ``scan2.uff``, ... after."""
    return "scan.uff" if which == 0 else f"scan{which + 1}.uff"


def scan_points(preset: Preset, which: int = 0) -> np.ndarray:
    """The scan grid [m]: (n_points,) along a beam; (n_x * n_y, 2) over a plate, x fastest; on
    a body the locations (n, 6) of the records: every point of the top face's grid and of the
    side faces' rows (at ``heights`` levels strictly between bottom and top), along x, y and z
    (the three records of a point follow each other). ``which`` indexes :attr:`Preset.scans`."""
    spec = _scan_spec(preset, which)
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


def scan_offsets(preset: Preset, which: int = 0) -> int:
    """How many start samples a scan's windows draw theirs from: one drive period (of the
    first drive's waveform when it has one), or one record under a waveform that does not
    repeat. ``which`` indexes :attr:`Preset.scans`."""
    spec = _scan_spec(preset, which)
    wave = spec.drives[0].waveform
    if wave is None:
        return int(np.ceil(preset.fs / spec.drives[0].frequency))
    if wave.period is None:
        return int(round(spec.record * preset.fs))
    return int(np.ceil(preset.fs * wave.period))


def scan_response(preset: Preset, model: Model, which: int = 0) -> Response:
    """The steady-state response a scan samples: one record plus the span of the windows'
    starts (:func:`scan_offsets`: one drive period).

    ``which`` indexes :attr:`Preset.scans`.
    """
    spec = _scan_spec(preset, which)
    n_rec = int(round(spec.record * preset.fs))
    per_period = scan_offsets(preset, which)
    return simulate_response(preset, spec.drives, spec.gap, (n_rec + per_period) / preset.fs,
                             model, spec.gaps)

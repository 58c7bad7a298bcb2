"""A 3-D body on six statically determinate gauges: a union of axis-aligned blocks.

Every gauge, force and sensor on a body carries a direction, and every scalar quantity (a
gauge's reaction, a pole's force, a probe's or a scan record's displacement) is the component
of a vector along it: shapes and relaxation shapes are evaluated at *locations*
(x, y, z, dx, dy, dz). The rigid motions are u = t + theta x (x - c), three translations and
three rotations; the shapes are vector fields, one polynomial field per axis
(:mod:`forcecal.model.vector_basis`); the mass quadrature is a tensor Gauss rule in each block, each
node entering once per axis.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from ..errors import InputError
from ..model.vector_basis import AXES, VectorShapeFit, fit_vector_shape
from .base import Frame, Located, LumpedMass, Structure, locations

if TYPE_CHECKING:
    from ..model.basis import ShapeFit
    from ..model.vector_basis import VectorShapeFit

__all__ = ["Body"]

Corner = tuple[float, float, float]
Block = tuple[Corner, Corner]
"""An axis-aligned box ((x0, y0, z0), (x1, y1, z1)) [m]."""

_N_BLOCK = 12
"""Gauss points per axis in each block (exact for degree <= 23 along each axis)."""


@dataclass(frozen=True)
class Body(Structure):
    """A body of ``density`` [kg/m^3] filling ``blocks`` (boxes that do not overlap).

    Its structure coordinates are locations (n, 6) (x, y, z [m], dx, dy, dz [1]).
    """

    blocks: tuple[Block, ...]
    density: float
    masses: tuple[LumpedMass, ...] = ()

    kind: ClassVar[str] = "body"
    mass_field: ClassVar[str] = "density"
    axes: ClassVar[tuple[str, ...]] = ("x", "y", "z")
    directed: ClassVar[bool] = True
    n_rigid: ClassVar[int] = 6
    bases: ClassVar[tuple[str, ...]] = ("polynomial",)
    singular_support: ClassVar[str] = ("some rigid motion moves none of them, e.g. their lines "
                                       "of action all meet one line or all lie parallel to one "
                                       "plane")

    @property
    def distributed_mass(self) -> float:
        return self.density * sum(float(np.prod(np.subtract(hi, lo))) for lo, hi in self.blocks)

    def contains(self, x: float, y: float = 0.0, z: float = 0.0, tol: float = 1e-9) -> bool:
        p = np.array([x, y, z])
        return any(bool(np.all((np.asarray(lo) - tol <= p) & (p <= np.asarray(hi) + tol)))
                   for lo, hi in self.blocks)

    def outside(self, x: float, y: float = 0.0, z: float = 0.0) -> str:
        return f"(x, y, z) = ({x}, {y}, {z}) lies in none of the structure's blocks"

    def extent(self) -> tuple[tuple[float, float], ...]:
        lo = np.min([blk[0] for blk in self.blocks], axis=0)
        hi = np.max([blk[1] for blk in self.blocks], axis=0)
        return tuple((float(a), float(b)) for a, b in zip(lo, hi, strict=True))

    def mass_quadrature(self) -> tuple[np.ndarray, np.ndarray]:
        qp, qw = block_quadrature(self.blocks, _N_BLOCK)
        pts = np.vstack([qp, np.array([[m.x, m.y, m.z] for m in self.masses]).reshape(-1, 3)])
        w = np.concatenate([qw * self.density, [m.mass for m in self.masses]])
        return _along_axes(pts), np.tile(w, 3)

    def grid(self, n: int = 401) -> np.ndarray:
        side = max(int(round((n / 3) ** (1 / 3))), 2)
        pts = np.vstack([np.stack(np.meshgrid(*[np.linspace(lo[a], hi[a], side)
                                                 for a in range(3)], indexing="ij"),
                                  axis=-1).reshape(-1, 3) for lo, hi in self.blocks])
        return _along_axes(pts)

    def rig_points(self, items: Sequence[Located]) -> np.ndarray:
        return locations(items)

    def up(self, coordinates: np.ndarray) -> np.ndarray:
        return np.asarray(coordinates, dtype=float)[:, 5]       # each location's dz

    def coordinates(self, points: np.ndarray, source: str = "<points>") -> np.ndarray:
        pts = np.asarray(points, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 6:
            found = pts.shape[1] if pts.ndim == 2 else 1
            raise InputError(f"{source}: a body's points need coordinates and a measuring "
                             f"direction (x, y, z, dx, dy, dz); found {found} columns")
        return pts

    def frame(self, gauges: np.ndarray) -> Frame:
        """Rotations about the gauges' centroid, divided by their largest distance from it."""
        g = np.asarray(gauges)[:, :3]
        centre = g.mean(axis=0)
        return Frame(centre, max(float(np.max(np.linalg.norm(g - centre, axis=1))), 1e-9))

    def rigid_modes(self, coordinates: np.ndarray, frame: Frame) -> np.ndarray:
        pts = self.coordinates(coordinates)
        r = pts[:, :3] - (np.zeros(3) if frame.centre is None else frame.centre)
        d = pts[:, 3:]
        # d . (theta x r) = theta . (r x d)
        return np.vstack([d.T, np.cross(r, d).T / frame.scale])

    def fit_shape(self, coordinates: np.ndarray, values: np.ndarray, criterion: str,
                  weights: np.ndarray, basis: str, min_order: int = 1) -> VectorShapeFit:
        return fit_vector_shape(coordinates, values, self.extent(), criterion, weights,
                                min_order)

    def model_notes(self, fits: Sequence[ShapeFit | VectorShapeFit]) -> tuple[str, ...]:
        first = fits[0]
        measured = first.axes if isinstance(first, VectorShapeFit) else (0, 1, 2)
        missing = [AXES[a] for a in range(3) if a not in measured]
        if not missing:
            return ()
        return (f"the scan measures no motion along {', '.join(missing)}; the body's inertia "
                "along it is taken as zero",)

    def combinations(self, force_points: np.ndarray,
                     force_names: Sequence[str]) -> tuple[tuple[str, ...], np.ndarray]:
        """Each force, the total (the forces along their own directions: the actuator's pull
        when its poles act along one direction), the resultant's components ``resultant_x``,
        ``_y``, ``_z`` [N] and its moment about the origin ``moment_x``, ``_y``, ``_z`` [N m]."""
        pts = np.asarray(force_points)
        n_f = len(force_names)
        d = pts[:, 3:]
        arm = np.cross(pts[:, :3], d)
        return ((*force_names, "total", "resultant_x", "resultant_y", "resultant_z",
                 "moment_x", "moment_y", "moment_z"),
                np.vstack([np.eye(n_f), np.ones(n_f), d.T, arm.T]))

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "density": self.density,
                "blocks": [{"min": list(lo), "max": list(hi)} for lo, hi in self.blocks]}

    @classmethod
    def from_keys(cls, keys: Any, masses: tuple[LumpedMass, ...],
                  fail: Callable[[str, str], Exception]) -> Body:
        return cls(blocks=_blocks(fail, keys.blocks), density=keys.density, masses=masses)


def _along_axes(points: np.ndarray) -> np.ndarray:
    """Points (n, 3) -> locations (3 n, 6): every point along x, then along y, then along z."""
    return np.vstack([np.column_stack([points, np.tile(e, (len(points), 1))])
                      for e in np.eye(3)])


def _blocks(fail: Callable[[str, str], Exception], keys: Sequence[Any]) -> tuple[Block, ...]:
    """A body's ``structure.blocks``: axis-aligned boxes {min = [x, y, z], max = [x, y, z]},
    each non-empty, none overlapping another."""
    out: list[Block] = []
    for k, blk in enumerate(keys):
        key = f"structure.blocks[{k}]"
        lo, hi = blk.min, blk.max
        if not all(a < b for a, b in zip(lo, hi, strict=True)):
            raise fail(f"{key}.max", f"= {list(hi)} must exceed min = {list(lo)} in x, y "
                       "and z")
        for j, (lo2, hi2) in enumerate(out):
            if all(max(a, c) < min(b, d) - 1e-12 for a, b, c, d in zip(lo, hi, lo2, hi2,
                                                                     strict=True)):
                raise fail(key, f"overlaps structure.blocks[{j}] (its mass would count "
                           "twice)")
        out.append(((lo[0], lo[1], lo[2]), (hi[0], hi[1], hi[2])))
    return tuple(out)


def block_quadrature(blocks: Sequence[Block], n: int = _N_BLOCK) -> tuple[np.ndarray, np.ndarray]:
    """Points and weights integrating over a union of axis-aligned boxes (an n x n x n
    Gauss-Legendre rule in each, exact for degree <= 2 n - 1 along each axis).

    Parameters
    ----------
    blocks : sequence of ((x0, y0, z0), (x1, y1, z1))
        [m] corners of each box.
    n : int
        Gauss points per axis.

    Returns
    -------
    points : (n_q, 3) ndarray
        [m]
    weights : (n_q,) ndarray
        [m^3]
    """
    g, w = np.polynomial.legendre.leggauss(n)
    g, w = 0.5 * (g + 1.0), 0.5 * w
    pts, wts = [], []
    for lo, hi in blocks:
        origin, size = np.asarray(lo, dtype=float), np.subtract(hi, lo)
        axes = [origin[a] + size[a] * g for a in range(3)]
        pts.append(np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3))
        wts.append(np.einsum("i,j,k->ijk", w, w, w).ravel() * float(np.prod(size)))
    return np.vstack(pts), np.concatenate(wts)

"""What every kind of structure answers, so that no stage of the method asks which kind it has.

A structure is the elastic body of a rig: its extent and mass distribution, the coordinates in
which its points are written, its rigid-body motions (from which the gauges' relaxation shapes
are combined), a mass quadrature (for the mass couplings m_{r,n}), the basis family of its
harmonic shapes, and the resultant combinations of forces it reports. One class per kind
answers these questions (:class:`~forcecal.structures.beam.Beam`,
:class:`~forcecal.structures.plate.Plate`, :class:`~forcecal.structures.body.Body`); the rig
parser picks the class, and every other module works through this interface.

Two kinds of coordinates appear:

- *rig points*: the rows the rig keeps for its gauges, forces and sensors,
  (n, 2) (x, y) [m] on beams and plates, (n, 6) *locations* (x, y, z, dx, dy, dz) on a body,
  where each scalar quantity is the component of a vector along its direction;
- *structure coordinates*: what shapes, rigid motions and bases are evaluated at, x (n,) on a
  beam, (x, y) (n, 2) on a plate, locations (n, 6) on a body (:meth:`Structure.coordinates`).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import numpy as np

from ..errors import InputError
from ..model.basis import fit_shape

if TYPE_CHECKING:
    from ..model.basis import ShapeFit
    from ..model.vector_basis import VectorShapeFit

__all__ = ["UP", "LumpedMass", "Structure", "locations", "ranges_text"]

UP = (0.0, 0.0, 1.0)
"""The measuring direction of beams and plates: +w, out of their plane."""


@dataclass(frozen=True)
class LumpedMass:
    """A point mass rigidly attached to the structure [kg] at (x, y, z) [m]."""

    x: float
    mass: float
    y: float = 0.0
    z: float = 0.0


class Located(Protocol):
    """A point of the rig with a measuring direction (a gauge, a force point, a sensor)."""

    @property
    def x(self) -> float: ...

    @property
    def y(self) -> float: ...

    @property
    def z(self) -> float: ...

    @property
    def direction(self) -> tuple[float, float, float]: ...


def locations(items: Iterable[Located]) -> np.ndarray:
    """Locations of points: rows (x, y, z, dx, dy, dz), a point [m] and the unit direction in
    which a force acts or a displacement is measured there.

    Parameters
    ----------
    items : iterable of objects with ``x``, ``y``, ``z`` and ``direction``
        Gauges, force points or sensors.

    Returns
    -------
    (n, 6) array [m, 1]
    """
    return np.array([[p.x, p.y, p.z, *p.direction] for p in items], dtype=float).reshape(-1, 6)


def ranges_text(lo: Iterable[float], hi: Iterable[float], axes: Iterable[str]) -> str:
    """An extent in words, e.g. ``x in [0, 0.6] m`` or ``x in [0, 0.5] m, y in [0, 0.4] m``.

    Parameters
    ----------
    lo, hi : iterable of float
        [m] the smallest and the largest coordinate along each of ``axes``.
    axes : iterable of str
    """
    return ", ".join(f"{a} in [{float(a0):.4g}, {float(a1):.4g}] m"
                     for a, a0, a1 in zip(axes, lo, hi, strict=False))


@dataclass(frozen=True)
class Frame:
    """Where a structure's rigid rotations are taken: about ``centre`` [m] (None: the origin),
    divided by the length ``scale`` [m] so that every rigid mode is of order 1."""

    centre: np.ndarray | None = None
    scale: float = 1.0


class Structure(ABC):
    """The protocol of a structure kind (see the module docstring).

    Class attributes
    ----------------
    kind : the rig file's ``structure.kind``
    axes : the coordinates each point gives in the rig file, ("x",), ("x", "y") or all three
    directed : whether every gauge, force and sensor carries a measuring direction
    n_rigid : rigid-body modes, and so the number of statically determinate gauges
    bases : the shape bases offered (``--basis``)
    singular_support : why a set of gauges may fail to hold it statically determinately
    """

    kind: ClassVar[str]
    axes: ClassVar[tuple[str, ...]]
    directed: ClassVar[bool] = False
    n_rigid: ClassVar[int]
    mass_field: ClassVar[str]
    """The field holding the distributed mass (mass per length, per area, density)."""
    bases: ClassVar[tuple[str, ...]] = ("polynomial", "modes")
    singular_support: ClassVar[str] = "gauges on one line, or at one point"
    masses: tuple[LumpedMass, ...]

    # -------------------------------------------------------------- geometry and mass

    @property
    def dim(self) -> int:
        """Number of coordinates of a point (1, 2 or 3)."""
        return len(self.axes)

    @property
    @abstractmethod
    def distributed_mass(self) -> float:
        """Mass of the continuum, without the lumped masses [kg]."""

    @property
    def total_mass(self) -> float:
        """Distributed plus lumped mass [kg]."""
        return self.distributed_mass + sum(m.mass for m in self.masses)

    def with_masses(self, distributed: float = 1.0,
                    lumped: Sequence[float] | None = None) -> Structure:
        """A copy whose distributed mass is scaled by ``distributed`` and whose k-th lumped
        mass by ``lumped[k]`` (an uncertainty budget's perturbations).

        Parameters
        ----------
        distributed : float
            [1] factor on the mass per length, per area or the density.
        lumped : sequence of float, optional
            [1] one factor per lumped mass (default: unchanged).

        Returns
        -------
        Structure
        """
        import dataclasses

        factors = [1.0] * len(self.masses) if lumped is None else list(lumped)
        masses = tuple(dataclasses.replace(m, mass=m.mass * f)
                       for m, f in zip(self.masses, factors, strict=True))
        field = self.mass_field
        changed: Structure = dataclasses.replace(  # type: ignore[type-var]
            self, masses=masses, **{field: getattr(self, field) * distributed})
        return changed

    @abstractmethod
    def contains(self, x: float, y: float = 0.0, z: float = 0.0, tol: float = 1e-9) -> bool:
        """Whether the point (x, y, z) [m] lies on the structure (within ``tol`` [m])."""

    @abstractmethod
    def outside(self, x: float, y: float = 0.0, z: float = 0.0) -> str:
        """Why a point off the structure is off it, e.g. ``x = 0.7 lies off the structure
        (0 <= x <= 0.6)``."""

    @abstractmethod
    def extent(self) -> tuple[Any, ...]:
        """The box mapped onto the shape basis' domain: (x0, x1) on a beam, ((x0, x1), (y0,
        y1)[, (z0, z1)]) otherwise [m]."""

    @abstractmethod
    def mass_quadrature(self) -> tuple[np.ndarray, np.ndarray]:
        """Points and masses that integrate rho * (any field) over the structure, the lumped
        masses included.

        Returns
        -------
        points : ndarray
            Structure coordinates of the quadrature nodes, then of the lumped masses.
        masses : (n_q,) ndarray
            [kg] the mass each point stands for.
        """

    @abstractmethod
    def up(self, coordinates: np.ndarray) -> np.ndarray:
        """(n,) [1]: what a unit translation against gravity (along +w; on a body +z) moves at
        each of these structure coordinates (what the structure's weight loads)."""

    @abstractmethod
    def grid(self, n: int = 401) -> np.ndarray:
        """About ``n`` structure coordinates covering the structure (for the peaks of shapes)."""

    # -------------------------------------------------------------- coordinates

    def rig_points(self, items: Sequence[Located]) -> np.ndarray:
        """Rows the rig keeps for gauges, forces or sensors: (n, 2) (x, y) [m]."""
        return np.array([[p.x, p.y] for p in items], dtype=float).reshape(-1, 2)

    @abstractmethod
    def coordinates(self, points: np.ndarray, source: str = "<points>") -> np.ndarray:
        """Rig points (or scan points) in the structure's own coordinates.

        Parameters
        ----------
        points : ndarray
            Rows as :meth:`rig_points` gives them, or already in structure coordinates.
        source : str
            Named in the error when the points do not fit the structure.

        Raises
        ------
        InputError
            When the points have too few columns for the structure.
        """

    # -------------------------------------------------------------- rigid motions

    def frame(self, gauges: np.ndarray) -> Frame:
        """The frame of the rotations, given the gauges' structure coordinates."""
        return Frame()

    @abstractmethod
    def rigid_modes(self, coordinates: np.ndarray, frame: Frame) -> np.ndarray:
        """The rigid-body modes at structure coordinates, (n_rigid, n_points) [1]."""

    # -------------------------------------------------------------- shapes

    @abstractmethod
    def fit_shape(self, coordinates: np.ndarray, values: np.ndarray, criterion: str,
                  weights: np.ndarray, basis: str,
                  min_order: int = 1) -> ShapeFit | VectorShapeFit:
        """Fit one harmonic's measured shape over the scan points, order chosen by
        ``criterion`` ("gcv" or "bic") from ``min_order`` up, in the ``basis`` family (one of
        :attr:`bases`)."""

    def model_notes(self, fits: Sequence[ShapeFit | VectorShapeFit]) -> tuple[str, ...]:
        """Notes a spatial model built from these fits should carry."""
        return ()

    def scan_mismatch(self, points: np.ndarray) -> str | None:
        """Why scan points, as a scan file gives them, are of another kind of structure (a
        plate's grid on a beam, a beam's line on a plate), or None when they may be of this
        one.

        Parameters
        ----------
        points : (n_points, n_dim) array [m]
            The scan's points (:attr:`forcecal.records.Scan.points`).
        """
        return None

    # -------------------------------------------------------------- reporting

    @abstractmethod
    def combinations(self, force_points: np.ndarray,
                     force_names: Sequence[str]) -> tuple[tuple[str, ...], np.ndarray]:
        """The linear combinations of the forces that are reported: each force, the total
        and the resultant's moments (and, on a body, its components).

        Returns
        -------
        names : tuple of str
        matrix : (n_combinations, n_forces) ndarray [1, m]
        """

    # -------------------------------------------------------------- rig file

    @abstractmethod
    def to_dict(self) -> dict[str, Any]:
        """The ``[structure]`` table of the rig file, without ``masses``."""

    @classmethod
    @abstractmethod
    def from_keys(cls, keys: Any, masses: tuple[LumpedMass, ...],
                  fail: Callable[[str, str], Exception]) -> Structure:
        """This kind from the rig file's ``[structure]`` table, validated against its schema
        (:data:`forcecal.schema.rig_file.STRUCTURE_KEYS`); ``fail(key, what)`` is the error
        for what the schema cannot say."""

    # -------------------------------------------------------------- helpers

    @staticmethod
    def _columns(points: np.ndarray, n: int, what: str, source: str) -> np.ndarray:
        pts = np.asarray(points, dtype=float)
        if pts.ndim == 1:
            pts = pts[:, None]
        if pts.shape[1] < n:
            raise InputError(f"{source}: {what}; found {pts.shape[1]} columns")
        return pts[:, :n]


class OutOfPlane(Structure, ABC):
    """A structure whose motion is one scalar field, the deflection w along +z over its 1 or 2
    coordinates (a beam in plane bending, a plate in out-of-plane bending).

    Its rigid motions are w = 1, x[, y]; its shapes are scalar fields on an orthonormal
    polynomial basis (or the mode-shape family); the reported resultant is the total force and
    its first moments sum(f x)[, sum(f y)].
    """

    def coordinates(self, points: np.ndarray, source: str = "<points>") -> np.ndarray:
        pts = np.asarray(points, dtype=float)
        if self.dim == 1 and pts.ndim == 1:
            return pts
        cols = self._columns(pts, self.dim, f"points need {', '.join(self.axes)}", source)
        return cols[:, 0] if self.dim == 1 else cols

    def rigid_modes(self, coordinates: np.ndarray, frame: Frame) -> np.ndarray:
        pts = np.asarray(coordinates, dtype=float).reshape(len(coordinates), -1)
        return np.vstack([np.ones(len(pts)), *pts[:, :self.dim].T])

    def up(self, coordinates: np.ndarray) -> np.ndarray:
        return np.ones(len(coordinates))

    def fit_shape(self, coordinates: np.ndarray, values: np.ndarray, criterion: str,
                  weights: np.ndarray, basis: str, min_order: int = 1) -> ShapeFit:
        return fit_shape(coordinates, values, self.extent(), criterion=criterion,
                         weights=weights, family="modes" if basis == "modes" else "legendre",
                         min_order=min_order)

    def combinations(self, force_points: np.ndarray,
                     force_names: Sequence[str]) -> tuple[tuple[str, ...], np.ndarray]:
        n_f = len(force_names)
        names = [*force_names, "total", *(f"moment_{a}" for a in self.axes)]
        rows = [*np.eye(n_f), np.ones(n_f), *np.asarray(force_points)[:, :self.dim].T]
        return tuple(names), np.array(rows)

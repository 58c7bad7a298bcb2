"""A beam in plane bending along x in [0, length], on two statically determinate gauges."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from .base import LumpedMass, OutOfPlane, ranges_text

__all__ = ["Beam"]

_N_QUAD = 64
"""Gauss-Legendre points along the beam (exact for polynomial shapes up to degree 126)."""
SCAN_WIDTH = 0.25
"""How far a beam's scan points may spread across it (in y), as a fraction of its length (a
beam is long beside its width); a wider spread is another structure's scan."""


@dataclass(frozen=True)
class Beam(OutOfPlane):
    """A beam of ``length`` [m] and ``mass_per_length`` [kg/m] along x in [0, length].

    Its structure coordinates are x (n,) [m]; its rigid motions w = 1, x.
    """

    length: float
    mass_per_length: float
    masses: tuple[LumpedMass, ...] = ()

    kind: ClassVar[str] = "beam"
    mass_field: ClassVar[str] = "mass_per_length"
    axes: ClassVar[tuple[str, ...]] = ("x",)
    n_rigid: ClassVar[int] = 2

    @property
    def distributed_mass(self) -> float:
        return self.mass_per_length * self.length

    def contains(self, x: float, y: float = 0.0, z: float = 0.0, tol: float = 1e-9) -> bool:
        return -tol <= x <= self.length + tol

    def outside(self, x: float, y: float = 0.0, z: float = 0.0) -> str:
        return f"x = {x} lies off the structure (0 <= x <= {self.length})"

    def extent(self) -> tuple[float, float]:
        return (0.0, self.length)

    def scan_mismatch(self, points: np.ndarray) -> str | None:
        """Points spread across the beam (in y) by more than ``SCAN_WIDTH`` of its length:
        the grid of a plate, or of another structure, not a beam's line."""
        pts = np.asarray(points, dtype=float).reshape(len(points), -1)
        if pts.shape[1] < 2 or np.ptp(pts[:, 1]) <= SCAN_WIDTH * self.length:
            return None
        lo, hi = pts[:, :2].min(axis=0), pts[:, :2].max(axis=0)
        return (f"its {len(pts)} points are 2-D, spread over a plane "
                f"({ranges_text(lo, hi, ('x', 'y'))}), where a beam's points lie along x (their y "
                f"within {SCAN_WIDTH * self.length:.4g} m, {SCAN_WIDTH:.0%} of its "
                f"{self.length:.4g} m length): a scan of another structure")

    def mass_quadrature(self) -> tuple[np.ndarray, np.ndarray]:
        xi, wi = np.polynomial.legendre.leggauss(_N_QUAD)
        x = 0.5 * self.length * (xi + 1.0)
        w = 0.5 * self.length * wi * self.mass_per_length
        return (np.concatenate([x, [m.x for m in self.masses]]),
                np.concatenate([w, [m.mass for m in self.masses]]))

    def grid(self, n: int = 401) -> np.ndarray:
        return np.linspace(0.0, self.length, n)

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "length": self.length,
                "mass_per_length": self.mass_per_length}

    @classmethod
    def from_keys(cls, keys: Any, masses: tuple[LumpedMass, ...],
                  fail: Callable[[str, str], Exception]) -> Beam:
        return cls(length=keys.length, mass_per_length=keys.mass_per_length, masses=masses)

"""A plate in out-of-plane bending over a polygonal outline, on three statically determinate
gauges; its mass quadrature (ear clipping, collapsed Gauss rules on the triangles)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from .base import LumpedMass, OutOfPlane, ranges_text

__all__ = ["Plate"]

_N_TRI = 12
"""Gauss points per direction on each triangle (exact for degree <= 22)."""
SCAN_WIDTH = 0.05
"""A plate's scan points spread across their own main line by at least this fraction of the
plate's smaller side; less is a line scan (a beam's), from which no (x, y) shape follows."""


@dataclass(frozen=True)
class Plate(OutOfPlane):
    """A plate of ``mass_per_area`` [kg/m^2] inside ``outline`` (n_vertices, 2) [m].

    Its structure coordinates are (x, y) (n, 2) [m]; its rigid motions w = 1, x, y.
    """

    outline: tuple[tuple[float, float], ...]
    mass_per_area: float
    masses: tuple[LumpedMass, ...] = ()

    kind: ClassVar[str] = "plate"
    mass_field: ClassVar[str] = "mass_per_area"
    axes: ClassVar[tuple[str, ...]] = ("x", "y")
    n_rigid: ClassVar[int] = 3

    @property
    def area(self) -> float:
        """[m^2] (shoelace formula)."""
        v = np.asarray(self.outline)
        x, y = v[:, 0], v[:, 1]
        return float(0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))

    @property
    def distributed_mass(self) -> float:
        return self.mass_per_area * self.area

    def contains(self, x: float, y: float = 0.0, z: float = 0.0, tol: float = 1e-9) -> bool:
        return bool(inside_polygon(np.asarray(self.outline), np.array([[x, y]]), tol)[0])

    def outside(self, x: float, y: float = 0.0, z: float = 0.0) -> str:
        return f"(x, y) = ({x}, {y}) lies outside the outline"

    def extent(self) -> tuple[tuple[float, float], tuple[float, float]]:
        v = np.asarray(self.outline)
        return ((float(v[:, 0].min()), float(v[:, 0].max())),
                (float(v[:, 1].min()), float(v[:, 1].max())))

    def scan_mismatch(self, points: np.ndarray) -> str | None:
        """Points that give x only, or lie along one line (across it less than
        ``SCAN_WIDTH`` of the plate's smaller side): a beam's scan, not a plate's."""
        pts = np.asarray(points, dtype=float).reshape(len(points), -1)
        need = "where a plate needs points (x, y) spread over its outline"
        span = ranges_text(pts.min(axis=0), pts.max(axis=0), self.axes[:pts.shape[1]])
        if pts.shape[1] < 2:
            return f"its {len(pts)} points give x only ({span}): a line, 1-D, {need}"
        xy = pts[:, :2] - pts[:, :2].mean(axis=0)
        across = float(np.ptp(xy @ np.linalg.svd(xy, full_matrices=False)[2][-1]))
        (x0, x1), (y0, y1) = self.extent()
        if across >= SCAN_WIDTH * min(x1 - x0, y1 - y0):
            return None
        return (f"its {len(pts)} points lie along a line ({span}; {across:.3g} m across it), "
                f"{need}")

    def mass_quadrature(self) -> tuple[np.ndarray, np.ndarray]:
        qp, qw = polygon_quadrature(np.asarray(self.outline, dtype=float), _N_TRI)
        pts = np.vstack([qp, np.array([[m.x, m.y] for m in self.masses]).reshape(-1, 2)])
        return pts, np.concatenate([qw * self.mass_per_area, [m.mass for m in self.masses]])

    def grid(self, n: int = 401) -> np.ndarray:
        (x0, x1), (y0, y1) = self.extent()
        side = int(np.sqrt(n)) + 1
        xx, yy = np.meshgrid(np.linspace(x0, x1, side), np.linspace(y0, y1, side))
        pts = np.column_stack([xx.ravel(), yy.ravel()])
        return pts[inside_polygon(np.asarray(self.outline), pts)]

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "mass_per_area": self.mass_per_area,
                "outline": [list(v) for v in self.outline]}

    @classmethod
    def from_keys(cls, keys: Any, masses: tuple[LumpedMass, ...],
                  fail: Callable[[str, str], Exception]) -> Plate:
        return cls(outline=tuple((float(x), float(y)) for x, y in keys.outline),
                   mass_per_area=keys.mass_per_area, masses=masses)


def inside_polygon(polygon: np.ndarray, points: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """Which points lie inside a simple polygon or within ``tol`` of its edges.

    Parameters
    ----------
    polygon : (n_vertices, 2) ndarray
        [m] the vertices, either orientation.
    points : (n_points, 2) ndarray
        [m]
    tol : float
        [m] distance to an edge within which a point counts as inside.

    Returns
    -------
    (n_points,) bool ndarray
    """
    v = np.asarray(polygon, dtype=float)
    p = np.atleast_2d(np.asarray(points, dtype=float))
    a, b = v, np.roll(v, -1, axis=0)                                 # edges a -> b
    px, py = p[:, 0:1], p[:, 1:2]
    # even-odd rule: edges that straddle the point's height, crossed to its right
    straddle = (a[:, 1] > py) != (b[:, 1] > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = a[:, 0] + (py - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    inside = np.count_nonzero(straddle & (px < x_cross), axis=1) % 2 == 1
    # distance to every edge, so that points on the outline count
    d = b - a
    length2 = np.maximum(np.sum(d**2, axis=1), 1e-300)
    u = np.clip(((px - a[:, 0]) * d[:, 0] + (py - a[:, 1]) * d[:, 1]) / length2, 0.0, 1.0)
    dist = np.hypot(px - (a[:, 0] + u * d[:, 0]), py - (a[:, 1] + u * d[:, 1]))
    result: np.ndarray = inside | np.any(dist <= tol, axis=1)
    return result


def triangulate(polygon: np.ndarray) -> np.ndarray:
    """Ear-clipping triangulation of a simple polygon.

    Parameters
    ----------
    polygon : (n_vertices, 2) ndarray
        [m] the vertices, either orientation.

    Returns
    -------
    (n_vertices - 2, 3, 2) ndarray
        [m] the triangles.
    """
    v = [(float(p[0]), float(p[1])) for p in np.asarray(polygon, dtype=float)]
    x, y = np.array(v).T
    if 0.5 * (np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))) < 0:
        v = v[::-1]                                            # counter-clockwise
    triangles = []
    while len(v) > 3:
        for i in range(len(v)):
            a, b, c = v[i - 1], v[i], v[(i + 1) % len(v)]
            if _cross(a, b, c) <= 0:
                continue                                        # reflex corner
            if any(_in_triangle(p, a, b, c) for p in v if p not in (a, b, c)):
                continue
            triangles.append((a, b, c))
            del v[i]
            break
        else:
            raise ValueError("the outline is not a simple polygon")
    triangles.append((v[0], v[1], v[2]))
    return np.array(triangles)


Point2 = tuple[float, float]


def _cross(o: Point2, a: Point2, b: Point2) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def _in_triangle(p: Point2, a: Point2, b: Point2, c: Point2) -> bool:
    return _cross(a, b, p) >= 0 and _cross(b, c, p) >= 0 and _cross(c, a, p) >= 0


def polygon_quadrature(polygon: np.ndarray, n: int = _N_TRI) -> tuple[np.ndarray, np.ndarray]:
    """Points and weights integrating over a polygon (exact for degree <= 2 n - 2).

    Each triangle of :func:`triangulate` is mapped from the unit square by the collapsed
    (Duffy) map, with an n x n Gauss-Legendre rule.

    Parameters
    ----------
    polygon : (n_vertices, 2) ndarray
        [m] the vertices.
    n : int
        Gauss points per direction on each triangle.

    Returns
    -------
    points : (n_q, 2) ndarray
        [m]
    weights : (n_q,) ndarray
        [m^2]
    """
    g, w = np.polynomial.legendre.leggauss(n)
    g = 0.5 * (g + 1.0)
    w = 0.5 * w
    uu, vv = np.meshgrid(g, g, indexing="ij")
    ww = np.outer(w, w)
    # unit triangle (0,0), (1,0), (0,1): s = u, t = v (1 - u), Jacobian (1 - u)
    s = uu.ravel()
    t = (vv * (1 - uu)).ravel()
    jw = (ww * (1 - uu)).ravel()
    pts, wts = [], []
    for a, b, c in triangulate(polygon):
        e1, e2 = b - a, c - a
        area2 = abs(e1[0] * e2[1] - e1[1] * e2[0])
        pts.append(a + np.outer(s, e1) + np.outer(t, e2))
        wts.append(jw * area2)
    return np.vstack(pts), np.concatenate(wts)

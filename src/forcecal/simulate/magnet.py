"""U-core electromagnet: magnetic circuit, pole forces and coil drive.

Magnetic circuit: reluctance ``(sum of the pole gaps + l_fe / mu_r) / (mu0 A)``, one flux
``Phi = N i / reluctance`` through every pole, force on the structure at each pole
``Phi^2 / (2 mu0 A)`` toward the magnet (+w). With two equal gaps s this is
``mu0 N^2 A i^2 / (4 (s + l_fe / (2 mu_r))^2)``.

Coil drive: an ideal current source, or a voltage source through the coil resistance with the
flux linkage ``lambda = N Phi`` as state: ``v = R i + d(lambda)/dt``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["MU0", "Drive", "Magnet", "Pole"]

MU0 = 4e-7 * math.pi
"""Permeability of free space [H/m] (the classical value, as in every textbook formula)."""


@dataclass(frozen=True)
class Pole:
    """One pole face: the force point's name, position x [m], static gap at w = 0 [m] and,
    on a plate, the second coordinate y [m] (ignored by a beam); on a body also z [m] and the
    unit ``direction`` of the pull (motion along it closes the gap)."""

    name: str
    x: float
    gap: float
    y: float = 0.0
    z: float = 0.0
    direction: tuple[float, float, float] = (0.0, 0.0, 1.0)


@dataclass(frozen=True)
class Drive:
    """Periodic coil drive: ``dc + ac * sin(2 pi f t + phase)`` in V or A.

    ``harmonics`` adds ``(n, amplitude, phase)`` terms for distorted drives.
    """

    kind: str  # "current" or "voltage"
    dc: float
    ac: float
    frequency: float
    phase: float = 0.0
    harmonics: tuple[tuple[int, float, float], ...] = ()

    def value(self, t: np.ndarray | float) -> np.ndarray | float:
        w = 2 * math.pi * self.frequency
        out = self.dc + self.ac * np.sin(w * np.asarray(t) + self.phase)
        for n, amp, ph in self.harmonics:
            out = out + amp * np.sin(n * w * np.asarray(t) + ph)
        return out


@dataclass(frozen=True)
class Magnet:
    """A U-core electromagnet with its coil.

    Attributes
    ----------
    poles : the pole faces (one or two)
    turns : N; pole_area : A [m^2]; iron_length : l_fe [m]; mu_r : relative permeability
    resistance : coil resistance [ohm] (used by a voltage drive)
    current_channel, flux_channel, voltage_channel : names of the recorded channels
    """

    poles: tuple[Pole, ...]
    turns: float = 400.0
    pole_area: float = 4.0e-4
    iron_length: float = 0.2
    mu_r: float = 2000.0
    resistance: float = 2.0
    current_channel: str = "i"
    flux_channel: str = "phi"
    voltage_channel: str = "v"

    @property
    def iron_gap(self) -> float:
        """l_fe / mu_r [m]: the iron path as an equivalent air length."""
        return self.iron_length / self.mu_r

    @property
    def gap_offset(self) -> float:
        """l_fe / (2 mu_r) [m]: the offset s_fe of f = K i^2 / (s + s_fe)^2 per pole."""
        return self.iron_gap / len(self.poles)

    @property
    def ideal_k(self) -> float:
        """mu0 N^2 A / 4 [N m^2 / A^2]."""
        return MU0 * self.turns**2 * self.pole_area / 4.0

    def reluctance(self, gaps: np.ndarray) -> np.ndarray:
        """Circuit reluctance [1/H] for pole gaps ``(n_poles, ...)`` [m]."""
        return (np.sum(gaps, axis=0) + self.iron_gap) / (MU0 * self.pole_area)

    def flux_from_current(self, current, gaps):
        """Flux through each pole [Wb]."""
        return self.turns * np.asarray(current) / self.reluctance(gaps)

    def pole_force(self, flux):
        """Force per pole [N] for the flux [Wb]; acts on the structure toward the magnet."""
        return np.asarray(flux) ** 2 / (2 * MU0 * self.pole_area)

    def static_force(self, current: float, gap: float) -> float:
        """Per-pole force [N] with every pole at the same gap [m] (closed form)."""
        n_p = len(self.poles)
        return (MU0 * self.turns**2 * self.pole_area * current**2
                / (2 * (n_p * gap + self.iron_gap) ** 2))

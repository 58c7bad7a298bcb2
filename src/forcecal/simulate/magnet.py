"""U-core electromagnet: magnetic circuit, pole forces and coil drive.

Magnetic circuit: reluctance ``(sum of the pole gaps + l_fe / mu_r) / (mu0 A)``, one flux
``Phi = N i / reluctance`` through every pole, force on the structure at each pole
``Phi^2 / (2 mu0 A)`` toward the magnet (+w). The iron may saturate (``saturation`` B_s): its
B-H curve ``H = B / (mu0 mu_r) (1 + (|B| / B_s)^KNEE)`` swells its share of the reluctance
(:func:`saturated_linkage`).

Coil drive: an ideal current source, or a voltage source through the coil resistance with the
flux linkage ``lambda = N Phi`` as state: ``v = R i + d(lambda)/dt``; a steady sine on a DC
bias, or a broadband :mod:`.waveforms` waveform on it.

Eddy currents (current drive only): in a ``lag`` core (``eddy_time`` tau), the default, the
magnetising current ``i_m`` follows the coil current, ``tau di_m/dt + i_m = i``, and the flux
and force take ``i_m`` in place of ``i`` (``H(f) = 1 / (1 + j 2 pi f tau)``). A ``solid`` or
``laminated`` core takes it from the flux diffusing into its iron (``conductivity``,
``core_thickness``; :mod:`.core`): half order above the diffusion time's frequency, near first
order for thin laminations.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from .core import CORE_NODES, CORES, diffusion_response
from .waveforms import Waveform

__all__: list[str] = []

MU0 = 4e-7 * math.pi
"""Permeability of free space [H/m] (the classical value, as in every textbook formula)."""
KNEE = 6.0
"""The order of the iron's B-H curve's knee: mu(B) = mu0 mu_r / (1 + (|B| / B_s)^KNEE)."""


def saturated_linkage(drive: ArrayLike, gap_sum: ArrayLike, iron: ArrayLike,
                      sat: ArrayLike) -> np.ndarray:
    """The flux linkage lambda of a magnetic circuit under saturation, by Newton's method.

    Solves ``lambda (G + iron (1 + (|lambda| sat)^KNEE)) = drive``, which is increasing and
    convex in ``|lambda|``: Newton from the unsaturated solution (never below the root) falls
    onto it monotonically.

    Parameters
    ----------
    drive : array
        ``N^2 mu0 A i`` [Wb m] (the linkage times the gaps without saturation).
    gap_sum, iron : arrays [m]
        G, the summed air gaps, and ``l_fe / mu_r``, the iron path's unsaturated equivalent gap.
    sat : array [1/Wb]
        ``1 / (N A B_s)`` (0: no saturation).

    Returns
    -------
    array [Wb]
        lambda, broadcast over the inputs.
    """
    c, g, fe, s = np.broadcast_arrays(*(np.asarray(x, dtype=float)
                                        for x in (drive, gap_sum, iron, sat)))
    lam = c / (g + fe)
    for _ in range(100):
        x = np.abs(lam) * s
        step = (lam * (g + fe * (1 + x**KNEE)) - c) / (g + fe * (1 + (KNEE + 1) * x**KNEE))
        lam = lam - step
        if np.all(np.abs(step) <= 1e-15 * np.abs(lam) + 1e-300):
            break
    return np.asarray(lam)


@dataclass(frozen=True)
class Pole:
    """One pole face of a magnet: a force point of the rig.

    Attributes
    ----------
    name : str
        The force point's name.
    x : float [m]
        Position along the structure.
    gap : float [m]
        Static air gap at zero deflection.
    y : float [m]
        On a plate or a body, the second coordinate (ignored by a beam).
    z : float [m]
        On a body, the third coordinate.
    direction : (dx, dy, dz)
        On a body, the unit direction of the pull (motion along it closes the gap).
    """

    name: str
    x: float
    gap: float
    y: float = 0.0
    z: float = 0.0
    direction: tuple[float, float, float] = (0.0, 0.0, 1.0)


@dataclass(frozen=True)
class Drive:
    """Coil drive: ``dc + ac * sin(2 pi f t + phase)`` in V or A, or ``dc + waveform(t)``.

    Attributes
    ----------
    source : {"current", "voltage"}
        What the source imposes on the coil.
    dc : float [A] or [V]
        The bias.
    ac : float [A] or [V]
        Amplitude of the fundamental.
    frequency : float [Hz]
        The fundamental frequency f.
    phase : float [rad]
        Phase of the fundamental.
    harmonics : tuple of (n, amplitude, phase)
        Extra terms ``amplitude * sin(2 pi n f t + phase)`` for distorted drives.
    drift : float [1/s]
        A slow linear drift of the drive's level: the whole drive (``dc``, ``ac`` and the
        harmonics) is scaled by ``1 + drift * t``.
    chirp : float [1/s]
        A slow linear drift of the frequency: the instantaneous frequency is
        ``f (1 + chirp * t)``, so every ``2 pi f t`` above reads ``2 pi f (t + chirp t^2 / 2)``.
    waveform : Waveform or None
        A broadband drive (:mod:`.waveforms`) in place of the ``ac`` sine (which must then be
        0): the drive reads ``dc + waveform(tau) + harmonics``, ``tau = t + chirp t^2 / 2``,
        all scaled by ``1 + drift * t``; ``frequency`` is then a nominal frequency (that of the
        harmonics). None (the default): the steady sine.
    """

    source: str  # "current" or "voltage"
    dc: float
    ac: float
    frequency: float
    phase: float = 0.0
    harmonics: tuple[tuple[int, float, float], ...] = ()
    drift: float = 0.0
    chirp: float = 0.0
    waveform: Waveform | None = None

    def __post_init__(self) -> None:
        if self.source not in ("current", "voltage"):
            raise ValueError(f"a drive imposes 'current' or 'voltage', not {self.source!r}")
        if self.waveform is not None and self.ac:
            raise ValueError("a drive with a waveform has ac = 0 (the waveform replaces the "
                             "sine)")

    @property
    def voltage_driven(self) -> bool:
        """Whether the coil's voltage is imposed (its current then follows the circuit)."""
        return self.source == "voltage"

    def value(self, t: np.ndarray | float) -> np.ndarray | float:
        """The drive at given times.

        Parameters
        ----------
        t : float or array [s]
            The times.

        Returns
        -------
        float or array [A] or [V]
            Shaped like ``t``.
        """
        w = 2 * math.pi * self.frequency
        if self.waveform is not None:
            tt = np.asarray(t, dtype=float)
            tau = tt + 0.5 * self.chirp * tt**2 if self.chirp else tt
            out = self.dc + self.waveform.value(tau)
            for n, amp, ph in self.harmonics:
                out = out + amp * np.sin(n * w * tau + ph)
            return out * (1.0 + self.drift * tt) if self.drift else out
        if self.drift or self.chirp:
            tt = np.asarray(t, dtype=float)
            arg = w * (tt + 0.5 * self.chirp * tt**2)
            out = self.dc + self.ac * np.sin(arg + self.phase)
            for n, amp, ph in self.harmonics:
                out = out + amp * np.sin(n * arg + ph)
            return out * (1.0 + self.drift * tt)
        out = self.dc + self.ac * np.sin(w * np.asarray(t) + self.phase)
        for n, amp, ph in self.harmonics:
            out = out + amp * np.sin(n * w * np.asarray(t) + ph)
        return out

    def scaled(self, level: float, frequency: float | None = None) -> Drive:
        """The same drive with its whole level (``dc``, ``ac``, harmonics, waveform) times
        ``level``, at ``frequency`` [Hz] (default: its own; a waveform keeps its own).

        Parameters
        ----------
        level : float
            The factor on every amplitude.
        frequency : float, optional
            The new fundamental [Hz].

        Returns
        -------
        Drive
        """
        return Drive(self.source, self.dc * level, self.ac * level,
                     self.frequency if frequency is None else frequency, self.phase,
                     tuple((n, amp * level, ph) for n, amp, ph in self.harmonics),
                     self.drift, self.chirp,
                     None if self.waveform is None else self.waveform.scaled(level))


@dataclass(frozen=True)
class Magnet:
    """A U-core electromagnet with its coil.

    Attributes
    ----------
    poles : tuple of Pole
        The pole faces (one or two).
    turns : float
        N, the coil's turns.
    pole_area : float [m^2]
        A, the area of each pole face.
    iron_length : float [m]
        l_fe, the length of the iron path.
    mu_r : float
        Relative permeability of the iron.
    resistance : float [ohm]
        Coil resistance (used by a voltage drive).
    current_channel : str
        Name of the recorded coil current channel.
    flux_channel : str
        Name of the recorded flux channel.
    voltage_channel : str
        Name of the recorded coil voltage channel.
    eddy_time : float [s]
        tau of the eddy currents in a ``lag`` core: the magnetising current follows the coil
        current through ``tau di_m/dt + i_m = i`` (current drive only); 0: no lag.
    core : {"lag", "solid", "laminated"}
        The core's eddy currents: a first-order lag (``eddy_time``), or the flux diffusing
        into a solid core or into laminations of ``core_thickness`` (:mod:`.core`).
    conductivity : float [S/m]
        sigma of a solid or laminated core's iron.
    core_thickness : float [m]
        ``2 d``: a solid core's thickness, or one lamination's; the field enters from both
        faces.
    core_nodes : int
        Finite elements across a solid or laminated core's half-thickness.
    saturation : float [T]
        B_s of the iron's B-H curve (:data:`KNEE`); 0: the iron never saturates.
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
    eddy_time: float = 0.0
    core: str = "lag"
    conductivity: float = 0.0
    core_thickness: float = 0.0
    core_nodes: int = CORE_NODES
    saturation: float = 0.0

    def __post_init__(self) -> None:
        if not self.saturation >= 0.0 or (self.saturation and self.core != "lag"):
            raise ValueError(f"a magnet's saturation must be >= 0 T, and 0 for a {self.core} "
                             f"core (its diffusion is linear), not {self.saturation!r}")
        if not self.eddy_time >= 0.0:
            raise ValueError(f"a magnet's eddy_time must be >= 0 s, not {self.eddy_time!r}")
        if self.core not in CORES:
            raise ValueError(f"a magnet's core is one of {', '.join(CORES)}, not {self.core!r}")
        if self.core != "lag" and not (self.conductivity > 0 and self.core_thickness > 0
                                       and self.eddy_time == 0 and self.core_nodes >= 2):
            raise ValueError(
                f"a {self.core} core needs a conductivity > 0 S/m, a core_thickness > 0 m and "
                f"core_nodes >= 2, and no eddy_time; found {self.conductivity!r} S/m, "
                f"{self.core_thickness!r} m, {self.core_nodes!r} nodes, eddy_time "
                f"{self.eddy_time!r} s")

    @property
    def diffusion_time(self) -> float:
        """tau_d = sigma mu_r mu0 d^2 [s] of a solid or laminated core (``d`` its
        half-thickness); 0 for a lag core."""
        if self.core == "lag":
            return 0.0
        return self.conductivity * self.mu_r * MU0 * (self.core_thickness / 2.0) ** 2

    @property
    def eddy_currents(self) -> bool:
        """Whether the core's magnetising current differs from the coil current."""
        return self.eddy_time > 0 or self.core != "lag"

    def eddy_response(self, frequency: ArrayLike) -> np.ndarray:
        """H(f): the force's small-signal component at frequency f [Hz] over that of ``i^2``
        at a fixed gap, ``1 / (1 + j 2 pi f tau)`` for a lag core (1 without eddy currents),
        the discretised diffusion's own response for a solid or laminated core
        (:func:`.core.diffusion_response`).

        Parameters
        ----------
        frequency : float or array [Hz]

        Returns
        -------
        complex array
            ``|H| = K(f) / K``, ``-angle(H)`` the force's lag [rad].
        """
        if self.core != "lag":
            return diffusion_response(frequency, self.diffusion_time, self.core_nodes)
        return 1.0 / (1.0 + 2j * math.pi * np.asarray(frequency, dtype=float) * self.eddy_time)

    @property
    def iron_gap(self) -> float:
        """l_fe / mu_r [m]: the iron path as an equivalent air length."""
        return self.iron_length / self.mu_r

    @property
    def gap_offset(self) -> float:
        """l_fe / (2 mu_r) [m]: the offset s_fe of f = K i^2 / (s + s_fe)^2 per pole."""
        return self.iron_gap / len(self.poles)

    @property
    def saturation_scale(self) -> float:
        """``1 / (N A B_s)`` [1/Wb]: ``|lambda|`` times it is ``|B| / B_s``; 0 without
        saturation."""
        return 1.0 / (self.turns * self.pole_area * self.saturation) if self.saturation else 0.0

    @property
    def ideal_k(self) -> float:
        """mu0 N^2 A / 4 [N m^2 / A^2]."""
        return MU0 * self.turns**2 * self.pole_area / 4.0

    def reluctance(self, gaps: np.ndarray) -> np.ndarray:
        """Circuit reluctance of the magnet.

        Parameters
        ----------
        gaps : (n_poles, ...) array [m]
            The pole gaps.

        Returns
        -------
        array [1/H]
            (sum of the gaps + l_fe / mu_r) / (mu0 A), shaped like ``gaps[0]``.
        """
        return (np.sum(gaps, axis=0) + self.iron_gap) / (MU0 * self.pole_area)

    def flux_from_current(self, current: ArrayLike, gaps: np.ndarray) -> np.ndarray:
        """Flux through each pole.

        Parameters
        ----------
        current : float or array [A]
            The coil current.
        gaps : (n_poles, ...) array [m]
            The pole gaps, broadcast against ``current`` after the pole axis is summed.

        Returns
        -------
        array [Wb]
            N i / reluctance, the same through every pole (the iron's reluctance at that flux
            where it saturates: :func:`saturated_linkage`).
        """
        drive = self.turns**2 * MU0 * self.pole_area * np.asarray(current)
        lam = saturated_linkage(drive, np.sum(gaps, axis=0), self.iron_gap,
                                self.saturation_scale)
        return lam / self.turns

    def pole_force(self, flux: ArrayLike) -> np.ndarray:
        """Force per pole, acting on the structure toward the magnet.

        Parameters
        ----------
        flux : float or array [Wb]
            The flux through the pole.

        Returns
        -------
        array [N]
            Phi^2 / (2 mu0 A).
        """
        return np.asarray(flux) ** 2 / (2 * MU0 * self.pole_area)

    def static_force(self, current: float, gap: float) -> float:
        """Per-pole force with every pole at the same gap (the saturated iron solved for).

        Parameters
        ----------
        current : float
            The coil current [A].
        gap : float
            The gap at every pole [m].

        Returns
        -------
        float
            The force per pole [N].
        """
        flux = self.flux_from_current(current, np.full(len(self.poles), gap))
        return float(self.pole_force(flux))

"""Built-in virtual rigs: the paper's beam, a calibration campaign, a near-resonance drive, a
plate on three gauges, a 3-D block on six gauges with measuring directions, two rigs scanned
under more than one load: two magnets on their own coils, and two magnets on one current whose
pole gaps change unequally; and two rigs under broadband drives (:mod:`.waveforms`), their
magnet's force lagging its current (eddy currents): a swept sine with a stepped-sine campaign
over frequency, and band-limited random; and two stepped-sine campaigns over a decade whose
magnets have real cores, the flux diffusing into the iron (:mod:`.core`): a solid core, whose
force falls off as a half-order system, and a laminated one, near first order.

Every preset is a complete description: structure, gauges, magnets, sensors, noise, the SLDV
scans and the runs. The drive's true frequency deliberately differs from the nominal one written
to the rig file, as a signal generator's does. Its ``realism`` says how its measurements are
made: ideal (white noise only, the default) or ``lab`` (:class:`.realism.Realism`: coloured
noise, quantization, sensitivity errors, a drifting drive, gravity preload and gauge offsets).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

from ..errors import InputError
from .magnet import Drive, Magnet, Pole
from .realism import Realism, resolve_realism
from .waveforms import BandLimitedRandom, PeriodicChirp, SweptSine

__all__ = ["get_preset"]


@dataclass(frozen=True)
class BeamSpec:
    """A rectangular steel beam on two stiff force gauges."""

    length: float = 0.6                         # m
    width: float = 0.04                         # m
    thickness: float = 0.012                    # m, in the bending direction
    youngs_modulus: float = 210e9               # Pa
    density: float = 7850.0                     # kg/m^3
    n_elements: int = 60
    damping_ratio: float = 0.01                 # of the first bending mode (stiffness-prop.)
    masses: tuple[tuple[float, float], ...] = ((0.30, 0.25),)   # (x m, kg): the armature
    gauges: tuple[tuple[str, float], ...] = (("R1", 0.0), ("R2", 0.6))
    gauge_stiffness: float = 2e9                # N/m

    @property
    def ei(self) -> float:
        """Bending stiffness [N m^2]."""
        return self.youngs_modulus * self.width * self.thickness**3 / 12

    @property
    def mass_per_length(self) -> float:
        """[kg/m]"""
        return self.density * self.width * self.thickness


@dataclass(frozen=True)
class PlateSpec:
    """A rectangular steel plate [0, a] x [0, b] on three stiff force gauges.

    ``masses`` are (x m, y m, kg), ``gauges`` (name, x m, y m); the plate is meshed by
    ``mesh = (nx, ny)`` Bogner-Fox-Schmit elements.
    """

    a: float = 0.5                              # m, along x
    b: float = 0.4                              # m, along y
    thickness: float = 0.008                    # m
    youngs_modulus: float = 210e9               # Pa
    poisson: float = 0.3
    density: float = 7850.0                     # kg/m^3
    mesh: tuple[int, int] = (10, 8)
    damping_ratio: float = 0.01                 # of the first bending mode (stiffness-prop.)
    masses: tuple[tuple[float, float, float], ...] = ((0.25, 0.20, 0.3),)  # the armature
    gauges: tuple[tuple[str, float, float], ...] = (
        ("R1", 0.05, 0.05), ("R2", 0.45, 0.05), ("R3", 0.25, 0.35))
    gauge_stiffness: float = 2e9                # N/m

    @property
    def flexural_rigidity(self) -> float:
        """D = E h^3 / (12 (1 - nu^2)) [N m]."""
        return self.youngs_modulus * self.thickness**3 / (12 * (1 - self.poisson**2))

    @property
    def mass_per_area(self) -> float:
        """[kg/m^2]"""
        return self.density * self.thickness

    @property
    def outline(self) -> tuple[tuple[float, float], ...]:
        """The rectangle's vertices [m], counter-clockwise from the origin."""
        return ((0.0, 0.0), (self.a, 0.0), (self.a, self.b), (0.0, self.b))


@dataclass(frozen=True)
class BodySpec:
    """A rectangular aluminium block [0, a] x [0, b] x [0, c] (a housing) on six stiff force
    gauges, each measuring along its own direction.

    ``masses`` are (x, y, z m, kg), ``gauges`` (name, x, y, z m, dx, dy, dz); the default is a
    3-2-1 mount: three gauges along z under the block, two along x on one end, one along y on a
    side. The block is meshed by ``mesh = (nx, ny, nz)`` hexahedra.
    """

    a: float = 0.5                              # m, along x
    b: float = 0.3                              # m, along y
    c: float = 0.04                             # m, along z
    youngs_modulus: float = 70e9                # Pa
    poisson: float = 0.33
    density: float = 2700.0                     # kg/m^3
    mesh: tuple[int, int, int] = (12, 8, 2)
    damping_ratio: float = 0.01                 # of the first bending mode (stiffness-prop.)
    masses: tuple[tuple[float, float, float, float], ...] = ((0.27, 0.15, 0.04, 0.3),)
    gauges: tuple[tuple[str, float, float, float, float, float, float], ...] = (
        ("Z1", 0.0, 0.15, 0.0, 0, 0, 1), ("Z2", 0.5, 0.02, 0.0, 0, 0, 1),
        ("Z3", 0.5, 0.28, 0.0, 0, 0, 1), ("X1", 0.0, 0.02, 0.02, 1, 0, 0),
        ("X2", 0.0, 0.28, 0.02, 1, 0, 0), ("Y1", 0.25, 0.0, 0.02, 0, 1, 0))
    gauge_stiffness: float = 2e9                # N/m

    @property
    def size(self) -> tuple[float, float, float]:
        """(a, b, c) side lengths [m]."""
        return (self.a, self.b, self.c)

    @property
    def blocks(self) -> tuple:
        """The block as the rig file describes it: ((x0, y0, z0), (x1, y1, z1)) [m]."""
        return (((0.0, 0.0, 0.0), self.size),)


@dataclass(frozen=True)
class NoiseSpec:
    """Standard deviations of the white measurement noise, in SI units."""

    gauge: float = 0.01          # N
    probe: float = 0.2e-6        # m
    current: float = 1e-3        # A
    flux: float = 1e-7           # Wb
    voltage: float = 1e-3        # V
    ldv: float = 50e-6           # m/s


@dataclass(frozen=True)
class RunSpec:
    """One recorded run: the drive of every magnet, the static gap, the record length.

    ``gap`` overrides every pole's static gap, then ``gaps`` (pole name -> m) single poles'.
    """

    name: str
    drives: tuple[Drive, ...]
    gap: float | None = None                   # m, overrides every pole's static gap
    duration: float = 1.0                      # s
    tare: bool = False
    labels: dict[str, str] = field(default_factory=dict)
    gaps: dict[str, float] = field(default_factory=dict)   # pole name -> m, after ``gap``
    manifest: bool = True                      # listed in manifest.csv


@dataclass(frozen=True)
class ScanSpec:
    """A sequential SLDV scan: ``n_points`` evenly along a beam, or on a plate an
    ``grid = (n_x, n_y)`` grid of points over the whole rectangle, edges included. On a body the
    grid covers the top face and ``heights`` rows of points the four side faces, and a 3-D
    SLDV measures every point along x, y and z in one acquisition.

    ``reference`` is the index of the magnet whose coil current is recorded beside every point;
    ``gap`` overrides every pole's static gap, then ``gaps`` (pole name -> m) single poles'.
    Under a broadband drive (a ``waveform``) every point's record is a window of one long
    response starting at its own random offset, within one period of a periodic waveform or
    within one record of another.
    """

    drives: tuple[Drive, ...]
    n_points: int = 61
    record: float = 0.5                        # s per point
    gap: float | None = None
    grid: tuple[int, int] | None = None        # plate and body only
    heights: int = 3                           # body only
    reference: int = 0                         # magnet whose coil current is the reference
    gaps: dict[str, float] = field(default_factory=dict)   # pole name -> m, after ``gap``


BeamSensor = tuple[str, float]
"""A probe on a beam: (name, x [m])."""
PlateSensor = tuple[str, float, float]
"""A probe on a plate: (name, x [m], y [m])."""
BodySensor = tuple[str, float, float, float, float, float, float]
"""A probe on a body: (name, x, y, z [m], dx, dy, dz), measuring along (dx, dy, dz)."""


@dataclass(frozen=True)
class Preset:
    """A complete virtual rig.

    ``beam`` is the structure: a :class:`BeamSpec` (sensors ``(name, x)``), a
    :class:`PlateSpec` (sensors ``(name, x, y)``, poles with their ``y``) or a :class:`BodySpec`
    (sensors ``(name, x, y, z, dx, dy, dz)``, poles with their ``y``, ``z`` and direction); the
    field keeps its historical name, :attr:`structure` is the neutral alias. ``scan`` is the
    first SLDV scan, ``more_scans`` further scans of the same rig under other loads;
    :attr:`scans` lists them all. ``realism`` is None for ideal measurements (white noise
    only) or the :class:`.realism.Realism` of a ``lab`` rig. ``band`` (lo, hi) [Hz] is set
    on a rig driven by broadband drives: its scan's band, written to the rig file with
    ``drive = "any"``.
    """

    name: str
    description: str
    beam: BeamSpec | PlateSpec | BodySpec
    magnets: tuple[Magnet, ...]
    sensors: (tuple[BeamSensor, ...] | tuple[PlateSensor, ...] | tuple[BodySensor, ...])
    scan: ScanSpec
    runs: tuple[RunSpec, ...]
    nominal_frequency: float
    fs: float = 10_000.0
    noise: NoiseSpec = field(default_factory=NoiseSpec)
    more_scans: tuple[ScanSpec, ...] = ()
    realism: Realism | None = None
    band: tuple[float, float] | None = None

    @property
    def scans(self) -> tuple[ScanSpec, ...]:
        """Every scan: ``scan`` first, then ``more_scans``."""
        return (self.scan, *self.more_scans)

    @property
    def structure(self) -> BeamSpec | PlateSpec | BodySpec:
        """The structure's specification (the same object as ``beam``)."""
        return self.beam

    @property
    def is_plate(self) -> bool:
        """True when the structure is a plate."""
        return isinstance(self.beam, PlateSpec)

    @property
    def is_body(self) -> bool:
        """True when the structure is a body (a 3-D block)."""
        return isinstance(self.beam, BodySpec)


_F_TRUE = 20.0 * (1 + 7e-4)          # the generator runs 0.07 % fast
_MAGNET = Magnet(poles=(Pole("F1", 0.25, 1.0e-3), Pole("F2", 0.35, 1.0e-3)))
_SENSORS = (("s1", 0.10), ("s2", 0.50))


def _paper() -> Preset:
    drive = Drive("voltage", dc=2.0, ac=1.0, frequency=_F_TRUE)
    return Preset(
        name="paper",
        description="the paper's layout: beam on gauges at its ends, U-core poles near mid-span, "
                    "two probes, voltage drive with a DC bias at 20 Hz",
        beam=BeamSpec(), magnets=(_MAGNET,), sensors=_SENSORS,
        scan=ScanSpec(drives=(drive,)),
        runs=(RunSpec("paper", drives=(drive,), duration=1.0),),
        nominal_frequency=20.0,
    )


def _resonance() -> Preset:
    f = 36.0 * (1 - 4e-4)
    drive = Drive("voltage", dc=2.0, ac=1.0, frequency=f)
    return Preset(
        name="resonance",
        description="second harmonic of a 36 Hz drive just above the first bending mode "
                    "(70.7 Hz): the harmonics' deflection shapes differ",
        beam=BeamSpec(), magnets=(_MAGNET,), sensors=_SENSORS,
        scan=ScanSpec(drives=(drive,)),
        runs=(RunSpec("resonance", drives=(drive,), duration=1.0),),
        nominal_frequency=36.0,
    )


def _campaign() -> Preset:
    runs = []
    for gap in (0.8e-3, 1.0e-3, 1.2e-3):
        for dc in (0.4, 0.6, 0.8):
            for ac in (0.1, 0.2):
                name = f"g{gap * 1e6:04.0f}_dc{dc * 10:02.0f}_ac{ac * 10:02.0f}"
                runs.append(RunSpec(
                    name, drives=(Drive("current", dc, ac, _F_TRUE),), gap=gap, duration=0.5,
                    labels={"dc": f"{dc}", "ac": f"{ac}", "repeat": "1"}))
    for rep in (2, 3):
        runs.append(RunSpec(
            f"g1000_dc06_ac02_r{rep}", drives=(Drive("current", 0.6, 0.2, _F_TRUE,
                                                     phase=0.7 * rep),),
            gap=1.0e-3, duration=0.5, labels={"dc": "0.6", "ac": "0.2", "repeat": str(rep)}))
    runs.append(RunSpec("tare", drives=(Drive("current", 0.0, 0.0, _F_TRUE),), gap=1.0e-3,
                        duration=0.5, tare=True, labels={"dc": "0", "ac": "0", "repeat": "1"}))
    return Preset(
        name="campaign",
        description="three static gaps x three DC currents x two AC amplitudes (current drive), "
                    "two repeats and a zero-current tare",
        beam=BeamSpec(), magnets=(_MAGNET,), sensors=_SENSORS,
        scan=ScanSpec(drives=(Drive("current", 0.6, 0.2, _F_TRUE),), gap=1.0e-3),
        runs=tuple(runs), nominal_frequency=20.0,
    )


_F_PLATE = 20.0 * (1 + 5e-4)         # the generator runs 0.05 % fast


def _plate() -> Preset:
    drive = Drive("voltage", dc=2.0, ac=1.0, frequency=_F_PLATE)
    magnet = Magnet(poles=(Pole("F1", 0.20, 1.0e-3, y=0.20), Pole("F2", 0.30, 1.0e-3, y=0.20)))
    return Preset(
        name="plate",
        description="steel plate 0.5 m x 0.4 m x 8 mm on three gauges (a triangle), a U-core "
                    "magnet whose two poles pull near the centre (2 forces, 3 gauges), four "
                    "probes, voltage drive with a DC bias at 20 Hz, scan on a 13 x 11 grid",
        beam=PlateSpec(), magnets=(magnet,),
        sensors=(("s1", 0.10, 0.30), ("s2", 0.40, 0.30), ("s3", 0.10, 0.10),
                 ("s4", 0.40, 0.10)),
        scan=ScanSpec(drives=(drive,), n_points=13 * 11, grid=(13, 11)),
        runs=(RunSpec("plate", drives=(drive,), duration=1.0),),
        nominal_frequency=20.0,
    )


_F_BODY = 150.0 * (1 - 4e-4)         # the generator runs 0.04 % slow


def _body() -> Preset:
    drive = Drive("current", dc=2.0, ac=1.0, frequency=_F_BODY)
    magnet = Magnet(poles=(Pole("F1", 0.22, 1.0e-3, y=0.15, z=0.04),
                           Pole("F2", 0.32, 1.0e-3, y=0.15, z=0.04)))
    return Preset(
        name="body",
        description="aluminium block 0.5 m x 0.3 m x 40 mm on six gauges (3-2-1 mount: three "
                    "along z, two along x, one along y), a U-core magnet above its top face "
                    "(2 forces, 6 gauges), four probes, current drive with a DC bias at 150 Hz, "
                    "3-D scan of the top face (13 x 9) and of the four sides at three heights",
        beam=BodySpec(), magnets=(magnet,),
        sensors=(("s1", 0.05, 0.25, 0.04, 0, 0, 1), ("s2", 0.45, 0.25, 0.04, 0, 0, 1),
                 ("s3", 0.05, 0.05, 0.04, 0, 0, 1), ("s4", 0.45, 0.05, 0.04, 0, 0, 1)),
        scan=ScanSpec(drives=(drive,), grid=(13, 9), heights=3, record=0.25),
        runs=(RunSpec("body", drives=(drive,), duration=1.0),),
        nominal_frequency=150.0,
    )


def _coils(a: tuple[float, float], b: tuple[float, float],
           phase_b: float = 0.0) -> tuple[Drive, Drive]:
    """Current drives (dc, ac) [A] of coils A and B at the fundamental, B shifted by phase_b."""
    return (Drive("current", *a, _F_TRUE), Drive("current", *b, _F_TRUE, phase=phase_b))


def _two_coil() -> Preset:
    left = Magnet(poles=(Pole("FA", 0.20, 1.0e-3),), current_channel="ia",
                  flux_channel="phia", voltage_channel="va")
    right = Magnet(poles=(Pole("FB", 0.42, 1.0e-3),), current_channel="ib",
                   flux_channel="phib", voltage_channel="vb")
    return Preset(
        name="two-coil",
        description="the paper's beam pulled by two magnets on their own coils (FA at 0.2 m on "
                    "coil A, FB at 0.42 m on coil B), current drives at 20 Hz; scanned twice, "
                    "coil A dominant (reference coil A) then coil B dominant and shifted in "
                    "phase (reference coil B); runs with coil B changed since the scans",
        beam=BeamSpec(), magnets=(left, right), sensors=_SENSORS,
        scan=ScanSpec(drives=_coils((0.5, 0.25), (0.2, 0.1)), reference=0),
        more_scans=(ScanSpec(drives=_coils((0.2, 0.1), (0.5, 0.25), 0.8), reference=1),),
        runs=(RunSpec("matched", drives=_coils((0.5, 0.25), (0.2, 0.1))),
              RunSpec("b_changed", drives=_coils((0.5, 0.25), (0.6, 0.3), 1.5)),
              RunSpec("b_only_weak_a", drives=_coils((0.15, 0.075), (0.6, 0.3), 0.5)),
              RunSpec("equal", drives=_coils((0.4, 0.2), (0.4, 0.2)))),
        nominal_frequency=20.0,
    )


def _one_pole(pole: Pole, k: int) -> Magnet:
    """Coil ``k`` of the tilt rig: a one-pole magnet on its own core, pulling
    ``mu0 N^2 A i^2 / (2 (s + l_fe / mu_r)^2)``. Its iron path is half the campaign U-core's
    (the same offset s_fe = 50 um); its 150 turns (0.75 ohm) pull 0.56 times as hard as one of
    the U-core's poles at the same gap, so that the closest pair of gaps (0.7 / 0.9 mm at 1 A)
    stays clear of pull-in and of harmonics the scans do not see."""
    return Magnet(poles=(pole,), turns=150.0, pole_area=_MAGNET.pole_area,
                  iron_length=_MAGNET.iron_length / 2, mu_r=_MAGNET.mu_r, resistance=0.75,
                  current_channel=f"i{k}", flux_channel=f"phi{k}", voltage_channel=f"v{k}")


def _same_current(dc: float, ac: float) -> tuple[Drive, Drive]:
    """Both coils driven alike: one current (dc, ac) [A] at the fundamental."""
    drive = Drive("current", dc, ac, _F_TRUE)
    return (drive, drive)


def _tilt() -> Preset:
    magnets = tuple(_one_pole(p, k + 1) for k, p in enumerate(_MAGNET.poles))
    runs = []
    for g1, g2 in ((0.8e-3, 1.2e-3), (1.2e-3, 0.8e-3), (0.7e-3, 0.9e-3), (1.1e-3, 1.3e-3),
                   (1.0e-3, 1.0e-3)):
        for dc in (0.4, 0.8):
            runs.append(RunSpec(
                f"g{g1 * 1e6:04.0f}_{g2 * 1e6:04.0f}_dc{dc * 10:02.0f}_ac02",
                drives=_same_current(dc, 0.2), gaps={"F1": g1, "F2": g2},
                duration=0.5, labels={"dc": f"{dc}", "ac": "0.2", "repeat": "1"}))
    runs.append(RunSpec("tare", drives=_same_current(0.0, 0.0),
                        gaps={"F1": 1.0e-3, "F2": 1.0e-3}, duration=0.5, tare=True,
                        labels={"dc": "0", "ac": "0", "repeat": "1"}))
    return Preset(
        name="tilt",
        description="the campaign's beam pulled at its pole positions by two one-pole magnets "
                    "on their own cores (F1 at 0.25 m on coil 1, F2 at 0.35 m on coil 2), both "
                    "coils carrying the same current, so the closer pole pulls harder: scanned "
                    "(0.7 A DC, 0.3 A AC) at equal gaps (1.0 mm) and at F1 0.8 mm, F2 1.2 mm; "
                    "five gap pairs x two DC currents at 0.2 A AC (current drive) and a "
                    "zero-current tare",
        beam=BeamSpec(), magnets=magnets, sensors=_SENSORS,
        scan=ScanSpec(drives=_same_current(0.7, 0.3), gap=1.0e-3),
        more_scans=(ScanSpec(drives=_same_current(0.7, 0.3),
                             gaps={"F1": 0.8e-3, "F2": 1.2e-3}),),
        runs=tuple(runs), nominal_frequency=20.0,
    )


_EDDY_MAGNET = dataclasses.replace(_MAGNET, eddy_time=0.5e-3)
"""The paper's U-core whose core lags: eddy currents, tau = 0.5 ms (17 degrees at 100 Hz)."""
_BROADBAND_SCAN = ScanSpec(
    drives=(Drive("current", 0.6, 0.0, 5.0, waveform=PeriodicChirp(0.1, 5.0, 200.0, 0.25)),),
    record=1.0, gap=1.0e-3)
"""A periodic chirp 5 -> 200 Hz every 0.25 s on 0.6 A DC: 1 s records hold four periods."""
_STEPS = (10.0, 14.68, 21.54, 31.62, 46.42, 60.0, 100.0)
"""[Hz] nominal steps: a decade 10..100 Hz log-spaced in 7, the sixth (68.1 Hz) moved to 60 Hz,
clear of the closed-loop first bending mode (67.3 / 69.0 / 69.8 Hz at 0.8 / 1.0 / 1.2 mm and
0.6 A)."""


def _step_ac(gap: float, f: float) -> float:
    """[A] a step's AC: 0.2 A keeps every pole's dynamic gap change below 10 % of the gap but
    at 0.8 mm and 60 Hz, 7 Hz under the mode, where 0.14 A keeps it below 15 %."""
    return 0.14 if gap < 0.9e-3 and f == 60.0 else 0.2


def _sweep() -> Preset:
    runs = [RunSpec("sweep", drives=(Drive("current", 0.6, 0.0, 10.0, waveform=SweptSine(
        0.1, 10.0, 150.0, 4.0)),), gap=1.0e-3, duration=4.0, manifest=False)]
    for gap in (0.8e-3, 1.0e-3, 1.2e-3):
        for f in _STEPS:
            ac = _step_ac(gap, f)
            runs.append(RunSpec(
                f"g{gap * 1e6:04.0f}_f{f:.2f}".replace(".", "p"), gap=gap, duration=0.5,
                drives=(Drive("current", 0.6, ac, f * (1 + 7e-4)),),
                labels={"dc": "0.6", "ac": f"{ac}", "frequency": f"{f}"}))
    runs.append(RunSpec("tare", drives=(Drive("current", 0.0, 0.0, _STEPS[0] * (1 + 7e-4)),),
                        gap=1.0e-3, duration=0.5, tare=True,
                        labels={"dc": "0", "ac": "0", "frequency": f"{_STEPS[0]}"}))
    return _sweep_rig("sweep", "the paper's beam and U-core magnet, whose force lags its current "
                      "(eddy currents, 0.5 ms), current drive: scanned under a periodic chirp "
                      "5-200 Hz on 0.6 A DC; a sweep 10 -> 150 Hz over 4 s (0.1 A on 0.6 A DC, "
                      "1 mm); a stepped-sine campaign over a decade, 10..100 Hz in 7 steps x "
                      "gaps 0.8, 1.0, 1.2 mm (0.6 A DC, 0.2 A AC) and a zero-current tare",
                      tuple(runs), _STEPS[0])


def _sweep_rig(name: str, description: str, runs: tuple[RunSpec, ...],
               nominal: float) -> Preset:
    """A preset of the sweep rig (the paper's beam, the U-core whose force lags its current,
    the chirp scan over 5-200 Hz) with these runs."""
    return Preset(name=name, description=description, beam=BeamSpec(), magnets=(_EDDY_MAGNET,),
                  sensors=_SENSORS, scan=_BROADBAND_SCAN, runs=runs, nominal_frequency=nominal,
                  band=(5.0, 200.0))


def _dwell() -> Preset:
    run = RunSpec("dwell", drives=(Drive("current", 0.6, 0.0, 40.0, waveform=SweptSine(
        0.05, 40.0, 100.0, 20.0)),), gap=1.0e-3, duration=20.0, manifest=False)
    return _sweep_rig("dwell", "the sweep rig (the paper's beam, a U-core whose force lags its "
                      "current) scanned under a periodic chirp 5-200 Hz (lines 4 Hz apart, the "
                      "chirp crossing the first bending mode in 2 ms a period); one run swept "
                      "slowly through that mode, 40 -> 100 Hz in 20 s (0.05 A on 0.6 A DC, "
                      "1 mm): half a second within its half-power band, longer than the scan's "
                      "records hold it", (run,), 40.0)


def _random() -> Preset:
    noise = BandLimitedRandom(0.07, 5.0, 150.0, period=4.0, seed=7)
    run = RunSpec("random", drives=(Drive("current", 0.6, 0.0, 5.0, waveform=noise),),
                  gap=1.0e-3, duration=4.0, manifest=False)
    return _sweep_rig("random", "the sweep rig (the paper's beam, a U-core whose force lags its "
                      "current) scanned under a periodic chirp 5-200 Hz; one run of "
                      "band-limited random current 5-150 Hz, 0.07 A RMS on 0.6 A DC, 4 s at "
                      "1 mm", (run,), 5.0)


_SOLID_MAGNET = dataclasses.replace(_MAGNET, core="solid", conductivity=2.0e6,
                                    core_thickness=2.0e-3)
"""The paper's U-core made of solid iron, 2 mm thick (sigma 2 MS/m, mu_r 2000): diffusion time
tau_d = sigma mu d^2 = 5.0 ms, its force lagging 6 degrees at 10 Hz and 39 at 100 Hz, where
it has fallen to 65 %."""
_LAMINATED_MAGNET = dataclasses.replace(_MAGNET, core="laminated", conductivity=2.0e6,
                                        core_thickness=0.35e-3)
"""The paper's U-core of 0.35 mm laminations (sigma 2 MS/m): tau_d = 0.15 ms, near first order
(tau_d / 3 = 51 us), 1.8 degrees of lag at 100 Hz."""
_CORE_STEPS = (10.0, 14.68, 21.54, 30.0, 46.42, 85.0, 100.0)
"""[Hz] nominal steps over a decade, 10..100 Hz log-spaced in 7, the fourth (31.62 Hz) moved to
30 Hz and the sixth (68.1 Hz) to 85 Hz: clear of the closed-loop first bending mode (67.3 /
69.0 / 69.8 Hz at 0.8 / 1.0 / 1.2 mm and 0.6 A) at the fundamental and at twice it, the
dynamic gap change within 12 % at 0.8 mm. The force's second harmonic stays inside the scan's
band (200 Hz): a 110 Hz step's, at 220 Hz, is not reconstructed."""


def _core_campaign(name: str, magnet: Magnet, what: str) -> Preset:
    """A stepped-sine campaign over :data:`_CORE_STEPS` x gaps 0.8, 1.0, 1.2 mm (0.6 A DC,
    0.2 A AC) and a zero-current tare, scanned under the sweep rig's chirp."""
    runs = []
    for gap in (0.8e-3, 1.0e-3, 1.2e-3):
        for f in _CORE_STEPS:
            runs.append(RunSpec(
                f"g{gap * 1e6:04.0f}_f{f:.2f}".replace(".", "p"), gap=gap, duration=0.5,
                drives=(Drive("current", 0.6, 0.2, f * (1 + 7e-4)),),
                labels={"dc": "0.6", "ac": "0.2", "frequency": f"{f}"}))
    runs.append(RunSpec("tare", drives=(Drive("current", 0.0, 0.0, _CORE_STEPS[0] * (1 + 7e-4)),),
                        gap=1.0e-3, duration=0.5, tare=True,
                        labels={"dc": "0", "ac": "0", "frequency": f"{_CORE_STEPS[0]}"}))
    return Preset(
        name=name,
        description=f"the paper's beam and U-core magnet with {what}, current drive: scanned "
                    "under a periodic chirp 5-200 Hz on 0.6 A DC; a stepped-sine campaign "
                    "over a decade, 10..100 Hz in 7 steps x gaps 0.8, 1.0, 1.2 mm (0.6 A DC, "
                    "0.2 A AC) and a zero-current tare",
        beam=BeamSpec(), magnets=(magnet,), sensors=_SENSORS, scan=_BROADBAND_SCAN,
        runs=tuple(runs), nominal_frequency=_CORE_STEPS[0], band=(5.0, 200.0),
    )


def _solid() -> Preset:
    return _core_campaign("solid", _SOLID_MAGNET,
                          "a solid iron core (2 mm, the flux diffusing in: tau_d = 5.0 ms)")


def _laminated() -> Preset:
    return _core_campaign("laminated", _LAMINATED_MAGNET,
                          "a laminated core (0.35 mm laminations: tau_d = 0.15 ms)")


_SATURATING_MAGNET = dataclasses.replace(_MAGNET, saturation=0.35)
"""The paper's U-core whose iron saturates (B_s = 0.35 T, a ferrite's, on the B-H curve of
:data:`.magnet.KNEE`): at 0.8 mm its static pull falls short of the unsaturated by 1.1 % at
0.8 A, 9 % at 1.2 A and 25 % at 1.6 A."""


def _saturation() -> Preset:
    runs = []
    for gap in (0.8e-3, 1.0e-3, 1.2e-3):
        for dc in (0.4, 0.7, 1.0, 1.3):
            runs.append(RunSpec(
                f"g{gap * 1e6:04.0f}_dc{dc * 10:02.0f}", drives=(Drive("current", dc, 0.2,
                                                                        _F_TRUE),),
                gap=gap, duration=0.5, labels={"dc": f"{dc}", "ac": "0.2"}))
    runs.append(RunSpec("tare", drives=(Drive("current", 0.0, 0.0, _F_TRUE),), gap=1.0e-3,
                        duration=0.5, tare=True, labels={"dc": "0", "ac": "0"}))
    return Preset(
        name="saturation",
        description="the campaign's beam and U-core magnet, its iron saturating (B_s 0.35 T): "
                    "three static gaps x four DC currents 0.4-1.3 A (0.2 A AC, current drive, "
                    "20 Hz) from the linear range into saturation, and a zero-current tare",
        beam=BeamSpec(), magnets=(_SATURATING_MAGNET,), sensors=_SENSORS,
        scan=ScanSpec(drives=(Drive("current", 0.6, 0.2, _F_TRUE),), gap=1.0e-3),
        runs=tuple(runs), nominal_frequency=20.0,
    )


PRESETS = {"paper": _paper, "resonance": _resonance, "campaign": _campaign, "plate": _plate,
           "body": _body, "two-coil": _two_coil, "tilt": _tilt, "sweep": _sweep,
           "random": _random, "dwell": _dwell, "solid": _solid, "laminated": _laminated,
           "saturation": _saturation}


def get_preset(name: str, realism: str | Realism | None = None) -> Preset:
    """The preset called ``name``.

    Parameters
    ----------
    name : str
        A key of :data:`PRESETS`.
    realism : str, Realism or None
        ``"ideal"`` or None (the preset as it is: white noise only), ``"lab"`` (the
        :class:`.realism.Realism` defaults) or a Realism; a ``lab`` preset without a
        zero-current tare run gets one (:func:`with_tare`).

    Returns
    -------
    Preset
        A fresh description of the virtual rig.

    Raises
    ------
    InputError
        An unknown name or realism.
    """
    if name not in PRESETS:
        raise InputError(f"preset '{name}' is unknown (choose from {', '.join(PRESETS)})")
    return with_realism(PRESETS[name](), realism)


def with_realism(preset: Preset, realism: str | Realism | None) -> Preset:
    """``preset`` under ``realism`` (as :func:`get_preset` takes it; None keeps the preset's
    own), with a zero-current tare run where a ``lab`` rig has none (:func:`with_tare`)."""
    chosen = resolve_realism(realism)
    if chosen is None:
        return preset
    return with_tare(dataclasses.replace(preset, realism=chosen))


def with_tare(preset: Preset) -> Preset:
    """``preset`` with a zero-current tare run (named ``tare``, 0.5 s, the first run's gaps and
    drive sources, every level zero) when it has none.

    Parameters
    ----------
    preset : Preset

    Returns
    -------
    Preset
        ``preset`` itself when one of its runs is a tare.
    """
    if any(r.tare for r in preset.runs) or not preset.runs:
        return preset
    first = preset.runs[0]
    zero = tuple(Drive(d.source, 0.0, 0.0, d.frequency) for d in first.drives)
    tare = RunSpec("tare", drives=zero, gap=first.gap, duration=0.5, tare=True,
                   gaps=dict(first.gaps))
    return dataclasses.replace(preset, runs=(*preset.runs, tare))


def first_mode_beta(beam: BeamSpec | PlateSpec | BodySpec, f1: float) -> float:
    """Stiffness-proportional damping coefficient giving the structure's ``damping_ratio`` at f1.

    Parameters
    ----------
    beam : BeamSpec, PlateSpec or BodySpec
        The structure, with its ``damping_ratio``.
    f1 : float
        The first bending frequency [Hz].

    Returns
    -------
    float
        beta [s], so that ``C = beta K``.
    """
    return 2 * beam.damping_ratio / (2 * math.pi * f1)

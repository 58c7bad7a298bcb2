"""The run against the scan: the probes' motion per unit of the actuator's drive must agree with
the scan's (METHOD.md section 6; docs/method.md section 7).

The scan measured the structure's motion with the coil current as its reference; a run under a
steady drive records both the current and the probes. An electromagnet pulls with i^2, so the
run's coordinate of the fundamental per unit of the fundamental of i^2,
rho = Q_1 P_1(scan) / P_1(run) (P: the harmonics of i^2 from each record's current; a
coordinate of 1 is the scan's motion), is real and positive whatever the current's bias,
amplitude or sign, and its size changes only with what the actuator's law does between scan
and run (the gap, the current's level). So:

- rho negative (beyond 90 degrees): the probes move against the scan's motion: their sign;
- rho's phase beyond its noise and :data:`PHASE_TOLERANCE`: a delay between the probes and the
  current channel (DAQ skew; n w0 tau at harmonic n);
- |rho| beyond :data:`MOTION_SPAN` either way: a unit or scale slip of the probes.

A model of several scans (one load each) or of spectra holds no single drive: not checked.
Under any drive (:func:`line_notes`) the same ratio, the first coordinate per unit of coil
current against the broadband scan's, over the lines that carry the drive: its sign and size.
"""

from __future__ import annotations

import math

import numpy as np

from ..model.broadband import BroadbandModel
from ..model.spatial import SpatialModel
from ..records import Run
from ..rig import Rig
from ..signals.fourier_sums import square_phasors
from ..signals.mains import near_mains
from .coordinates import Coordinates

__all__ = ["LineRatio", "scan_notes"]

PHASE_TOLERANCE = math.radians(1.0)
"""[rad] how far the phase of the motion per unit of i^2 may move between scan and run without
a mistake: the structure's and the core's phase change with the load (gap, bias, level) away
from a resonance. Over the ``campaign`` preset's gaps (0.8-1.2 mm) and currents it moves by at
most 0.3 degrees; a delay of 4 samples at 10 kHz moves it by 2.9 degrees at 20 Hz."""
PHASE_SIGMAS = 5.0
"""...and how many of its standard uncertainties."""
MOTION_SPAN = 20.0
"""[1] the farthest factor by which the motion per unit of i^2 moves between scan and run
without a mistake: the law's K(s) ~ 1 / s^2 over a campaign's gaps and the magnetic stiffness
(a factor of 0.65 to 2.3 over the ``campaign`` preset); a unit slip (1000 for mm as m, 25.4
for inches as mm) lies beyond it."""
BIAS = 2.0
"""Under any drive, the current's DC must be at least this many times its standard deviation:
the pull, ~ i^2, is then mostly 2 I_0 i, linear in the current as the scan's shapes per ampere
are (its square's lines at most a quarter of that in RMS); a drive without bias is not
checked."""
DRIVE_SHARE = 0.1
"""Under any drive, the lines compared carry at least this share of the current's largest line
in the band."""
SEGMENT = 4.0
"""[s] A stream's segments for the run against the scan under any drive (lines 0.25 Hz apart;
the scan's coordinate is interpolated between its own lines)."""
MIN_SHARE = 0.05
"""The fundamental of i^2 must hold at least this share of its AC, in the scan and in the run
(a drive without DC bias pulls at 2 w0 only)."""


def scan_notes(model: SpatialModel, coords: Coordinates, current: np.ndarray,
               sensor_names: list[str], what: str) -> list[str]:
    """A note when the probes' motion per unit of i^2 contradicts the scan's (see the module
    docstring).

    Parameters
    ----------
    model : SpatialModel
        With the scan's drive (:attr:`~forcecal.model.spatial.SpatialModel.drive`); without it
        the check is not made.
    coords : Coordinates
    current : (H+1,) complex ndarray [A]
        The run's coil current, harmonics 0..H.
    sensor_names : list of str
    what : str
        The run, at the start of the note.

    Returns
    -------
    list of str
    """
    if model.drive is None or len(model.drive) < 2 or 1 not in model.harmonics or len(current) < 2:
        return []
    k = model.index(1)
    members, q, _ = coords.span(k)
    if len(members) != 1 or not np.isfinite(q[0]):
        return []
    scan_p, run_p = square_phasors(model.drive)[:3], square_phasors(current[:3])
    if not all(abs(p[1]) > MIN_SHARE * np.abs(p[1:]).sum() for p in (scan_p, run_p)):
        return []
    rho = complex(q[0] * scan_p[1] / run_p[1])
    probes = ", ".join(sensor_names)
    phase, size = math.degrees(np.angle(rho)), abs(rho)
    head = (f"{what}: the probes {probes} move {size:#.3g} times the scan's motion per unit of "
            f"the current squared, at {phase:+#.3g} degrees to it (harmonic 1)")
    gross = _sign_or_slip(head, phase, size)
    if gross:
        return gross
    sigma = float(coords.q_std[k]) / max(abs(complex(q[0])), 1e-300)
    limit = max(PHASE_SIGMAS * sigma, PHASE_TOLERANCE)
    if abs(np.angle(rho)) > limit:
        lag = -np.angle(rho) / (2 * np.pi * model.f0)         # x(t - tau): e^{-j w0 tau}
        return [f"{head}, beyond the {math.degrees(limit):.2g} degrees that noise and the "
                f"load allow: the probes {probes} recorded {1e3 * lag:+.3g} ms late against "
                "the current channel (a delay, DAQ skew between modules or a filter's), or a "
                "probe's position"]
    return []


def run_line_notes(rig: Rig, model: BroadbandModel, run: Run, coordinate: np.ndarray,
                   what: str) -> list[str]:
    """:func:`line_notes` of a run held whole, where it has the coil current."""
    act = rig.actuator
    if act.current not in run.channels:
        return []
    return line_notes(model, coordinate, act.current_scale * run.channel(act.current), run.fs,
                      rig.mains, list(rig.sensor_names), what)


def line_notes(model: BroadbandModel, coordinate: np.ndarray, current: np.ndarray, fs: float,
               mains: float | None, sensor_names: list[str], what: str) -> list[str]:
    """Under any drive, a note when the probes' motion per unit of coil current contradicts the
    broadband scan's in sign or in size (see the module docstring), over the whole record at
    once (:class:`LineRatio`, one segment).

    Parameters
    ----------
    model : BroadbandModel
    coordinate : (n,) array
        The run's first coordinate, sample by sample.
    current : (n,) array [A]
        The run's coil current.
    fs : float [Hz]
    mains : float or None [Hz]
        The mains' frequency (its harmonics' lines left out).
    sensor_names : list of str
    what : str
        The run, at the start of the note.

    Returns
    -------
    list of str
    """
    ratio = LineRatio(model, fs, mains)
    ratio.add(coordinate, current)
    return ratio.notes(sensor_names, what)


class LineRatio:
    """The run's motion per unit of coil current against the broadband scan's, gathered over
    segments of a record as it comes (a stream's memory stays flat) or over the whole record.

    The run's first coordinate and its current, each through a Hann window over a segment,
    give per line ``Q`` and ``I``; the scan's first coordinate per unit of its reference, the
    current, ``a``, between its lines. Over the lines of the model's band that carry the drive
    (:data:`DRIVE_SHARE` of the segment's largest) and lie clear of the mains' harmonics,
    rho = sum Q (I a)^* / sum |I a|^2 over every segment: near 1 under the scan's own bias and
    gap, real and positive under any bias of the scan's sign (the pull's part linear in the
    current is 2 I_0 i); where the model kept the scan's bias (from time records), rho is
    taken per unit of that part, times the scan's bias over the run's, and a run biased the
    other way is told from flipped probes. A drive whose DC is under :data:`BIAS` standard
    deviations is not checked. Its phase beyond 90 degrees is the probes' sign (or, without
    the scan's bias, a bias of the other sign); its size beyond :data:`MOTION_SPAN` either way
    a unit or scale slip. A delay is not judged: the lines' phases move with the load near a
    resonance by more than a skew of a few samples does.

    Parameters
    ----------
    model : BroadbandModel
    fs : float [Hz]
    mains : float or None [Hz]
    segment : int or None
        Samples per segment; None: the whole record is one (:meth:`add` once).
    """

    def __init__(self, model: BroadbandModel, fs: float, mains: float | None,
                 segment: int | None = None) -> None:
        self.model, self.fs, self.mains, self.segment = model, float(fs), mains, segment
        self._held: list[np.ndarray] = []           # (2, m) blocks not yet a segment
        self._sums = np.zeros(3)                    # samples, sum i, sum i^2
        self._num, self._den, self._lines = 0j, 0.0, 0
        self._span = (math.inf, -math.inf)

    def add(self, coordinate: np.ndarray, current: np.ndarray) -> None:
        """The next samples of the run's first coordinate and of its current [A]."""
        pair = np.vstack([np.asarray(coordinate, float), np.asarray(current, float)])
        self._sums += (pair.shape[1], float(pair[1].sum()), float(np.square(pair[1]).sum()))
        if self.segment is None:
            self._segment(pair)
            return
        self._held.append(pair)
        held = np.hstack(self._held)
        while held.shape[1] >= self.segment:
            self._segment(held[:, :self.segment])
            held = held[:, self.segment:]
        self._held = [held]

    def _segment(self, pair: np.ndarray) -> None:
        """Gather one segment's lines."""
        n = pair.shape[1]
        window = np.hanning(n)
        q, i = np.fft.rfft((pair - pair.mean(axis=1, keepdims=True)) * window, axis=1)
        f = np.fft.rfftfreq(n, 1.0 / self.fs)
        model = self.model
        lo = max(model.band[0], float(model.frequencies.min()))
        hi = min(model.band[1], float(model.frequencies.max()))
        band = (f >= lo) & (f <= hi) & ~near_mains(f, self.mains, 3 * self.fs / n)
        if np.count_nonzero(band) < 3:
            return
        lines = band & (np.abs(i) >= DRIVE_SHARE * np.abs(i[band]).max())
        scan = model.coordinates[0]
        ia = i[lines] * (np.interp(f[lines], model.frequencies, scan.real)
                         + 1j * np.interp(f[lines], model.frequencies, scan.imag))
        self._num += complex(np.sum(q[lines] * np.conj(ia)))
        self._den += float(np.sum(np.abs(ia) ** 2))
        self._lines += int(np.count_nonzero(lines))
        if np.any(lines):
            self._span = (min(self._span[0], float(f[lines].min())),
                          max(self._span[1], float(f[lines].max())))

    def notes(self, sensor_names: list[str], what: str) -> list[str]:
        """The note, if any (see the class), once the record is in; a stream's last samples
        short of a segment count when they span at least a tenth of one."""
        if self.segment is not None and self._held and self._held[0].shape[1] >= max(
                16, self.segment // 10):
            self._segment(self._held[0])
            self._held = []
        count, total, squares = self._sums
        bias = total / max(count, 1.0)
        std = math.sqrt(max(squares / max(count, 1.0) - bias**2, 0.0))
        if not abs(bias) >= BIAS * std or self._lines < 3 or not self._den > 0:
            return []
        rho = self._num / self._den
        scan_bias = _scan_bias(self.model)
        if scan_bias is not None:
            rho *= scan_bias / bias               # per unit of 2 I_0 i: the biases' ratio out
        phase, size = math.degrees(np.angle(rho)), abs(rho)
        head = (f"{what}: the probes {', '.join(sensor_names)} move {size:#.3g} times the "
                f"scan's motion per unit of the coil current, at {phase:+.3g} degrees to it "
                f"({self._lines} lines, {self._span[0]:.4g}-{self._span[1]:.4g} Hz, the "
                f"current's bias {bias:+.3g} A"
                + (": one of the other sign than the scan's turns it too)" if scan_bias is None
                   else f" against the scan's {scan_bias:+.3g} A, their ratio taken out)"))
        return _sign_or_slip(head, phase, size)


def _scan_bias(model: BroadbandModel) -> float | None:
    """[A] the scan's current bias, where its records kept one beyond :data:`BIAS` standard
    deviations (the shapes per ampere then scale with it), else None."""
    if model.reference is None:
        return None
    dc, ac = model.reference
    return dc if abs(dc) >= BIAS * ac and dc != 0 else None


def _sign_or_slip(head: str, phase: float, size: float) -> list[str]:
    """The note on a motion per unit of drive ``size`` times the scan's at ``phase`` degrees
    to it: against it (the probes' sign), or beyond :data:`MOTION_SPAN` (a unit slip)."""
    if abs(phase) > 90:
        return [f"{head}: they move against the scan's motion, so the probes' sign is likely "
                "flipped (sensors[].scale), or the scan's response; the inertia is taken "
                "with the wrong sign"]
    if not 1 / MOTION_SPAN <= size <= MOTION_SPAN:
        return [f"{head}, beyond the factor of {MOTION_SPAN:g} that the gap and the current's "
                "level allow: a unit or scale slip of the probes (sensors[].scale: mm for m is "
                "1000) or of the scan's response; the inertia is off by as much"]
    return []

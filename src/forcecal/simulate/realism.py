"""How real the virtual rig's measurements are: ideal (white noise only, the estimator's own
noise model) or ``lab``: coloured noise, ADC quantization, sensor sensitivity errors, a drifting
drive, gravity preload and gauge offsets.

:class:`Realism` states every level with its default; :func:`resolve_realism` turns the names
``"ideal"`` and ``"lab"`` into one (``None`` for ideal). This module holds the configuration and
the signal primitives (pink noise, mains hum, quantization); :mod:`.lab` applies them to the
rig's channels.

Noise levels are stated relative to each channel's white noise (:class:`.presets.NoiseSpec`),
so one setting serves gauges, probes, coil channels and the vibrometer alike, and a preset
without noise stays without noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..rig import TypeB

__all__: list[str] = []


@dataclass(frozen=True)
class Adc:
    """One channel kind's analogue-to-digital converter: ``bits`` over ``-full_scale ..
    +full_scale`` (SI units), mid-tread rounding, saturating at the ends of its range.

    Attributes
    ----------
    bits : int
        Resolution.
    full_scale : float
        Half the input range, in the channel's SI unit.
    """

    bits: int
    full_scale: float

    @property
    def step(self) -> float:
        """The quantization step, ``2 full_scale / 2**bits`` [SI unit]."""
        return 2.0 * self.full_scale / 2.0**self.bits

    def quantize(self, x: np.ndarray) -> np.ndarray:
        """What the converter reads of ``x``: the nearest code, clipped to the range.

        Parameters
        ----------
        x : ndarray
            The analogue values [SI unit].

        Returns
        -------
        ndarray
            Integer multiples of :attr:`step`, within ``-2**(bits-1) .. 2**(bits-1) - 1`` codes.
        """
        top = 2.0 ** (self.bits - 1)
        codes = np.clip(np.round(np.asarray(x, dtype=float) / self.step), -top, top - 1)
        out: np.ndarray = codes * self.step
        return out


@dataclass(frozen=True)
class AdcSpec:
    """The converter of every channel kind (defaults: 16 bits; ranges that hold every preset's
    signals, gravity preload included, with room to spare).

    ============  ========  ==============  ===================================
    kind          bits      full scale      step
    ============  ========  ==============  ===================================
    gauge         16        +-200 N         6.1 mN (white noise 10 mN)
    probe         16        +-1 mm          30.5 nm (0.2 um)
    current       16        +-10 A          0.31 mA (1 mA)
    flux          16        +-1 mWb         30.5 nWb (0.1 uWb)
    voltage       16        +-50 V          1.5 mV (1 mV)
    ldv           16        +-50 mm/s       1.5 um/s (50 um/s)
    ============  ========  ==============  ===================================
    """

    gauge: Adc = Adc(16, 200.0)
    probe: Adc = Adc(16, 1e-3)
    current: Adc = Adc(16, 10.0)
    flux: Adc = Adc(16, 1e-3)
    voltage: Adc = Adc(16, 50.0)
    ldv: Adc = Adc(16, 0.05)


LAB_TYPE_B = TypeB(gauge_scale=0.005, probe_scale=0.01, current_scale=0.002,
                   position=0.2e-3, mass=0.005, gap=10e-6, declared=True)
"""The ``[uncertainty]`` a ``lab`` rig file declares: gauges 0.5 %, probes 1 %, current sensor
0.2 % (relative), positions 0.2 mm, masses 0.5 %, gaps 10 um. The sensitivities are drawn from
them; positions, masses and gaps are declared but the rig file gives the simulator's own."""


@dataclass(frozen=True)
class Realism:
    """The imperfections of a ``lab`` virtual rig, with their defaults.

    Every measured channel (gauges, probes, coil current, flux and voltage, the scan's
    vibrometer response and its reference current) carries, besides its white noise of standard
    deviation sigma (:class:`.presets.NoiseSpec`):

    - **1/f (pink) noise** whose one-sided power spectral density is ``(2 sigma^2 / fs) *
      flicker_corner / f``: it equals the white noise's at ``flicker_corner`` and grows as 1/f
      below it (from 1 / record length up to fs / 2);
    - **mains hum**: ``sum_h hum[h] * sigma * sin(2 pi h mains t + phase_h)`` at the mains
      frequency and its harmonics, a random phase per harmonic, channel and record;
    - **quantization** by the channel kind's :class:`Adc` (:class:`AdcSpec`).

    The rig's sensors and set-up:

    - **sensitivities**: each gauge's, probe's and current sensor's true sensitivity is the rig
      file's scale times ``1 + e``, e drawn from ``type_b`` (``gauge_scale``, ``probe_scale``,
      ``current_scale``); the rig file written declares ``type_b``. Positions, masses and gaps
      are declared (``position``, ``mass``, ``gap``) but not perturbed: the rig file gives the
      simulator's own values;
    - **gravity**: the structure's weight (``gravity`` [m/s^2], acting along -w, on a body along
      -z: the magnet pulls against it) preloads the gauges, a DC the gauges read on every
      record; the pole gaps are those at rest under it;
    - **gauge offsets**: a zero offset per gauge, drawn with standard deviation
      ``gauge_offset`` [N]; the tare record (zero current; a preset without one gets one)
      carries the preload and the offsets as every other run does;
    - **a drifting drive**: from scan point to scan point the drive's level is scaled by
      ``1 + a_k`` and its frequency by ``1 + b_k``, random walks with steps of standard
      deviation ``scan_level_step`` and ``scan_frequency_step`` (the reference records the same
      drive); within each run the level drifts linearly by ``drift`` [1/s] and the frequency by
      ``chirp`` [1/s] (:class:`.magnet.Drive`), drawn per run with standard deviations
      ``run_level_drift`` and ``run_frequency_drift``, far below what
      :func:`forcecal.forces.diagnostics.drift_notes` flags (1e-3 of the frequency within a record).

    Attributes
    ----------
    flicker_corner : float [Hz]
        The 1/f corner (default 5 Hz).
    mains : float [Hz]
        The mains frequency (default 50 Hz).
    hum : tuple of (int, float)
        (harmonic of the mains, amplitude in units of the channel's white sigma); default
        ((1, 3.0), (3, 1.0), (5, 0.5)): 50, 150 and 250 Hz.
    adc : AdcSpec
        The converters.
    type_b : TypeB
        The declared type-B standard uncertainties (default :data:`LAB_TYPE_B`).
    gravity : float [m/s^2]
        Default 9.81.
    gauge_offset : float [N]
        Standard deviation of each gauge's zero offset (default 0.5 N).
    scan_level_step, scan_frequency_step : float
        Steps of the drive's random walks from scan point to scan point, relative (defaults
        5e-4 and 1e-5).
    run_level_drift, run_frequency_drift : float [1/s]
        Standard deviations of a run's linear drifts of level and frequency (defaults 1e-3
        and 2e-5 per second).
    """

    flicker_corner: float = 5.0
    mains: float = 50.0
    hum: tuple[tuple[int, float], ...] = ((1, 3.0), (3, 1.0), (5, 0.5))
    adc: AdcSpec = field(default_factory=AdcSpec)
    type_b: TypeB = LAB_TYPE_B
    gravity: float = 9.81
    gauge_offset: float = 0.5
    scan_level_step: float = 5e-4
    scan_frequency_step: float = 1e-5
    run_level_drift: float = 1e-3
    run_frequency_drift: float = 2e-5

    def describe(self) -> dict:
        """The settings as plain JSON-ready values."""
        adc = {k: {"bits": a.bits, "full_scale": a.full_scale, "step": a.step}
               for k, a in vars(self.adc).items()}
        tb = {k: getattr(self.type_b, k) for k in TypeB.KEYS}
        return {"flicker_corner_Hz": self.flicker_corner, "mains_Hz": self.mains,
                "hum_relative_to_white": [list(h) for h in self.hum], "adc": adc,
                "type_b": tb, "gravity_m_s2": self.gravity, "gauge_offset_N": self.gauge_offset,
                "scan_level_step": self.scan_level_step,
                "scan_frequency_step": self.scan_frequency_step,
                "run_level_drift_per_s": self.run_level_drift,
                "run_frequency_drift_per_s": self.run_frequency_drift}


REALISMS = ("ideal", "lab")
"""The named settings: ``ideal`` (white noise only) and ``lab`` (:class:`Realism` defaults)."""


def resolve_realism(realism: str | Realism | None) -> Realism | None:
    """The :class:`Realism` a name stands for (``None`` for ideal).

    Parameters
    ----------
    realism : str, Realism or None
        ``"ideal"`` or None (white noise only), ``"lab"`` (the defaults), or a Realism.

    Returns
    -------
    Realism or None

    Raises
    ------
    InputError
        Another name.
    """
    if realism is None or isinstance(realism, Realism):
        return realism
    if realism == "ideal":
        return None
    if realism == "lab":
        return Realism()
    raise InputError(f"realism '{realism}' is unknown (choose from {', '.join(REALISMS)})")


def pink_noise(shape: tuple[int, ...], fs: float, sigma: float, corner: float,
               rng: np.random.Generator) -> np.ndarray:
    """1/f noise whose one-sided PSD is ``(2 sigma^2 / fs) * corner / f``.

    White Gaussian noise of standard deviation sigma, shaped in frequency by
    ``sqrt(corner / f)`` and without its DC bin: the white PSD ``2 sigma^2 / fs`` times
    ``corner / f``.

    Parameters
    ----------
    shape : tuple of int
        (..., n_samples), time on the last axis.
    fs : float
        [Hz] sampling rate.
    sigma : float
        The channel's white standard deviation [SI unit].
    corner : float
        [Hz] where the pink PSD equals the white one.
    rng : numpy.random.Generator

    Returns
    -------
    ndarray of ``shape``
    """
    n = shape[-1]
    white = sigma * rng.standard_normal(shape)
    if sigma == 0.0 or corner == 0.0 or n < 2:
        return np.zeros(shape)
    spec = np.fft.rfft(white, axis=-1)
    f = np.fft.rfftfreq(n, 1.0 / fs)
    gain = np.zeros_like(f)
    gain[1:] = np.sqrt(corner / f[1:])
    out: np.ndarray = np.fft.irfft(spec * gain, n=n, axis=-1)
    return out


def hum(shape: tuple[int, ...], fs: float, sigma: float, realism: Realism,
        rng: np.random.Generator) -> np.ndarray:
    """Mains hum: ``sum_h a_h sigma sin(2 pi h mains t + phase)``, a random phase per harmonic
    and record.

    Parameters
    ----------
    shape : tuple of int
        (..., n_samples), time on the last axis; each record gets its own phases.
    fs : float
        [Hz] sampling rate.
    sigma : float
        The channel's white standard deviation [SI unit]; the hum's amplitudes are in its units.
    realism : Realism
        ``mains`` and ``hum``.
    rng : numpy.random.Generator

    Returns
    -------
    ndarray of ``shape``
    """
    t = np.arange(shape[-1]) / fs
    out = np.zeros(shape)
    for h, amp in realism.hum:
        phase = rng.uniform(0.0, 2 * math.pi, size=(*shape[:-1], 1))
        out += amp * sigma * np.sin(2 * math.pi * h * realism.mains * t + phase)
    return out


def coloured(shape: tuple[int, ...], fs: float, sigma: float, realism: Realism,
             rng: np.random.Generator) -> np.ndarray:
    """The noise of a ``lab`` channel beside its white part: pink plus hum.

    Parameters
    ----------
    shape : tuple of int
        (..., n_samples).
    fs : float
        [Hz] sampling rate.
    sigma : float
        The channel's white standard deviation [SI unit].
    realism : Realism
    rng : numpy.random.Generator

    Returns
    -------
    ndarray of ``shape``
    """
    return (pink_noise(shape, fs, sigma, realism.flicker_corner, rng)
            + hum(shape, fs, sigma, realism, rng))

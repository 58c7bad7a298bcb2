"""The virtual rig's finite-element beam under broadband drives: the helpers that synthesise its
scans and runs, shared by the broadband tests (model/, forces/, realtime/, signals/, campaign/).

The scan and the run are synthesised from the beam's own modes, the paper's pole pattern and its
gauge springs: exact periodic responses to a band-limited random force, with white noise on
every channel. The fixtures built with them (``beam``, ``bb_scan``, ``bb_model``, ``random_run``,
``chirp``, ``random_scan``) are in ``tests/conftest.py``.
"""

from __future__ import annotations

import numpy as np

from forcecal.records import Run, Scan
from forcecal.simulate.virtual_rig import _gauge_forces, _points

FS = 10_000.0


def band_noise(rng, n, lo, hi):
    """``n`` samples of unit-RMS noise, its lines flat over ``lo``-``hi`` Hz (periodic in n)."""
    f = np.fft.rfftfreq(n, 1 / FS)
    spec = np.where((f >= lo) & (f <= hi), np.exp(2j * np.pi * rng.random(f.size)), 0)
    x = np.fft.irfft(spec, n)
    return x / x.std()


def random_force_run(beam, rng, hi, seconds=4.0):
    """(run, force at each pole, noise-free gauges) under 6 N + a 1.5 N RMS random force over
    5-``hi`` Hz at each pole, no coil current."""
    n = int(seconds * FS)
    u = 6.0 + 1.5 * band_noise(rng, n, 5.0, hi)                      # N at each pole
    run, gauges = record_run(beam, rng, u, np.zeros(n), "random")
    return run, u, gauges


def record_run(beam, rng, u, current, name):
    """The FE beam's run under the force ``u`` (N at each pole (N,), or at each its own
    (2, N)): its gauges and probes with white noise, and the coil current as given; and the
    noise-free gauges."""
    preset, model, phi, _rig, modal = beam
    n = u.shape[-1]
    f = np.fft.rfftfreq(n, 1 / FS)
    q = modal(f, np.fft.rfft(u, axis=-1).T)
    disp = phi @ np.fft.irfft(q, n, axis=0).T
    vel = phi @ np.fft.irfft(2j * np.pi * f[:, None] * q, n, axis=0).T
    gauges = _gauge_forces(model, preset, disp, vel)
    probes = model.row(_points(preset, preset.sensors)) @ disp
    ch = {"R1": gauges[0] + 0.01 * rng.standard_normal(n),
          "R2": gauges[1] + 0.01 * rng.standard_normal(n),
          "s1": probes[0] + 0.2e-6 * rng.standard_normal(n),
          "s2": probes[1] + 0.2e-6 * rng.standard_normal(n), "i": current}
    return Run(channels=ch, fs=FS, t0=0.0, name=name, source=f"{name}.csv"), gauges


def noisy_chirp(chirp, noise, seed):
    """The chirp scan with white noise ``noise`` [m/s] on every response and 1e-3 A on every
    reference, drawn from ``seed``."""
    x, resp, ref = chirp
    rng = np.random.default_rng(seed)
    return Scan(points=x, response=resp + noise * rng.standard_normal(resp.shape),
                reference=ref + 1e-3 * rng.standard_normal(ref.shape), fs=FS,
                quantity="velocity", source="noisy.uff")

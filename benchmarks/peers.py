"""Benchmark: forcecal beside two peer methods of force identification, on the any-drive runs.

Simulates the `sweep` and `random` presets (seed 0; the ideal rig, then the ``lab`` rig) and
estimates the pole forces F1 and F2 four ways from the same records:

- forcecal, run the way a user would (``forcecal scan`` on the chirp scan, ``forcecal
  reconstruct``; :func:`any_drive._drive_run`), and its reactions-only estimate beside it;
- frame-by-frame FRF inversion, as structural-dynamics toolboxes run it: the record cut into
  Hann frames (:data:`FRAME` samples, :data:`OVERLAP` overlap), each frame's spectrum inverted
  line by line through the FRF matrix from the two pole forces to the four responses (the
  probes' displacements s1, s2 and the gauges' reactions R1, R2, each weighted by its noise
  level), Tikhonov-regularised with the parameter chosen per line and per frame by generalized
  cross-validation, and the frames overlap-added back into time series; the record's mean is
  inverted through the static FRF on its own; the lines above the top of the rig file's band
  (200 Hz, the analysis band forcecal is given too) are left out, as an inversion over the
  FRFs' band does (every line to fs / 2 is reported beside it);
- an augmented Kalman filter (random-walk forces on a modal model, after Lourens et al. 2012):
  the modes below :data:`MODE_TOP` times the band's top kept as states (coordinates and
  velocities), the others as residual static flexibility (a feedthrough), the measurements the
  probes and the gauges; the steady-state filter and its Rauch-Tung-Striebel smoother, the
  random walk's variance chosen by the innovations' maximum likelihood over :data:`Q_GRID`;
  the smoother's covariance is its stated uncertainty (its output with the content above the
  band's top removed is reported beside it).

Both peers take the virtual rig's own finite-element model (its exact FRF, its true modes and
damping, as the simulator's trapezoidal steps realise them): a best case for them, information
forcecal does not have (it learns its spatial model from the SLDV scan). Neither peer is told
that both poles carry one flux (F1 = F2 in the truth). Every channel's noise level is read
from the record itself, from its spectrum between :data:`NOISE_BAND` (where the structure's
response to the drive is negligible); on the ``lab`` rig the tare's mean is taken off every
channel first, as forcecal takes the tare.

For every method it reports the total force's RMS error in every 0.5 s window as a fraction of
the window's AC RMS (:func:`any_drive._windows`), against the truth and against the truth
without its content above the scan's band, and each force's the same way (over its own AC
RMS); for the Kalman filter also its error over its stated uncertainty; and how the FRF
inversion's worst window moves with the frame length and the filter's with the modes kept.

Run:  .venv/bin/python benchmarks/peers.py [--ideal-only]
Writes benchmarks/results/peers.json.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import scipy.linalg
import scipy.signal
from any_drive import _drive_run, _in_band, _windows

from forcecal.simulate.export import write_simulation
from forcecal.simulate.integrate import drive_oversample
from forcecal.simulate.physics import _points, build_model
from forcecal.simulate.presets import get_preset

RESULTS = Path(__file__).parent / "results"
WIDTH = 0.5
"""[s] the windows' width, as ``any_drive.py``'s."""
FRAME = 8192
"""Samples per frame of the FRF inversion (0.82 s at 10 kHz): a power of two at least three
decay times 1 / (zeta omega) of the structure's slowest elastic mode (0.23 s at 70.7 Hz)."""
OVERLAP = 0.75
"""The frames' overlap (Hann windows: a constant sum of squares, as overlap-add needs)."""
FRAMES_TRIED = (2048, 4096, 8192, 16384)
"""Frame lengths of the inversion's sensitivity check."""
LAMBDA_DECADES = np.linspace(-8.0, 0.0, 81)
"""The GCV's grid: Tikhonov parameters from 1e-8 to 1 times the line's largest singular value
(plus none at all)."""
MODE_TOP = 4.0
"""The filter keeps every elastic mode below this many times the top of the scan's band."""
MODES_TRIED = (1.0, 2.0, 4.0, 8.0)
"""Multiples of the band's top of the filter's sensitivity check."""
START = 2500
"""Samples (0.25 s) over which the filter runs its own covariance from its first state before
its steady gain takes over (the likelihood is taken after them)."""
START_SCALE = 100.0
"""The first state's standard deviations over the steady filter's."""
Q_GRID = np.logspace(-7.0, 1.0, 17)
"""[N^2] the random walk's increment variance per sample, the likelihood's grid."""
NOISE_BAND = (2500.0, 4500.0)
"""[Hz] where every channel's noise floor is read (white noise: its level there is its level
everywhere)."""
CASES = (("sweep", "ideal"), ("random", "ideal"), ("sweep", "lab"), ("random", "lab"))


@dataclass(frozen=True)
class Structure:
    """What the peers know of the structure: the virtual rig's own finite-element model.

    w2 : (n_dof,) [rad^2/s^2] and phi : (n_dof, n_dof) its mass-normalised modes; beta [s] its
    stiffness-proportional damping; inv_k : (n_dof, n_dof) [m/N] its static flexibility;
    probes, gauges, poles : (2, n_dof) the rows of the probes', gauges' and poles' deflections;
    k_gauge [N/m] the gauges' stiffness; band (lo, hi) [Hz] the scan's band of the rig file;
    steps, the simulator's trapezoidal steps per sample under the run's drive.
    """

    w2: np.ndarray
    phi: np.ndarray
    beta: float
    inv_k: np.ndarray
    probes: np.ndarray
    gauges: np.ndarray
    poles: np.ndarray
    k_gauge: float
    band: tuple[float, float]
    steps: int


def structure(preset_name: str) -> Structure:
    """The finite-element model of ``preset_name``'s beam on its gauges (the simulator's)."""
    preset = get_preset(preset_name)
    model = build_model(preset)
    w2, phi = model.modes
    poles = [(p.name, p.x) for m in preset.magnets for p in m.poles]
    assert preset.band is not None, "a broadband preset"
    return Structure(w2=w2, phi=phi, beta=model.beta, inv_k=np.linalg.inv(model.stiffness),
                     probes=model.row(_points(preset, preset.sensors)),
                     gauges=model.row(_points(preset, preset.beam.gauges)),
                     poles=model.row(_points(preset, poles)),
                     k_gauge=preset.beam.gauge_stiffness, band=preset.band,
                     steps=drive_oversample(preset.runs[0].drives, preset.fs))


def frf(s: Structure, omega: np.ndarray, fs: float) -> np.ndarray:
    """(n_lines, 4, 2) the FRF from the pole forces [N] to s1, s2 [m] and R1, R2 [N] at
    ``omega`` [rad/s] of a record sampled at ``fs`` [Hz]: every mode of the model, C = beta K,
    each gauge a spring and its dashpot (what the gauge measures is the force it exerts on the
    beam), as the simulator's trapezoidal steps realise it (the continuous FRF at
    (2 / h) tan(omega h / 2), h its step)."""
    h = 1.0 / (fs * s.steps)
    omega = (2.0 / h) * np.tan(0.5 * h * np.asarray(omega, dtype=float))
    modal_in = s.phi.T @ s.poles.T                                          # (n_dof, 2)
    probe = s.probes @ s.phi                                                # (2, n_dof)
    gauge = -s.k_gauge * (s.gauges @ s.phi)
    w = omega[:, None]
    receptance = 1.0 / (s.w2[None, :] - w**2 + 1j * w * s.beta * s.w2[None, :])
    out = np.empty((len(omega), 4, 2), dtype=complex)
    out[:, :2] = np.einsum("pm,fm,mk->fpk", probe, receptance, modal_in)
    out[:, 2:] = (1.0 + 1j * w[:, :, None] * s.beta) * np.einsum(
        "gm,fm,mk->fgk", gauge, receptance, modal_in)
    return out


def noise_levels(y: np.ndarray, fs: float) -> np.ndarray:
    """(n_channels,) every channel's white-noise standard deviation, from the median of its
    Welch spectrum over :data:`NOISE_BAND` (one-sided PSD P: sigma^2 = P fs / 2)."""
    f, p = scipy.signal.welch(y, fs, nperseg=1024, axis=-1)
    inside = (f >= NOISE_BAND[0]) & (f <= NOISE_BAND[1])
    return np.sqrt(np.median(p[:, inside], axis=1) * fs / 2.0)


# ------------------------------------------------------------------ frame-by-frame FRF inversion

def frf_inversion(y: np.ndarray, fs: float, s: Structure, sigma: np.ndarray,
                  frame: int = FRAME, overlap: float = OVERLAP, limited: bool = True
                  ) -> tuple[np.ndarray, dict]:
    """Frame-by-frame inversion of ``y`` (4, n) = [s1, s2, R1, R2] into the pole forces
    (2, n) [N]: weighted by 1 / ``sigma``, Tikhonov per line and frame, its parameter the GCV
    minimum over :data:`LAMBDA_DECADES` (and 0); the mean through the static FRF. ``limited``:
    the lines above the top of the rig's band are left out (their forces zero), as an
    inversion over the FRFs' analysis band does; else every line up to fs / 2 is inverted."""
    weight = 1.0 / sigma[:, None]
    level = y.mean(axis=1)
    h0 = weight * frf(s, np.zeros(1), fs)[0].real
    mean_force = np.linalg.lstsq(h0, weight[:, 0] * level, rcond=None)[0]
    kw = {"fs": fs, "window": "hann", "nperseg": frame, "noverlap": int(frame * overlap)}
    f, _, z = scipy.signal.stft(y - level[:, None], boundary="even", padded=True, **kw)
    hw = weight[None] * frf(s, 2 * np.pi * f, fs)                               # (n_f, 4, 2)
    u, sv, vh = np.linalg.svd(hw, full_matrices=False)                      # sv (n_f, 2)
    x = weight[:, :, None] * z                                              # (4, n_f, n_t)
    beta = np.einsum("fmi,mft->fit", u.conj(), x)                           # (n_f, 2, n_t)
    b2 = np.abs(beta) ** 2
    outside = np.maximum(np.sum(np.abs(x) ** 2, axis=0) - b2.sum(axis=1), 0.0)  # (n_f, n_t)
    m = x.shape[0]
    best = np.full(outside.shape, np.inf)
    lam2 = np.zeros(outside.shape)
    for lam in np.concatenate([[0.0], 10.0 ** LAMBDA_DECADES]):
        l2 = (lam * sv[:, 0]) ** 2                                          # (n_f,)
        phi_f = sv**2 / (sv**2 + l2[:, None])                               # (n_f, 2)
        resid = np.sum((1 - phi_f[:, :, None]) ** 2 * b2, axis=1) + outside
        gcv = resid / (m - phi_f.sum(axis=1))[:, None] ** 2
        better = gcv < best
        best = np.where(better, gcv, best)
        lam2 = np.where(better, l2[:, None], lam2)
    gain = sv[:, :, None] / (sv[:, :, None] ** 2 + lam2[:, None, :])        # (n_f, 2, n_t)
    if limited:
        gain[f > s.band[1]] = 0.0
    forces_f = np.einsum("fik,fit->kft", vh.conj(), gain * beta)            # (2, n_f, n_t)
    _, ac = scipy.signal.istft(forces_f, boundary=True, **kw)
    forces = ac[:, :y.shape[1]] + mean_force[:, None]
    in_band = (f >= s.band[0]) & (f <= s.band[1])
    ratio = np.sqrt(lam2[in_band]) / sv[in_band, :1]
    return forces, {"frame": frame, "overlap": overlap, "frames": int(z.shape[-1]),
                    "top_Hz": float(s.band[1]) if limited else fs / 2,
                    "lambda_zero_share_in_band": float(np.mean(ratio == 0.0)),
                    "lambda_over_smax_in_band_median": float(np.median(ratio)),
                    "lambda_over_smax_in_band_p90": float(np.quantile(ratio, 0.9))}


# ------------------------------------------------------------------ augmented Kalman filter

@dataclass(frozen=True)
class StateSpace:
    """The augmented model z = [q, qd, p] sampled at dt: z' = F z + G w (w the forces' random
    walk increments), y = H z (measurements over their noise: unit variance)."""

    F: np.ndarray
    G: np.ndarray
    H: np.ndarray
    n_forces: int
    modes_hz: tuple[float, ...]


def state_space(s: Structure, fs: float, sigma: np.ndarray, mode_top: float = MODE_TOP
                ) -> StateSpace:
    """The kept modes' state space, stepped as the simulator steps them (the trapezoidal rule,
    :attr:`Structure.steps` steps per sample, the forces linear between samples), with the
    random-walk forces, and the residual modes' static flexibility as a feedthrough;
    measurements weighted by 1 / ``sigma``."""
    keep = (s.w2 > (2 * np.pi) ** 2) & (s.w2 < (2 * np.pi * mode_top * s.band[1]) ** 2)
    w2, phi = s.w2[keep], s.phi[:, keep]
    n, m = len(w2), s.poles.shape[0]
    a = np.zeros((2 * n, 2 * n))
    a[:n, n:] = np.eye(n)
    a[n:, :n] = -np.diag(w2)
    a[n:, n:] = -np.diag(s.beta * w2)
    b = np.vstack([np.zeros((n, m)), phi.T @ s.poles.T])
    # the simulator's own stepping: the trapezoidal rule at ``steps`` steps per sample, the
    # forces linear between samples
    h = 1.0 / (fs * s.steps)
    lhs = np.eye(2 * n) - 0.5 * h * a
    step = np.linalg.solve(lhs, np.eye(2 * n) + 0.5 * h * a)
    half = np.linalg.solve(lhs, 0.5 * h * b)
    phi_d, at_k, at_next = np.eye(2 * n), np.zeros((2 * n, m)), np.zeros((2 * n, m))
    for j in range(s.steps):
        w0, w1 = j / s.steps, (j + 1) / s.steps          # weights of p_(k+1) at the sub-steps
        phi_d = step @ phi_d
        at_k = step @ at_k + half * ((1 - w0) + (1 - w1))
        at_next = step @ at_next + half * (w0 + w1)
    f = np.block([[phi_d, at_k + at_next], [np.zeros((m, 2 * n)), np.eye(m)]])
    g = np.vstack([at_next, np.eye(m)])
    residual = s.inv_k - phi @ np.diag(1.0 / w2) @ phi.T
    kg = -s.k_gauge
    c = np.block([[s.probes @ phi, np.zeros((2, n))],
                  [kg * s.gauges @ phi, kg * s.beta * s.gauges @ phi]])
    d = np.vstack([s.probes @ residual @ s.poles.T, kg * s.gauges @ residual @ s.poles.T])
    h = np.hstack([c, d]) / sigma[:, None]
    hz = tuple(float(x) for x in np.sqrt(w2) / (2 * np.pi))
    return StateSpace(F=f, G=g, H=h, n_forces=m, modes_hz=hz)


@dataclass(frozen=True)
class SteadyFilter:
    """The steady-state Kalman filter of a :class:`StateSpace` under random-walk variance q:
    predicted and filtered covariances P, Pf, innovation covariance S, gain K, and the
    augmented state's process noise covariance Q."""

    P: np.ndarray
    Pf: np.ndarray
    S: np.ndarray
    K: np.ndarray
    Q: np.ndarray


def steady_filter(ss: StateSpace, q: float) -> SteadyFilter:
    """The steady state of the filter (the discrete Riccati equation's solution)."""
    qz = q * ss.G @ ss.G.T
    r = np.eye(ss.H.shape[0])
    p = scipy.linalg.solve_discrete_are(ss.F.T, ss.H.T, qz, r)
    p = 0.5 * (p + p.T)
    sc = ss.H @ p @ ss.H.T + r
    k = np.linalg.solve(sc, ss.H @ p).T
    pf = p - k @ sc @ k.T
    return SteadyFilter(P=p, Pf=0.5 * (pf + pf.T), S=sc, K=k, Q=qz)


def _start(ss: StateSpace, y0: np.ndarray) -> np.ndarray:
    """A first state: the forces and the static modal deflection that best explain the first
    sample (no motion)."""
    n2 = ss.F.shape[0] - ss.n_forces
    n = n2 // 2
    # the kept modes' statics under constant forces: the discrete model's fixed point
    fixed = np.linalg.solve(np.eye(n2) - ss.F[:n2, :n2], ss.F[:n2, n2:])     # (n2, m)
    p0 = np.linalg.lstsq(ss.H[:, :n2] @ fixed + ss.H[:, n2:], y0, rcond=None)[0]
    z = np.concatenate([fixed @ p0, p0])
    z[n:n2] = 0.0
    return z


def kalman_filter(ss: StateSpace, kf: SteadyFilter, y: np.ndarray, start: int = START
                  ) -> tuple[np.ndarray, np.ndarray, list[np.ndarray], float]:
    """The forward pass over ``y`` (n_y, n) (weighted): predicted and filtered states
    (n_z, n), the predicted covariances of the first ``start`` samples (the filter's own,
    from :func:`_start` with :data:`START_SCALE` times the steady standard deviations; the
    steady one after), and the innovations' log-likelihood after them."""
    n = y.shape[1]
    nz = ss.F.shape[0]
    zp = np.empty((nz, n))
    zf = np.empty((nz, n))
    f, h = ss.F, ss.H
    qz = kf.Q
    z = _start(ss, y[:, 0])
    p = START_SCALE**2 * kf.P
    covs = []
    ll = 0.0
    sinv = np.linalg.inv(kf.S)
    for j in range(n):
        zp[:, j] = z
        e = y[:, j] - h @ z
        if j < start:
            covs.append(p)
            sc = h @ p @ h.T + np.eye(h.shape[0])
            k = np.linalg.solve(sc, h @ p).T
            gain_off = np.eye(nz) - k @ h                   # the Joseph form: p stays p.d.
            p = f @ (gain_off @ p @ gain_off.T + k @ k.T) @ f.T + qz
            p = 0.5 * (p + p.T)
        else:
            k = kf.K
            ll -= 0.5 * float(e @ sinv @ e)
        z = z + k @ e
        zf[:, j] = z
        z = f @ z
    _, logdet = np.linalg.slogdet(kf.S)
    ll -= 0.5 * (n - start) * (logdet + y.shape[0] * np.log(2 * np.pi))
    return zp, zf, covs, ll


def rts_smoother(ss: StateSpace, kf: SteadyFilter, zp: np.ndarray, zf: np.ndarray,
                 covs: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The Rauch-Tung-Striebel pass: smoothed states (n_z, n), with the filter's own gains
    over its first samples (``covs``, the predicted covariances) and the steady gain after,
    and the smoothed covariance of the steady part (the discrete Lyapunov equation
    P = Pf + J (P - P_pred) J^T)."""
    steady = np.linalg.solve(kf.P, ss.F @ kf.Pf).T
    h = ss.H
    n = zf.shape[1]
    zs = np.empty_like(zf)
    zs[:, -1] = zf[:, -1]
    for j in range(n - 2, -1, -1):
        if j + 1 < len(covs):
            p = covs[j]
            sc = h @ p @ h.T + np.eye(h.shape[0])
            k = np.linalg.solve(sc, h @ p).T
            gain_off = np.eye(len(p)) - k @ h
            pf = gain_off @ p @ gain_off.T + k @ k.T
            j_gain = np.linalg.solve(covs[j + 1], ss.F @ pf).T
        else:
            j_gain = steady
        zs[:, j] = zf[:, j] + j_gain @ (zs[:, j + 1] - zp[:, j + 1])
    cov = scipy.linalg.solve_discrete_lyapunov(steady, kf.Pf - steady @ kf.P @ steady.T)
    return zs, 0.5 * (cov + cov.T)


def augmented_kalman(y: np.ndarray, fs: float, s: Structure, sigma: np.ndarray,
                     mode_top: float = MODE_TOP) -> tuple[np.ndarray, np.ndarray, dict]:
    """The pole forces (2, n) [N] and the total's stated standard deviation [N] (constant:
    the smoother's steady covariance) from ``y`` (4, n), the random walk's variance the
    innovations' maximum likelihood over :data:`Q_GRID`."""
    ss = state_space(s, fs, sigma, mode_top)
    yw = y / sigma[:, None]
    liks = []
    for q in Q_GRID:
        kf = steady_filter(ss, float(q))
        liks.append(kalman_filter(ss, kf, yw, start=0)[3])
    q = float(Q_GRID[int(np.argmax(liks))])
    kf = steady_filter(ss, q)
    zp, zf, covs, _ = kalman_filter(ss, kf, yw)
    zs, cov = rts_smoother(ss, kf, zp, zf, covs)
    settled = float(np.max(np.abs(covs[-1] - kf.P)) / np.max(np.abs(kf.P)))
    m = ss.n_forces
    ones = np.ones(m)
    total_std = float(np.sqrt(ones @ cov[-m:, -m:] @ ones))
    at_edge = int(np.argmax(liks)) in (0, len(Q_GRID) - 1)
    return zs[-m:], np.full(y.shape[1], total_std), {
        "modes_hz": list(ss.modes_hz), "states": int(ss.F.shape[0]), "q_N2": q,
        "q_at_grid_edge": at_edge, "loglik": [float(v) for v in liks],
        "force_std_N": [float(v) for v in np.sqrt(np.diag(cov[-m:, -m:]))],
        "total_std_N": total_std, "start_cov_vs_steady": settled}


# ------------------------------------------------------------------ comparison

def _force_windows(est: pd.DataFrame, truth: pd.DataFrame, column: str, names: list[str],
                   top: float | None = None) -> dict[str, list[float]]:
    """Each force's windows (``column`` with the force's name in place of 'total'), over its
    own AC RMS, and the total's."""
    out = {}
    for name in [*names, "total"]:
        col = column.replace("total", name)
        out[name] = _windows(est, truth.assign(total=truth[name]), col, WIDTH, top)
    return out


def _frame(t: np.ndarray, forces: np.ndarray, names: list[str]) -> pd.DataFrame:
    cols = {"time": t, **{n: forces[k] for k, n in enumerate(names)}}
    cols["total"] = forces.sum(axis=0)
    return pd.DataFrame(cols)


def _channels(folder: Path, run: str, names: list[str]) -> np.ndarray:
    """(4, n) the run's probes and gauges, each less its tare's mean when there is a tare."""
    y = pd.read_csv(folder / "runs" / f"{run}.csv")[names].to_numpy().T
    tare = folder / "runs" / "tare.csv"
    if tare.exists():
        y = y - pd.read_csv(tare)[names].to_numpy().mean(axis=0)[:, None]
    return y


def compare(folder: Path, preset: str, s: Structure) -> dict:
    """Every method on one simulated run of ``preset`` under ``folder``."""
    start = time.perf_counter()
    r = _drive_run(folder, preset)
    forcecal_s = time.perf_counter() - start
    est = pd.read_csv(folder / "out" / f"{preset}.forces.csv")
    truth = pd.read_csv(folder / "truth" / f"{preset}.forces.csv")
    top = float(json.loads((folder / "model.json").read_text())["band"][1])
    forces = [c for c in truth.columns if c not in ("time", "total")]
    t = truth["time"].to_numpy()
    fs = 1.0 / (t[1] - t[0])
    y = _channels(folder, preset, ["s1", "s2", "R1", "R2"])
    sigma = noise_levels(y, fs)

    start = time.perf_counter()
    inv, inv_info = frf_inversion(y, fs, s, sigma)
    inv_s = time.perf_counter() - start
    start = time.perf_counter()
    akf, akf_std, akf_info = augmented_kalman(y, fs, s, sigma)
    akf_s = time.perf_counter() - start
    inv_est, akf_est = _frame(t, inv, forces), _frame(t, akf, forces)

    inner = slice(int(WIDTH * fs), -int(WIDTH * fs))
    err = (akf_est["total"] - truth["total"]).to_numpy()[inner]
    akf_info["observed_to_stated"] = float(np.sqrt(np.mean(err**2)) / akf_std[0])
    akf_info["within_2u"] = float(np.mean(np.abs(err) <= 2 * akf_std[0]))
    frames = {}
    for frame in FRAMES_TRIED:
        other = _frame(t, frf_inversion(y, fs, s, sigma, frame)[0], forces)
        ws = _windows(other, truth, "total", WIDTH)
        frames[str(frame)] = {"worst": max(ws), "worst_inner": max(ws[1:-1]),
                              "worst_in_band": max(_windows(other, truth, "total", WIDTH, top))}
    modes = {}
    for mult in MODES_TRIED:
        other, _, info = augmented_kalman(y, fs, s, sigma, mult)
        other_est = _frame(t, other, forces)
        ws = _windows(other_est, truth, "total", WIDTH)
        modes[str(mult)] = {"modes_hz": info["modes_hz"], "q_N2": info["q_N2"],
                            "worst": max(ws), "worst_inner": max(ws[1:-1]),
                            "worst_in_band": max(_windows(other_est, truth, "total", WIDTH,
                                                          top))}
    full = _frame(t, frf_inversion(y, fs, s, sigma, limited=False)[0], forces)
    passed = _frame(t, np.array([_in_band(x, fs, s.band[1]) for x in akf]), forces)
    methods = {"forcecal": (est, "total"), "frf_inversion": (inv_est, "total"),
               "akf": (akf_est, "total"), "reactions_only": (est, "total_static"),
               "frf_inversion_every_line": (full, "total"), "akf_low_passed": (passed, "total")}
    out: dict = {"band_top_Hz": top, "noise_std": dict(zip(["s1", "s2", "R1", "R2"],
                                                             sigma.tolist(), strict=True)),
                 "seconds": {"forcecal_with_stream": forcecal_s, "frf_inversion": inv_s,
                             "akf_with_q_search": akf_s},
                 "forcecal_ratio_model": r.get("ratio_model")}
    for key, (frame_df, column) in methods.items():
        out[key] = {"windows": _force_windows(frame_df, truth, column, forces),
                    "windows_in_band": _force_windows(frame_df, truth, column, forces, top)}
    out["forcecal"]["check"] = {"windows": r["windows"], "windows_in_band": r["windows_in_band"]}
    out["frf_inversion"]["settings"] = inv_info
    out["frf_inversion"]["frame_lengths"] = frames
    out["akf"]["settings"] = akf_info
    out["akf"]["mode_sets"] = modes
    return out


def run(cases: tuple[tuple[str, str], ...] = CASES) -> dict:
    results: dict = {
        "seed": 0,
        "note": ("both peers take the virtual rig's own finite-element model: the FRF "
                 "inversion its exact FRF (every mode, its damping), the Kalman filter its "
                 "true modes, frequencies and damping and the residual modes' exact static "
                 "flexibility; forcecal learns its model from the SLDV scan. A best case for "
                 "the peers."),
        "frf_inversion": {"frame": FRAME, "overlap": OVERLAP, "window": "hann",
                          "regularisation": "Tikhonov per spectral line and frame, parameter "
                                            "by GCV over 1e-8..1 x the line's largest singular "
                                            "value (81 log steps) and 0",
                          "responses": "s1, s2, R1, R2, each over its noise level",
                          "mean": "the record's mean through the static FRF"},
        "akf": {"mode_top_x_band_top": MODE_TOP, "q_grid_N2": Q_GRID.tolist(),
                "tuning": "maximum likelihood of the steady filter's innovations over the grid",
                "measurements": "s1, s2, R1, R2, each over its noise level",
                "discretisation": "exact, forces linear between samples (first-order hold)"},
        "noise_levels": f"median Welch PSD over {NOISE_BAND[0]:g}-{NOISE_BAND[1]:g} Hz"}
    structures = {p: structure(p) for p in {c[0] for c in cases}}
    with tempfile.TemporaryDirectory() as tmp:
        for preset, realism in cases:
            folder = Path(tmp) / f"{preset}-{realism}"
            start = time.perf_counter()
            write_simulation(folder, preset, seed=0, realism=realism)
            sim_s = time.perf_counter() - start
            res = compare(folder, preset, structures[preset])
            res["seconds"]["simulate"] = sim_s
            results[f"{preset}_{realism}"] = res
    return results


def report(res: dict) -> None:
    labels = (("forcecal", "forcecal"), ("frf_inversion", "FRF inv."), ("akf", "AKF"),
              ("reactions_only", "reactions"))
    for key, r in res.items():
        if not isinstance(r, dict) or "akf" not in r or "settings" not in r["akf"]:
            continue
        inv, akf = r["frf_inversion"]["settings"], r["akf"]["settings"]
        print(f"{key}: total force's RMS error per {WIDTH} s window, % of the window's AC RMS "
              f"(against the truth | without its content above {r['band_top_Hz']:g} Hz)")
        print(f"  {'start [s]':>9} " + " ".join(f"{name:>10}" for _, name in labels) + "  | "
              + " ".join(f"{name:>10}" for _, name in labels))
        n = len(r["forcecal"]["windows"]["total"])
        for k in range(n):
            row = [r[m]["windows"]["total"][k] for m, _ in labels]
            band = [r[m]["windows_in_band"]["total"][k] for m, _ in labels]
            print(f"  {k * WIDTH:9.1f} " + " ".join(f"{v:10.2%}" for v in row) + "  | "
                  + " ".join(f"{v:10.2%}" for v in band))
        for force in [f for f in r["forcecal"]["windows"] if f != "total"]:
            print(f"  {force} worst window: " + ", ".join(
                f"{name} {max(r[m]['windows'][force]):.2%}" for m, name in labels))
        print(f"  FRF inversion: {inv['frame']} samples x {inv['frames']} frames, "
              f"{inv['overlap']:.0%} overlap; GCV chose no regularisation on "
              f"{inv['lambda_zero_share_in_band']:.0%} of the in-band lines x frames, median "
              f"lambda / s_max {inv['lambda_over_smax_in_band_median']:.1e}; worst window by "
              "frame length (all, inner): " + ", ".join(
                  f"{k} {v['worst']:.2%} {v['worst_inner']:.2%}"
                  for k, v in r["frf_inversion"]["frame_lengths"].items()))
        print(f"  AKF: modes {', '.join(f'{f:.0f}' for f in akf['modes_hz'])} Hz, q = "
              f"{akf['q_N2']:.1e} N^2 per sample{' (grid edge)' if akf['q_at_grid_edge'] else ''}"
              f", stated total std {akf['total_std_N']:.2e} N, observed / stated "
              f"{akf['observed_to_stated']:.2f}, {akf['within_2u']:.0%} within 2 u; worst window "
              "by modes kept (all, inner): " + ", ".join(
                  f"{len(v['modes_hz'])} {v['worst']:.2%} {v['worst_inner']:.2%}"
                  for v in r["akf"]["mode_sets"].values()))
        sec = r["seconds"]
        for m, what in (("frf_inversion_every_line", "FRF inversion of every line to fs / 2"),
                        ("akf_low_passed", f"AKF with its content above {r['band_top_Hz']:g} Hz "
                                           "removed")):
            print(f"  {what}: windows " + " ".join(f"{v:.2%}" for v in r[m]["windows"]["total"])
                  + "; in band " + " ".join(f"{v:.2%}"
                                            for v in r[m]["windows_in_band"]["total"]))
        print(f"  seconds: simulate {sec['simulate']:.1f}, forcecal (scan, reconstruct, stream) "
              f"{sec['forcecal_with_stream']:.1f}, FRF inversion {sec['frf_inversion']:.1f}, "
              f"AKF with its q search {sec['akf_with_q_search']:.1f}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--ideal-only", action="store_true", help="skip the lab rig")
    args = parser.parse_args()
    start = time.perf_counter()
    res = run(CASES[:2] if args.ideal_only else CASES)
    res["run_s"] = time.perf_counter() - start
    report(res)
    print(f"run time {res['run_s']:.0f} s")
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "peers.json").write_text(json.dumps(res, indent=1))
    sys.exit(0)

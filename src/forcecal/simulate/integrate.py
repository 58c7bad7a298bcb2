"""Time integration of the beam (or plate) coupled to its electromagnets.

Newmark average acceleration (trapezoidal rule: unconditionally stable, no numerical damping)
for the structure; the coil flux linkage by the same trapezoidal rule; the magnetic force and
the structural motion solved together at every step by Newton's method on the flux linkages.

Under steady sines the record starts on the periodic steady state: passes over a few periods
alternate with a projection of the structure onto the exact discrete periodic response to the
magnetic forces of the last pass, so the slowly decaying free vibration of a lightly damped beam
never has to be waited out. Under a broadband drive (:mod:`.waveforms`) it is waited out: the
rig starts at rest a lead time before the record (:func:`lead_time`).

The trapezoidal rule steps a sine as if at a slightly higher frequency, so a coarse step makes
the rig's inertia heavier than its mass says; under steady sines the step is cut until that
error is negligible (:func:`steady_oversample`). A core's eddy currents are states stepped by
the same rule: a lag core's magnetising current, a solid or laminated one's field (:mod:`.core`).

The time loop itself is compiled (:mod:`.newmark`); this module sets it up in modal
coordinates, finds the steady state and samples the record of the virtual rig (METHOD.md
section 6).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from .beam import BeamModel
from .core import diffusion_step
from .magnet import MU0, Drive, Magnet, Pole, saturated_linkage
from .newmark import CLOSED_GAP, NO_CONVERGENCE, march
from .plate import PlateModel
from .response import Record, Response, _finish_record, _new_record
from .solid import SolidModel

__all__: list[str] = []

Model = BeamModel | PlateModel | SolidModel
"""A finite-element model of the structure: beam, plate or body."""

State = tuple[np.ndarray, np.ndarray, np.ndarray, list[float], list[float], list[float],
              np.ndarray]
"""The stepper's state: modal q, qd, qdd (n_modes,), per magnet the flux linkage [Wb], the coil
current [A] and the magnetising current [A] (the coil current's lagged image with eddy currents
in the core, :attr:`.magnet.Magnet.eddy_time`; unused without), and (n_m, n_x) the field [A] at
the diffusion nodes of every solid or laminated core (:mod:`.core`; unused for the others)."""

LEAD_TIME_CONSTANTS = 10.0
"""A non-periodic drive's record starts after this many decay times ``1 / (zeta omega)`` of
the slowest-decaying elastic mode (its free vibration then down by e^-10, 5e-5; e^-7 when the
magnets' negative stiffness lowers that mode's frequency squared by 30 %)."""
MAX_LEAD = 30.0
"""[s] the longest lead a non-periodic drive is stepped through before its record."""
INERTIA_TOLERANCE = 1e-3
"""Under a steady drive the step is cut until the trapezoidal rule's relative error in the
inertia at twice the fundamental, (w dt)^2 / 6, is at most this (:func:`steady_oversample`)."""


class SimulationError(RuntimeError):
    """The simulated rig left its physical range (pole contact, no convergence)."""


def pole_points(model: Model, poles: Sequence[Pole]) -> np.ndarray:
    """Where the poles act, as ``model.row`` takes them.

    Parameters
    ----------
    model : BeamModel, PlateModel or SolidModel
        The structure; its ``dim`` (1 when absent) says how it takes points.
    poles : sequence of Pole
        The poles.

    Returns
    -------
    array [m]
        x (n,) on a beam, (x, y) (n, 2) on a plate (a model with ``dim == 2``), locations
        (x, y, z, dx, dy, dz) (n, 6) on a body.
    """
    if getattr(model, "dim", 1) == 3:
        return np.array([[p.x, p.y, p.z, *p.direction] for p in poles],
                        dtype=float).reshape(-1, 6)
    if getattr(model, "dim", 1) == 2:
        return np.array([[p.x, p.y] for p in poles], dtype=float).reshape(-1, 2)
    return np.array([p.x for p in poles])


class _Stepper:
    """Newmark stepping of the coupled system in modal coordinates.

    The damping is classical (``C = beta K``: internal to the beam, and a dashpot inside each
    gauge whose force the gauge measures), so Newmark in modal coordinates is exactly Newmark
    in nodal coordinates, at a fraction of the cost per step.
    """

    def __init__(self, model: Model, magnets: Sequence[Magnet], drives: Sequence[Drive],
                 dt: float, beta: float):
        if len(magnets) > 2:
            raise ValueError("at most two independent magnets")
        self.model, self.magnets, self.drives, self.dt = model, magnets, drives, dt
        w2, phi = model.modes
        self.phi = phi                                                      # mass-normalised
        self.w2 = w2
        self.c = beta * w2                                                  # 2 zeta w
        self.keff = w2 + (2 / dt) * self.c + 4 / dt**2
        poles = [p for mg in magnets for p in mg.poles]
        self.pole_rows = model.row(pole_points(model, poles))               # (n_poles, n_dof)
        self.static_gap = np.array([p.gap for p in poles])
        n_m = len(magnets)
        self.S = np.zeros((n_m, len(poles)))                                # magnet <- poles
        j = 0
        for i, mg in enumerate(magnets):
            self.S[i, j:j + len(mg.poles)] = 1.0
            j += len(mg.poles)
        self.force_vectors = self.pole_rows.T @ self.S.T                    # (n_dof, n_m)
        self.modal_force = phi.T @ self.force_vectors                       # (n_modes, n_m)
        self.G = self.modal_force / self.keff[:, None]
        self.pole_modal = self.pole_rows @ phi                              # (n_poles, n_modes)
        self.Hp = self.pole_modal @ self.G                                  # (n_poles, n_m)
        self.HS = self.S @ self.Hp                                          # (n_m, n_m)
        self.turns2 = [mg.turns**2 for mg in magnets]
        self.mu_a = [MU0 * mg.pole_area for mg in magnets]
        self.iron = [mg.iron_gap for mg in magnets]
        self.sat = [mg.saturation_scale for mg in magnets]
        self.res = [mg.resistance for mg in magnets]
        self.voltage_driven = [d.voltage_driven for d in drives]
        self.fscale = [1.0 / (2 * mg.turns**2 * MU0 * mg.pole_area) for mg in magnets]
        self.n_m = n_m
        self.eddy = [float(mg.eddy_time) for mg in magnets]
        self.sp = np.ascontiguousarray(self.S @ self.pole_modal)            # (n_m, n_modes)
        self.gsum0 = self.S @ self.static_gap
        self.coils = (np.array(self.fscale), np.array(self.mu_a), np.array(self.iron),
                      np.array(self.sat), np.array(self.turns2), np.array(self.res),
                      np.array(self.voltage_driven, dtype=bool))
        self.eddy_a = np.array(self.eddy)
        self.cores = _core_steps(magnets, dt)
        for mg, d in zip(magnets, drives, strict=True):
            if mg.eddy_currents and d.voltage_driven:
                what = "eddy_time > 0" if mg.core == "lag" else f"a {mg.core} core"
                raise ValueError(f"magnet {mg.current_channel!r}: {what} needs a current "
                                 "drive (the lag of the magnetising current is modelled for an "
                                 "imposed coil current only)")

    def drive(self, t: float) -> list[float]:
        """The drive of every magnet at time t [s], [A] or [V]."""
        return [float(d.value(t)) for d in self.drives]

    def run(self, t0: float, n_steps: int, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
            lam: list[float], cur: list[float], mag: list[float], nodes: np.ndarray,
            keep_every: int = 0) -> tuple[State, np.ndarray, Record | None]:
        """Advance n_steps from time t0 (modal state q, qd, qdd; coil state lam, cur, mag;
        the cores' diffusion nodes).

        Returns the final state, the magnet forces of every step (n_m, n_steps) and, when
        ``keep_every`` > 0, every keep_every-th sample of the state (time on the last axis).

        Raises
        ------
        SimulationError
            When a pole closes its gap or the magnetic circuit does not converge.
        """
        n_m = self.n_m
        times = t0 + self.dt * np.arange(n_steps + 1)
        drive = np.array([np.broadcast_to(d.value(times), times.shape) for d in self.drives],
                         dtype=float)
        q, qd, qdd = (np.array(x, dtype=float) for x in (q, qd, qdd))
        lam_a = np.array(lam, dtype=float)
        cur_a, mag_a = np.array(cur, dtype=float), np.array(mag, dtype=float)
        nodes_a = np.array(nodes, dtype=float)
        n_keep = n_steps // keep_every if keep_every else 0
        out = _new_record(len(q), n_m, n_keep)
        rec = out if out is not None else _new_record(len(q), n_m, 1)
        assert rec is not None, "a record of one sample"
        forces = np.empty((n_m, n_steps))
        status, _ = march(q, qd, qdd, lam_a, lam_a.copy(), cur_a, mag_a, drive, self.dt,
                          self.c, self.keff, self.G, self.sp, self.gsum0, self.HS,
                          *self.coils, self.eddy_a, self.cores, nodes_a,
                          keep_every if out is not None else 0,
                          forces, rec["q"], rec["qd"], rec["qdd"], rec["lam"], rec["i"],
                          rec["f"], rec["d"])
        if status == CLOSED_GAP:
            raise SimulationError("a pole closed its air gap (pull-in): lower the drive")
        if status == NO_CONVERGENCE:
            raise SimulationError("the magnetic circuit did not converge within a time step")
        state: State = (q, qd, qdd, lam_a.tolist(), cur_a.tolist(), mag_a.tolist(), nodes_a)
        return state, forces, _finish_record(out)

    # ---------------------------------------------------------------- steady state

    def static_state(self, t0: float, values: Sequence[float] | None = None) -> State:
        """Static equilibrium under the coil state of time t0 (quasi-static coil), or under
        the drive ``values`` [A] or [V] of every magnet when given."""
        d = self.drive(t0) if values is None else [float(v) for v in values]
        cur = np.array([d[m] / self.res[m] if self.voltage_driven[m] else d[m]
                        for m in range(self.n_m)])
        q = np.zeros(len(self.w2))
        stiff = np.where(self.w2 > 0, self.w2, np.inf)
        for _ in range(500):
            gaps = self.static_gap - self.pole_modal @ q
            lam = saturated_linkage(np.array(self.turns2) * np.array(self.mu_a) * cur,
                                    self.S @ gaps, np.array(self.iron), np.array(self.sat))
            f = lam**2 * np.array(self.fscale)
            q_new = (self.modal_force @ f) / stiff
            done = np.max(np.abs(q_new - q)) <= 1e-14 * np.max(np.abs(q_new)) + 1e-300
            q = q_new
            if done:
                break
        nodes = np.repeat(cur[:, None], self.cores[1].shape[1], axis=1)   # no field gradient
        return (q, np.zeros_like(q), np.zeros_like(q), lam.tolist(), cur.tolist(), cur.tolist(),
                nodes)

    def periodic_structure(self, t: np.ndarray, forces: np.ndarray, t_end: float, f0: float,
                           n_harm: int = 40) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Exact discrete periodic response of the structure to periodic magnet forces.

        ``forces`` (n_m, n) sampled at ``t`` holds at least one period; returns the modal
        (q, qd, qdd) at ``t_end`` on the discrete steady state of the Newmark recurrence
        (frequency warped: s' = j (2/dt) tan(w dt / 2)).
        """
        w0 = 2 * math.pi * f0
        n = np.arange(1, n_harm + 1)
        basis = np.hstack([np.ones((len(t), 1)), np.cos(np.outer(t, n * w0)),
                           -np.sin(np.outer(t, n * w0))])
        # normal equations: the harmonics over two periods are nearly orthogonal (condition
        # ~1), and the Gram product by einsum stays off the multithreaded BLAS, which a QR of
        # this tall matrix would enter (seconds per call on a loaded machine)
        gram = np.einsum("ti,tj->ij", basis, basis)
        rhs = np.einsum("ti,mt->im", basis, forces)
        coef = np.linalg.solve(gram, rhs)                                   # (2H+1, n_m)
        fh = np.vstack([coef[:1] + 0j, coef[1:n_harm + 1] + 1j * coef[n_harm + 1:]])
        fm = fh @ self.modal_force.T                                        # (H+1, n_modes)
        s = 2j / self.dt * np.tan(np.arange(n_harm + 1) * w0 * self.dt / 2)[:, None]
        qh = fm / (self.w2 + s * self.c + s**2)
        ph = np.exp(1j * np.arange(n_harm + 1) * w0 * t_end)[:, None]
        return ((qh * ph).real.sum(0), (s * qh * ph).real.sum(0),
                (s**2 * qh * ph).real.sum(0))


def _core_steps(magnets: Sequence[Magnet], dt: float) -> tuple[np.ndarray, ...]:
    """The trapezoidal steps of every magnet's core diffusion (:func:`.core.diffusion_step`),
    zero-padded to the most nodes: (diffuse (n_m,) bool, A (n_m, n_x, n_x), b_old, b_new,
    c (n_m, n_x), c_new (n_m,)); a lag core's rows are zero and unused."""
    n_m = len(magnets)
    n_x = max([mg.core_nodes for mg in magnets if mg.core != "lag"], default=1)
    diffuse = np.array([mg.core != "lag" for mg in magnets], dtype=bool)
    a = np.zeros((n_m, n_x, n_x))
    b_old, b_new, c = np.zeros((n_m, n_x)), np.zeros((n_m, n_x)), np.zeros((n_m, n_x))
    c_new = np.zeros(n_m)
    for m, mg in enumerate(magnets):
        if diffuse[m]:
            k = mg.core_nodes
            a[m, :k, :k], b_old[m, :k], b_new[m, :k], c[m, :k], c_new[m] = diffusion_step(
                k, mg.diffusion_time, dt)
    return diffuse, a, b_old, b_new, c, c_new


def integrate(model: Model, magnets: tuple[Magnet, ...], drives: tuple[Drive, ...],
              fs: float, duration: float, oversample: int | None = None,
              settle_periods: int = 3,
              max_passes: int = 8, tol: float = 1e-8, lead: float | None = None) -> Response:
    """Simulate the rig on its steady state and sample it at ``fs`` for ``duration``.

    Under steady sines (no drive with a ``waveform``) the record starts on the periodic steady
    state. Under a broadband drive (any drive with a ``waveform``: a sweep, random, multi-tone,
    a periodic chirp) the rig starts from its static equilibrium under the drives' DC a lead
    time before t = 0 (before the earliest waveform's ``onset`` too) and is stepped through:
    the free vibration of that start has decayed by the record.

    Parameters
    ----------
    model : BeamModel, PlateModel or SolidModel
        The assembled structure with its gauge springs (damping ``beta * stiffness``); a plate
        (``model.dim == 2``) takes each pole at its (x, y), a body at its location.
    magnets : tuple of Magnet
        The electromagnets (at most two).
    drives : tuple of Drive
        One drive per magnet; steady drives share one fundamental frequency.
    fs : float
        Output sampling rate [Hz].
    duration : float
        Record length [s]; the first sample is at t = 0.
    oversample : int, optional
        Internal steps per output sample; default :func:`steady_oversample` of the
        fundamental under steady sines, of the top of the band under a broadband drive.
    settle_periods : int
        Periods stepped per pass towards the steady state.
    max_passes : int
        Most passes towards the steady state.
    tol : float
        Relative change of the modal state between passes that counts as steady.
    lead : float or None
        [s] under a broadband drive, the time stepped before t = 0; None:
        :data:`LEAD_TIME_CONSTANTS` decay times ``1 / (zeta omega)`` of the slowest-decaying
        elastic mode (above 1 Hz), at most :data:`MAX_LEAD`.

    Returns
    -------
    Response
        The record, sampled at ``fs``.

    Raises
    ------
    SimulationError
        When a pole closes its gap or the magnetic circuit does not converge.
    ValueError
        Not one drive per magnet, more than two magnets, or eddy currents (a lag, a solid or a
        laminated core) in a voltage-driven magnet.
    """
    if len(magnets) != len(drives):
        raise ValueError("one drive per magnet")
    f0 = drives[0].frequency
    broadband = any(d.waveform is not None for d in drives)
    if oversample is None:
        oversample = drive_oversample(drives, fs)
    dt = 1.0 / (fs * oversample)
    st = _Stepper(model, magnets, drives, dt, model.beta)
    if broadband:
        return _stepped_through(st, drives, fs, duration, oversample, lead)
    per_period = max(int(round(1.0 / (f0 * dt))), 2)
    n_settle = settle_periods * per_period
    n_out = int(round(duration * fs))
    t_start = -1.0 / fs                       # the first kept sample falls on t = 0
    t = t_start - (max_passes + 1) * n_settle * dt
    state, t = _steady_state(st, st.static_state(t), t, n_settle, per_period, f0, max_passes,
                             tol)
    n_lead = int(round((t_start - t) / dt))
    if n_lead > 0:
        state, _, _ = st.run(t, n_lead, *state)
    _, _, rec = st.run(t_start, n_out * oversample, *state, keep_every=oversample)
    assert rec is not None, "a record of no sample"          # n_out > 0 samples were kept
    return _response(st, rec, n_out, fs)


def steady_oversample(f0: float, fs: float) -> int:
    """Internal steps per output sample under a steady drive at ``f0`` [Hz] sampled at ``fs``.

    The trapezoidal rule steps a sine of angular frequency w as if it were at
    (2 / dt) tan(w dt / 2): its acceleration is -(w^2)(1 + (w dt)^2 / 6 + ...) times its
    displacement, so a rig stepped coarsely weighs more than its mass says, and an estimate
    that is exact for the continuous physics would seem biased by the simulator's own
    error. The step is cut until that error at twice the fundamental (a biased
    electromagnet pulls at f0 and 2 f0) is at most :data:`INERTIA_TOLERANCE`: 1 step per
    sample for the beams at 20 Hz and 10 kHz, 3 for the body at 150 Hz.

    Parameters
    ----------
    f0, fs : float
        [Hz] the fundamental and the output sampling rate.

    Returns
    -------
    int
    """
    x = 2 * math.pi * 2 * f0 / fs
    return max(int(math.ceil(x / math.sqrt(6 * INERTIA_TOLERANCE) - 1e-12)), 1)


def drive_oversample(drives: Sequence[Drive], fs: float) -> int:
    """Internal steps per output sample for ``drives`` sampled at ``fs`` [Hz]:
    :func:`steady_oversample` of the fundamental under steady sines, of the top of the band
    under a broadband drive (on the ``sweep`` preset, 3 steps a sample for a sweep to 150 Hz,
    4 for the scan's chirp to 200 Hz; with one, the rig's inertia at 200 Hz was 0.26 % heavier
    than its mass says)."""
    tops = [d.waveform.band[1] for d in drives if d.waveform is not None]
    return steady_oversample(max(tops) if tops else drives[0].frequency, fs)


def lead_time(model: Model) -> float:
    """The default lead [s] of a broadband drive: :data:`LEAD_TIME_CONSTANTS` decay times
    ``1 / (zeta omega) = 2 / (beta omega^2)`` of the slowest-decaying elastic mode above 1 Hz,
    at most :data:`MAX_LEAD`.

    Parameters
    ----------
    model : BeamModel, PlateModel or SolidModel

    Returns
    -------
    float
    """
    w2 = model.modes[0]
    decay = 0.5 * model.beta * w2[w2 > (2 * math.pi) ** 2]                 # zeta omega [1/s]
    if not len(decay) or np.min(decay) <= 0:
        return MAX_LEAD
    return float(min(LEAD_TIME_CONSTANTS / np.min(decay), MAX_LEAD))


def _stepped_through(st: _Stepper, drives: Sequence[Drive], fs: float, duration: float,
                     oversample: int, lead: float | None) -> Response:
    """:func:`integrate` under a broadband drive: from the static equilibrium under the DC a
    lead before t = 0 (and before every waveform's onset), stepped through the record."""
    dt = st.dt
    t_start = -1.0 / fs                       # the first kept sample falls on t = 0
    start = -(lead_time(st.model) if lead is None else lead)
    for d in drives:
        if d.waveform is not None and d.waveform.onset is not None:
            start = min(start, d.waveform.onset)
    n_lead = max(int(math.ceil((t_start - start) / dt - 1e-9)), 0)
    t = t_start - n_lead * dt
    values = [d.dc if d.waveform is not None else float(d.value(t)) for d in drives]
    state = st.static_state(t, values)
    if n_lead > 0:
        state, _, _ = st.run(t, n_lead, *state)
    n_out = int(round(duration * fs))
    _, _, rec = st.run(t_start, n_out * oversample, *state, keep_every=oversample)
    assert rec is not None, "a record of no sample"          # n_out > 0 samples were kept
    return _response(st, rec, n_out, fs)


def _steady_state(st: _Stepper, state: State, t: float, n_settle: int, per_period: int,
                  f0: float, max_passes: int, tol: float) -> tuple[State, float]:
    """(state, time [s]) on the periodic steady state, from ``state`` at time ``t``.

    Passes of ``n_settle`` steps alternate with a projection of the structure onto the exact
    discrete periodic response to the magnetic forces of the last two periods, until the
    modal displacement changes by less than ``tol`` (relative) or ``max_passes`` are done.
    """
    dt = st.dt
    for _ in range(max_passes):
        state, forces, _ = st.run(t, n_settle, *state)
        times = t + dt * np.arange(1, n_settle + 1)
        t += n_settle * dt
        window = slice(-2 * per_period, None)
        q, qd, qdd = st.periodic_structure(times[window], forces[:, window], t, f0)
        change = np.max(np.abs(q - state[0])) / max(np.max(np.abs(q)), 1e-300)
        state = (q, qd, qdd, *state[3:])
        if change < tol:
            break
    return state, t


def _response(st: _Stepper, rec: Record, n_out: int, fs: float) -> Response:
    """The :class:`Response` of ``n_out`` samples at ``fs`` [Hz] kept in ``rec``."""
    phi = st.phi
    u, v, a = phi @ rec["q"], phi @ rec["qd"], phi @ rec["qdd"]
    gaps = st.static_gap[:, None] - st.pole_rows @ u
    turns = np.sqrt(np.array(st.turns2))[:, None]
    flux = rec["lam"] / turns
    t_out = np.arange(n_out) / fs
    # coil voltage: imposed, or R i + d(lambda)/dt for a current drive
    dlam = np.gradient(rec["lam"], t_out, axis=1) if n_out > 1 else np.zeros_like(rec["lam"])
    res = np.array(st.res)[:, None]
    voltage = np.where(np.array(st.voltage_driven)[:, None], rec["d"], res * rec["i"] + dlam)
    return Response(t=t_out, u=u, v=v, a=a, current=rec["i"], flux=flux, voltage=voltage,
                    pole_force=st.S.T @ rec["f"], gap=gaps)

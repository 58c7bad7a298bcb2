"""The compiled time loop of the rig: Newmark steps of the structure, Newton on the coils.

:class:`.integrate._Stepper` sets the rig up in modal coordinates; :func:`march` steps it.
Every step solves the magnetic force and the structural motion together: the structure's
Newmark (average acceleration) update is linear in the magnets' forces, so Newton runs on the
flux linkages alone (one or two magnets), each coil's flux linkage stepped by the trapezoidal
rule under an imposed voltage, or set by an imposed current. A core with eddy currents lags its
magnetising current behind the coil current, ``tau di_m/dt + i_m = i``, by the same rule; a
solid or laminated core steps the field at its diffusion nodes (:mod:`.core`) by the same rule,
the magnetising current their mean.

The loop and its per-step helpers are compiled (Numba, cached on disk).
"""

from __future__ import annotations

import numba
import numpy as np

from .magnet import KNEE

__all__: list[str] = []

CLOSED_GAP = 1
""":func:`march`'s status when a pole closed its air gap (pull-in)."""
NO_CONVERGENCE = 2
""":func:`march`'s status when Newton on the flux linkages did not converge within a step."""
_NEWTON_STEPS = 40


@numba.njit(cache=True)
def march(q, qd, qdd, lam, lam_prev, cur, mag, drive, dt, c, keff, g, sp, gsum0, hs,
          fscale, mu_a, iron, sat, turns2, res, voltage, eddy, cores, nodes, keep_every, forces,
          rec_q, rec_qd, rec_qdd, rec_lam, rec_i, rec_f, rec_d):  # pragma: no cover - compiled
    """Step the rig ``drive.shape[1] - 1`` times, in place.

    Parameters
    ----------
    q, qd, qdd : (n_modes,) float arrays
        The modal state, advanced in place.
    lam, lam_prev, cur, mag : (n_m,) float arrays
        Per magnet: the flux linkage [Wb] of the step and of the one before (Newton's first
        guess extrapolates them), the coil current [A] and the magnetising current [A],
        advanced in place.
    drive : (n_m, n_steps + 1) float array
        The drives [A] or [V] at the start and after every step.
    dt : float
        [s] the step.
    c, keff : (n_modes,) float arrays
        2 zeta omega per mode, and Newmark's effective stiffness per mode.
    g : (n_modes, n_m) float array
        Modal displacement of the step per unit magnet force.
    sp : (n_m, n_modes) float array
        Each magnet's summed pole gaps' change per unit modal displacement.
    gsum0 : (n_m,) float array
        Each magnet's summed static pole gaps [m].
    hs : (n_m, n_m) float array
        The summed gaps' change of magnet m per unit force of magnet k in the step.
    fscale, mu_a, iron, sat, turns2, res : (n_m,) float arrays
        Force per flux linkage squared, mu_0 times pole area, iron's equivalent gap
        (unsaturated), ``1 / (N A B_s)`` (0: no saturation; :func:`_iron`), turns squared, coil
        resistance.
    voltage : (n_m,) bool array
        Whether the magnet's voltage is imposed (else its current).
    eddy : (n_m,) float array
        [s] each core's eddy-current time (0: none).
    cores : tuple (diffuse, A, b_old, b_new, c, c_new)
        Per magnet: whether its core diffuses (bool (n_m,)), and its step
        (:func:`.core.diffusion_step`, zero-padded to ``n_x`` nodes): (n_m, n_x, n_x),
        (n_m, n_x) three times and (n_m,).
    nodes : (n_m, n_x) float array
        [A] the field at every diffusing core's nodes, advanced in place.
    keep_every : int
        Keep every keep_every-th step's state in the ``rec_*`` rows (0: none).
    forces : (n_m, n_steps) float array
        Filled with every step's magnet forces [N].
    rec_q, rec_qd, rec_qdd : (n_keep, n_modes) float arrays
    rec_lam, rec_i, rec_f, rec_d : (n_keep, n_m) float arrays

    Returns
    -------
    (int, int)
        The status (0, :data:`CLOSED_GAP` or :data:`NO_CONVERGENCE`) and the step it ended on.
    """
    n_modes = q.shape[0]
    n_m = lam.shape[0]
    n_steps = drive.shape[1] - 1
    a0, a1, v4 = 4.0 / dt**2, 2.0 / dt, 4.0 / dt
    q_lin = np.empty(n_modes)
    gsum_lin = np.empty(n_m)
    guess = np.empty(n_m)
    lam_old = np.empty(n_m)
    eff_old = np.empty(n_m)
    eff_new = np.empty(n_m)
    f = np.empty(n_m)
    r = np.empty(n_m)
    jac = np.empty((n_m, n_m))
    step = np.empty(n_m)
    diffuse = cores[0]
    work = np.empty(nodes.shape[1])
    for m in range(n_m):
        eff_old[m] = mag[m] if eddy[m] > 0 or diffuse[m] else drive[m, 0]
    for n in range(n_steps):
        _magnetising_step(n_m, n, mag, eff_new, drive, dt, eddy)
        for m in range(n_m):
            if diffuse[m]:
                mag[m] = _diffusion_step(m, nodes, cores, drive[m, n], drive[m, n + 1], work)
                eff_new[m] = mag[m]
        _linear_prediction(n_modes, q, qd, qdd, c, keff, a0, a1, v4, q_lin)
        _newton_start(n_m, n_modes, lam, lam_prev, lam_old, guess, gsum_lin, gsum0, sp, q_lin)
        status = _newton_flux(n_m, lam, lam_old, cur, eff_old, eff_new, gsum_lin, hs, fscale,
                              mu_a, iron, sat, turns2, res, voltage, dt, f, r, jac, step)
        if status != 0:
            return status, n
        _coil_currents(n_m, n, lam, cur, f, gsum_lin, hs, fscale, mu_a, iron, sat, turns2,
                       voltage, drive, forces)
        _modal_update(n_modes, n_m, q, qd, qdd, q_lin, g, f, a0, a1, v4)
        for m in range(n_m):
            eff_old[m] = eff_new[m]
        if keep_every > 0 and (n + 1) % keep_every == 0:
            _keep_step((n + 1) // keep_every - 1, n_m, n, q, qd, qdd, lam, cur, f, drive,
                       rec_q, rec_qd, rec_qdd, rec_lam, rec_i, rec_f, rec_d)
    return 0, n_steps


@numba.njit(cache=True)
def _magnetising_step(n_m, n, mag, eff_new, drive, dt, eddy):  # pragma: no cover - compiled
    """Every coil's effective drive after step ``n``: the magnetising current stepped through the
    core's lag by the trapezoidal rule, or the drive itself when the core has no eddy currents."""
    for m in range(n_m):
        d_new = drive[m, n + 1]
        if eddy[m] > 0:
            # i_m' = (i_m (tau/dt - 1/2) + (i + i') / 2) / (tau/dt + 1/2)
            mag[m] = ((mag[m] * (eddy[m] / dt - 0.5) + 0.5 * (drive[m, n] + d_new))
                      / (eddy[m] / dt + 0.5))
            eff_new[m] = mag[m]
        else:
            eff_new[m] = d_new


@numba.njit(cache=True)
def _diffusion_step(m, nodes, cores, d_old, d_new, work):  # pragma: no cover - compiled
    """Magnet ``m``'s core field stepped by the trapezoidal rule (its nodes in place), and
    its magnetising current after the step."""
    _, a, b_old, b_new, c, c_new = cores
    n_x = nodes.shape[1]
    for j in range(n_x):
        acc = b_old[m, j] * d_old + b_new[m, j] * d_new
        for k in range(n_x):
            acc += a[m, j, k] * nodes[m, k]
        work[j] = acc
    out = c_new[m] * d_new
    for j in range(n_x):
        nodes[m, j] = work[j]
        out += c[m, j] * work[j]
    return out


@numba.njit(cache=True)
def _linear_prediction(n_modes, q, qd, qdd, c, keff, a0, a1, v4,
                       q_lin):  # pragma: no cover - compiled
    """Newmark's modal displacement of the step without the magnets' forces, into ``q_lin``."""
    for j in range(n_modes):
        q_lin[j] = (a0 * q[j] + v4 * qd[j] + qdd[j] + c[j] * (a1 * q[j] + qd[j])) / keff[j]


@numba.njit(cache=True)
def _newton_start(n_m, n_modes, lam, lam_prev, lam_old, guess, gsum_lin, gsum0, sp,
                  q_lin):  # pragma: no cover - compiled
    """The summed gaps without the magnets' forces, and Newton's first guess of every flux
    linkage, extrapolated from the last two steps (``lam_old`` and ``lam_prev`` keep the last)."""
    for m in range(n_m):
        acc = gsum0[m]
        for j in range(n_modes):
            acc -= sp[m, j] * q_lin[j]
        gsum_lin[m] = acc
        guess[m] = 2.0 * lam[m] - lam_prev[m]
        lam_old[m] = lam[m]
        lam_prev[m] = lam[m]
        lam[m] = guess[m]


@numba.njit(cache=True)
def _newton_flux(n_m, lam, lam_old, cur, eff_old, eff_new, gsum_lin, hs, fscale, mu_a, iron,
                 sat, turns2, res, voltage, dt, f, r, jac, step):  # pragma: no cover - compiled
    """Newton on the flux linkages of the step, ``lam`` updated in place: 0 once converged,
    :data:`CLOSED_GAP` when a pole closes its gap, else :data:`NO_CONVERGENCE`."""
    for _ in range(_NEWTON_STEPS):
        if _newton_residual(n_m, lam, lam_old, cur, eff_old, eff_new, gsum_lin, hs, fscale,
                            mu_a, iron, sat, turns2, res, voltage, dt, f, r, jac):
            return CLOSED_GAP
        _newton_solve(n_m, r, jac, step)
        if _newton_update(n_m, lam, step):
            return 0
    return NO_CONVERGENCE


@numba.njit(cache=True)
def _iron(iron, sat, lam):  # pragma: no cover - compiled
    """The iron path's equivalent gap at the flux linkage ``lam``, ``iron (1 + (|lam| sat)^KNEE)``
    (the B-H curve of :mod:`.magnet`), and its derivative in ``lam``."""
    if sat == 0.0:
        return iron, 0.0
    x = abs(lam) * sat
    xk = x**KNEE
    slope = iron * KNEE * xk / lam if lam != 0.0 else 0.0
    return iron * (1.0 + xk), slope


@numba.njit(cache=True)
def _newton_residual(n_m, lam, lam_old, cur, eff_old, eff_new, gsum_lin, hs, fscale, mu_a,
                     iron, sat, turns2, res, voltage, dt, f, r, jac):  # pragma: no cover - compiled
    """The coils' residuals ``r`` and their Jacobian ``jac`` at the flux linkages ``lam`` (the
    forces ``f`` with them); True when a pole's gap has closed."""
    for k in range(n_m):
        f[k] = lam[k] ** 2 * fscale[k]
    for m in range(n_m):
        gs = gsum_lin[m]
        for k in range(n_m):
            gs -= hs[m, k] * f[k]
        if gs <= 0:
            return True
        fe, dfe = _iron(iron[m], sat[m], lam[m])
        rel = (gs + fe) / mu_a[m]
        if voltage[m]:
            i_m = lam[m] * rel / turns2[m]
            gr = dt / 2 * res[m]
            r[m] = (lam[m] - lam_old[m] - dt / 2 * (eff_old[m] + eff_new[m])
                    + gr * (cur[m] + i_m))
            for k in range(n_m):
                drel = (-hs[m, k] * 2 * lam[k] * fscale[k] + (dfe if k == m else 0.0)) / mu_a[m]
                jac[m, k] = ((1.0 + gr * rel / turns2[m] if k == m else 0.0)
                             + gr * lam[m] / turns2[m] * drel)
        else:
            r[m] = lam[m] - turns2[m] * eff_new[m] / rel
            for k in range(n_m):
                drel = (-hs[m, k] * 2 * lam[k] * fscale[k] + (dfe if k == m else 0.0)) / mu_a[m]
                jac[m, k] = ((1.0 if k == m else 0.0)
                             + turns2[m] * eff_new[m] / rel**2 * drel)
    return False


@numba.njit(cache=True)
def _newton_solve(n_m, r, jac, step):  # pragma: no cover - compiled
    """Newton's step ``jac^-1 r`` for one or two magnets, by Cramer's rule, into ``step``."""
    if n_m == 1:
        step[0] = r[0] / jac[0, 0]
    else:
        det = jac[0, 0] * jac[1, 1] - jac[0, 1] * jac[1, 0]
        step[0] = (jac[1, 1] * r[0] - jac[0, 1] * r[1]) / det
        step[1] = (jac[0, 0] * r[1] - jac[1, 0] * r[0]) / det


@numba.njit(cache=True)
def _newton_update(n_m, lam, step):  # pragma: no cover - compiled
    """``lam`` moved by Newton's step; True when every step is at rounding."""
    done = True
    for m in range(n_m):
        lam[m] -= step[m]
        if abs(step[m]) > 1e-15 * abs(lam[m]) + 1e-30:
            done = False
    return done


@numba.njit(cache=True)
def _coil_currents(n_m, n, lam, cur, f, gsum_lin, hs, fscale, mu_a, iron, sat, turns2,
                   voltage, drive, forces):  # pragma: no cover - compiled
    """The converged step's magnet forces (into ``f`` and column ``n`` of ``forces``) and coil
    currents: from the flux linkage where the voltage is imposed, else the drive."""
    for k in range(n_m):
        f[k] = lam[k] ** 2 * fscale[k]
    for m in range(n_m):
        if voltage[m]:
            gs = gsum_lin[m]
            for k in range(n_m):
                gs -= hs[m, k] * f[k]
            fe, _ = _iron(iron[m], sat[m], lam[m])
            cur[m] = lam[m] * (gs + fe) / mu_a[m] / turns2[m]
        else:
            cur[m] = drive[m, n + 1]
        forces[m, n] = f[m]


@numba.njit(cache=True)
def _modal_update(n_modes, n_m, q, qd, qdd, q_lin, g, f, a0, a1,
                  v4):  # pragma: no cover - compiled
    """Newmark's update of the modal state under the step's magnet forces ``f``, in place."""
    for j in range(n_modes):
        q_new = q_lin[j]
        for m in range(n_m):
            q_new += g[j, m] * f[m]
        dq = q_new - q[j]
        qd_new = a1 * dq - qd[j]
        qdd[j] = a0 * dq - v4 * qd[j] - qdd[j]
        q[j] = q_new
        qd[j] = qd_new


@numba.njit(cache=True)
def _keep_step(k, n_m, n, q, qd, qdd, lam, cur, f, drive, rec_q, rec_qd, rec_qdd, rec_lam,
               rec_i, rec_f, rec_d):  # pragma: no cover - compiled
    """Step ``n``'s state into row ``k`` of the ``rec_*`` arrays."""
    rec_q[k, :] = q
    rec_qd[k, :] = qd
    rec_qdd[k, :] = qdd
    for m in range(n_m):
        rec_lam[k, m] = lam[m]
        rec_i[k, m] = cur[m]
        rec_f[k, m] = f[m]
        rec_d[k, m] = drive[m, n + 1]

"""The magnet's iron core: eddy currents as the flux diffusing into the iron, in depth.

A solid or laminated core is a slab of iron (the core itself, or a lamination) of thickness
``2 d``, conductivity sigma and permeability ``mu = mu_r mu_0``. The coil's MMF sets the field at
both faces, ``H(+-d) = N i / l_fe``, and it diffuses in, ``dH/dt = (1 / (sigma mu)) d^2H/dx^2``:
eddy currents screen the inside. The magnetising current is the iron's mean field,
``i_m = l_fe mean(H) / N``, the flux through the gaps ``N i_m / reluctance`` as a lag core's
(:class:`.magnet.Magnet`). With ``xi = x / d`` from the mid-plane and ``u = l_fe H / N`` [A]::

    du/dt = (1 / tau_d) d^2u/dxi^2,   u(1) = i,   du/dxi(0) = 0,   i_m = int_0^1 u dxi,

``tau_d = sigma mu d^2``. The slab's exact response is ``tanh(sqrt(s tau_d)) / sqrt(s tau_d)``:
first order at low frequency (``1 - s tau_d / 3``), half order above.

The simulator does not use that formula: it discretises the depth by linear finite elements
stepped by the trapezoidal rule with the rest of the rig (:func:`diffusion_step`), and its
truth is that discretised model's own response (:func:`diffusion_response`), which converges
to the closed form by the square of the element size.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

__all__: list[str] = []

CORES = ("lag", "solid", "laminated")
"""A magnet's core: a first-order lag of the magnetising current (``eddy_time``), or the flux
diffusing into a solid core or into thin laminations (``conductivity``, ``core_thickness``)."""
CORE_NODES = 20
"""Finite elements across a slab's half-thickness by default: the discretised response is
within 4e-4 of the slab's closed form in gain, and 0.02 degrees in phase, up to
``w tau_d = 5``."""


def _slab_matrices(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                    np.ndarray, float]:
    """Linear finite elements on ``xi`` in [0, 1], ``n`` equal ones: the interior nodes' mass
    ``M`` and stiffness ``K`` (n, n), the face node's columns ``m_b`` and ``k_b`` (n,), and the
    weights of the mean field, ``c`` (n,) on the interior nodes and ``c_b`` on the face's."""
    h = 1.0 / n
    mass = np.zeros((n + 1, n + 1))
    stiff = np.zeros((n + 1, n + 1))
    for e in range(n):
        idx = np.ix_([e, e + 1], [e, e + 1])
        mass[idx] += np.array([[2.0, 1.0], [1.0, 2.0]]) * h / 6.0
        stiff[idx] += np.array([[1.0, -1.0], [-1.0, 1.0]]) / h
    weights = np.full(n + 1, h)
    weights[[0, -1]] = h / 2.0
    return (mass[:n, :n], stiff[:n, :n], mass[:n, n], stiff[:n, n], weights[:n],
            float(weights[n]))


def diffusion_step(nodes: int, tau_d: float, dt: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """The trapezoidal step of a slab's field: ``u' = A u + b_old i + b_new i'``,
    ``i_m' = c . u' + c_new i'``.

    ``nodes`` linear elements from the mid-plane to the face (consistent mass ``M``, stiffness
    ``K``; the face's node carries the coil's current) give
    ``M u' + m_b i' = -(K u + k_b i) / tau_d`` for the interior nodes, stepped as
    ``(M + a K) u' = (M - a K) u - m_b (i' - i) - a k_b (i + i')``, ``a = dt / (2 tau_d)``;
    ``i_m`` is the exact integral of the elements' field.

    Parameters
    ----------
    nodes : int
        Elements across the half-thickness (the interior nodes stepped).
    tau_d : float
        [s] the diffusion time ``sigma mu d^2``.
    dt : float
        [s] the time step.

    Returns
    -------
    A : (nodes, nodes) array
    b_old, b_new, c : (nodes,) arrays
    c_new : float
    """
    mass, stiff, m_b, k_b, c, c_b = _slab_matrices(nodes)
    a = dt / (2.0 * tau_d)
    lhs = mass + a * stiff
    step = np.linalg.solve(lhs, np.column_stack([mass - a * stiff, m_b - a * k_b,
                                                 -m_b - a * k_b]))
    return (np.ascontiguousarray(step[:, :nodes]), step[:, nodes].copy(),
            step[:, nodes + 1].copy(), c, c_b)


def diffusion_response(frequency: ArrayLike, tau_d: float, nodes: int) -> np.ndarray:
    """The discretised slab's response ``I_m / I`` at ``frequency`` [Hz] (its state space's,
    not the closed form's).

    Parameters
    ----------
    frequency : float or array [Hz]
    tau_d : float
        [s] the diffusion time.
    nodes : int
        Elements across the half-thickness.

    Returns
    -------
    complex array
        Shaped like ``frequency``; 1 at 0 Hz.
    """
    mass, stiff, m_b, k_b, c, c_b = _slab_matrices(nodes)
    f = np.asarray(frequency, dtype=float)
    out = np.empty(f.shape, dtype=complex)
    for k, fk in np.ndenumerate(f):
        s = 2j * np.pi * fk
        u = np.linalg.solve(s * mass + stiff / tau_d, -(s * m_b + k_b / tau_d))
        out[k] = c @ u + c_b
    return out

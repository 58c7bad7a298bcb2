"""What the stepper keeps of a simulated record, and the :class:`Response` it becomes."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__: list[str] = []

Record = dict[str, np.ndarray]
"""Kept samples by name: ``q``, ``qd``, ``qdd`` (modal state) and ``lam``, ``i``, ``f``, ``d``
(flux linkage, current, force and drive value of every magnet)."""


@dataclass(frozen=True)
class Response:
    """What the virtual rig did over the record, sampled at ``fs``.

    Attributes
    ----------
    t : (n_samples,) array [s]
        Sample times, the first at 0.
    u : (n_dof, n_samples) array [m]
        Nodal displacement.
    v : (n_dof, n_samples) array [m/s]
        Nodal velocity.
    a : (n_dof, n_samples) array [m/s^2]
        Nodal acceleration.
    current : (n_magnets, n_samples) array [A]
        Coil current.
    flux : (n_magnets, n_samples) array [Wb]
        Flux through each pole of the magnet.
    voltage : (n_magnets, n_samples) array [V]
        Coil voltage.
    pole_force : (n_poles, n_samples) array [N]
        Force on the structure at each pole, +w.
    gap : (n_poles, n_samples) array [m]
        Air gap at each pole.
    """

    t: np.ndarray
    u: np.ndarray
    v: np.ndarray
    a: np.ndarray
    current: np.ndarray
    flux: np.ndarray
    voltage: np.ndarray
    pole_force: np.ndarray
    gap: np.ndarray


def _new_record(n_modes: int, n_m: int, n_keep: int) -> Record | None:
    """Row-per-sample storage of the kept states (transposed by :func:`_finish_record`)."""
    if not n_keep:
        return None
    out = {k: np.empty((n_keep, n_modes)) for k in ("q", "qd", "qdd")}
    out.update({k: np.empty((n_keep, n_m)) for k in ("lam", "i", "f", "d")})
    return out


def _finish_record(out: Record | None) -> Record | None:
    """Time on the last axis: (n_modes or n_m, n_keep)."""
    if out is None:
        return None
    return {k: np.ascontiguousarray(v.T) for k, v in out.items()}

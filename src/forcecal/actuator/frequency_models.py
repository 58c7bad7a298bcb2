"""The core's response over frequency: how the magnetising current follows the coil current.

A frequency model takes the coil current's phasor ``I`` at ``s = j w`` to the magnetising
current's, ``I_m = H(s; tau) I`` with ``H(0) = 1``; the force is
``f = K i_m^2 sum_p 1 / (s_p + s_fe)^2`` (:mod:`.frequency`). Two models, one time constant
each:

- ``first-order``: ``H = 1 / (1 + s tau)``, a lumped eddy-current loop (``tau di_m/dt + i_m =
  i``); a laminated core is close to it.
- ``half-order``: ``H = tanh(sqrt(s tau)) / sqrt(s tau)``, the flux diffusing into an iron slab
  of half-thickness ``d`` from both faces, ``tau = sigma mu d^2`` (a solid core, Zhu & Knospe
  2010): first order at low frequency (``H ~ 1 - s tau / 3``), half order above
  (``H ~ (s tau)^(-1/2)``, the lag tending to 45 degrees).

Each answers ``response(w, tau) -> (H, dH/dtau)`` on angular frequencies [rad/s] and
``equivalent``, the time constant of the first-order model it matches at low frequency per unit
of its own tau (the fits start and scale from it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError

__all__: list[str] = []


@dataclass(frozen=True)
class FirstOrder:
    """``H = 1 / (1 + s tau)``: a lumped eddy-current loop."""

    name: str = "first-order"
    formula: str = "f = K i_m^2 / (s + s_fe)^2, tau di_m/dt + i_m = i"
    equivalent: float = 1.0
    rank: int = 0

    @staticmethod
    def response(w: np.ndarray, tau: float) -> tuple[np.ndarray, np.ndarray]:
        """H and dH/dtau at the angular frequencies ``w`` [rad/s] (any shape)."""
        d = 1.0 + 1j * w * tau
        return 1.0 / d, -1j * w / d**2


_SERIES = 1e-2
"""Below this ``|s tau|`` the half-order response is taken from its Taylor series (to
``(s tau)^5``: error below 1e-11), where ``tanh(r) / r`` loses digits."""
_TANH_COEF = np.array([1.0, -1.0 / 3, 2.0 / 15, -17.0 / 315, 62.0 / 2835, -1382.0 / 155925])
"""``tanh(sqrt(z)) / sqrt(z) = sum_k c_k z^k``."""


@dataclass(frozen=True)
class HalfOrder:
    """``H = tanh(sqrt(s tau)) / sqrt(s tau)``: the flux diffusing into a slab (a solid
    core)."""

    name: str = "half-order"
    formula: str = "f = K i_m^2 / (s + s_fe)^2, I_m = I tanh(sqrt(s tau)) / sqrt(s tau)"
    equivalent: float = 1.0 / 3.0
    rank: int = 1

    @staticmethod
    def response(w: np.ndarray, tau: float) -> tuple[np.ndarray, np.ndarray]:
        """H and dH/dtau at the angular frequencies ``w`` [rad/s] (any shape)."""
        s = 1j * np.asarray(w, dtype=float)
        z = s * tau
        small = np.abs(z) < _SERIES
        powers = np.arange(_TANH_COEF.size)
        zs = np.where(small, z, 0.0)[..., None]
        h_series = np.sum(_TANH_COEF * zs**powers, axis=-1)
        dz_series = np.sum(_TANH_COEF[1:] * powers[1:] * zs ** (powers[1:] - 1), axis=-1)
        r = np.sqrt(np.where(small, 1.0, z))
        t = np.where(r.real > 20.0, 1.0, np.tanh(np.where(r.real > 20.0, 0.0, r)))
        h = np.where(small, h_series, t / r)
        dz = np.where(small, dz_series, ((1.0 - t * t) * r - t) / (2.0 * r**3))
        return h, s * dz


FrequencyModel = FirstOrder | HalfOrder
"""A model of the core's response."""
FREQUENCY_MODELS: dict[str, FrequencyModel] = {m.name: m for m in (FirstOrder(), HalfOrder())}
"""Every frequency model by name, simplest first: a calibration chooses among them."""


def frequency_model(name: str) -> FrequencyModel:
    """The frequency model called ``name``.

    Parameters
    ----------
    name : str
        A key of :data:`FREQUENCY_MODELS`.

    Returns
    -------
    FirstOrder or HalfOrder

    Raises
    ------
    InputError
        An unknown name.
    """
    try:
        return FREQUENCY_MODELS[name]
    except KeyError:
        raise InputError(f"frequency model {name!r} is unknown (choose from "
                         f"{', '.join(FREQUENCY_MODELS)})") from None

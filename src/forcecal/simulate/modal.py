"""What every finite-element model of the virtual rig offers the integrator: its size and its
undamped modes, computed once per model.

A model is a frozen dataclass with ``stiffness`` and ``mass`` (n_dof, n_dof) arrays that mixes
in :class:`ModalModel`.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
import scipy.linalg

__all__: list[str] = []


class ModalModel:
    """Mixin: ``n_dof`` and ``modes`` from the model's ``stiffness`` and ``mass``."""

    stiffness: np.ndarray
    mass: np.ndarray

    @property
    def n_dof(self) -> int:
        """Number of degrees of freedom."""
        return self.stiffness.shape[0]

    @cached_property
    def modes(self) -> tuple[np.ndarray, np.ndarray]:
        """Undamped modes: ``(w2, phi)``, w2 (n_dof,) [rad^2/s^2] ascending (clipped at 0),
        phi (n_dof, n_dof) mass-normalised (``phi.T M phi = I``). Computed once per model."""
        w2, phi = scipy.linalg.eigh(self.stiffness, self.mass)
        return np.clip(w2, 0.0, None), phi

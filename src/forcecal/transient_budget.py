"""The type-B part of the uncertainty of forces under any drive (GUM; METHOD.md sections 6, 7).

The rig declares the standard uncertainties of its gauges' and probes' sensitivities, of its
positions and of its masses (``[uncertainty]``, :class:`forcecal.rig.TypeB`; defaults when it
declares none). A steady run propagates them through its harmonic solve
(:mod:`forcecal.budget`); under any drive they move the estimate f = Psi^+ (J - R)
(:mod:`forcecal.transient`) sample by sample, each to first order:

- a gauge's sensitivity scales its reaction, R_r (1 + e). The inertia does not follow: the
  structure's transfer from the reactions to the probes' coordinate is fitted on the same
  readings and takes the scale back, so J stays the probes';
- a probe's sensitivity or position moves the first shape's coordinate the probes give,
  q_1 = c^T s, and with it the inertia, by c_j dp_j(nu) / (c^T p(nu)) at every frequency, p
  the operating shape at the probes (:meth:`forcecal.broadband.BroadbandModel.mixing`);
- a gauge's position moves Psi and its mass couplings with every shape, m_r, and a force
  point's Psi alone; the masses move the couplings. The inertia J_r(nu) is proportional to
  m_r . a(nu), so it moves by dm_r . a / (m_r . a).

Each parameter's change of every force and of the total, over the record, is its error in the
estimate for a one-standard-uncertainty error of the parameter; the parameters are
independent, so each sample's variance is the sum of their squares. Against the estimate
itself with each parameter moved (the readings scaled, the rig moved and its couplings
recomputed), these first-order changes hold to 1 % (tests/test_broadband). The split between
the beam's pole forces is sensitive: on the ``sweep`` rig a gauge read 2 % high moves the pole
forces by 42-59 % of their AC RMS and the total by 8 % (the reactions are several times the
force near the first mode); the rig's default uncertainties (no ``[uncertainty]``) raise each
force's median stated uncertainty from 0.003 N to 0.09 N there, the total's from 0.005 N to
0.04 N.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np

from .broadband import BroadbandModel
from .budget import massed_rig, moved_rig
from .inertia import mass_coupling
from .reaction_transfer import filtered
from .relaxation import force_matrix
from .rig import Rig

__all__ = ["TypeBMoves", "type_b_moves", "type_b_notes", "type_b_variance"]


@dataclass(frozen=True)
class TypeBMoves:
    """How each declared type-B parameter, moved by its standard uncertainty, moves the
    estimate under any drive.

    Attributes
    ----------
    names : tuple of str
        Each parameter (``gauges[0].scale``, ``sensors[1].x``, ...).
    pinv : (n_par, n_forces, n_gauges) array
        The change of Psi^+.
    couplings : (n_par, n_gauges, n_shapes) array [kg]
        The change of every gauge's coupling with every shape of the span.
    probes : (n_par, n_probes, n_shapes) array [m]
        The change of the span's shapes at the probes as they read them (a sensitivity
        scales its row, a position moves it).
    gauge : (n_par,) int array
        The gauge whose reading scales by the standard uncertainty (-1: none) ...
    scale : (n_par,) array
        ... and by how much.
    """

    names: tuple[str, ...]
    pinv: np.ndarray
    couplings: np.ndarray
    probes: np.ndarray
    gauge: np.ndarray
    scale: np.ndarray


def type_b_moves(rig: Rig, model: BroadbandModel) -> TypeBMoves | None:
    """Every type-B parameter with a non-zero standard uncertainty, as it moves Psi^+, the
    couplings and the shapes at the probes (central differences over +-u for positions and
    masses); None when the rig declares none."""
    tb = rig.type_b
    n_g, n_p = len(rig.gauges), len(rig.sensors)

    def solved(r: Rig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        at = r.structure.coordinates(r.sensor_points, source=f"rig '{r.source}'")
        return (np.linalg.pinv(force_matrix(r)), np.real(mass_coupling(r, model.values)),
                np.real(model.values(at)))

    base = solved(rig)
    names: list[str] = []
    rows: list[tuple[np.ndarray, ...]] = []
    gauge: list[int] = []
    scale: list[float] = []

    def add(name: str, parts: tuple[np.ndarray, ...], g: int = -1, s: float = 0.0) -> None:
        names.append(name)
        rows.append(parts)
        gauge.append(g)
        scale.append(s)

    zero = tuple(np.zeros_like(b) for b in base)
    for i in range(n_g if tb.gauge_scale > 0 else 0):
        add(f"gauges[{i}].scale", zero, i, tb.gauge_scale)
    for j in range(n_p if tb.probe_scale > 0 else 0):
        probes = np.zeros_like(base[2])
        probes[j] = tb.probe_scale * base[2][j]
        add(f"sensors[{j}].scale", (zero[0], zero[1], probes))
    variants: list[tuple[str, float, Callable[[float], Rig]]] = []
    if tb.position > 0:
        variants += [(f"{group}[{i}].{axis}", tb.position,
                      partial(moved_rig, rig, group, i, axis))
                     for group in ("gauges", "forces", "sensors")
                     for i in range(len(getattr(rig, group))) for axis in rig.structure.axes]
    if tb.mass > 0:
        variants += [(name, tb.mass, partial(massed_rig, rig, k)) for name, k in (
            ("structure (distributed mass)", None),
            *((f"structure.masses[{k}].mass", k) for k in range(len(rig.structure.masses))))]
    for name, u, apply in variants:
        plus, minus = solved(apply(u)), solved(apply(-u))
        add(name, tuple(0.5 * (a - b) for a, b in zip(plus, minus, strict=True)))
    if not names:
        return None
    return TypeBMoves(names=tuple(names), pinv=np.array([r[0] for r in rows]),
                      couplings=np.array([r[1] for r in rows]),
                      probes=np.array([r[2] for r in rows]), gauge=np.array(gauge),
                      scale=np.array(scale))


def type_b_variance(moves: TypeBMoves | None, model: BroadbandModel, probe_shapes: np.ndarray,
                    coordinate_map: np.ndarray, pinv: np.ndarray, acceleration: np.ndarray,
                    inertia: np.ndarray, reactions: np.ndarray, fs: float) -> np.ndarray:
    """(n_forces + 1, N) [N^2]: each force's and the total's variance from the declared type-B
    uncertainties, sample by sample.

    Parameters
    ----------
    moves : TypeBMoves or None
    model : BroadbandModel
        Its couplings are the rig's.
    probe_shapes : (n_probes, n_shapes) array [m]
    coordinate_map : (n_probes,) array [1/m]
    pinv : (n_forces, n_gauges) array
    acceleration : (N,) array [1/s^2]
        The estimate's q''_1.
    inertia, reactions : (n_gauges, N) arrays [N]
        The estimate's J and smoothed R.
    fs : float [Hz]
    """
    n = inertia.shape[-1]
    if moves is None:
        return np.zeros((len(pinv) + 1, n))
    var = np.zeros((len(pinv) + 1, n))
    static = inertia - reactions
    for k in range(len(moves.names)):                           # one at a time: memory

        def response(f: np.ndarray, k: int = k) -> np.ndarray:   # q''_1 -> dJ, (n_g, n_f)
            mix = model.mixing(f)
            seen = coordinate_map @ (probe_shapes @ mix)          # c^T p(nu): beta
            by_probe = coordinate_map @ (moves.probes[k] @ mix) / seen
            return (moves.couplings[k] @ mix + (model.couplings @ mix) * by_probe) / seen

        d_inertia = filtered(np.tile(acceleration, (len(inertia), 1)), fs, response)
        if moves.gauge[k] >= 0:
            d_inertia[moves.gauge[k]] -= moves.scale[k] * reactions[moves.gauge[k]]
        d_force = moves.pinv[k] @ static + pinv @ d_inertia
        var += np.vstack([d_force, d_force.sum(axis=0)]) ** 2
    return var


def type_b_notes(rig: Rig, source: str) -> tuple[str, ...]:
    """The run's note when the rig declares no type-B uncertainties (the defaults used)."""
    return () if rig.type_b.declared else (f"run '{source}': {rig.type_b.describe()}",)

"""The type-B part of the uncertainty budget (GUM; METHOD.md sections 6 and 7).

Noise is not the only source of error in a force estimate: the gauges' and probes' sensitivities
are known to a calibration's uncertainty, the positions of gauges, force points and probes to a
ruler's, the masses to a balance's or a handbook's. The rig declares their standard
uncertainties (``[uncertainty]``, :class:`forcecal.rig.TypeB`); this module propagates them to
every force harmonic and every reported combination (each force, the total, the resultant's
moments).

Linear propagation (GUM 5.1): each parameter theta_i (a gauge's or a probe's scale, one
coordinate of one point, the distributed mass, one lumped mass) is moved by +-u(theta_i) and the
force solve is repeated with the estimate's own formulas (the coordinate map over the members
the run used, the mass couplings recomputed for the moved rig); the central difference is the
sensitivity times u. The parameters are independent, so their variances add; the budget groups
them by source. Monte Carlo (GUM Supplement 1, :func:`monte_carlo`) draws every parameter and
every channel phasor at once and checks the linear propagation. The run's harmonic fits, kept
harmonics and members are held at the estimate's: a type-B error moves the forces, not which
harmonics the data show.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np

from ..model.broadband import BroadbandModel
from ..model.inertia import inertia_term, mass_coupling
from ..model.relaxation import force_matrix
from ..model.spatial import SpatialModel
from ..rig import Rig
from .coordinates import coordinate_map, sensor_weights
from .reaction_transfer import fourier_filter
from .solve import force_solve
from .uncertainty import combinations

__all__ = [
    "SOURCES",
    "Parameter",
    "SolveInputs",
    "combination_phasors",
    "draw_std",
    "monte_carlo",
    "parameters",
    "type_b_notes",
]


# --- from budget ---
SOURCES = ("gauge sensitivity", "probe sensitivity", "positions", "masses")
"""The budget's type-B sources, in the order reported."""


@dataclass(frozen=True)
class SolveInputs:
    """What the force solve of one run needs, held at the estimate's values.

    Attributes
    ----------
    gauges : (n_gauges, H+1) complex ndarray
        [N] reaction phasors in SI, before the tare.
    tare : (n_gauges,) ndarray
        [N] the tare's DC.
    sensors : (n_sensors, H+1) complex ndarray
        [m] probe phasors in SI.
    sensor_std : (n_sensors, H+1) ndarray
        [m] their standard uncertainties.
    gauge_std : (n_gauges, H+1) ndarray
        [N] the reactions' standard uncertainties.
    w0 : float
        [rad/s] the fundamental.
    members : tuple of tuple of int
        Per harmonic of the model, the members of its span the run uses.
    kept, with_inertia : (H+1,) bool ndarray
    ac_coupled : bool
    """

    gauges: np.ndarray
    tare: np.ndarray
    sensors: np.ndarray
    sensor_std: np.ndarray
    gauge_std: np.ndarray
    w0: float
    members: tuple[tuple[int, ...], ...]
    kept: np.ndarray
    with_inertia: np.ndarray
    ac_coupled: bool


Couplings = tuple[np.ndarray, ...]


def model_couplings(rig: Rig, model: SpatialModel) -> Couplings:
    """Per harmonic, the (n_gauges, n_members) mass couplings of the span on ``rig``."""
    return tuple(np.column_stack([mass_coupling(rig, f.evaluate) for f in model.members(k)])
                 for k in range(len(model.harmonics)))


def combination_phasors(rig: Rig, model: SpatialModel, inputs: SolveInputs,
                        couplings: Couplings | None = None) -> np.ndarray:
    """The reported combinations' phasors from fixed inputs: the estimate's force solve.

    Parameters
    ----------
    rig : Rig
        Possibly perturbed (moved points, scaled masses).
    model : SpatialModel
    inputs : SolveInputs
    couplings : tuple of ndarray, optional
        The span's couplings on ``rig`` (default: the model's own).

    Returns
    -------
    (n_combinations, H+1) complex ndarray [N]
    """
    h = inputs.gauges.shape[1] - 1
    at = rig.structure.coordinates(rig.sensor_points)
    reactions = inputs.gauges.copy()
    reactions[:, 0] -= inputs.tare
    inertia = np.zeros_like(reactions)
    for k, n in enumerate(model.harmonics):
        n = int(n)
        if n > h or not inputs.with_inertia[n]:
            continue
        cols = list(inputs.members[k])
        phi = model.member_values(k, at)[:, cols]
        gain, _ = coordinate_map(phi, sensor_weights(inputs.sensor_std[:, n]))
        m = (model.member_couplings(k) if couplings is None else couplings[k])[:, cols]
        inertia[:, n] = inertia_term(m, np.atleast_1d(gain @ inputs.sensors[:, n]),
                                     n * inputs.w0)
    inertia[:, ~inputs.kept] = 0.0
    reactions[:, ~inputs.kept] = 0.0
    force = force_solve(np.linalg.pinv(force_matrix(rig)), inertia, reactions)
    if inputs.ac_coupled:
        force[:, 0] = 0.0
    combo: np.ndarray = combinations(rig)[1] @ force
    return combo


@dataclass(frozen=True)
class Parameter:
    """One type-B parameter: its name (a rig key), its budget source, its standard
    uncertainty and how a deviation ``d`` (in its unit) changes the rig and the inputs."""

    name: str
    source: str
    std: float
    apply: Callable[[float], tuple[Rig, SolveInputs, bool]]
    """d -> (rig, inputs, whether the couplings must be recomputed)."""


@dataclass(frozen=True)
class TypeBSource:
    """One type-B parameter of the rig, whichever drive propagates it.

    Attributes
    ----------
    name : str
        Its dotted key, e.g. ``gauges[0].scale``, ``sensors[1].x``, ``structure.masses[0].mass``.
    source : str
        The budget's source it belongs to (:data:`SOURCES`).
    std : float
        Its standard uncertainty [1 or m].
    channel : str or None
        "gauges" or "sensors" for a sensitivity (it scales channel ``index``), else None.
    index : int
        The channel of a sensitivity.
    rig_at : callable or None
        d -> the rig with the parameter moved by d (positions and masses), else None.
    """

    name: str
    source: str
    std: float
    channel: str | None = None
    index: int = -1
    rig_at: Callable[[float], Rig] | None = None


def type_b_sources(rig: Rig) -> list[TypeBSource]:
    """Every type-B parameter of the rig with a non-zero standard uncertainty, in the order
    both drives propagate them: gauge and probe sensitivities, the positions of gauges, forces
    and probes, the distributed and the lumped masses."""
    tb = rig.type_b
    out: list[TypeBSource] = []
    if tb.gauge_scale > 0:
        out += [TypeBSource(f"gauges[{i}].scale", "gauge sensitivity", tb.gauge_scale,
                            "gauges", i) for i in range(len(rig.gauges))]
    if tb.probe_scale > 0:
        out += [TypeBSource(f"sensors[{i}].scale", "probe sensitivity", tb.probe_scale,
                            "sensors", i) for i in range(len(rig.sensors))]
    if tb.position > 0:
        out += [TypeBSource(f"{group}[{i}].{axis}", "positions", tb.position, None, i,
                            partial(moved_rig, rig, group, i, axis))
                for group in ("gauges", "forces", "sensors")
                for i in range(len(getattr(rig, group))) for axis in rig.structure.axes]
    if tb.mass > 0:
        out += [TypeBSource(name, "masses", tb.mass, None, -1, partial(massed_rig, rig, k))
                for name, k in (("structure (distributed mass)", None),
                                *((f"structure.masses[{k}].mass", k)
                                  for k in range(len(rig.structure.masses))))]
    return out


def central_difference(plus: np.ndarray, minus: np.ndarray) -> np.ndarray:
    """The linear propagation of a type-B parameter (GUM 5.1.3): half the change of a result
    between the parameter moved by +u and by -u."""
    out: np.ndarray = 0.5 * (plus - minus)
    return out


def parameters(rig: Rig, inputs: SolveInputs) -> list[Parameter]:
    """Every type-B parameter of the rig with a non-zero standard uncertainty
    (:func:`type_b_sources`), as it moves the steady estimate's rig and inputs.

    Parameters
    ----------
    rig : Rig
        Its ``type_b`` gives the standard uncertainties.
    inputs : SolveInputs

    Returns
    -------
    list of Parameter
    """
    def scaled(field: str, i: int) -> Callable[[float], tuple[Rig, SolveInputs, bool]]:
        def apply(d: float) -> tuple[Rig, SolveInputs, bool]:
            arr = getattr(inputs, field).copy()
            arr[i] *= 1.0 + d
            changes: dict[str, Any] = {field: arr}
            if field == "gauges":
                changes["tare"] = inputs.tare * np.where(np.arange(len(inputs.tare)) == i,
                                                         1.0 + d, 1.0)
            return rig, dataclasses.replace(inputs, **changes), False
        return apply

    def moved(source: TypeBSource) -> Callable[[float], tuple[Rig, SolveInputs, bool]]:
        rig_at = source.rig_at
        assert rig_at is not None
        recouple = source.source == "masses" or source.name.startswith("gauges[")

        def apply(d: float) -> tuple[Rig, SolveInputs, bool]:
            return rig_at(d), inputs, recouple
        return apply

    return [Parameter(s.name, s.source, s.std,
                      scaled(s.channel, s.index) if s.channel is not None else moved(s))
            for s in type_b_sources(rig)]


def moved_rig(rig: Rig, group: str, i: int, axis: str, d: float) -> Rig:
    """The rig with point ``i`` of ``group`` ("gauges", "forces", "sensors") moved by ``d``
    [m] along ``axis``: a position's type-B parameter."""
    items = list(getattr(rig, group))
    items[i] = dataclasses.replace(items[i], **{axis: getattr(items[i], axis) + d})
    changes: dict[str, Any] = {group: tuple(items)}
    return dataclasses.replace(rig, **changes)


def massed_rig(rig: Rig, k: int | None, d: float) -> Rig:
    """The rig with its distributed mass (``k`` None) or its lumped mass ``k`` scaled by
    ``1 + d``: a mass's type-B parameter."""
    st = rig.structure
    lumped = [1.0 + (d if j == k else 0.0) for j in range(len(st.masses))]
    return dataclasses.replace(rig, structure=st.with_masses(1.0 + d if k is None else 1.0,
                                                              lumped))


def type_b_variance(rig: Rig, model: SpatialModel, inputs: SolveInputs
                    ) -> dict[str, np.ndarray]:
    """Each type-B source's variance of Re and of Im in every combination and harmonic
    (linear propagation). Kept apart: a sensitivity scales a phasor, so its error lies along
    the phasor, not evenly on Re and Im (:func:`pooled_variance` pools them).

    Parameters
    ----------
    rig : Rig
    model : SpatialModel
    inputs : SolveInputs

    Returns
    -------
    dict
        Source (:data:`SOURCES`) -> (n_combinations, H+1, 2) ndarray [N^2]: of Re and of Im
        (the DC's on Re, zero on Im).
    """
    n_c = len(combinations(rig)[0])
    h = inputs.gauges.shape[1] - 1
    out = {s: np.zeros((n_c, h + 1, 2)) for s in SOURCES}
    for p in parameters(rig, inputs):
        ends = []
        for d in (p.std, -p.std):
            rig_p, inp_p, recouple = p.apply(d)
            ends.append(combination_phasors(rig_p, model, inp_p,
                                            model_couplings(rig_p, model) if recouple else None))
        delta = central_difference(ends[0], ends[1])
        out[p.source] += np.stack([delta.real**2, delta.imag**2], axis=-1)
    return out


def pooled_variance(var: np.ndarray) -> np.ndarray:
    """(..., H+1) from the variances of Re and Im (..., H+1, 2): their mean for n >= 1, the
    real DC's for n = 0."""
    pooled: np.ndarray = var.mean(axis=-1)
    pooled[..., 0] = var[..., 0, 0]
    return pooled


def monte_carlo(rig: Rig, model: SpatialModel, inputs: SolveInputs, n_draws: int,
                rng: np.random.Generator, noise: bool = True) -> np.ndarray:
    """GUM Supplement 1: the combinations' phasors over joint draws of every type-B parameter
    (Gaussian, its standard uncertainty: the same parameters as :func:`parameters`) and, with
    ``noise``, of every channel phasor.

    Parameters
    ----------
    rig : Rig
    model : SpatialModel
    inputs : SolveInputs
    n_draws : int
    rng : numpy.random.Generator
    noise : bool
        Draw the gauges' and probes' phasors from their standard uncertainties too (the shape
        coefficients stay at the model's: their part is the linear propagation's).

    Returns
    -------
    (n_draws, n_combinations, H+1) complex ndarray [N]
    """
    tb = rig.type_b
    draws = []
    for _ in range(n_draws):
        g = 1.0 + tb.gauge_scale * rng.standard_normal(len(rig.gauges))
        s = 1.0 + tb.probe_scale * rng.standard_normal(len(rig.sensors))
        inp = dataclasses.replace(inputs, gauges=inputs.gauges * g[:, None],
                                  tare=inputs.tare * g, sensors=inputs.sensors * s[:, None])
        if noise:
            inp = dataclasses.replace(inp, gauges=_jitter(inp.gauges, inp.gauge_std, rng),
                                      sensors=_jitter(inp.sensors, inp.sensor_std, rng))
        cur = drawn_rig(rig, rng)
        draws.append(combination_phasors(cur, model, inp, model_couplings(cur, model)))
    return np.array(draws)


def drawn_rig(rig: Rig, rng: np.random.Generator) -> Rig:
    """The rig with its geometry and masses drawn from their declared type-B uncertainties:
    every coordinate of every gauge, force point and sensor moved by N(0, u_position), the
    distributed mass and each lumped mass scaled by 1 + N(0, u_mass) (in that order of draws).
    A Monte Carlo draw of :func:`monte_carlo`; in a study, the rig a lab would declare for the
    true one."""
    tb = rig.type_b
    st = rig.structure
    moved: dict[str, Any] = {group: tuple(dataclasses.replace(p, **{
                 ax: getattr(p, ax) + tb.position * rng.standard_normal()
                 for ax in st.axes}) for p in getattr(rig, group))
             for group in ("gauges", "forces", "sensors")}
    masses = st.with_masses(1.0 + tb.mass * rng.standard_normal(),
                            (1.0 + tb.mass * rng.standard_normal(len(st.masses))).tolist())
    return dataclasses.replace(rig, structure=masses, **moved)


def draw_std(draws: np.ndarray) -> np.ndarray:
    """(n_combinations, H+1) standard deviation of Monte Carlo draws (n_draws, n_c, H+1): of Re
    and Im pooled for n >= 1, of the real DC for n = 0, as the stated uncertainties are."""
    std: np.ndarray = np.sqrt(0.5 * (draws.real.var(axis=0) + draws.imag.var(axis=0)))
    std[:, 0] = draws[:, :, 0].real.std(axis=0)
    return std


MONTE_CARLO_SOURCES = ("gauge noise", "probe noise", *SOURCES)
"""The budget's sources a :func:`monte_carlo` run draws (the scan shapes' and the unresolved
harmonics' parts stay those of the linear propagation)."""


def _jitter(x: np.ndarray, std: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Phasors drawn about ``x`` with Re and Im of std ``std`` (the DC real)."""
    z = rng.standard_normal(x.shape) + 1j * rng.standard_normal(x.shape)
    z[:, 0] = z[:, 0].real
    out: np.ndarray = x + std * z
    return out


# --- from transient_budget ---
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
    for source in type_b_sources(rig):
        if source.channel == "gauges":
            add(source.name, zero, source.index, source.std)
        elif source.channel == "sensors":
            probes = np.zeros_like(base[2])
            probes[source.index] = source.std * base[2][source.index]
            add(source.name, (zero[0], zero[1], probes))
        else:
            assert source.rig_at is not None
            plus, minus = solved(source.rig_at(source.std)), solved(source.rig_at(-source.std))
            add(source.name, tuple(central_difference(a, b)
                                   for a, b in zip(plus, minus, strict=True)))
    if not names:
        return None
    return TypeBMoves(names=tuple(names), pinv=np.array([r[0] for r in rows]),
                      couplings=np.array([r[1] for r in rows]),
                      probes=np.array([r[2] for r in rows]), gauge=np.array(gauge),
                      scale=np.array(scale))


def series_type_b_variance(moves: TypeBMoves | None, model: BroadbandModel,
                           probe_shapes: np.ndarray, coordinate_map: np.ndarray, pinv: np.ndarray,
                           acceleration: np.ndarray, inertia: np.ndarray, reactions: np.ndarray,
                           fs: float, absorbed: Callable[[np.ndarray], float] | None = None
                           ) -> np.ndarray:
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
    absorbed : callable, optional
        Where the inertia's scale is calibrated in situ: the relative change of that scale a
        change of the total (N,) makes (:func:`forcecal.forces.inertia_scale.scale_shift`);
        each parameter's change then keeps only what the scale does not absorb.
    """
    n = inertia.shape[-1]
    if moves is None:
        return np.zeros((len(pinv) + 1, n))
    var = np.zeros((len(pinv) + 1, n))
    static = inertia - reactions
    by_inertia = (None if absorbed is None
                  else np.vstack([pinv @ inertia, (pinv @ inertia).sum(axis=0)]))
    through = fourier_filter(acceleration[None, :], fs)
    for k in range(len(moves.names)):                           # one at a time: memory

        def response(f: np.ndarray, k: int = k) -> np.ndarray:   # q''_1 -> dJ, (n_g, n_f)
            mix = model.mixing(f)
            seen = coordinate_map @ (probe_shapes @ mix)          # c^T p(nu): beta
            by_probe = coordinate_map @ (moves.probes[k] @ mix) / seen
            return (moves.couplings[k] @ mix + (model.couplings @ mix) * by_probe) / seen

        d_inertia = through(response)                           # (n_g, N)
        if moves.gauge[k] >= 0:
            d_inertia[moves.gauge[k]] -= moves.scale[k] * reactions[moves.gauge[k]]
        d_force = moves.pinv[k] @ static + pinv @ d_inertia
        d_all = np.vstack([d_force, d_force.sum(axis=0)])
        if absorbed is not None and by_inertia is not None:
            d_all += absorbed(d_all[-1]) * by_inertia
        var += d_all**2
    return var


def type_b_notes(rig: Rig, source: str) -> tuple[str, ...]:
    """The run's note when the rig declares no type-B uncertainties (the defaults used)."""
    return () if rig.type_b.declared else (f"run '{source}': {rig.type_b.describe()}",)

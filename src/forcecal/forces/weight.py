"""The tare against the rig's weight: where the gauges were zeroed without the structure on them
(the rig's ``[weight]`` table), a zero-current record reads the structure's weight.

At rest, relaxing gauge r by psi_r, the gauges balance gravity: R_r = g sum_q m_q psi_r(q) u(q)
over the rig's mass quadrature and lumped masses (u: the component along +w, on a body +z,
:meth:`forcecal.structures.Structure.up`). The tare's means less these, d, have the covariance
of the record's noise, the gauges' zeros (``weight.gauge_zero``), their scales
(``uncertainty.gauge_scale``) and the masses (``uncertainty.mass``: the distributed mass and
each lumped mass on its own); d^T C^-1 d is a chi-square of one degree of freedom per gauge,
judged at :data:`~forcecal.forces.diagnostics.FALSE_ALARM` a record. Beyond it the note gives
the mass the gauges carry beyond the rig's, where it sits when that is beyond its noise, and the
mistakes of one parameter that explain d (the distributed mass, a lumped mass, a gauge's scale,
every gauge's, a gauge's zero), the best first. The inertia term rests on the rig's masses: a
mass the rig gets wrong is a force the method gets wrong by the same share of the inertia. A
tare that carries current is not a weight (the other checks name it), and is not checked.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np

from ..model.inertia import mass_weights
from ..records import Run
from ..rig import Rig
from .diagnostics import FALSE_ALARM, chi_square_limit

__all__ = ["weight_notes"]

ALIKE = 4.0
"""Causes whose chi-squares lie within this of the best one's are said to be alike."""
BLOCKS = 10
"""Blocks of the tare record whose means' scatter gives its mean's noise."""
SLIP = 0.5
"""The largest relative error of a mass or a scale named as an explanation: beyond it a value
is not a slip but another mistake (a unit, a part left out), which the note's mass and centre
describe."""
CENTRED = 3.0
"""The extra mass's standard uncertainties beyond which the note says where it sits (a total
within its noise has no centre to speak of: d over a sum near zero)."""
IDLE_CURRENT = 0.05
"""A tare whose current's RMS exceeds this share of the run's is not a weight record (the
magnet would pull there with a share of the run's force near the square of it)."""


def weight_parts(rig: Rig) -> list[tuple[str, np.ndarray]]:
    """Each mass's weight on the gauges: the distributed mass's, then each lumped mass's.

    Returns
    -------
    list of (key, (n_gauges,) ndarray [N])
        The rig key that declares the mass, and the reactions its weight draws at rest.
    """
    assert rig.weight is not None
    st, g, n = rig.structure, rig.weight.gravity, len(rig.structure.masses)

    def weighs(distributed: float, lumped: list[float]) -> np.ndarray:
        alone = dataclasses.replace(rig, structure=st.with_masses(distributed, lumped))
        points, weights = mass_weights(alone)
        out: np.ndarray = weights @ (g * st.up(points))
        return out

    return [(f"structure.{st.mass_field}", weighs(1.0, [0.0] * n)),
            *((f"structure.masses[{k}] ({m.mass:.3g} kg)",
               weighs(0.0, [float(j == k) for j in range(n)])) for k, m in enumerate(st.masses))]


def tare_reactions(rig: Rig, tare: Run) -> tuple[np.ndarray, np.ndarray]:
    """(n_gauges,) [N]: each gauge's mean over the tare record, with its scale; and (n_gauges,)
    [N^2] its variance, from the scatter of the means of :data:`BLOCKS` blocks of the record
    (drift and 1/f noise included)."""
    means, var = [], []
    for g in rig.gauges:
        x = g.scale * np.asarray(tare.channel(g.name), dtype=float)
        blocks = [float(np.mean(b)) for b in np.array_split(x, min(BLOCKS, len(x)))]
        means.append(float(np.mean(x)))
        var.append(float(np.var(blocks, ddof=1)) / len(blocks) if len(blocks) > 1 else 0.0)
    return np.array(means), np.array(var)


class _Misfit(NamedTuple):
    """A tare's reactions against the rig's weight."""

    read: np.ndarray                          # (n_g,) [N] the tare's reactions
    parts: list[tuple[str, np.ndarray]]       # each mass's weight on the gauges
    d: np.ndarray                             # (n_g,) [N] the reactions less the weight
    cov: np.ndarray                           # (n_g, n_g) [N^2] d's covariance
    inv: np.ndarray                           # (n_g, n_g) [1/N^2] its pseudo-inverse

    @property
    def chi_square(self) -> float:
        return float(self.d @ self.inv @ self.d)


def _misfit(rig: Rig, tare: Run) -> _Misfit:
    parts = weight_parts(rig)
    read, noise = tare_reactions(rig, tare)
    d = read - sum((e for _, e in parts), start=np.zeros(len(read)))
    cov = _covariance(rig, read, noise, parts)
    return _Misfit(read, parts, d, cov, np.linalg.pinv(cov))


def weight_chi_square(rig: Rig, tare: Run) -> tuple[float, int]:
    """(chi-square, degrees of freedom) of a tare's reactions against the rig's weight."""
    m = _misfit(rig, tare)
    return m.chi_square, len(m.d)


def _covariance(rig: Rig, read: np.ndarray, noise: np.ndarray,
                parts: list[tuple[str, np.ndarray]]) -> np.ndarray:
    """The covariance of the tare's reactions less the weight's: the record's noise, the
    gauges' zeros and scales, the masses."""
    assert rig.weight is not None
    tb = rig.type_b
    cov = np.diag(noise + rig.weight.gauge_zero**2 + (tb.gauge_scale * read) ** 2)
    for _, e in parts:
        cov += tb.mass**2 * np.outer(e, e)
    return cov


def _causes(rig: Rig, read: np.ndarray, parts: list[tuple[str, np.ndarray]]
            ) -> list[tuple[str, str, np.ndarray]]:
    """(name, form, column): each mistake of one parameter and the change of d per unit of it;
    ``relative`` ones per unit of b with the rig's value off by b / (1 - b) (a mass: -b)."""
    names = rig.gauge_names
    one = np.eye(len(names))
    out = [(key, "mass", e) for key, e in parts]
    out += [(f"gauge '{g}' scale (its 'scale' in the rig)", "relative", read * one[k])
            for k, g in enumerate(names)]
    if len(names) > 1:
        out.append(("every gauge's scale (their 'scale' in the rig)", "relative", read))
    out += [(f"gauge '{g}' zero (its reading without the structure)", "N", one[k])
            for k, g in enumerate(names)]
    return out


def _fitted(d: np.ndarray, inv: np.ndarray, c: np.ndarray) -> tuple[float, float]:
    """(chi-square left, coefficient) of d with the column c's multiple taken out."""
    cc = float(c @ inv @ c)
    if cc <= 0.0:
        return float(d @ inv @ d), 0.0
    a = float(c @ inv @ d) / cc
    r = d - a * c
    return float(r @ inv @ r), a


def _relative(form: str, a: float) -> float:
    """The rig's value against the truth, less 1, of a ``mass`` or ``relative`` cause of
    coefficient ``a`` (inf where no positive truth gives it)."""
    if form == "mass":
        return -a / (1 + a) if a > -1.0 else np.inf
    return a / (1 - a) if a < 1.0 else np.inf


def _plausible(form: str, a: float) -> bool:
    """Whether a cause's size is a slip of one key (at most :data:`SLIP` of its value)."""
    return form == "N" or abs(_relative(form, a)) <= SLIP


def _size_text(name: str, form: str, a: float) -> str:
    if form == "N":
        return f"{name} off by {a:+.3g} N"
    return f"{name} off by {100 * _relative(form, a):+.3g} %"


def _where(rig: Rig, d: np.ndarray, cov: np.ndarray) -> str:
    """The extra mass the gauges carry and, on a beam or plate where it is beyond
    :data:`CENTRED` standard uncertainties, its centre."""
    assert rig.weight is not None
    st = rig.structure
    ups = st.up(st.coordinates(rig.gauge_points))
    total = float(ups @ d)
    text = (f"{abs(total / rig.weight.gravity):.3g} kg {'more' if total > 0 else 'less'} than "
            "the rig's masses")
    if st.directed or abs(total) <= CENTRED * np.sqrt(float(ups @ cov @ ups)):
        return text
    centre = np.asarray(rig.gauge_points, dtype=float)[:, :st.dim].T @ d / total
    return text + ", centred at " + ", ".join(f"{a} = {c:.3g} m"
                                              for a, c in zip(st.axes, centre, strict=False))


def current_rms(rig: Rig, record: Run) -> float:
    """[A] the RMS of a record's coil current (its mean included)."""
    return float(np.sqrt(np.mean(np.square(rig.actuator.current_scale
                                           * record.channel(rig.actuator.current)))))


def weight_notes(rig: Rig, tare: Run | None, driven: float | None, what: str) -> list[str]:
    """A note when a tare's reactions contradict the rig's weight (see the module docstring).

    Parameters
    ----------
    rig : Rig
        With its ``[weight]`` table; without it, or without a tare, nothing is checked.
    tare : Run or None
        The zero-current record.
    driven : float or None
        [A] the RMS current of a record under the drive (the run the tare zeroes, or the
        scan's reference): a tare whose current exceeds :data:`IDLE_CURRENT` of it is not
        weighed, nor one with a current channel when it is None. A tare without the current
        channel is a zero-current record by declaration.
    what : str
        The run, at the start of the note.

    Returns
    -------
    list of str
    """
    if rig.weight is None or tare is None:
        return []
    if rig.actuator.current in tare.channels and (
            driven is None or current_rms(rig, tare) > IDLE_CURRENT * driven):
        return []
    read, parts, d, cov, inv = m = _misfit(rig, tare)
    chi2, dof = m.chi_square, len(d)
    limit = chi_square_limit(dof, FALSE_ALARM)
    if chi2 <= limit:
        return []
    tried = sorted((*_fitted(d, inv, c), name, form) for name, form, c in _causes(rig, read, parts))
    left = chi_square_limit(dof - 1, FALSE_ALARM) if dof > 1 else 0.0
    explain = [t for t in tried if t[0] <= left and _plausible(t[3], t[1])]
    head = (f"{what}: the tare '{tare.source}' reads {float(read.sum()):.4g} N on the gauges "
            f"where the rig's masses weigh {float((read - d).sum()):.4g} N (weight.gravity = "
            f"{rig.weight.gravity:g} m/s^2): {_where(rig, d, cov)}; chi-square {chi2:.3g} for "
            f"{dof} degrees of freedom (chance exceeds {limit:.3g} at a {FALSE_ALARM:g} rate)")
    if not explain:
        c2, a, name, form = tried[0]
        return [f"{head}; no single mistake tried explains it (a mass, a gauge's scale or "
                f"zero); the closest: {_size_text(name, form, a)} (chi-square then {c2:.3g})"]
    alike = sum(1 for t in explain if t[0] - explain[0][0] <= ALIKE)
    said = "; ".join(f"{_size_text(name, form, a)} (chi-square then {c2:.3g})"
                     for c2, a, name, form in explain[:max(alike, 3)])
    return [f"{head}; explained by {said}"
            + (f" (the data cannot tell the first {alike} apart)" if alike > 1 else "")
            + "; the inertia rests on the rig's masses"]

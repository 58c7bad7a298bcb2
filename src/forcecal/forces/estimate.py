"""The result of a force reconstruction: :class:`ForceEstimate`, the forces of one run with
their uncertainties, the inertia term, the reactions-only baseline and the notes, and the
views a user reads them through (a short repr, an HTML table, pandas frames)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol

import numpy as np

from ..errors import InputError
from ..rig import TypeB
from ..signals.fourier_sums import series_at
from .budget import MONTE_CARLO_SOURCES
from .coordinates import Coordinates
from .solve import SPLIT_CONDITION

__all__ = ["SERIES_FORMATS", "Estimate", "ForceEstimate", "inertia_share_of", "series_summary"]

_BLOCK = 1 << 16        # time stamps per block of the per-instant uncertainty


SERIES_FORMATS = ("csv", "hdf5", "mat", "uff")
"""The formats a harmonic estimate's force series is written in, the default first."""


class Estimate(Protocol):
    """What a run's estimate answers under either drive (:class:`ForceEstimate`, steady;
    :class:`forcecal.forces.transient.TransientEstimate`, any drive), and what the one writer
    (:func:`forcecal.io.results.write_estimate`) and the command line read."""

    formats: ClassVar[tuple[str, ...]]
    """The series formats it can be written in, the default first."""

    @property
    def run_name(self) -> str:
        """The run (its file's stem)."""
        ...

    @property
    def force_names(self) -> tuple[str, ...]:
        """The rig's forces, in the order of the rows."""
        ...

    @property
    def time(self) -> np.ndarray:
        """(N,) [s]: the instants of the series."""
        ...

    @property
    def notes(self) -> tuple[str, ...]:
        """What the estimate says of itself: assumptions the data contradict, set-asides."""
        ...

    @property
    def provenance(self) -> dict | None:
        """Where it comes from (:func:`forcecal.provenance.provenance`), when known."""
        ...

    @property
    def inertia_share(self) -> float:
        """The inertia term's share of the total's AC RMS [1]."""
        ...

    def columns(self) -> dict[str, np.ndarray]:
        """Each force and ``total`` over :attr:`time`, with ``_static`` (reactions only) and
        ``_std`` (standard uncertainty) [N], in file order."""
        ...

    def force_over_time(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """One force's (or ``total``'s) samples and their standard uncertainties [N]."""
        ...

    def summary(self) -> dict:
        """The JSON document of the run's forces."""
        ...

    def to_dataframe(self) -> Any:
        """The force series as a pandas DataFrame indexed by time [s]."""
        ...

    def _repr_html_(self) -> str: ...


@dataclass(frozen=True)
class ForceEstimate:
    """The forces of one run.

    Attributes
    ----------
    run_name : str
        The run (its file's stem).
    force_names, gauge_names : tuple of str
        The rig's forces and gauges, in the order of the arrays' rows.
    f0 : float [Hz]
        The run's refined fundamental.
    f0_std : float [Hz]
        Its standard uncertainty.
    harmonics : (H+1,) int array
        0..H; phasors follow the convention of :mod:`forcecal.signals.harmonics`.
    force : (n_forces, H+1) complex array [N]
        The external forces' phasors.
    force_std : (n_forces, H+1) array [N]
        Their standard uncertainties (of Re and of Im each).
    total : (H+1,) complex array [N]
        The forces' sum.
    total_std : (H+1,) array [N]
        Its standard uncertainty.
    static : (n_forces, H+1) complex array [N]
        The reactions-only phasors.
    inertia : (n_gauges, H+1) complex array [N]
        The inertia term J_{r,n}.
    reactions : (n_gauges, H+1) complex array [N]
        The gauges' phasors (the tare's DC taken off).
    with_inertia : (H+1,) bool array
        Harmonics whose inertia came from the scan model.
    kept : (H+1,) bool array
        Harmonics the data support (a shape in the model, or reactions above five times
        their noise); the others are set to zero.
    coordinates : Coordinates
        The generalized coordinates of every harmonic's span.
    time : (n_samples,) array [s]
        The run's sample times.
    series : (n_forces, n_samples) array [N]
        The forces sample by sample.
    static_series : (n_forces, n_samples) array [N]
        -Psi^+ R(t) sample by sample.
    psi_condition : float
        Condition number of the force matrix Psi.
    consistency : (H+1,) array [N]
        |Psi f - (J - R)| per harmonic: the force solve's residual (nonzero with more gauges
        than forces).
    combination_names : tuple of str
        Every force, the total and the resultant's first moments
        (:func:`forcecal.forces.uncertainty.combinations`).
    combination, combination_std : (n_c, H+1) arrays [N, N m]
        Their phasors and standard uncertainties: the noise and the type-B parts combined,
        of Re and of Im pooled (the DC's own for n = 0).
    combination_std_re_im : (n_c, H+1, 2) array [N, N m] or None
        The same, of Re and of Im apart: a sensitivity or a mass scales a phasor, so its part
        lies along the phasor (a phasor along Re has its type-B error on Re, up to sqrt(2)
        times the pooled value).
    dc_observed : bool
        False for AC-coupled gauges (the DC is not estimated).
    notes : tuple of str
        What the estimate noticed (self-checks, defaults, limits).
    budget : dict of str to (n_c, H+1) array [N, N m]
        Each source's standard uncertainty in every combination and harmonic (noise: gauges,
        probes and shapes, unresolved harmonics; type B: :data:`forcecal.forces.budget.SOURCES`);
        their root sum of squares is ``combination_std``.
    type_b : TypeB or None
        The rig's type-B standard uncertainties the budget used.
    monte_carlo_std : (n_c, H+1) array [N, N m] or None
        The standard deviation of a Monte Carlo over the sources
        :data:`forcecal.forces.budget.MONTE_CARLO_SOURCES` (None without one).
    monte_carlo_draws : int
        Its number of draws (0 without one).
    """

    run_name: str
    force_names: tuple[str, ...]
    gauge_names: tuple[str, ...]
    f0: float
    harmonics: np.ndarray
    force: np.ndarray
    force_std: np.ndarray
    total: np.ndarray
    total_std: np.ndarray
    static: np.ndarray
    inertia: np.ndarray
    reactions: np.ndarray
    with_inertia: np.ndarray
    kept: np.ndarray
    coordinates: Coordinates
    time: np.ndarray
    series: np.ndarray
    static_series: np.ndarray
    psi_condition: float
    consistency: np.ndarray
    f0_std: float = 0.0
    combination_names: tuple[str, ...] = ()
    combination: np.ndarray | None = None
    combination_std: np.ndarray | None = None
    combination_std_re_im: np.ndarray | None = None
    dc_observed: bool = True
    notes: tuple[str, ...] = field(default=())
    budget: dict[str, np.ndarray] = field(default_factory=dict)
    type_b: TypeB | None = None
    monte_carlo_std: np.ndarray | None = None
    monte_carlo_draws: int = 0
    provenance: dict | None = None
    dropped_rms: np.ndarray | None = None
    """(n_forces + 1,) [N] the RMS of the harmonics above H that the reactions show and the
    estimate leaves out (``--harmonics``), each force's and the total's; counted in the
    waveform's uncertainty. None when none is left out."""

    formats: ClassVar[tuple[str, ...]] = SERIES_FORMATS

    def columns(self) -> dict[str, np.ndarray]:
        """As :func:`series_columns`."""
        return series_columns(self)

    def force_over_time(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """One force's (or ``total``'s) samples and their standard uncertainties [N]."""
        cols = self.columns()
        return cols[name], cols[f"{name}_std"]

    def summary(self) -> dict:
        """As :func:`estimate_summary`."""
        return estimate_summary(self)

    @property
    def total_series(self) -> np.ndarray:
        """(n_samples,) [N]"""
        return self.series.sum(axis=0)

    @property
    def inertia_share(self) -> float:
        """RMS of the inertia's contribution to the total AC force over the RMS of that force."""
        inertia_total = np.sum(self.inertia_force[:, 1:], axis=0)
        return float(np.sqrt(np.sum(np.abs(inertia_total) ** 2))
                     / np.sqrt(np.sum(np.abs(self.total[1:]) ** 2)))

    @property
    def inertia_force(self) -> np.ndarray:
        """(n_forces, H+1) complex [N]: the inertia's contribution Psi^+ J_n to each force."""
        return self.force - self.static

    def expanded(self, k: float = 2.0) -> np.ndarray:
        """(n_c, H+1) [N, N m]: expanded uncertainties k u of every combination and harmonic
        (k = 2: about 95 % coverage for a normal distribution)."""
        assert self.combination_std is not None
        out: np.ndarray = k * self.combination_std
        return out

    @property
    def waveform_std(self) -> float:
        """Standard uncertainty [N] of the total force waveform (RMS over the record, AC part).

        The phasors' uncertainties, plus the fundamental's: an error df in f0 turns harmonic n
        by 2 pi n df (t - t_mid), whose mean square over a record of duration T is
        (2 pi n df)^2 T^2 / 12.
        """
        n = self.harmonics[1:]
        duration = self.time[-1] - self.time[0] if self.time.size > 1 else 0.0
        drift = (2 * np.pi * n * self.f0_std * duration) ** 2 / 12 * np.abs(self.total[1:]) ** 2 / 2
        dropped = 0.0 if self.dropped_rms is None else float(self.dropped_rms[-1]) ** 2
        return float(np.sqrt(np.sum(self.total_std[1:] ** 2) + np.sum(drift) + dropped))

    def _fundamentals(self) -> list[tuple[str, float, float, float]]:
        """(name, |F_1|, its std, reactions-only |F_1|) [N] of every force and the total."""
        if self.force.shape[1] < 2:
            return []
        f, std, st = (np.vstack([a, a.sum(axis=0)]) for a in (self.force, self.force_std,
                                                              self.static))
        std[-1] = self.total_std
        return [(name, float(abs(f[k, 1])), float(std[k, 1]), float(abs(st[k, 1])))
                for k, name in enumerate((*self.force_names, "total"))]

    def __repr__(self) -> str:
        """One line: the run, its fundamental, every force's |F_1| with std, the inertia share."""
        amps = ", ".join(f"{name} {a:.4g} ± {s:.2g}" for name, a, s, _ in self._fundamentals())
        return (f"ForceEstimate(run '{self.run_name}', f0 = {self.f0:.6g} Hz, "
                f"|F_1| [N]: {amps or 'none'}; inertia share {self._share()})")

    def _share(self) -> str:
        return f"{100 * self.inertia_share:.1f} %" if np.any(self.total[1:]) else "n/a"

    def _repr_html_(self) -> str:
        """A small table for notebooks: per force, |F_1| with std and the reactions-only one."""
        from html import escape

        rows = "".join(f"<tr><td>{escape(n)}</td><td>{a:.4g}</td><td>{s:.2g}</td>"
                       f"<td>{r:.4g}</td></tr>" for n, a, s, r in self._fundamentals())
        return (f"<p><b>ForceEstimate</b> of run '{escape(self.run_name)}': f<sub>0</sub> = "
                f"{self.f0:.6g} Hz, inertia share {self._share()}</p><table><tr><th>force</th>"
                "<th>|F<sub>1</sub>| [N]</th><th>std [N]</th>"
                f"<th>reactions only [N]</th></tr>{rows}</table>")

    @staticmethod
    def _pandas() -> Any:
        import pandas  # type: ignore[import-untyped]  # imported on use only

        return pandas

    def to_dataframe(self) -> Any:
        """The force series as a pandas DataFrame: index ``time`` [s], the columns of
        :meth:`columns`, those of ``NAME.forces.csv``: every force and ``total``, the same with
        suffix ``_static`` (reactions only) and with suffix ``_std`` (standard uncertainty at
        each instant) [N]. Example: ``est.to_dataframe()[["total", "total_std"]]``."""
        pd = self._pandas()
        return pd.DataFrame(self.columns(), index=pd.Index(self.time, name="time"))

    def harmonics_frame(self) -> Any:
        """Every force's harmonics as a pandas DataFrame, index (``force``, ``harmonic``):
        ``amplitude`` |F_n| [N], ``phase`` [rad], ``std`` [N] (of Re and of Im),
        ``static_amplitude`` (reactions only) [N], ``with_inertia``, ``kept`` (bool). A
        harmonic the data do not support (``kept`` false) has no estimate: NaN in its
        amplitudes, phase and std. Example: ``est.harmonics_frame().loc["F1", "amplitude"]``."""
        pd = self._pandas()
        n_f = len(self.force_names)
        index = pd.MultiIndex.from_product(
            [list(self.force_names), [int(n) for n in self.harmonics]], names=["force", "harmonic"])
        dropped = ~np.tile(self.kept.astype(bool), n_f)

        def known(values: np.ndarray) -> np.ndarray:
            return np.where(dropped, np.nan, values.ravel())

        return pd.DataFrame({
            "amplitude": known(np.abs(self.force)), "phase": known(np.angle(self.force)),
            "std": known(self.force_std), "static_amplitude": known(np.abs(self.static)),
            "with_inertia": np.tile(self.with_inertia.astype(bool), n_f),
            "kept": ~dropped}, index=index)


_HarmonicRows = list[dict[str, int | float | bool | dict[str, float]]]
"""One JSON object per harmonic the data support, in harmonic order."""


def estimate_summary(est: ForceEstimate) -> dict:
    """The JSON document of one run's forces.

    Parameters
    ----------
    est : ForceEstimate
        The run's estimate.

    Returns
    -------
    dict
        Fundamental, per-harmonic phasors with standard uncertainties (forces, total, and the
        resultant's first moments and, on a body, components), inertia share, conditioning
        figures and generalized coordinates, ready for :func:`json.dumps`.
    """
    forces = {name: _harmonic_rows(est, est.force[k], est.force_std[k], est.static[k],
                                   _budget(est, name), _re_im(est, name))
              for k, name in enumerate(est.force_names)}
    forces["total"] = _harmonic_rows(est, est.total, est.total_std, est.static.sum(axis=0),
                                     _budget(est, "total"), _re_im(est, "total"))
    resultant, components = _resultant_rows(est)
    c = est.coordinates
    return {
        "run": est.run_name,
        "fundamental_hz": est.f0,
        "fundamental_std_hz": est.f0_std,
        "dc_observed": est.dc_observed,
        "forces": forces,
        "resultant_moments": resultant,
        **({"resultant_components": components} if components else {}),
        "split_well_determined": bool(est.psi_condition <= SPLIT_CONDITION),
        "inertia_share": est.inertia_share,
        "waveform_std_n": est.waveform_std,
        "uncertainty": {
            "coverage_factor": 2,
            "budget_sources": list(est.budget),
            **({} if est.monte_carlo_std is None else {"monte_carlo": {
                "draws": est.monte_carlo_draws, "sources": list(MONTE_CARLO_SOURCES),
                "linear_same_sources": "budget_std_n of those sources, root sum of squares"}}),
            **({} if est.type_b is None else {
                "type_b": {k: getattr(est.type_b, k) for k in type(est.type_b).KEYS},
                "type_b_declared": est.type_b.declared,
                "type_b_text": est.type_b.describe()}),
        },
        "conditioning": {
            "psi_condition_number": est.psi_condition,
            "force_consistency_residual_n": est.consistency.tolist(),
            "sensor_gain": {str(int(n)): float(g)
                            for n, g in zip(c.harmonics, c.gain, strict=True)},
            "sensor_chi2": {str(int(n)): (None if not np.isfinite(x) else float(x))
                            for n, x in zip(c.harmonics, c.chi2, strict=True)},
        },
        "generalized_coordinates": [
            {"harmonic": int(n), "re": float(q.real), "im": float(q.imag), "std": float(s),
             **({} if not c.members or c.members[k] == (0,) else {
                 "shapes": [int(j) for j in c.members[k]],
                 "span": [{"re": float(v.real), "im": float(v.imag),
                           "std": float(np.sqrt(c.q_cov[k][i, i].real))}
                          for i, v in enumerate(c.q_span[k])]})}
            for k, (n, q, s) in enumerate(zip(c.harmonics, c.q, c.q_std, strict=True))
        ],
        "notes": list(est.notes),
    }


def _budget(est: ForceEstimate, name: str) -> dict[str, np.ndarray]:
    """Each uncertainty source's (H+1,) standard uncertainty of combination ``name`` (and the
    Monte Carlo's, under ``monte carlo``, when one was run)."""
    if not est.budget or name not in est.combination_names:
        return {}
    k = est.combination_names.index(name)
    out = {source: std[k] for source, std in est.budget.items()}
    if est.monte_carlo_std is not None:
        out["monte carlo"] = est.monte_carlo_std[k]
    return out


def _re_im(est: ForceEstimate, name: str) -> np.ndarray | None:
    """(H+1, 2) standard uncertainties of Re and of Im of combination ``name``, if known."""
    if est.combination_std_re_im is None or name not in est.combination_names:
        return None
    out: np.ndarray = est.combination_std_re_im[est.combination_names.index(name)]
    return out


def _harmonic_rows(est: ForceEstimate, ph: np.ndarray, std: np.ndarray,
                   static: np.ndarray | None,
                   budget: dict[str, np.ndarray] | None = None,
                   re_im: np.ndarray | None = None) -> _HarmonicRows:
    """Rows of one force's phasors ``ph`` (H+1,) [N] and their uncertainties ``std`` (H+1,)
    [N] (expanded, k = 2, beside; each source's part when ``budget`` is given), with the
    reactions-only amplitude when ``static`` (H+1,) [N] is given."""
    rows: _HarmonicRows = []
    for n in est.harmonics:
        if not est.kept[n]:
            continue
        row: dict[str, int | float | bool | dict[str, float]] = {
            "harmonic": int(n),
            "frequency_hz": float(n * est.f0),
            "amplitude_n": float(abs(ph[n])),
            "phase_rad": float(np.angle(ph[n])),
            "std_n": float(std[n]),
            "expanded_k2_n": float(2 * std[n]),
            "inertia_compensated": bool(est.with_inertia[n]),
        }
        if re_im is not None and n > 0:
            row["std_re_n"], row["std_im_n"] = float(re_im[n, 0]), float(re_im[n, 1])
        if budget:
            row["budget_std_n"] = {src: float(b[n]) for src, b in budget.items()
                                   if src != "monte carlo"}
            if "monte carlo" in budget:
                row["monte_carlo_std_n"] = float(budget["monte carlo"][n])
        if static is not None:
            row["static_amplitude_n"] = float(abs(static[n]))
        rows.append(row)
    return rows


def _resultant_rows(est: ForceEstimate) -> tuple[dict[str, _HarmonicRows],
                                                   dict[str, _HarmonicRows]]:
    """Rows of the resultant's first moments [N m] and of a body's resultant vector [N]."""
    resultant: dict[str, _HarmonicRows] = {}
    components: dict[str, _HarmonicRows] = {}
    if est.combination is None or est.combination_std is None:
        return resultant, components
    for k, name in enumerate(est.combination_names):
        if name.startswith(("moment", "resultant")):
            target = resultant if name.startswith("moment") else components
            target[name] = _harmonic_rows(est, est.combination[k], est.combination_std[k], None,
                                          _budget(est, name))
    return resultant, components


def waveform_std_series(est: ForceEstimate, start: int = 0, stop: int | None = None
                        ) -> np.ndarray:
    """Standard uncertainty of every force and of the total at each time stamp (those of
    samples ``start`` to ``stop`` - 1, default all: the same values as the whole's).

    The phasors' uncertainties propagate as in :attr:`ForceEstimate.waveform_std`: harmonic n
    enters x(t) as Re(X_n) cos(n w0 t) - Im(X_n) sin(n w0 t), whose variance is
    ``std_n**2`` (Re and Im each have the standard uncertainty ``std_n``), and the DC its own
    ``std_0**2``. An error df in the fundamental turns harmonic n by 2 pi n df (t - t_mid):
    the waveform moves by (df / f0) (t - t_mid) dx/dt, zero at mid-record and largest at its
    ends. The two are independent:

        u(t)**2 = sum_n std_n**2 + (f0_std / f0)**2 (t - t_mid)**2 (dx_AC/dt)**2,

    plus the mean square of the harmonics left out (:attr:`ForceEstimate.dropped_rms`).

    Over the record, the RMS of u(t) without the DC term is the estimate's ``waveform_std``
    for the total (to the sampling of the record).

    Parameters
    ----------
    est : ForceEstimate
        The run's estimate.
    start, stop : int, optional
        The samples, ``stop`` None for the last (a writer's block of rows).

    Returns
    -------
    (n_forces + 1, stop - start) ndarray [N]
        One row per force in ``est.force_names`` order, then the total (its phasors'
        uncertainties ``est.total_std`` account for the correlation between the forces).
    """
    phasors = np.vstack([est.force, est.total[None, :]])
    std = np.vstack([est.force_std, est.total_std[None, :]])
    t = np.asarray(est.time, dtype=float)
    stop = t.size if stop is None else min(stop, t.size)
    out = np.empty((phasors.shape[0], max(stop - start, 0)))
    out[:] = np.sum(std**2, axis=1)[:, None]
    if est.dropped_rms is not None:
        out += (est.dropped_rms**2)[:, None]
    if est.f0_std != 0.0 and t.size > 1:
        # dx_AC/dt has the phasors j n w0 X_n; a block of time stamps at a time, so that
        # memory holds the result and no more; the blocks are the whole record's, each
        # evaluated whole, so that any part has the whole's values
        rate = phasors * (1j * 2.0 * np.pi * est.f0 * np.arange(phasors.shape[1]))
        t_mid = 0.5 * (t[0] + t[-1])
        for s in range(start - start % _BLOCK, stop, _BLOCK):
            part = t[s:s + _BLOCK]
            drift = (est.f0_std / est.f0 * (part - t_mid) * series_at(rate, est.f0, part)) ** 2
            a, b = max(s, start), min(s + _BLOCK, stop)
            out[:, a - start:b - start] += drift[:, a - s:b - s]
    return np.sqrt(out, out=out)


def series_columns(est: ForceEstimate, start: int = 0, stop: int | None = None
                   ) -> dict[str, np.ndarray]:
    """The columns of the force series after ``time``, in file order (their rows ``start``
    to ``stop`` - 1, default all: a writer's block of rows has the whole's values).

    Parameters
    ----------
    est : ForceEstimate
        The run's estimate.
    start, stop : int, optional
        The rows, ``stop`` None for the last.

    Returns
    -------
    dict name -> (stop - start,) ndarray [N]
        Every force and ``total``; the same with suffix ``_static`` (reactions only); the same
        with suffix ``_std`` (:func:`waveform_std_series`).

    Raises
    ------
    InputError
        Two columns of one name (a force named like another's ``_static`` or ``_std``).
    """
    names = (*est.force_names, "total")
    rows = slice(start, stop)
    series, static_series = est.series[:, rows], est.static_series[:, rows]   # views
    static = [*static_series, static_series.sum(axis=0)]
    values = [*series, series.sum(axis=0), *static, *waveform_std_series(est, start, stop)]
    keys = [*names, *(f"{n}_static" for n in names), *(f"{n}_std" for n in names)]
    columns = dict(zip(keys, values, strict=True))
    if len(columns) != len(keys):
        twice = sorted({k for k in keys if keys.count(k) > 1})
        raise InputError(f"run '{est.run_name}': the force columns {', '.join(twice)} would be "
                         "written twice; rename the rig's forces")
    return columns


def series_summary(columns: dict[str, np.ndarray], force_names: tuple[str, ...]) -> dict:
    """Every force's and the total's mean, AC RMS and RMS uncertainty [N], and the
    reactions-only total's AC RMS, from an estimate's :meth:`~Estimate.columns` over time."""
    def rms(x: np.ndarray) -> float:
        return float(np.sqrt(np.mean((x - x.mean()) ** 2)))

    def quad(s: np.ndarray) -> float:
        return float(np.sqrt(np.mean(s**2)))

    def row(name: str) -> dict[str, float]:
        return {"mean_n": float(columns[name].mean()), "ac_rms_n": rms(columns[name]),
                "std_n": quad(columns[f"{name}_std"])}

    return {"forces": {n: row(n) for n in force_names}, "total": row("total"),
            "static_total_ac_rms_n": rms(columns["total_static"])}


def inertia_share_of(total: np.ndarray, static_total: np.ndarray) -> float:
    """RMS of the AC inertia term's part in a total force series over the AC total's RMS [1]:
    the part is the total less its reactions-only estimate ``static_total`` [N]."""
    ac = total - total.mean()
    part = (total - static_total) - (total - static_total).mean()
    rms = float(np.sqrt(np.mean(ac**2)))
    return float(np.sqrt(np.mean(part**2))) / rms if rms > 0 else 0.0

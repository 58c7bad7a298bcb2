"""Repeatability over repeated runs (paper fig. 9): the spread of K, mean force and amplitude.

Runs that share their static gaps and labels but for ``repeat`` are repeats of one setpoint;
their spread, pooled over the setpoints, is what the campaign says about repeatability.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..io.manifest import ManifestEntry
from .runs import RunResult

__all__: list[str] = []

_Setpoint = tuple[Any, ...]
"""``(gap, sorted per-pole gaps, sorted labels but repeat)`` of a manifest row."""


@dataclass(frozen=True)
class Repeatability:
    """Spread over repeated runs (same static gap and labels but for ``repeat``).

    Attributes
    ----------
    groups : tuple of dict
        One per setpoint with two runs or more: ``key`` (labels), ``runs``, per run ``k_total``
        (the chosen law's K refitted to that run alone, its other parameters kept) ``mean_force``
        [N] and ``amplitude`` [N] (fundamental of the total), and their relative standard
        deviations.
    k_total_rel_std : float or None [-]
        Pooled relative standard deviation of the per-run K over the groups.
    mean_force_rel_std : float or None [-]
        Pooled relative standard deviation of the mean force.
    amplitude_rel_std : float or None [-]
        Pooled relative standard deviation of the fundamental's amplitude.
    """

    groups: tuple[dict[str, Any], ...] = ()
    k_total_rel_std: float | None = None
    mean_force_rel_std: float | None = None
    amplitude_rel_std: float | None = None


def _rel_std(values: Sequence[float]) -> float:
    """Sample standard deviation over the absolute mean [-]."""
    v = np.asarray(values, dtype=float)
    return float(np.std(v, ddof=1) / abs(np.mean(v)))


def _pooled(values: list[float]) -> float | None:
    """RMS of relative standard deviations, None when there are none."""
    return float(np.sqrt(np.mean(np.square(values)))) if values else None


def _setpoint(entry: ManifestEntry) -> _Setpoint:
    """Runs sharing this key are repeats of one setpoint."""
    labels = tuple(sorted((k, v) for k, v in entry.labels.items() if k != "repeat"))
    return (entry.gap, tuple(sorted(entry.gaps.items())), labels)


def _group_row(
    key: _Setpoint,
    members: list[int],
    results: Sequence[RunResult],
    run_k: np.ndarray,
    ac_only: bool,
) -> dict[str, Any]:
    """The JSON-ready row of one repeated setpoint."""
    ks = [float(run_k[k]) for k in members]
    means = [float(results[k].estimate.total[0].real) for k in members]
    amps = [float(abs(results[k].estimate.total[1])) for k in members]
    row: dict[str, Any] = {
        "gap": key[0],
        "gaps": dict(key[1]),
        "labels": dict(key[2]),
        "runs": [results[k].name for k in members],
        "k_total": ks,
        "amplitude": amps,
        "amplitude_rel_std": _rel_std(amps),
    }
    if np.all(np.isfinite(ks)):
        row["k_total_rel_std"] = _rel_std(ks)
    if not ac_only:
        row["mean_force"] = means
        row["mean_force_rel_std"] = _rel_std(means)
    return row


def repeatability(results: Sequence[RunResult], run_k: np.ndarray, ac_only: bool) -> Repeatability:
    """The spread over the repeated setpoints of a campaign.

    Parameters
    ----------
    results : sequence of RunResult
        The reconstructed runs.
    run_k : (n_runs,) array [N m^2/A^2]
        The chosen law's K_total refitted to each run alone (NaN for laws without K).
    ac_only : bool
        The gauges are AC-coupled: the mean force is not measured and not reported.

    Returns
    -------
    Repeatability
        One row per repeated setpoint and the pooled relative standard deviations.
    """
    groups: dict[_Setpoint, list[int]] = {}
    for k, r in enumerate(results):
        groups.setdefault(_setpoint(r.entry), []).append(k)
    rows = [
        _group_row(key, members, results, run_k, ac_only)
        for key, members in groups.items()
        if len(members) >= 2
    ]
    k_std = [row["k_total_rel_std"] for row in rows if "k_total_rel_std" in row]
    mean_std = [row["mean_force_rel_std"] for row in rows if "mean_force_rel_std" in row]
    amp_std = [row["amplitude_rel_std"] for row in rows]
    return Repeatability(
        groups=tuple(rows),
        k_total_rel_std=_pooled(k_std),
        mean_force_rel_std=_pooled(mean_std),
        amplitude_rel_std=_pooled(amp_std),
    )

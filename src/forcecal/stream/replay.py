"""Recorded runs through the streaming estimator, as a live acquisition would feed it, and
the streamed forces written as a table."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.run_files import write_table_csv, write_table_hdf5
from ..records import Run
from ..rig import Rig
from ..spatial import SpatialModel
from .estimator import StreamEstimator

__all__ = ["replay", "write_stream_csv"]



# --------------------------------------------------------------------------------------------
# recorded runs


def replay(rig: Rig, model: SpatialModel, run: Run, block: int = 256, *,
           f0_guess: float | None = None, n_harmonics: int | None = None,
           forgetting: float | None = None, track_frequency: bool = True,
           sensor_std: Sequence[float] | np.ndarray | None = None, tare: Run | None = None,
           ac_coupled: bool = False, extra_harmonics: Sequence[int] = ()
           ) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Feed a recorded run block by block, as a live acquisition would.

    Parameters
    ----------
    rig : Rig
    model : SpatialModel
    run : Run
        The recording, fed in blocks.
    block : int
        Samples per block.
    f0_guess : float, optional
        [Hz] start of the frequency tracking (default: the scan model's fundamental).
    n_harmonics : int, optional
        As :class:`StreamEstimator`.
    forgetting : float, optional
        As :class:`StreamEstimator`.
    track_frequency : bool
        As :class:`StreamEstimator`.
    sensor_std : sequence of float, optional
        As :class:`StreamEstimator`.
    tare : Run, optional
        A zero-current record whose gauge DC is subtracted (as in the batch estimate).
    ac_coupled : bool
        As :class:`StreamEstimator`.
    extra_harmonics : sequence of int
        As :class:`StreamEstimator`.

    Returns
    -------
    time : (n_samples,) ndarray
        [s]
    forces : dict
        Force name -> (n_samples,) [N].
    static : dict
        Force name -> (n_samples,) [N], reactions-only.
    """
    if int(block) != block or block < 1:
        raise InputError(f"stream: block must be a positive whole number of samples; "
                         f"got {block}")
    block = int(block)
    tare_dc = None
    if tare is not None:
        tare_dc = [g.scale * tare.channel(g.name).mean() for g in rig.gauges]
    est = StreamEstimator(rig, model, f0_guess or model.f0, run.fs, n_harmonics=n_harmonics,
                          forgetting=forgetting, t0=run.t0, track_frequency=track_frequency,
                          sensor_std=sensor_std, tare_dc=tare_dc, ac_coupled=ac_coupled,
                          extra_harmonics=extra_harmonics)
    raw = np.stack([run.channel(name) for name in est.channel_names])
    n = raw.shape[1]
    force = np.empty((len(est.force_names), n))
    static = np.empty_like(force)
    for start in range(0, n, block):
        force[:, start:start + block], static[:, start:start + block] = \
            est.process(raw[:, start:start + block])
    names = est.force_names
    return (run.time, {k: force[i] for i, k in enumerate(names)},
            {k: static[i] for i, k in enumerate(names)})


def write_stream_csv(path: str | Path, time: np.ndarray, forces: Mapping[str, np.ndarray],
                     static: Mapping[str, np.ndarray]) -> Path:
    """Write a streamed estimate with the columns of ``reconstruct``'s ``NAME.forces.csv``:
    ``time``, one per force, ``total``, then the same with suffix ``_static`` [N].

    A path ending in ``.h5``/``.hdf5`` is written as HDF5 (one dataset per column, the
    layout of a run file), which is an order of magnitude faster than text for long streams.

    Parameters
    ----------
    path : str or Path
        The output file.
    time : (n_samples,) ndarray
        [s]
    forces : mapping
        Force name -> (n_samples,) [N].
    static : mapping
        Force name -> (n_samples,) [N], reactions-only.

    Returns
    -------
    Path
    """
    if list(forces) != list(static):
        raise InputError(f"table '{path}': forces {list(forces)} and static {list(static)} "
                         "name different forces")
    cols = {name: np.asarray(v, dtype=float) for name, v in forces.items()}
    cols["total"] = np.sum(list(cols.values()), axis=0)
    stat = {f"{name}_static": np.asarray(v, dtype=float) for name, v in static.items()}
    stat["total_static"] = np.sum(list(stat.values()), axis=0)
    if Path(path).suffix.lower() in (".h5", ".hdf5"):
        return write_table_hdf5(path, time, {**cols, **stat})
    return write_table_csv(path, time, {**cols, **stat})

"""Recorded runs through the streaming estimator, as a live acquisition would feed it, and
the streamed forces written as a table.

:func:`stream_table` is the real stream: the run is read in blocks (:mod:`forcecal.io.blocks`),
each block goes through the estimator in pieces of ``block`` samples and its forces are
appended to the table at once (:mod:`forcecal.io.table_writer`), so that memory does not grow
with the record's length. :func:`replay` feeds a run held in memory the same way and returns
the forces as arrays.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, ClassVar

import numpy as np

from ..errors import DataError, InputError
from ..forces.estimate import inertia_share_of, series_summary
from ..io.blocks import RunBlocks
from ..io.table_writer import CSV_DIGITS, table_writer
from ..model.spatial import SpatialModel
from ..records import Run
from ..rig import Rig
from .end_segments import EndSegments
from .estimator import StreamEstimator

__all__ = [
    "StreamedForces",
    "bounded_forces",
    "replay",
    "stream_steady",
    "stream_table",
    "write_stream_csv",
]

Check = Callable[[np.ndarray, Mapping[str, np.ndarray], Mapping[str, np.ndarray]], None]
"""A test of each block of streamed forces before it is written: (time, forces, static)."""


def bounded_forces(source: str, limit: float) -> Check:
    """A :data:`Check` that stops a stream (DataError naming the run, the force and the time)
    at a streamed force that is not finite or beyond ``limit`` [N]."""
    def check(t: np.ndarray, forces: Mapping[str, np.ndarray],
              static: Mapping[str, np.ndarray]) -> None:
        for name, values in [*forces.items(), *static.items()]:
            bad = ~np.isfinite(values) | (np.abs(values) > limit)
            if bad.any():
                k = int(np.argmax(bad))
                raise DataError(f"run '{source}': the streamed force {name!r} is "
                                f"{values[k]:.4g} N at t={t[k]:.6g} s, not finite or beyond "
                                f"{limit:g} N; nothing written")
    return check


STREAM_READ = 1 << 13
"""Samples a stream reads at a time (whole calls of its block): an eighth of a batch read
(:data:`forcecal.io.blocks.READ_BLOCK`); the blocks and the table's rows in flight stay small
beside what the compiled code holds, at the same speed."""


def _block_size(block: int) -> int:
    if int(block) != block or block < 1:
        raise InputError(f"stream: block must be a positive whole number of samples; "
                         f"got {block}")
    return int(block)


def _estimator(rig: Rig, model: SpatialModel, fs: float, t0: float,
               f0_guess: float | None, options: dict) -> StreamEstimator:
    return StreamEstimator(rig, model, f0_guess or model.f0, fs, t0=t0, **options)


def stream_forces(est: StreamEstimator, blocks: Iterable[np.ndarray], block: int = 256,
                  t0: float = 0.0
                  ) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """The estimator's forces of every block read, fed to it in pieces of ``block`` samples.

    Parameters
    ----------
    est : StreamEstimator
        The estimator, before the first sample of the record.
    blocks : iterable of (n_channels, m) ndarray
        Consecutive raw samples in the order of ``est.channel_names``.
    block : int
        Samples per call of :meth:`StreamEstimator.process`.
    t0 : float
        [s] time of the record's first sample.

    Yields
    ------
    time : (m,) ndarray
        [s] t0 + k / fs of the block's samples.
    force : (n_forces, m) ndarray
        [N] as :meth:`StreamEstimator.process`.
    static : (n_forces, m) ndarray
        [N] the reactions-only estimate.
    std : (n_forces + 1, m) ndarray
        [N] the forces' and their total's standard uncertainty at each sample
        (:attr:`StreamEstimator.last_std`).
    """
    block = _block_size(block)
    start = 0
    for raw in blocks:
        m = raw.shape[1]
        force = np.empty((len(est.force_names), m))
        static = np.empty_like(force)
        std = np.empty((len(est.force_names) + 1, m))
        for s in range(0, m, block):
            force[:, s:s + block], static[:, s:s + block] = est.process(raw[:, s:s + block])
            std[:, s:s + block] = est.last_std
        yield t0 + np.arange(start, start + m) / est.fs, force, static, std
        start += m


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
    block = _block_size(block)
    tare_dc = None
    if tare is not None:
        tare_dc = [g.scale * tare.channel(g.name).mean() for g in rig.gauges]
    est = _estimator(rig, model, run.fs, run.t0, f0_guess, {
        "n_harmonics": n_harmonics, "forgetting": forgetting,
        "track_frequency": track_frequency, "sensor_std": sensor_std, "tare_dc": tare_dc,
        "ac_coupled": ac_coupled, "extra_harmonics": extra_harmonics})
    force, static, _ = _replay_arrays(est, run, block)
    names = est.force_names
    return (run.time, {k: force[i] for i, k in enumerate(names)},
            {k: static[i] for i, k in enumerate(names)})


def stream_columns(names: Sequence[str], std: bool = False) -> list[str]:
    """The table's columns after ``time``: one per force, ``total``, the same ``_static``, and
    with ``std`` the same ``_std`` (the forces' and the total's standard uncertainty)."""
    return [*names, "total", *(f"{n}_static" for n in names), "total_static",
            *((*(f"{n}_std" for n in names), "total_std") if std else ())]


def stream_rows(force: np.ndarray, static: np.ndarray,
                std: np.ndarray | None = None) -> np.ndarray:
    """The table's rows (columns of :func:`stream_columns`) of forces, reactions-only forces
    and, when given, their standard uncertainties (each force's, then the total's)."""
    return np.concatenate([force, force.sum(axis=0)[None], static, static.sum(axis=0)[None],
                           *(() if std is None else (std,))])


def stream_table(rig: Rig, model: SpatialModel, blocks: RunBlocks, target: str | Path,
                 block: int = 256, *, check: Check | None = None, digits: int = CSV_DIGITS,
                 stdout: IO[bytes] | None = None, f0_guess: float | None = None,
                 note: Callable[[str], None] | None = None, **options: object) -> int:
    """Stream a run file through the estimator into a table, block by block.

    Parameters
    ----------
    rig : Rig
    model : SpatialModel
    blocks : RunBlocks
        The run, open for reading in blocks and checked
        (:func:`forcecal.io.blocks.check_run_blocks`).
    target : str or Path
        ``NAME.csv``, ``NAME.h5``/``NAME.hdf5``, or ``-`` for CSV on standard output; the
        columns of :func:`write_stream_csv`, then each force's and the total's ``_std``.
    block : int
        Samples per call of :meth:`StreamEstimator.process`.
    check : callable, optional
        Called with (time, forces, static) of every block before it is written; an exception
        it raises stops the stream and leaves no output file.
    digits : int
        Significant digits of the CSV columns (the time is written exactly).
    stdout : binary file, optional
        Where ``-`` writes (default: standard output).
    f0_guess : float, optional
        As :func:`replay`.
    note : callable, optional
        Called with the notes of ``reconstruct``'s checks on the stream's first (and last)
        seconds once the run is through, before the table is in place
        (:class:`~forcecal.realtime.end_segments.EndSegments`; a refusal leaves no table).
    **options
        As :class:`StreamEstimator` (``n_harmonics``, ``forgetting``, ...).

    Returns
    -------
    int
        Rows written.
    """
    block = _block_size(block)
    est = _estimator(rig, model, blocks.fs, blocks.t0, f0_guess, dict(options))
    names = est.force_names
    size = block * max(1, STREAM_READ // block)   # whole calls of ``block`` a read
    first = None if note is None else EndSegments(
        rig, model, blocks.fs, blocks.t0, blocks.n_samples, list(blocks.channel_names),
        blocks.source, note)
    read = list(est.channel_names)
    extra = [c for c in (first.channels if first else []) if c not in read]
    rows = [[*read, *extra].index(c) for c in (first.channels if first else [])]

    def raw() -> Iterator[np.ndarray]:
        for samples in blocks.blocks([*read, *extra], size):
            if first is not None:
                first.add(samples[rows])
            yield samples[:len(read)]

    with table_writer(target, stream_columns(names, std=True), blocks.fs, blocks.t0, digits=digits,
                      rows=blocks.n_samples, stdout=stdout) as out:
        for time, force, static, std in stream_forces(est, raw(), block, blocks.t0):
            if check is not None:
                check(time, dict(zip(names, force, strict=True)),
                      dict(zip(names, static, strict=True)))
            out.write(time, stream_rows(force, static, std))
        if first is not None:        # before the table is in place: a refusal leaves none
            first.finish()
        return out.rows


def write_stream_csv(path: str | Path, time: np.ndarray, forces: Mapping[str, np.ndarray],
                     static: Mapping[str, np.ndarray], digits: int = 0) -> Path:
    """Write a streamed estimate with the columns of ``reconstruct``'s ``NAME.forces.csv``:
    ``time``, one per force, ``total``, then the same with suffix ``_static`` [N].

    A path ending in ``.h5``/``.hdf5`` is written as HDF5 (one dataset per column, the
    layout of a run file), which is faster than text for long streams.

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
    digits : int
        Significant digits of the CSV columns; 0, the default: every value reads back
        exactly (in 15 digits when they suffice, else 17).

    Returns
    -------
    Path
    """
    if list(forces) != list(static):
        raise InputError(f"table '{path}': forces {list(forces)} and static {list(static)} "
                         "name different forces")
    time = np.asarray(time, dtype=float).ravel()
    force = np.array([np.asarray(v, dtype=float).ravel() for v in forces.values()])
    stat = np.array([np.asarray(v, dtype=float).ravel() for v in static.values()])
    for name, column in [*zip(forces, force, strict=True), *zip(static, stat, strict=True)]:
        if column.size != time.size:
            raise InputError(f"table '{path}': column {name!r} has {column.size} values, time "
                             f"has {time.size}")
    step = float(np.mean(np.diff(time))) if time.size > 1 else 1.0
    with table_writer(path, stream_columns(list(forces)), 1.0 / step,
                      float(time[0]) if time.size else 0.0, digits=digits,
                      rows=time.size) as out:
        out.write(time, stream_rows(force.reshape(-1, time.size), stat.reshape(-1, time.size)))
    return Path(path)


@dataclass(frozen=True)
class StreamedForces:
    """The forces of one run under a steady drive as the recursive estimator gives them
    (``stream``), at every sample: an :class:`~forcecal.forces.estimate.Estimate`.

    Attributes
    ----------
    run_name : str
    force_names : tuple of str
    time : (N,) array [s]
    force, static : (n_forces, N) arrays [N]
        With inertia, and reactions only.
    std : (n_forces + 1, N) array [N]
        Each force's and the total's standard uncertainty at each sample.
    notes : tuple of str
    """

    run_name: str
    force_names: tuple[str, ...]
    time: np.ndarray
    force: np.ndarray
    static: np.ndarray
    std: np.ndarray
    notes: tuple[str, ...] = ()
    provenance: dict | None = None
    formats: ClassVar[tuple[str, ...]] = ("csv",)

    def columns(self) -> dict[str, np.ndarray]:
        """The columns of ``stream``'s table after ``time`` (:func:`stream_columns`)."""
        rows = stream_rows(self.force, self.static, self.std)
        return dict(zip(stream_columns(self.force_names, std=True), rows, strict=True))

    def force_over_time(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """One force's (or ``total``'s) samples and their standard uncertainties [N]."""
        cols = self.columns()
        return cols[name], cols[f"{name}_std"]

    @property
    def inertia_share(self) -> float:
        """RMS of the AC inertia term's part in the total over the AC total's RMS [1]."""
        return inertia_share_of(self.force.sum(axis=0), self.static.sum(axis=0))

    def summary(self) -> dict:
        """The JSON document of the run: every force's and the total's mean, AC RMS and RMS
        uncertainty, the reactions-only AC RMS, the inertia share, the notes."""
        return {"run": self.run_name, "drive": "steady",
                "estimator": "recursive least squares of the harmonics",
                **series_summary(self.columns(), self.force_names),
                "inertia_share": self.inertia_share, "notes": list(self.notes)}

    def to_dataframe(self) -> Any:
        """The force series as a pandas DataFrame: index ``time`` [s], the columns of
        :meth:`columns`."""
        import pandas  # type: ignore[import-untyped]  # imported on use only

        return pandas.DataFrame(self.columns(), index=pandas.Index(self.time, name="time"))

    def __repr__(self) -> str:
        """One line: the run, the total's AC RMS with its uncertainty, the inertia share."""
        s = series_summary(self.columns(), self.force_names)["total"]
        return (f"StreamedForces(run '{self.run_name}', total AC RMS {s['ac_rms_n']:.4g} N ± "
                f"{s['std_n']:.2g}; inertia share {100 * self.inertia_share:.1f} %)")

    def _repr_html_(self) -> str:
        """The one line of :meth:`__repr__`, for notebooks."""
        from html import escape

        return f"<p>{escape(repr(self))}</p>"


def stream_steady(rig: Rig, model: SpatialModel, run: Run, tare: Run | None = None,
                  block: int = 256) -> StreamedForces:
    """A run under a steady drive through the recursive estimator, as ``stream`` gives it
    (with the defaults of :class:`StreamEstimator`), the tare's gauge DC taken off, with the
    notes of ``reconstruct``'s checks on its first (and last) seconds
    (:class:`~forcecal.realtime.end_segments.EndSegments`).

    Raises
    ------
    InputError, DataError
        As :func:`replay`.
    """
    tare_dc = None if tare is None else [g.scale * tare.channel(g.name).mean()
                                         for g in rig.gauges]
    est = _estimator(rig, model, run.fs, run.t0, None, {"tare_dc": tare_dc})
    force, static, std = _replay_arrays(est, run, block)
    notes: list[str] = []
    first = EndSegments(rig, model, run.fs, run.t0, run.time.size, list(run.channels),
                        run.source, notes.append, tare=tare)
    first.add(np.stack([run.channel(c) for c in first.channels]))
    first.finish()
    return StreamedForces(run.name, tuple(est.force_names), run.time, force, static, std,
                          tuple(notes))


def _replay_arrays(est: StreamEstimator, run: Run, block: int
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A run held in memory through ``est``: its forces and reactions-only forces
    (n_forces, N) and their standard uncertainties (n_forces + 1, N) [N]."""
    raw = np.stack([run.channel(name) for name in est.channel_names])
    pieces = list(stream_forces(est, [raw], block, run.t0))      # (time, force, static, std)
    force, static, std = (np.concatenate([p[k] for p in pieces], axis=1) for k in (1, 2, 3))
    return force, static, std

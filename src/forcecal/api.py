"""The method's steps as a Python API: thin wrappers re-exported at the package's top level.

Each function is one step of the command line (INTERFACES.md section 5) and takes or returns
the stage objects (SI units). The chain, on a rig file, a scan, a run and a
campaign manifest::

    import forcecal

    rig = forcecal.load_rig("rig.toml")
    scan = forcecal.read_scan("scan.uff", rig=rig)
    model = forcecal.build_spatial_model(rig, scan)
    est = forcecal.reconstruct(rig, model, forcecal.read_run("runs/r01.csv"))
    result = forcecal.calibrate(rig, model, "manifest.csv")
    forcecal.write_calibration(result, "out")        # calibration.json, certificate, figures
    cal = forcecal.load_calibration("out/calibration.json")
    forcecal.predict(cal, current=[1.0, 2.0], gaps=1.0e-3)    # the law, with its uncertainty

Of these, only :func:`write_calibration` writes files (where it is told).

Like the command line, this module sits outside the core: it reads files (:mod:`forcecal.io`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager
from dataclasses import replace
from pathlib import Path

from .actuator import Calibration, Law, predict, predict_flux
from .actuator.ac_only import DEFAULT_SAMPLES_PER_PERIOD
from .campaign import CampaignResult, calibrate_campaign, write_calibration
from .campaign import load_calibration as _load_calibration
from .cluster.threads import limited, thread_count, with_threads
from .drives import drive_of
from .forces.estimate import Estimate
from .io.run_files import read_run
from .io.scan_files import read_scan as _read_scan
from .model.broadband import BroadbandModel, load_any_model
from .model.spatial import SpatialModel
from .provenance import provenance
from .records import Run, Scan, ScanFRF, ScanSpectra
from .rig import Rig

# load_rig and read_run are re-exported unchanged.
__all__ = [
    "build_spatial_model",
    "calibrate",
    "load_calibration",
    "load_model",
    "predict",
    "predict_flux",
    "read_run",
    "read_scan",
    "reconstruct",
    "threads",
    "write_calibration",
]


def read_scan(path: str | Path, rig: Rig | None = None,
              reference_label: str = "Ref") -> Scan | ScanSpectra | ScanFRF:
    """Read an SLDV scan, choosing the reader from the file suffix.

    Parameters
    ----------
    path : str or Path
        ``.uff``/``.unv`` (Universal File), ``.h5``/``.hdf5`` or ``.npz``.
    rig : Rig, optional
        The rig the scan was measured on. On a rig whose gauges, forces and sensors carry a
        measuring direction (a 3-D body), every record's point is read with its direction,
        ``(n, 6)``; without a rig, points only.
    reference_label : str
        For a Universal File: the text in id line 2 of the reference records.

    Returns
    -------
    Scan, ScanSpectra or ScanFRF
        The records in SI units, ``source`` = ``str(path)``: time records per point, or (a
        Universal File of spectra, function type 12) complex spectra per point, or (a broadband
        scan's FRFs with their coherence, function types 4 and 6) FRFs per point.

    Raises
    ------
    InputError
        An unknown suffix, a missing or unreadable file, or a missing or malformed array.
    DataError
        Records that do not pair up or disagree.

    Examples
    --------
    >>> rig = forcecal.load_rig("rig.toml")                      # doctest: +SKIP
    >>> scan = forcecal.read_scan("scan.uff", rig=rig)           # doctest: +SKIP
    >>> scan.n_points                                            # doctest: +SKIP
    """
    locations = bool(rig is not None and rig.structure.directed)
    return _read_scan(path, reference_label=reference_label, locations=locations)


@with_threads
def calibrate(
    rig: Rig,
    scan_or_model: Scan | SpatialModel,
    manifest_path: str | Path,
    progress: Callable[[int, int, str], None] | None = None,
    workers: int | None = None,
    laws: Sequence[Law] | None = None,
    ac_only: bool = False,
    samples_per_period: int = DEFAULT_SAMPLES_PER_PERIOD,
) -> CampaignResult:
    """Reconstruct every run of a campaign and calibrate the actuator law on them.

    A thin wrapper over :func:`forcecal.campaign.calibrate_campaign` that also takes a scan,
    from which the spatial model is built first (:func:`forcecal.model.spatial.build_spatial_model`
    with its defaults). Write the result with :func:`forcecal.campaign.write_calibration`.

    Parameters
    ----------
    rig : Rig
        The rig; ``rig.actuator`` names the current (and flux) channels.
    scan_or_model : Scan, ScanSpectra, ScanFRF, SpatialModel or BroadbandModel
        The SLDV scan, or the model already built from it.
    manifest_path : str or Path
        The campaign manifest CSV (runs, static gaps, tares).
    progress : callable, optional
        Called as ``progress(done, total, run_name)`` after each run.
    workers : int, optional
        Processes reconstructing the runs (default 1: serially, safe in any script). With
        more than one, a calling script must guard its top level with
        ``if __name__ == "__main__":`` (every worker process imports the script again); a
        script without the guard is refused with an InputError naming its line.
    laws : sequence of Law, optional
        Candidate laws (default: the (current, gap) laws,
        :data:`forcecal.campaign.CURRENT_GAP_LAWS`).
    ac_only : bool
        The gauges are AC-coupled: the laws are fitted to the harmonics alone.
    samples_per_period : int
        Calibration samples taken from each run.

    Returns
    -------
    CampaignResult
        The runs, the chosen law's ``calibration``, the candidate laws' scores and the
        reactions-only comparison.

    Raises
    ------
    FitError
        When no candidate law is identifiable from the campaign.
    InputError
        A bad manifest or run; workers asked for from a script without
        ``if __name__ == "__main__":``.

    Examples
    --------
    >>> result = forcecal.calibrate(rig, scan, "manifest.csv")   # doctest: +SKIP
    >>> result.calibration                                       # doctest: +SKIP
    """
    model = (scan_or_model if isinstance(scan_or_model, SpatialModel | BroadbandModel)
             else build_spatial_model(rig, scan_or_model))
    return calibrate_campaign(rig, model, manifest_path, progress=progress,
                              workers=1 if workers is None else workers, laws=laws,
                              ac_only=ac_only, samples_per_period=samples_per_period)


def load_calibration(path: str | Path) -> Calibration:
    """Read the calibration of a ``calibration.json``.

    Parameters
    ----------
    path : str or Path
        A file written by ``forcecal calibrate`` (or by :meth:`Calibration.save`).

    Returns
    -------
    Calibration
        The chosen law with its parameters and covariance; predict with
        :func:`forcecal.actuator.predict`.

    Raises
    ------
    InputError
        Naming the file, when it is missing, not JSON, or lacks a key.

    Examples
    --------
    >>> cal = forcecal.load_calibration("out/calibration.json")  # doctest: +SKIP
    >>> forcecal.actuator.predict(cal, 1.5, 1e-3).total          # doctest: +SKIP
    """
    return _load_calibration(path)


@with_threads
def build_spatial_model(rig: Rig, scan: Scan | ScanSpectra | ScanFRF,
                        n_harmonics: int = 6, criterion: str = "gcv",
                        basis: str = "polynomial") -> SpatialModel | BroadbandModel:
    """The spatial model of a scan, as the rig's drive builds it: harmonic shapes and their
    mass couplings from a steady scan (:func:`forcecal.model.spatial.build_spatial_model`), or
    from a broadband scan (``acquisition.band``) the shapes over its band
    (:func:`forcecal.model.broadband.build_broadband_model`).

    Parameters
    ----------
    rig : Rig
    scan : Scan, ScanSpectra or ScanFRF
        From :func:`read_scan`.
    n_harmonics : int
        Harmonics 1..H considered (a steady scan).
    criterion : {"gcv", "bic"}
        How each shape's order is chosen.
    basis : {"polynomial", "modes"}
        The shapes' family (a steady scan).

    Returns
    -------
    SpatialModel or BroadbandModel

    Examples
    --------
    >>> model = forcecal.build_spatial_model(rig, scan)          # doctest: +SKIP
    """
    return drive_of(rig).build_model(rig, scan, n_harmonics=n_harmonics, criterion=criterion,
                                     basis=basis)


def load_model(path: str | Path) -> SpatialModel | BroadbandModel:
    """Read a ``MODEL.json`` written by ``forcecal scan``: a harmonic model or a broadband one.

    Parameters
    ----------
    path : str or Path
        The file.

    Returns
    -------
    SpatialModel or BroadbandModel
        The model, with the rig it was built for (a model is refused for another rig).

    Raises
    ------
    InputError
        Naming the file, when it is missing, not JSON, or not a model.

    Examples
    --------
    >>> model = forcecal.load_model("model.json")                # doctest: +SKIP
    """
    return load_any_model(path)


@with_threads
def reconstruct(rig: Rig, model: SpatialModel | BroadbandModel, run: Run,
                n_harmonics: int | None = None, tare: Run | None = None,
                ac_coupled: bool = False, monte_carlo: int = 0) -> Estimate:
    """The forces of one run, as the rig's drive estimates them: harmonic phasors and their
    series under a steady drive (:class:`~forcecal.forces.estimate.ForceEstimate`), or forces
    sample by sample under any drive
    (:class:`~forcecal.forces.transient.TransientEstimate`); both answer
    :class:`~forcecal.forces.estimate.Estimate`.

    Parameters
    ----------
    rig : Rig
    model : SpatialModel or BroadbandModel
        From :func:`build_spatial_model` or :func:`load_model`.
    run : Run
        The recording (gauge, sensor and current channels named as in the rig).
    n_harmonics : int, optional
        Steady drive: harmonics 1..H estimated (default: the model's).
    tare : Run, optional
        A zero-current record: its mean gauge (and under any drive probe) values are the zero.
    ac_coupled : bool
        Steady drive: the gauges have no DC (piezoelectric).
    monte_carlo : int
        Steady drive: draws of a Monte Carlo of the inputs (GUM S1) beside the linear budget.

    Returns
    -------
    Estimate

    Raises
    ------
    InputError
        A model of another rig, or an option the drive has no use for.
    DataError
        Channels the method cannot use (named).

    Examples
    --------
    >>> est = forcecal.reconstruct(rig, model, forcecal.read_run("runs/r01.csv"))  # doctest: +SKIP
    >>> est.to_dataframe()[["total", "total_static"]]                             # doctest: +SKIP
    """
    est = drive_of(rig).reconstruct(rig, model, run, n_harmonics=n_harmonics, tare=tare,
                                    ac_coupled=ac_coupled, monte_carlo=monte_carlo)
    return replace(est, provenance=_origin(rig, model, run, tare))


@with_threads
def stream(rig: Rig, model: SpatialModel | BroadbandModel, run: Run,
           tare: Run | None = None) -> Estimate:
    """A run through the real-time estimator of the rig's drive, as ``forcecal stream`` gives
    it: the recursive harmonic estimator under a steady drive, the fixed-latency one sample by
    sample under any drive (or with a broadband model).

    Parameters
    ----------
    rig : Rig
    model : SpatialModel or BroadbandModel
    run : Run
    tare : Run, optional
        A zero-current record, as :func:`reconstruct`.

    Returns
    -------
    Estimate
        Its forces at every sample, with their standard uncertainties.

    Examples
    --------
    >>> live = forcecal.stream(rig, model, forcecal.read_run("runs/r01.csv"))  # doctest: +SKIP
    """
    est = drive_of(rig).stream_run(rig, model, run, tare)
    return replace(est, provenance=_origin(rig, model, run, tare))


def threads(n: int) -> AbstractContextManager[int]:
    """Run the forcecal calls inside on ``n`` BLAS/OpenMP threads (and Numba's, when its
    threading layer runs), restored after: for a call that is one large matrix problem.

    Every API call runs on one thread unless told (``FORCECAL_THREADS``, or this): forcecal's
    work is many small matrix problems, for which one thread is the fastest and leaves the other
    cores to other processes. Workers started inside (``workers=``) get ``n`` threads each.
    Usable as a decorator.

    Parameters
    ----------
    n : int
        Threads, a whole number >= 1.

    Returns
    -------
    context manager
        Yields ``n``.

    Raises
    ------
    InputError
        ``n`` is 0, negative or not a whole number.

    Examples
    --------
    >>> with forcecal.threads(4):                                # doctest: +SKIP
    ...     est = forcecal.reconstruct(rig, model, run)
    """
    return limited(thread_count(n, "forcecal.threads"))


def _origin(rig: Rig, model: SpatialModel | BroadbandModel, run: Run, tare: Run | None) -> dict:
    """The provenance of an estimate made in Python: the rig, the model's source, the run and
    the tare, and this process's command line."""
    return provenance([str(x.source) for x in (rig, model, run, tare) if x is not None])

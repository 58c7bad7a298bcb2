"""The ``forcecal`` command line (INTERFACES.md section 5).

``main(argv=None) -> int``: 0 on success, 2 for bad input or arguments (one line on stderr that
names the file, key or channel), 130 when interrupted. Output files are written atomically.
Warnings are said once a command is through: a refused input's line stands alone. stdout holds
what a command wrote (its paths first) and its summary; stderr errors, warnings and progress
(on a terminal, with ``-v``, and always for ``demo``); ``-q`` leaves both empty on success but
for the data a command is asked to print (``predict``'s force, ``schema`` to stdout).
"""

from __future__ import annotations

import io
import json
import os
import sys
import time
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..cluster.pool import run_jobs
from ..cluster.threads import limited
from ..errors import ForcecalError, InputError
from .parser import PROG, build_parser, check_arguments
from .parser import ArgumentError as _ArgumentError

__all__ = ["main"]

def _say(msg: str) -> None:
    """A line on stderr: errors and warnings, whatever the verbosity."""
    print(msg, file=sys.stderr, flush=True)


_VERBOSITY = [1]
"""0 with -q (errors and warnings only, no result lines), 1 by default (progress on a
terminal), 2 with -v (progress everywhere and details)."""


def _info(msg: str, level: int = 1) -> None:
    """A progress or detail line on stderr, shown at verbosity ``level`` and above.

    Progress (level 1) is shown on a terminal, or everywhere with ``-v``: a script or a pipe
    reading stderr sees only errors and warnings, one line each."""
    if _VERBOSITY[0] < level:
        return
    if level == 1 and _VERBOSITY[0] == 1 and not _interactive():
        return
    _say(msg)


def _step(msg: str) -> None:
    """A step of ``demo`` on stderr, one line each, on a terminal or not (a person watches a
    demo, through a pipe or ``make`` too); none with ``-q``."""
    if _VERBOSITY[0] >= 1:
        _say(msg)


def _interactive() -> bool:
    """Whether stderr is a terminal."""
    isatty = getattr(sys.stderr, "isatty", None)
    try:
        return bool(isatty and isatty())
    except (ValueError, OSError):
        return False


def _print(msg: object) -> None:
    """A result line on stdout (a path written, its summary, a note), none with ``-q``."""
    if _VERBOSITY[0] >= 1:
        _write(msg)


def _write(msg: object) -> None:
    """A line on stdout, whatever the verbosity: the data a command was asked to print.
    Characters it cannot encode (a file name's undecodable bytes) are replaced, never an
    error after the outputs are written."""
    text = str(msg)
    encoding = getattr(sys.stdout, "encoding", None) or "utf-8"
    text = text.encode(encoding, "replace").decode(encoding, "replace")
    print(text, flush=True)


STREAM_SUFFIXES = (".csv", ".h5", ".hdf5")
"""What ``stream -o`` writes: CSV, or HDF5 in the run layout."""
MAX_HARMONICS = 100
"""Most harmonics ``--harmonics`` may ask for."""
MANY_JOBS = 4
"""Campaigns from which ``calibrate`` starts a local cluster when ``--workers`` is not given
(fewer are done serially: the cluster's start would cost more)."""


_STARTED = [time.perf_counter()]


def _progress(done: int, total: int, name: str) -> None:
    """A progress bar line with the time spent and, from the pace so far, the time left."""
    width = 24
    filled = int(width * done / max(total, 1))
    spent = time.perf_counter() - _STARTED[0]
    left = spent / max(done, 1) * (total - done)
    _info(f"  [{'#' * filled}{'.' * (width - filled)}] {done}/{total} {name}  "
          f"({spent:.0f} s, about {left:.0f} s left)")


# --------------------------------------------------------------------------------- commands


def _cmd_simulate(args) -> int:
    from ..io.staging import staged_folder
    from ..simulate.export import check_scan_export, write_simulation
    from ..simulate.presets import get_preset

    realism = getattr(args, "realism", "ideal")
    export = getattr(args, "scan_export", "time")
    # an unknown preset, or an export it cannot give, is refused before any folder is made
    check_scan_export(get_preset(args.preset, realism), export)
    with staged_folder(args.out) as stage:
        write_simulation(stage, args.preset, seed=args.seed,
                         progress=lambda m: _info(f"  simulating {m}"),
                         binary_uff=args.binary_uff, realism=realism, scan_export=export)
    _print(args.out)
    return 0


def _read_scan(args, rig, path=None):
    from ..io.scan_files import read_scan

    return read_scan(args.scan if path is None else path,
                     reference_label=args.reference_label, locations=rig.structure.directed)


def _build_model(rig, scans, args):
    """The model of one scan, or of several (a span of shapes per harmonic), as the rig's
    drive builds it."""
    from ..drives import drive_of

    drive = drive_of(rig)
    drive.check_scans(rig, len(scans))
    models = []
    for scan in scans:
        try:
            models.append(drive.build_model(rig, scan, n_harmonics=args.harmonics,
                                            criterion=args.criterion, basis=args.basis))
        except ForcecalError as exc:
            if str(scan.source) in str(exc) or str(rig.source) in str(exc):
                raise
            raise type(exc)(f"scan '{scan.source}' on rig '{rig.source}': {exc}") from None
    return models[0] if len(models) == 1 else drive.merge_models(rig, models)


def _model_for(args, rig):
    """The model: from a saved MODEL.json (either kind), or built from the scan."""
    from ..model.broadband import load_any_model

    if str(args.scan).endswith(".json"):
        return load_any_model(args.scan)
    return _build_model(rig, [_read_scan(args, rig)], args)


def _inputs(args) -> list[str]:
    """The input files a command read: the rig, the scans or model, the runs, the tare, the
    manifest (for the provenance of what it writes)."""
    files = [args.rig, *getattr(args, "scans", []), getattr(args, "scan", None),
             *getattr(args, "runs", []), getattr(args, "run", None), getattr(args, "tare", None),
             *(getattr(args, "manifest", None) or [])]
    return [str(f) for f in files if f]


def _provenance(args) -> dict:
    from ..provenance import provenance

    return provenance(_inputs(args), argv=[PROG, *args.argv])


def _save_model(model, path: str, scan: str, provenance: dict | None = None) -> None:
    """Write MODEL.json atomically, strict JSON: a model with NaN or Infinity is refused."""
    from .._atomic import write_text_atomic

    try:
        doc = model.to_json()
        if provenance is not None:
            doc["provenance"] = provenance
        text = json.dumps(doc, indent=1, allow_nan=False)
    except ValueError:
        raise InputError(f"scan '{scan}': the spatial model holds non-finite values (the scan's "
                         "records do not determine it); nothing written") from None
    write_text_atomic(path, text)


def _cmd_scan(args) -> int:
    from ..drives import drive_of
    from ..io.staging import clean_stale
    from ..rig import load_rig

    rig = load_rig(args.rig)
    _info(f"  reading {len(args.scans)} scan{'s' if len(args.scans) > 1 else ''}")
    scans = [_read_scan(args, rig, path) for path in args.scans]
    _info("  fitting the harmonic shapes and their mass couplings")
    model = _build_model(rig, scans, args)
    clean_stale(Path(args.output).parent)
    _save_model(model, args.output, ", ".join(args.scans), _provenance(args))
    for line in drive_of(rig).model_lines(model, args.output, len(scans)):
        _print(line)
    return 0


def _read_runs(paths, rig=None, check=True):
    """The run files, under the rig's channel names when a rig is given (its ``[channels]``
    and group); each checked against the rig's channels unless ``check`` is false."""
    from ..io.run_files import read_run
    from ..signals.checks import check_run_for_rig

    runs = [read_run(p, rig) for p in paths]
    if rig is not None and check:
        for run in runs:
            check_run_for_rig(rig, run)
    return runs


def _load_rig(args):
    """The rig file, with the TDMS group of ``--group`` when given."""
    from dataclasses import replace

    from ..rig import load_rig

    rig = load_rig(args.rig)
    group = getattr(args, "group", None)
    return replace(rig, run_group=group) if group is not None else rig


def _check_distinct_names(paths) -> None:
    """Runs are written as OUT/NAME.*: two run files with one NAME would overwrite each other."""
    seen: dict[str, str] = {}
    for path in paths:
        name = Path(path).stem
        if name in seen:
            raise InputError(f"run '{path}': its outputs {name}.forces.csv and {name}.json would "
                             f"overwrite those of run '{seen[name]}'; rename one of them")
        seen[name] = str(path)


def _cmd_reconstruct(args) -> int:
    from ..cluster.jobs import reconstruct_job
    from ..drives import drive_of
    from ..io.results import write_estimate
    from ..io.staging import staged_folder

    if args.monte_carlo != 0 and not 10 <= args.monte_carlo <= 100_000:
        raise _ArgumentError(f"{PROG} reconstruct: argument --monte-carlo: {args.monte_carlo} "
                             "draws; give 0 (none) or 10 to 100000")
    _check_distinct_names(args.runs)
    rig = _load_rig(args)
    drive = drive_of(rig)
    drive.check_options(rig, ac_coupled=args.ac_coupled, monte_carlo=args.monte_carlo,
                        fmt=args.format)
    model = _model_for(args, rig)
    runs = _read_runs(args.runs, rig)
    tare = _read_runs([args.tare], rig, check=False)[0] if args.tare else None
    estimates = run_jobs(reconstruct_job,
                         [(rig, model, run, tare, args.ac_coupled, args.monte_carlo)
                          for run in runs],
                         names=[run.name for run in runs],
                         workers=1 if args.workers is None else _workers(args, len(runs)),
                         scheduler=args.scheduler,
                         progress=_progress if len(runs) > 1 else None)
    sources = [run.source for run in runs]
    del runs, tare                   # the records, freed before the outputs are written
    lines = []
    origin = _provenance(args)
    with staged_folder(args.output) as stage:
        for est, source in zip(estimates, sources, strict=True):
            series, _ = write_estimate(est, stage, source=source, fmt=args.format,
                                       provenance=origin)
            lines += drive.run_lines(est, Path(args.output) / series.name,
                                     _VERBOSITY[0] >= 2)
    for line in lines:
        _print(line)
    return 0


def _workers(args, n_jobs: int) -> int:
    """Local workers for ``n_jobs`` jobs: ``--workers``, else one per core when there are
    several jobs (and a local cluster is worth its start, about a second, and its overhead,
    1-2 s per job on 2 cores), else 1. ``reconstruct`` runs serially unless given ``--workers``
    (a run of a few seconds' record costs less than a job's overhead)."""
    if args.workers is not None:
        if args.workers < 1:
            raise _ArgumentError(f"{PROG} {args.command}: argument --workers: {args.workers} is "
                                 "not a positive number of processes")
        return int(args.workers)
    if n_jobs < MANY_JOBS:
        return 1
    return max(1, min(n_jobs, os.cpu_count() or 1))


def _laws(args) -> tuple[str, ...] | None:
    """``calibrate --laws``: the names, each a known law (else an argument error listing them),
    or None for the default candidates."""
    from ..actuator.laws import LAWS

    if args.laws is None:
        return None
    unknown = [n for n in args.laws if n not in LAWS]
    if unknown:
        raise _ArgumentError(f"{PROG} calibrate: argument --laws: unknown law '{unknown[0]}'; "
                             f"known: {', '.join(LAWS)}")
    return tuple(dict.fromkeys(args.laws))


def _cmd_calibrate(args) -> int:
    from ..actuator.laws import get_law
    from ..campaign import calibrate_campaign, report_text, write_calibration
    from ..cluster.jobs import calibrate_job, calibrate_jobs, campaign_folders
    from ..io.staging import staged_folder

    laws = _laws(args)
    rig = _load_rig(args)
    if laws is not None and "flux" in laws and not rig.actuator.flux:
        raise _ArgumentError(f"{PROG} calibrate: argument --laws: the law 'flux' needs the "
                             f"runs' flux, and rig '{args.rig}' names no [actuator] flux "
                             "channel")
    model = _model_for(args, rig)
    manifests = [str(m) for m in args.manifest]
    if len(manifests) == 1:
        result = calibrate_campaign(rig, model, manifests[0], progress=_progress,
                                    ac_only=args.ac_coupled,
                                    workers=None if args.workers is None else args.workers,
                                    laws=None if laws is None else [get_law(n) for n in laws])
        results, folders = [result], [Path(args.output)]
    else:
        folders = campaign_folders(args.output, manifests)
        results = run_jobs(calibrate_job,
                           calibrate_jobs(rig, model, manifests, args.ac_coupled, laws),
                           names=[f.name for f in folders],
                           workers=_workers(args, len(manifests)),
                           scheduler=args.scheduler, progress=_progress)
    origin = _provenance(args)
    summary: list[str] = []           # said after every path, composed before they are moved
    with staged_folder(args.output) as stage:
        for result, folder in zip(results, folders, strict=True):
            where = stage / folder.relative_to(args.output)
            where.mkdir(parents=True, exist_ok=True)
            path = write_calibration(result, where)
            if not args.no_report:
                from ..report.pipeline import calibration_report

                shown = model.harmonic(rig, result.runs[0].estimate.f0)
                calibration_report(rig, shown, result, where, provenance=origin,
                                   figure_format=args.figure_format)
            _print(folder / path.name)
            summary += _calibration_summary(result, folder, not args.no_report)
            if _VERBOSITY[0] >= 2:
                summary += report_text(result).rstrip("\n").splitlines()
    for line in summary:
        _print(line)
    return 0


def _calibration_summary(result, folder: Path, certificate: bool) -> list[str]:
    """What ``calibrate`` says of a campaign after the paths it wrote: the law chosen, its gain
    constant (its first parameter, K) with the standard and the expanded uncertainty (the value
    to the digits the uncertainty warrants, as the certificate), the held-out error and where
    the certificate is."""
    from ..campaign.statistics import COVERAGE_FACTOR
    from ..report.cells import unc, value

    cal = result.calibration
    law = cal.law_object
    name, unit = law.param_names[0], law.param_units[0]
    gain, u = float(cal.params[0]), float(cal.stderr[0])
    k = COVERAGE_FACTOR if result.uncertainty is None else result.uncertainty.coverage_factor
    n = len(result.selection.candidates)
    return [f"{folder}: law {cal.law}, {law.formula} (chosen of {n} candidate law"
            f"{'s' if n > 1 else ''})", *_flux_hint(result),
            f"  {name} = {value(gain, k * u)} ± {unc(k * u)} {unit} (expanded "
            f"uncertainty U, k = {k:g}; standard u = {unc(u)})",
            f"  held-out error {100 * result.selection.best.held_out.rms:.3g} % (RMS relative "
            "error of the force predicted for runs left out of the fit)",
            f"  certificate: {folder / 'report.html'}" if certificate else
            "  no certificate (--no-report)", *_notes_summary(result)]


MAX_NOTE_KINDS = 4
"""Kinds of note ``calibrate`` says of its runs at most (all are in calibration.json)."""


def _notes_summary(result) -> list[str]:
    """The runs' notes, said once per kind (:meth:`CampaignResult.note_kinds`), each with how
    many runs carry it and the first of them; every run's notes are in calibration.json."""
    ranked = result.note_kinds()
    lines = [f"  note ({len(names)} of {len(result.runs)} runs; '{names[0]}'): {text}"
             for text, names in ranked[:MAX_NOTE_KINDS]]
    if len(ranked) > MAX_NOTE_KINDS:
        lines.append(f"  ... {len(ranked) - MAX_NOTE_KINDS} more kinds of note")
    if lines:
        lines.append("  every run's notes: 'runs' in calibration.json")
    return lines


def _flux_hint(result) -> list[str]:
    """Where the saturating law was chosen and the runs carry the flux, the line that points to
    the flux law, which holds where the iron saturates (none otherwise)."""
    if result.calibration.law != "k_i2_sfe2_sat" or any(r.samples.flux is None
                                                         for r in result.runs):
        return []
    names = [c.name for c in result.selection.candidates] + [
        name for name, _ in result.selection.skipped]
    return ["  the iron saturates and the runs carry the flux: add the flux law, f = phi^2 / "
            f"(mu0 A_eff), to the candidates with --laws flux {' '.join(names)}"]


def _predict_inputs(args, cal) -> str:
    """What ``predict`` is given, checked against what the calibration's law predicts from (the
    API's checks: the same limits and wording, naming the options); said in messages."""
    from ..actuator.prediction import check_current_and_gaps, check_flux

    where = f"{PROG} predict: calibration '{args.calibration}' (law '{cal.law}')"
    if cal.law_object.needs_flux:
        if args.flux is None or args.current is not None or args.gap is not None:
            raise _ArgumentError(f"{where} predicts from the flux through one pole: give "
                                 "--flux WB alone, without --current or --gap")
        if args.frequency is not None:
            raise _ArgumentError(f"{where}: argument --frequency: the force follows the flux "
                                 "at any frequency; give --flux alone")
        try:
            check_flux(cal, args.flux, name="argument --flux:")
        except InputError as exc:
            raise _ArgumentError(f"{PROG} predict: {exc}") from None
        return f"{args.flux:g} Wb"
    if args.flux is not None or args.current is None or args.gap is None:
        raise _ArgumentError(f"{where} predicts from current and gap: give --current A and "
                             "--gap M (--flux is for a calibration of the flux law)")
    try:
        check_current_and_gaps(cal, args.current, args.gap,
                               names=("argument --current:", "argument --gap:"))
    except InputError as exc:
        raise _ArgumentError(f"{PROG} predict: {exc}") from None
    return f"{args.current:g} A and {args.gap:g} m"


def _cmd_predict(args) -> int:
    from ..actuator import predict, predict_flux
    from ..campaign import load_calibration

    cal = load_calibration(args.calibration)
    given = _predict_inputs(args, cal)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            pred = (predict_flux(cal, args.flux) if cal.law_object.needs_flux else
                    predict(cal, args.current, args.gap, frequency=args.frequency))  # floats
        except ForcecalError as exc:
            raise InputError(f"calibration '{args.calibration}': {exc}") from None
    values = [float(pred.total), float(pred.std), *map(float, pred.per_pole)]
    if not all(np.isfinite(values)):
        raise InputError(f"calibration '{args.calibration}': its law gives no finite force at "
                         f"{given}")
    for w in caught:
        _say(f"{PROG}: warning: {w.message}")
    if args.json:
        extra = {} if args.frequency is None else {
            "frequency_hz": args.frequency,
            **{key: float(getattr(pred, key)) for key in (
                "k_frequency", "k_frequency_std", "lag_deg", "lag_deg_std")}}
        _write(json.dumps({"total_n": values[0], "std_n": values[1],
                           "per_pole_n": values[2:], "law": cal.law, **extra},
                          allow_nan=False))
    else:
        _write(f"{pred.total:.6g}")
    return 0


def _cmd_stream(args) -> int:
    """The run read, streamed and written block by block (memory flat in its length); a file
    output appears whole or not at all, ``-o -`` writes CSV to stdout as it goes."""
    from dataclasses import replace

    from ..drives import drive_of
    from ..io.blocks import check_run_blocks, open_run_blocks
    from ..io.results import MAX_FORCE_N
    from ..io.staging import clean_stale
    from ..realtime.replay import bounded_forces

    to_stdout = args.output == "-"
    suffix = Path(args.output).suffix.lower()
    if not to_stdout and suffix not in STREAM_SUFFIXES:
        raise _ArgumentError(f"{PROG} stream: argument -o/--output: {args.output!r} ends in "
                             f"{suffix or 'no suffix'!r}; expected {', '.join(STREAM_SUFFIXES)}"
                             " or - (CSV on stdout)")
    rig = _load_rig(args)
    drive = drive_of(rig)
    model = _model_for(args, rig)
    harmonic = drive.streams_harmonics(model)
    if not harmonic and (args.steady or args.memory is not None):
        raise _ArgumentError(f"{PROG} stream: argument {'--steady' if args.steady else '--memory'}"
                             f": the model '{args.scan}' is a broadband one (any drive); its "
                             "stream has a fixed latency and no memory to set")
    tare = _read_runs([args.tare], rig, check=False)[0] if args.tare else None
    blocks = check_run_blocks(rig, open_run_blocks(args.run, rig))
    if tare is not None:             # as reconstruct: the gauges' zero (the probes' too under
        blocks = replace(blocks, offsets={c: float(np.mean(tare.channel(c)))     # any drive)
                                          for c in drive.zeroed_channels(rig, model)})
        from ..forces.weight import weight_notes  # weighed against the scan's drive

        for text in weight_notes(rig, tare, model.drive_rms, f"run '{args.run}'"):
            _say(f"note: {text}")
    check = bounded_forces(blocks.source, MAX_FORCE_N)     # the limit every output keeps
    with blocks:
        if not to_stdout:
            clean_stale(Path(args.output).parent)
        drive.stream(rig, model, blocks, args.output, check=check, block=args.block,
                     note=lambda text: _say(f"note: {text}"), tare=tare,
                     forgetting=_forgetting(args, model, blocks.fs) if harmonic else None)
    if not to_stdout:
        _print(args.output)
    return 0


STEADY_MEMORY_PERIODS = 100.0
"""``stream --steady``: the memory, in drive periods, of the steady mode."""


def _forgetting(args, model, fs: float) -> float | None:
    """The forgetting factor of ``--memory PERIODS`` or ``--steady`` (None: the default)."""
    periods = STEADY_MEMORY_PERIODS if args.steady else args.memory
    if periods is None:
        return None
    if not 1.0 <= periods <= 1e5:
        raise _ArgumentError(f"{PROG} stream: argument --memory: {periods:g} periods; give 1 "
                             "to 100000")
    return 1.0 - model.f0 / (fs * periods)


def _cmd_report(args) -> int:
    from ..drives import drive_of
    from ..io.staging import staged_folder
    from ..report.pipeline import run_report

    if args.truth is not None and not Path(args.truth).is_dir():
        raise _ArgumentError(f"{PROG} report: argument --truth: {args.truth!r} is not a folder")
    _check_distinct_names(args.runs)
    rig = _load_rig(args)
    drive_of(rig).check_report(rig)
    if str(args.scan).endswith(".json"):
        from ..model.spatial import load_model

        scan = load_model(args.scan)
    else:
        scan = _read_scan(args, rig)
    runs = _read_runs(args.runs, rig)
    with staged_folder(args.output) as stage:
        path = run_report(rig, scan, runs, stage, truth_dir=args.truth,
                          n_harmonics=args.harmonics, criterion=args.criterion, basis=args.basis,
                          provenance=_provenance(args), progress=_info,
                          figure_format=args.figure_format)
    _print(Path(args.output) / Path(path).relative_to(stage))
    return 0


def _cmd_demo(args) -> int:
    from .demo import run_demo

    start = time.perf_counter()
    report = run_demo(Path(args.out), progress=_step)
    _step(f"  done in {time.perf_counter() - start:.1f} s")
    _print(f"report: {report}")
    calibration = Path(args.out) / "calibration" / "report.html"
    if calibration.is_file():
        _print(f"calibration report (the actuator law, its uncertainty, the campaign): "
               f"{calibration}")
    return 0


def _cmd_schema(args) -> int:
    from .._atomic import write_text_atomic
    from ..schema.rig_file import key_table, rig_json_schema_text

    text = key_table() if args.keys else rig_json_schema_text()
    if args.out is None or args.out == "-":
        sys.stdout.write(text)
    else:
        _print(write_text_atomic(args.out, text))
    return 0


COMMANDS = {"demo": _cmd_demo, "simulate": _cmd_simulate, "scan": _cmd_scan,
            "reconstruct": _cmd_reconstruct, "calibrate": _cmd_calibrate,
            "predict": _cmd_predict, "stream": _cmd_stream, "report": _cmd_report,
            "schema": _cmd_schema}
"""Each command's handler, by the name the parser (:mod:`forcecal.cli.parser`) gives it."""


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    parser = build_parser()
    try:
        try:
            args = parser.parse_args(argv)
        except SystemExit as exc:  # --help, --version: printed; return instead of exiting
            return exc.code if isinstance(exc.code, int) else 0
        if not args.command:
            parser.error("a command is required")
        args.argv = list(sys.argv[1:] if argv is None else argv)
        _VERBOSITY[0] = 0 if getattr(args, "quiet", False) else (
            2 if getattr(args, "verbose", False) else 1)
        _STARTED[0] = time.perf_counter()
        check_arguments(args, MAX_HARMONICS)
        _expand_run_folders(args)
        for stream in (sys.stdout, sys.stderr):  # a file name's undecodable bytes: replaced
            reconfigure = getattr(stream, "reconfigure", None)
            if reconfigure is not None:
                try:
                    reconfigure(errors="replace")
                except (ValueError, OSError, io.UnsupportedOperation):
                    pass
        held: list[str] = []  # said once the command is through: a refusal is its one line
        with warnings.catch_warnings(), limited(getattr(args, "threads", None)):
            warnings.simplefilter("default")
            warnings.showwarning = lambda message, *_a, **_k: held.append(
                f"{PROG}: warning: {message}")
            status = COMMANDS[args.command](args)
        for line in held:
            _say(line)
        return status
    except _ArgumentError as exc:
        _say(str(exc))
        return 2
    except ForcecalError as exc:
        _say(f"{PROG}: {exc}")
        return 2
    except RecursionError:
        _say(f"{PROG}: an input is nested too deeply to be read")
        return 2
    except KeyboardInterrupt:
        _say(f"{PROG}: interrupted; no output file was left half-written")
        return 130
    except BrokenPipeError:                # `forcecal stream ... -o - | head`
        _say(f"{PROG}: stdout: its reader closed the pipe; the table written there is cut short")
        return 2
    except OSError as exc:                 # a file's name when the error has one
        where = [str(x) for x in (exc.filename, exc.strerror or exc) if x]
        _say(f"{PROG}: {': '.join(where)}".replace("\n", " "))
        return 2
    except Exception as exc:  # a bug: say so in one line; the traceback on demand
        if os.environ.get("FORCECAL_DEBUG"):
            raise
        _say(f"{PROG}: internal error ({type(exc).__name__}: {exc}); "
             "set FORCECAL_DEBUG=1 for the traceback and please report it")
        return 1


def _expand_run_folders(args) -> None:
    """A folder given as RUN stands for the run files in it (sorted); what is skipped is noted
    on stdout. ``stream`` replays one run: its folder must hold exactly one."""
    from ..io.run_files import run_paths

    if isinstance(getattr(args, "runs", None), list):
        args.runs, notes = run_paths(args.runs)
    elif isinstance(getattr(args, "run", None), str) and Path(args.run).is_dir():
        runs, notes = run_paths([args.run])
        if len(runs) != 1:
            raise InputError(f"run folder '{args.run}': {len(runs)} run files; "
                             f"'{PROG} {args.command}' replays one run, name its file")
        args.run = runs[0]
    else:
        return
    for note in notes:
        _print(f"note: {note}")


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())


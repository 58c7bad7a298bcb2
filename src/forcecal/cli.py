"""The ``forcecal`` command line (INTERFACES.md section 5).

``main(argv=None) -> int``: 0 on success, 2 for bad input or arguments (one line on stderr that
names the file, key or channel), 130 when interrupted. Output files are written atomically.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import sys
import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .errors import DataError, ForcecalError, InputError

__all__ = ["main"]

PROG = "forcecal"


class _ArgumentError(Exception):
    """Bad command-line arguments (reported in one line, exit status 2)."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line instead of usage + message
        raise _ArgumentError(f"{self.prog}: {message} (see '{self.prog} --help')")


def _say(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def _print(msg: object) -> None:
    """A line on stdout; characters it cannot encode (a file name's undecodable bytes) are
    replaced, never an error after the outputs are written."""
    text = str(msg)
    encoding = getattr(sys.stdout, "encoding", None) or "utf-8"
    text = text.encode(encoding, "replace").decode(encoding, "replace")
    print(text, flush=True)


STREAM_SUFFIXES = (".csv", ".h5", ".hdf5")
"""What ``stream -o`` writes: CSV, or HDF5 in the run layout."""
MAX_FORCE_N = 1e8
"""Largest force an output may hold [N]; beyond, the inputs were not what they claimed."""
EXTRAPOLATION = 10.0
"""``predict`` extrapolates (with a warning) up to this factor beyond the calibrated currents
and gaps, and refuses beyond."""
MAX_HARMONICS = 100
"""Most harmonics ``--harmonics`` may ask for."""


def _progress(done: int, total: int, name: str) -> None:
    width = 24
    filled = int(width * done / max(total, 1))
    _say(f"  [{'#' * filled}{'.' * (width - filled)}] {done}/{total} {name}")


# --------------------------------------------------------------------------------- commands


def _cmd_simulate(args) -> int:
    from .io.staging import staged_folder
    from .simulate.export import write_simulation
    from .simulate.presets import get_preset

    get_preset(args.preset)  # an unknown preset is refused before any folder is made
    with staged_folder(args.out) as stage:
        write_simulation(stage, args.preset, seed=args.seed,
                         progress=lambda m: _say(f"  simulating {m}"),
                         binary_uff=args.binary_uff)
    _print(args.out)
    return 0


def _read_scan(args, rig):
    from .io.scan_files import read_scan

    return read_scan(args.scan, reference_label=args.reference_label,
                     locations=rig.structure.directed)


def _build_model(rig, scan, args):
    from .spatial import build_spatial_model

    try:
        return build_spatial_model(rig, scan, n_harmonics=args.harmonics,
                                   criterion=args.criterion, basis=args.basis)
    except ForcecalError as exc:
        if str(scan.source) in str(exc) or str(rig.source) in str(exc):
            raise
        raise type(exc)(f"scan '{scan.source}' on rig '{rig.source}': {exc}") from None


def _model_for(args, rig):
    """The spatial model: from a saved MODEL.json, or built from the scan."""
    from .spatial import load_model

    if str(args.scan).endswith(".json"):
        return load_model(args.scan)
    return _build_model(rig, _read_scan(args, rig), args)


def _save_model(model, path: str, scan: str) -> None:
    """Write MODEL.json atomically, strict JSON: a model with NaN or Infinity is refused."""
    from ._atomic import write_text_atomic

    try:
        text = json.dumps(model.to_json(), indent=1, allow_nan=False)
    except ValueError:
        raise InputError(f"scan '{scan}': the spatial model holds non-finite values (the scan's "
                         "records do not determine it); nothing written") from None
    write_text_atomic(path, text)


def _cmd_scan(args) -> int:
    from .io.staging import clean_stale
    from .rig import load_rig

    rig = load_rig(args.rig)
    model = _build_model(rig, _read_scan(args, rig), args)
    clean_stale(Path(args.output).parent)
    _save_model(model, args.output, args.scan)
    mac = model.similarity.min()
    _print(f"{args.output}: fundamental {model.f0:.6g} Hz, harmonics "
          f"{', '.join(str(n) for n in model.harmonics)} (orders "
          f"{', '.join(str(s.order) for s in model.shapes)}); lowest MAC between harmonics "
          f"{mac:.5f}: {'one shape serves all' if model.one_shape else 'shapes differ'}")
    for note in model.notes:
        _print(f"note: {note}")
    return 0


def _read_runs(paths, rig=None):
    """The run files; each checked against the rig's channels when a rig is given."""
    from .checks import check_run_for_rig
    from .io.run_files import read_run

    runs = [read_run(p) for p in paths]
    if rig is not None:
        for run in runs:
            check_run_for_rig(rig, run)
    return runs


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
    from .forces import reconstruct
    from .io.results import write_estimate
    from .io.staging import staged_folder
    from .rig import load_rig

    _check_distinct_names(args.runs)
    rig = load_rig(args.rig)
    model = _model_for(args, rig)
    runs = _read_runs(args.runs, rig)
    tare = _read_runs([args.tare])[0] if args.tare else None
    estimates = []
    for k, run in enumerate(runs):
        estimates.append(reconstruct(rig, model, run, tare=tare, ac_coupled=args.ac_coupled))
        if len(runs) > 1:
            _progress(k + 1, len(runs), run.name)
    lines = []
    with staged_folder(args.output) as stage:
        for est, run in zip(estimates, runs, strict=True):
            csv, _ = write_estimate(est, stage, source=run.source)
            lines.append(f"{Path(args.output) / csv.name}: f0 {est.f0:.6g} Hz, total AC "
                         f"uncertainty {est.waveform_std:.3g} N, inertia share "
                         f"{est.inertia_share:.1%}")
            lines += [f"note: {note}" for note in est.notes]
    for line in lines:
        _print(line)
    return 0


def _cmd_calibrate(args) -> int:
    from .campaign import calibrate_campaign, write_calibration
    from .io.staging import staged_folder
    from .rig import load_rig

    rig = load_rig(args.rig)
    model = _model_for(args, rig)
    result = calibrate_campaign(rig, model, args.manifest, progress=_progress,
                                ac_only=args.ac_coupled)
    with staged_folder(args.output) as stage:
        path = write_calibration(result, stage)
        if not args.no_report:
            from .report.pipeline import calibration_report

            calibration_report(rig, model, result, stage)
    _print(Path(args.output) / path.name)
    return 0


def _cmd_predict(args) -> int:
    from .actuator import predict
    from .actuator.prediction import MAX_CURRENT_A, MAX_GAP_M
    from .campaign import load_calibration

    if not (np.isfinite(args.current) and abs(args.current) <= MAX_CURRENT_A):
        raise _ArgumentError(f"{PROG} predict: argument --current: {args.current!r} A is not a "
                             f"finite current within {MAX_CURRENT_A:g} A")
    if not (np.isfinite(args.gap) and 0 < args.gap <= MAX_GAP_M):
        raise _ArgumentError(f"{PROG} predict: argument --gap: {args.gap!r} m is not an air gap "
                             f"between 0 and {MAX_GAP_M:g} m (0.0008 for 0.8 mm)")
    cal = load_calibration(args.calibration)
    top = max(abs(v) for v in cal.current_range)
    if abs(args.current) > EXTRAPOLATION * top:
        raise _ArgumentError(f"{PROG} predict: argument --current: {args.current:g} A is more "
                             f"than {EXTRAPOLATION:g} times the largest calibrated current "
                             f"{top:.4g} A (calibration '{args.calibration}')")
    lo, hi = cal.gap_range
    if not lo / EXTRAPOLATION <= args.gap <= hi * EXTRAPOLATION:
        raise _ArgumentError(f"{PROG} predict: argument --gap: {args.gap:g} m is more than "
                             f"{EXTRAPOLATION:g} times outside the calibrated gaps {lo:.4g} to "
                             f"{hi:.4g} m (calibration '{args.calibration}')")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            pred = predict(cal, [args.current], args.gap)
        except ForcecalError as exc:
            raise InputError(f"calibration '{args.calibration}': {exc}") from None
    values = [float(pred.total[0]), float(pred.std[0]), *map(float, pred.per_pole[0])]
    if not all(np.isfinite(values)):
        raise InputError(f"calibration '{args.calibration}': its law gives no finite force at "
                         f"{args.current:g} A and {args.gap:g} m")
    for w in caught:
        _say(f"{PROG}: warning: {w.message}")
    if args.json:
        _print(json.dumps({"total_n": values[0], "std_n": values[1],
                           "per_pole_n": values[2:], "law": cal.law}, allow_nan=False))
    else:
        _print(f"{pred.total[0]:.6g}")
    return 0


def _cmd_stream(args) -> int:
    from .checks import check_run_for_rig
    from .io.run_files import read_run
    from .io.staging import clean_stale
    from .rig import load_rig
    from .stream import replay, write_stream_csv

    suffix = Path(args.output).suffix.lower()
    if suffix not in STREAM_SUFFIXES:
        raise _ArgumentError(f"{PROG} stream: argument -o/--output: {args.output!r} ends in "
                             f"{suffix or 'no suffix'!r}; expected {', '.join(STREAM_SUFFIXES)}")
    rig = load_rig(args.rig)
    model = _model_for(args, rig)
    run = read_run(args.run)
    check_run_for_rig(rig, run)
    t, forces, static = replay(rig, model, run, block=args.block)
    for name, values in [*forces.items(), *static.items()]:
        bad = ~np.isfinite(values)
        if bad.any() or np.max(np.abs(values)) > MAX_FORCE_N:
            k = int(np.argmax(bad | (np.abs(values) > MAX_FORCE_N)))
            raise DataError(f"run '{run.source}': the streamed force {name!r} is "
                            f"{values[k]:.4g} N at t={t[k]:.6g} s, not finite or beyond "
                            f"{MAX_FORCE_N:g} N; nothing written")
    clean_stale(Path(args.output).parent)
    write_stream_csv(args.output, t, forces, static)
    _print(args.output)
    return 0


def _cmd_report(args) -> int:
    from .io.staging import staged_folder
    from .report.pipeline import run_report
    from .rig import load_rig

    if args.truth is not None and not Path(args.truth).is_dir():
        raise _ArgumentError(f"{PROG} report: argument --truth: {args.truth!r} is not a folder")
    _check_distinct_names(args.runs)
    rig = load_rig(args.rig)
    scan = _read_scan(args, rig)
    runs = _read_runs(args.runs, rig)
    with staged_folder(args.output) as stage:
        path = run_report(rig, scan, runs, stage, truth_dir=args.truth,
                          n_harmonics=args.harmonics, criterion=args.criterion, basis=args.basis)
    _print(Path(args.output) / Path(path).relative_to(stage))
    return 0


def _cmd_demo(args) -> int:
    from .demo import run_demo

    start = time.perf_counter()
    report = run_demo(Path(args.out), progress=_say)
    _say(f"  done in {time.perf_counter() - start:.1f} s")
    print(f"report: {report}")
    return 0


# --------------------------------------------------------------------------------- parser


def _model_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--harmonics", type=int, default=6, metavar="H",
                   help="harmonics 1..H considered (default 6)")
    p.add_argument("--criterion", choices=("gcv", "bic"), default="gcv",
                   help="how each shape's order is chosen (default gcv)")
    p.add_argument("--basis", choices=("polynomial", "modes"), default="polynomial",
                   help="shape basis: orthonormal polynomials (default) or mode shapes")
    p.add_argument("--reference-label", default="Ref",
                   help="text in id line 2 of the scan's reference records (default 'Ref')")


def _demo_parser(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    p = sub.add_parser("demo", help="simulate the built-in rig and run every stage",
                       formatter_class=fmt, epilog="example:\n  forcecal demo demo-output")
    p.add_argument("out", nargs="?", default="forcecal-demo", help="output folder")
    p.set_defaults(func=_cmd_demo)

def _simulate_parser(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    p = sub.add_parser("simulate", help="write a virtual rig's files", formatter_class=fmt,
                       epilog="example:\n  forcecal simulate lab --preset campaign --seed 1")
    p.add_argument("out", help="output folder")
    p.add_argument("--preset", default="paper", help="paper, resonance, campaign, plate or body")
    p.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    p.add_argument("--binary-uff", action="store_true", help="write the scan as dataset 58b")
    p.set_defaults(func=_cmd_simulate)

def _scan_parser(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    p = sub.add_parser("scan", help="build the spatial model from an SLDV scan",
                       formatter_class=fmt,
                       epilog="example:\n  forcecal scan lab/rig.toml lab/scan.uff -o model.json")
    p.add_argument("rig")
    p.add_argument("scan", help="UFF (.uff/.unv), HDF5 (.h5) or NPZ scan")
    p.add_argument("-o", "--output", required=True, help="MODEL.json")
    _model_options(p)
    p.set_defaults(func=_cmd_scan)

def _reconstruct_parser(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    p = sub.add_parser("reconstruct", help="forces of each run", formatter_class=fmt,
                       epilog="example:\n  forcecal reconstruct lab/rig.toml lab/scan.uff "
                              "lab/runs/paper.csv -o forces")
    p.add_argument("rig")
    p.add_argument("scan", help="scan file, or a MODEL.json written by 'forcecal scan'")
    p.add_argument("runs", nargs="+", metavar="RUN", help="CSV, TDMS or HDF5 recordings")
    p.add_argument("-o", "--output", required=True, help="output folder")
    p.add_argument("--tare", help="zero-current record whose gauge DC is subtracted")
    p.add_argument("--ac-coupled", action="store_true",
                   help="gauges without DC (piezoelectric): estimate the harmonics only")
    _model_options(p)
    p.set_defaults(func=_cmd_reconstruct)

def _calibrate_parser(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    p = sub.add_parser("calibrate", help="fit the actuator law over a campaign",
                       formatter_class=fmt,
                       epilog="example:\n  forcecal calibrate lab/rig.toml lab/scan.uff "
                              "--manifest lab/manifest.csv -o calibration")
    p.add_argument("rig")
    p.add_argument("scan", help="scan file, or a MODEL.json")
    p.add_argument("--manifest", required=True, help="campaign manifest CSV")
    p.add_argument("-o", "--output", required=True, help="output folder")
    p.add_argument("--ac-coupled", action="store_true",
                   help="fit the law on the harmonics alone (gauges without DC)")
    p.add_argument("--no-report", action="store_true", help="skip the figures and HTML")
    _model_options(p)
    p.set_defaults(func=_cmd_calibrate)

def _predict_parser(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    p = sub.add_parser("predict", help="actuator force from a calibration",
                       formatter_class=fmt,
                       epilog="example:\n  forcecal predict calibration/calibration.json "
                              "--current 0.6 --gap 0.001")
    p.add_argument("calibration")
    p.add_argument("--current", type=float, required=True, help="coil current, A")
    p.add_argument("--gap", type=float, required=True, help="air gap at every pole, m")
    p.add_argument("--json", action="store_true", help="uncertainty and per-pole split")
    p.set_defaults(func=_cmd_predict)

def _stream_parser(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    p = sub.add_parser("stream", help="replay a run through the real-time estimator",
                       formatter_class=fmt,
                       epilog="example:\n  forcecal stream lab/rig.toml model.json "
                              "lab/runs/paper.csv -o paper.stream.csv --block 256")
    p.add_argument("rig")
    p.add_argument("scan", metavar="MODEL", help="MODEL.json (or a scan file)")
    p.add_argument("run")
    p.add_argument("-o", "--output", required=True, help="output CSV")
    p.add_argument("--block", type=int, default=256, help="samples per block (default 256)")
    _model_options(p)
    p.set_defaults(func=_cmd_stream)

def _report_parser(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    p = sub.add_parser("report", help="figures and an HTML report for runs",
                       formatter_class=fmt,
                       epilog="example:\n  forcecal report lab/rig.toml lab/scan.uff "
                              "lab/runs/paper.csv -o report --truth lab/truth")
    p.add_argument("rig")
    p.add_argument("scan")
    p.add_argument("runs", nargs="+", metavar="RUN")
    p.add_argument("-o", "--output", required=True, help="output folder")
    p.add_argument("--truth", help="folder of NAME.forces.csv ground truth to overlay")
    _model_options(p)
    p.set_defaults(func=_cmd_report)


def build_parser() -> argparse.ArgumentParser:
    fmt = argparse.RawDescriptionHelpFormatter
    parser = _Parser(prog=PROG, description="External forces on a vibrating structure from "
                     "force gauges, inertia and an SLDV scan; electromagnet calibration.",
                     formatter_class=fmt)
    from . import __version__

    parser.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    _demo_parser(sub, fmt)
    _simulate_parser(sub, fmt)
    _scan_parser(sub, fmt)
    _reconstruct_parser(sub, fmt)
    _calibrate_parser(sub, fmt)
    _predict_parser(sub, fmt)
    _stream_parser(sub, fmt)
    _report_parser(sub, fmt)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    parser = build_parser()
    try:
        try:
            args = parser.parse_args(argv)
        except SystemExit as exc:  # --help, --version: printed; return instead of exiting
            return exc.code if isinstance(exc.code, int) else 0
        if not getattr(args, "func", None):
            parser.error("a command is required")
        _check_arguments(args)
        for stream in (sys.stdout, sys.stderr):  # a file name's undecodable bytes: replaced
            reconfigure = getattr(stream, "reconfigure", None)
            if reconfigure is not None:
                try:
                    reconfigure(errors="replace")
                except (ValueError, OSError, io.UnsupportedOperation):
                    pass
        with warnings.catch_warnings():
            warnings.simplefilter("default")
            warnings.showwarning = _show_warning
            return args.func(args)
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
    except OSError as exc:
        _say(f"{PROG}: {exc.filename or ''}: {exc.strerror or exc}".replace("\n", " "))
        return 2
    except Exception as exc:  # a bug: say so in one line; the traceback on demand
        if os.environ.get("FORCECAL_DEBUG"):
            raise
        _say(f"{PROG}: internal error ({type(exc).__name__}: {exc}); "
             "set FORCECAL_DEBUG=1 for the traceback and please report it")
        return 1


def _check_arguments(args: argparse.Namespace) -> None:
    """What argparse's types cannot say: ranges, empty paths, missing folders."""
    prog = f"{PROG} {args.command}"
    harmonics = getattr(args, "harmonics", None)
    if harmonics is not None and not 1 <= harmonics <= MAX_HARMONICS:
        raise _ArgumentError(f"{prog}: argument --harmonics: {harmonics} is not a number of "
                             f"harmonics from 1 to {MAX_HARMONICS}")
    for name in ("output", "out"):
        value = getattr(args, name, None)
        if isinstance(value, str) and not value.strip():
            option = "-o/--output" if name == "output" else "OUT"
            raise _ArgumentError(f"{prog}: argument {option}: an empty path; name the output "
                                 "(use '.' for the current folder)")
    seed = getattr(args, "seed", None)
    if seed is not None and seed < 0:
        raise _ArgumentError(f"{prog}: argument --seed: {seed} is negative; expected a whole "
                             "number >= 0")
    block = getattr(args, "block", None)
    if block is not None and block < 1:
        raise _ArgumentError(f"{prog}: argument --block: {block} is not a positive number of "
                             "samples")


def _show_warning(message, category, filename, lineno, file=None, line=None):
    _say(f"{PROG}: warning: {message}")


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())


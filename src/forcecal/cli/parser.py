"""The ``forcecal`` command line's arguments: one parser per command, every option with its
help and an example (INTERFACES.md section 5); :mod:`forcecal.cli` runs them."""

from __future__ import annotations

import argparse
from typing import Any

from ..cluster.threads import ENVIRONMENT, thread_count
from ..errors import InputError

__all__: list[str] = []

PROG = "forcecal"


class ArgumentError(Exception):
    """Bad command-line arguments (reported in one line, exit status 2).

    The message starts with the program and the command the arguments were given to
    (``"forcecal predict: argument --gap: ..."``) and ends pointing to that command's help,
    ``(see 'forcecal predict --help')``, which is added when the message lacks it.
    """

    def __init__(self, message: str) -> None:
        prog = message.split(":", 1)[0]
        words = prog.split()
        if words[:1] == [PROG] and len(words) <= 2 and not message.endswith("--help')"):
            message = f"{message} (see '{prog} --help')"
        super().__init__(message)


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line instead of usage + message
        raise ArgumentError(f"{self.prog}: {message}")


class _CommandParser(_Parser):
    """A command's parser: it refuses the arguments it does not know itself, pointing to its
    own help (argparse leaves them to the top parser, whose help does not list them)."""

    def parse_known_args(self, args: Any = None, namespace: Any = None) -> Any:
        parsed, extras = super().parse_known_args(args, namespace)
        if extras:
            self.error(f"unrecognized arguments: {' '.join(extras)}")
        return parsed, extras


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

def _simulate_parser(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    p = sub.add_parser("simulate", help="write a virtual rig's files", formatter_class=fmt,
                       epilog="example:\n  forcecal simulate lab --preset campaign --seed 1")
    p.add_argument("out", help="output folder")
    p.add_argument("--preset", default="paper",
                   help="paper, resonance, campaign, plate, body, two-coil (two magnets on their "
                        "own coils, scanned twice) or tilt (two magnets on one current at unequal "
                        "pole gaps, scanned twice), sweep (a swept-sine run and a stepped-sine "
                        "campaign 10-100 Hz, an eddy-current magnet, a chirp scan), random "
                        "(a band-limited random run), dwell (a 20 s sweep slowly through the "
                        "beam's first mode), solid or laminated (stepped-sine campaigns of a "
                        "core whose flux diffuses) or saturation (an iron that saturates); a "
                        "second scan is written to scan2.uff")
    p.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    p.add_argument("--binary-uff", action="store_true", help="write the scans as dataset 58b")
    p.add_argument("--scan-export", choices=("time", "frfs"), default="time",
                   help="time: the scans' time records (default); frfs: a broadband preset's "
                        "scans as SLDV software exports FRFs (H1 and its coherence), the "
                        "averages behind them in rig.toml's acquisition.scan_averages")
    p.add_argument("--realism", choices=("ideal", "lab"), default="ideal",
                   help="ideal: white noise only (default); lab: 1/f noise and 50 Hz mains hum "
                        "with its 3rd and 5th harmonics on every channel, 16-bit ADCs, sensor "
                        "sensitivity errors drawn from the [uncertainty] the rig file declares, "
                        "a drifting drive, gravity preload and gauge offsets (with a zero-current "
                        "tare run); truth/simulator.json states every drawn error")

def _scan_parser(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    p = sub.add_parser("scan", help="build the spatial model from an SLDV scan",
                       formatter_class=fmt,
                       epilog="examples:\n  forcecal scan lab/rig.toml lab/scan.uff -o model.json"
                              "\n  forcecal scan lab/rig.toml lab/scan.uff lab/scan2.uff -o "
                              "model.json   # two loads: two shapes per harmonic")
    p.add_argument("rig")
    p.add_argument("scans", nargs="+", metavar="SCAN",
                   help="UFF (.uff/.unv), HDF5 (.h5) or NPZ scan; several scans of the rig under "
                        "different loads give each harmonic a span of shapes")
    p.add_argument("-o", "--output", required=True, help="MODEL.json")
    _model_options(p)

def _reconstruct_parser(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    p = sub.add_parser("reconstruct", help="forces of each run", formatter_class=fmt,
                       epilog="example:\n  forcecal reconstruct lab/rig.toml lab/scan.uff "
                              "lab/runs/paper.csv -o forces")
    p.add_argument("rig")
    p.add_argument("scan", help="scan file, or a MODEL.json written by 'forcecal scan'")
    p.add_argument("runs", nargs="+", metavar="RUN",
                   help="CSV, TDMS, HDF5 or UFF recordings, or folders of them")
    p.add_argument("-o", "--output", required=True, help="output folder")
    p.add_argument("--tare", help="zero-current record whose gauge DC is subtracted")
    p.add_argument("--ac-coupled", action="store_true",
                   help="gauges without DC (piezoelectric): estimate the harmonics only")
    p.add_argument("--format", choices=("csv", "hdf5", "mat", "uff"), default="csv",
                   help="format of the force series NAME.forces.<csv|h5|mat|uff>, with "
                        "uncertainty columns NAME_std (default csv); NAME.json is always "
                        "written")
    p.add_argument("--monte-carlo", type=int, default=0, metavar="N",
                   help="also propagate the noise and the rig's type-B uncertainties by N Monte "
                        "Carlo draws (GUM Supplement 1; seeded): monte_carlo_std_n in NAME.json")
    _model_options(p)

def _calibrate_parser(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    p = sub.add_parser("calibrate", help="fit the actuator law over a campaign",
                       formatter_class=fmt,
                       epilog="example:\n  forcecal calibrate lab/rig.toml lab/scan.uff "
                              "--manifest lab/manifest.csv -o calibration")
    p.add_argument("rig")
    p.add_argument("scan", help="scan file, or a MODEL.json")
    p.add_argument("--manifest", required=True, nargs="+", metavar="CSV",
                   help="campaign manifest CSV; several campaigns (one folder each in OUT, "
                        "named after the manifest) are spread over --workers or --scheduler")
    p.add_argument("-o", "--output", required=True, help="output folder")
    p.add_argument("--ac-coupled", action="store_true",
                   help="fit the law on the harmonics alone (gauges without DC)")
    p.add_argument("--laws", nargs="+", metavar="LAW", default=None,
                   help="the candidate laws, chosen among by held-out error (default: every "
                        "law of current and gap: k_i2_s2 k_i2_sfe2 k_i0_sfe2 power "
                        "k_i2_sfe2_sat); 'flux' needs the runs' flux channel and predicts "
                        "from it (predict --flux)")
    p.add_argument("--no-report", action="store_true", help="skip the figures and HTML")
    _model_options(p)

def _predict_parser(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    p = sub.add_parser("predict", help="actuator force from a calibration",
                       formatter_class=fmt,
                       epilog="example:\n  forcecal predict calibration/calibration.json "
                              "--current 0.6 --gap 0.001")
    p.add_argument("calibration")
    p.add_argument("--current", type=float, default=None,
                   help="coil current, A (a law of current and gap)")
    p.add_argument("--gap", type=float, default=None,
                   help="air gap at every pole, m (a law of current and gap)")
    p.add_argument("--flux", type=float, default=None,
                   help="flux through one pole, Wb (the flux law, calibrate --laws flux)")
    p.add_argument("--frequency", type=float, default=None,
                   help="Hz: the force at this frequency (K(f) and its lag, from a calibration "
                        "over frequency)")
    p.add_argument("--json", action="store_true", help="uncertainty and per-pole split")

def _stream_parser(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    p = sub.add_parser("stream", help="replay a run through the real-time estimator",
                       formatter_class=fmt,
                       epilog="example:\n  forcecal stream lab/rig.toml model.json "
                              "lab/runs/paper.csv -o paper.stream.csv --block 256")
    p.add_argument("rig")
    p.add_argument("scan", metavar="MODEL", help="MODEL.json (or a scan file)")
    p.add_argument("run")
    p.add_argument("-o", "--output", required=True,
                   help="output: NAME.csv, NAME.h5 (HDF5), or - for CSV on stdout")
    p.add_argument("--block", type=int, default=256, help="samples per block (default 256)")
    p.add_argument("--tare", help="zero-current record whose gauge DC is subtracted (under any "
                                  "drive its probes' too, and with acquisition.mains its gauges' "
                                  "hum is stated)")
    memory = p.add_mutually_exclusive_group()
    memory.add_argument("--memory", type=float, default=None, metavar="PERIODS",
                        help="memory of the estimator in drive periods (default 2: latency of "
                             "about 2 periods, for following changes)")
    memory.add_argument("--steady", action="store_true",
                        help="steady mode: a memory of 100 periods, for a steady drive; within "
                             "1.5x of the batch estimate's error while following a slow drift")
    _model_options(p)

def _report_parser(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    p = sub.add_parser("report", help="figures and an HTML report for runs",
                       formatter_class=fmt,
                       epilog="example:\n  forcecal report lab/rig.toml lab/scan.uff "
                              "lab/runs/paper.csv -o report --truth lab/truth")
    p.add_argument("rig")
    p.add_argument("scan", help="scan file, or a MODEL.json written by 'forcecal scan' "
                                "(from one scan or several)")
    p.add_argument("runs", nargs="+", metavar="RUN")
    p.add_argument("-o", "--output", required=True, help="output folder")
    p.add_argument("--truth", help="folder of NAME.forces.csv ground truth to overlay")
    _model_options(p)


def _schema_parser(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    p = sub.add_parser("schema", help="the rig file's JSON Schema, for an editor",
                       formatter_class=fmt,
                       epilog="example:\n  forcecal schema rig.schema.json   # then, at the top "
                              "of a rig file:\n  #:schema ./rig.schema.json")
    p.add_argument("out", nargs="?", metavar="OUT",
                   help="the file to write (default: standard output)")
    p.add_argument("--keys", action="store_true",
                   help="the table of the rig file's keys (Markdown) instead")


def _threads(text: str) -> int:
    """``--threads N``: a whole number >= 1 (:func:`forcecal.cluster.threads.thread_count`)."""
    try:
        return thread_count(text)
    except InputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def build_parser() -> argparse.ArgumentParser:
    fmt = argparse.RawDescriptionHelpFormatter
    parser = _Parser(prog=PROG, description="External forces on a vibrating structure from "
                     "force gauges, inertia and an SLDV scan; electromagnet calibration.",
                     formatter_class=fmt)
    from .. import __version__

    parser.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND",
                               parser_class=_CommandParser)
    _demo_parser(sub, fmt)
    _simulate_parser(sub, fmt)
    _scan_parser(sub, fmt)
    _reconstruct_parser(sub, fmt)
    _calibrate_parser(sub, fmt)
    _predict_parser(sub, fmt)
    _stream_parser(sub, fmt)
    _report_parser(sub, fmt)
    _schema_parser(sub, fmt)
    for command in sub.choices.values():                         # after the command too
        verbosity = command.add_mutually_exclusive_group()
        verbosity.add_argument("-q", "--quiet", action="store_true",
                               help="silent on success: errors and warnings only (no progress, no "
                                    "result lines; what was asked for, as predict's number, "
                                    "is still printed)")
        verbosity.add_argument("-v", "--verbose", action="store_true",
                               help="details (the uncertainty budget of every force), and "
                                    "progress even when stderr is not a terminal")
        command.add_argument("--threads", type=_threads, metavar="N", default=None,
                             help=f"BLAS/OpenMP threads of the command (default: {ENVIRONMENT}, "
                                  "else 1, fastest for forcecal's many small matrix problems; "
                                  "workers get as many each)")
    for name in ("reconstruct", "calibrate"):                      # the commands of many jobs
        jobs = sub.choices[name].add_mutually_exclusive_group()
        jobs.add_argument(
            "--workers", type=int, metavar="N", default=None,
            help="processes of a local Dask cluster over which several runs or campaigns are "
                 "spread (default: calibrate, one per core from 4 campaigns; reconstruct, "
                 "serially)")
        jobs.add_argument(
            "--scheduler", metavar="ADDRESS",
            help="an existing Dask scheduler (tcp://host:8786) whose workers run the jobs")
    for name in ("calibrate", "report"):                           # the commands that draw
        sub.choices[name].add_argument(
            "--figure-format", choices=("png", "svg", "pdf"), default="png",
            help="file format of the figures (default png; png and svg are embedded in the "
                 "HTML page, pdf is linked from it beside a PNG preview)")
    for name in ("reconstruct", "calibrate", "stream", "report"):  # the commands that read runs
        sub.choices[name].add_argument(
            "--group", metavar="NAME",
            help="TDMS group, or HDF5 group path, the runs are read from (default: the rig's "
                 "acquisition.group, or the file's only group of channels)")
    return parser


def check_arguments(args: argparse.Namespace, max_harmonics: int) -> None:
    """What argparse's types cannot say: ranges and empty paths."""
    prog = f"{PROG} {args.command}"
    harmonics = getattr(args, "harmonics", None)
    if harmonics is not None and not 1 <= harmonics <= max_harmonics:
        raise ArgumentError(f"{prog}: argument --harmonics: {harmonics} is not a number of "
                            f"harmonics from 1 to {max_harmonics}")
    for name in ("output", "out"):
        value = getattr(args, name, None)
        if isinstance(value, str) and not value.strip():
            option = "-o/--output" if name == "output" else "OUT"
            raise ArgumentError(f"{prog}: argument {option}: an empty path; name the output "
                                "(use '.' for the current folder)")
    seed = getattr(args, "seed", None)
    if seed is not None and seed < 0:
        raise ArgumentError(f"{prog}: argument --seed: {seed} is negative; expected a whole "
                            "number >= 0")
    block = getattr(args, "block", None)
    if block is not None and block < 1:
        raise ArgumentError(f"{prog}: argument --block: {block} is not a positive number of "
                            "samples")

"""Benchmark: the installed command on one BLAS thread (forcecal's default) against as many as
the machine has cores (what BLAS takes when nothing limits it, as before forcecal set its own).

Times, as whole processes started with no thread variable in their environment
(``OMP_NUM_THREADS``, ``OPENBLAS_NUM_THREADS``, ``MKL_NUM_THREADS``, ``FORCECAL_THREADS``
removed):

- ``forcecal reconstruct`` of the demo's 'paper' run (its scan, one run);
- ``forcecal calibrate --workers 1`` of the demo's campaign (seed 1, 21 runs and the report);

each with the default (one thread), with the thread variables set to one in its environment (as
a Makefile pins them; the default must match it) and with ``--threads C`` (C the cores), on an
idle machine
and beside a busy process (a NumPy matrix product in a loop, on one core). Each figure is the
minimum and median of ``--repeats`` runs, the two thread settings alternated run by run, after
one warm-up run of each command (Numba's cache).

Run:  .venv/bin/python benchmarks/threads.py [--repeats 3]
Writes benchmarks/results/threads.json.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results" / "threads.json"
FORCECAL = str(Path(sys.executable).with_name("forcecal"))
if not Path(FORCECAL).exists():                  # installed elsewhere than the interpreter
    FORCECAL = shutil.which("forcecal") or FORCECAL
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                    "FORCECAL_THREADS")
BUSY = ("import numpy as np\n"
        "a = np.random.default_rng(0).random((300, 300))\n"
        "while True:\n"
        "    a = a @ a\n"
        "    a /= np.abs(a).max()\n")
"""The busy neighbour: a matrix product in a loop, on one BLAS thread (one core)."""


def clean_env() -> dict[str, str]:
    """This process's environment without any thread variable."""
    return {k: v for k, v in os.environ.items() if k not in THREAD_VARIABLES}


PINNED = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
"""The thread variables as a Makefile pins them."""


def run(argv: list[str], pinned: bool = False) -> float:
    """Wall seconds of one command, as a whole process (its environment's thread variables
    pinned to one, or none set); it must succeed."""
    t0 = time.perf_counter()
    subprocess.run(argv, env={**clean_env(), **(PINNED if pinned else {})}, check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    return time.perf_counter() - t0


@contextlib.contextmanager
def busy_neighbour() -> Iterator[None]:
    """A process holding one core for the block's duration."""
    proc = subprocess.Popen([sys.executable, "-c", BUSY],
                            env={**clean_env(), **PINNED})
    try:
        time.sleep(1.0)                                  # let it start spinning
        yield
    finally:
        proc.terminate()
        proc.wait()


def demo_lab(folder: Path) -> dict[str, list[str]]:
    """The demo's two rigs simulated into ``folder``; each command's arguments (output in it)."""
    for preset, seed in (("paper", 0), ("campaign", 1)):
        subprocess.run([FORCECAL, "simulate", str(folder / preset), "--preset", preset,
                        "--seed", str(seed), "-q"], env=clean_env(), check=True,
                       stdout=subprocess.DEVNULL)
    paper, campaign = folder / "paper", folder / "campaign"
    return {
        "reconstruct": [FORCECAL, "reconstruct", str(paper / "rig.toml"),
                        str(paper / "scan.uff"), str(paper / "runs" / "paper.csv"),
                        "-o", str(folder / "forces"), "-q"],
        "calibrate --workers 1": [FORCECAL, "calibrate", str(campaign / "rig.toml"),
                                  str(campaign / "scan.uff"), "--manifest",
                                  str(campaign / "manifest.csv"), "-o",
                                  str(folder / "calibration"), "--workers", "1", "-q"],
    }


def measure(argv: list[str], cores: int, repeats: int) -> dict[str, dict[str, float]]:
    """min and median wall seconds of the command on one thread (its default), pinned by the
    environment, and on ``cores``, alternated."""
    settings: dict[str, list[float]] = {"1 thread": [], "pinned": [], f"{cores} threads": []}
    for _ in range(repeats):
        settings["1 thread"].append(run(argv))
        settings["pinned"].append(run(argv, pinned=True))
        settings[f"{cores} threads"].append(run([*argv, "--threads", str(cores)]))
    return {k: {"min_s": min(v), "median_s": statistics.median(v), "runs_s": v}
            for k, v in settings.items()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3, help="runs of each figure (default 3)")
    ap.add_argument("--conditions", nargs="+", default=["idle", "one core busy"],
                    choices=["idle", "one core busy"], help="the machine's states (default both)")
    args = ap.parse_args(argv)
    cores = os.cpu_count() or 1
    rows = []
    with tempfile.TemporaryDirectory(prefix="forcecal-threads-") as tmp:
        print("simulating the demo's rigs", flush=True)
        commands = demo_lab(Path(tmp))
        for name, command in commands.items():
            print(f"warm-up: {name}", flush=True)
            run(command)
        for condition in args.conditions:
            for name, command in commands.items():
                print(f"{condition}: {name}", flush=True)
                with busy_neighbour() if condition != "idle" else contextlib.nullcontext():
                    figures = measure(command, cores, args.repeats)
                rows.append({"condition": condition, "command": f"forcecal {name}", **figures})
    res = {"machine": {"python": platform.python_version(), "cores": cores,
                       "system": platform.platform(), "load_average": os.getloadavg()},
           "repeats": args.repeats, "rows": rows}
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(res, indent=2) + "\n")
    many = f"{cores} threads"
    print(f"\nwall seconds, min / median of {args.repeats} runs; {cores} cores; no thread "
          "variable set")
    print(f"{'condition':<15}{'command':<34}{'default':>15}{'pinned':>15}{many:>15}"
          f"{'default/pinned':>16}{'many/default':>14}")
    for r in rows:
        one, pin, more = r["1 thread"], r["pinned"], r[many]
        print(f"{r['condition']:<15}{r['command']:<34}"
              + "".join(f"{x['min_s']:7.2f} /{x['median_s']:6.2f}" for x in (one, pin, more))
              + f"{one['min_s'] / pin['min_s']:16.2f}{more['median_s'] / one['median_s']:14.2f}")
    print(f"\ndefault: forcecal's own limit (one thread); pinned: the thread variables set to one "
          f"in the environment\ndefault/pinned: of the minima; many/default: of the medians "
          f"({cores} threads over the default)\nwritten: {RESULTS}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

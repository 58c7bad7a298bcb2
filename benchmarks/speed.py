"""Speed and memory of forcecal: the streaming estimator, the batch reconstruction, the scan
model, and how each scales.

Run from the project root::

    .venv/bin/python benchmarks/speed.py            # full run, a few minutes
    .venv/bin/python benchmarks/speed.py --quick    # shorter stream and fewer sizes

Prints a table and writes ``benchmarks/results/speed.json``. Everything runs on one core (the
BLAS thread pools are pinned to one thread before numpy is imported). Times are given as wall
time and as CPU time of this process; on a loaded machine the CPU time is the fairer figure.

Signals: the 'paper' preset is simulated once (seed 0) and its batch estimate supplies channel
phasors (gauges, probes consistent with the scan model's shapes, coil current); synthetic
records are those phasors plus the preset's white noise, at any rate and length, with a whole
number of periods so that repeating them continues the drive without a phase jump. The long
batch runs (``forcecal reconstruct`` end to end on 1, 2 and, in full mode, 10 minutes at
10 kHz) are every channel of the simulated run as a Fourier series plus its noise, written to
HDF5 a block at a time.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import contextlib  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from forcecal.forces.steady import ForceEstimate, implied_phasors, reconstruct  # noqa: E402
from forcecal.io.run_files import read_run, write_run_hdf5  # noqa: E402
from forcecal.io.uff import read_scan_uff  # noqa: E402
from forcecal.model.spatial import SpatialModel, build_spatial_model  # noqa: E402
from forcecal.realtime import StreamEstimator, harmonic_update, steady_count  # noqa: E402
from forcecal.records import Run, Scan  # noqa: E402
from forcecal.rig import Rig, load_rig  # noqa: E402
from forcecal.signals.harmonics import fit_harmonics  # noqa: E402
from forcecal.simulate.export import write_simulation  # noqa: E402
from forcecal.simulate.presets import NoiseSpec  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results" / "speed.json"
ONLY_RESULTS = RESULTS.with_name("speed_reconstruct.json")     # of ``--only reconstruct``
STREAM_RESULTS = RESULTS.with_name("speed_stream.json")        # of ``--only stream``
FS_STREAM = 51_200.0          # [Hz] streaming rate of the benchmark
BLOCK = 256                   # samples per block
BASE_SAMPLES = 131_072        # 2.56 s at 51.2 kS/s ...
BASE_PERIODS = 51             # ... holding 51 whole periods of the synthetic drive
F_STREAM = BASE_PERIODS * FS_STREAM / BASE_SAMPLES     # 19.921875 Hz
TARGET_RATE = 1_000_000       # [samples/s] streaming target on one core
LONG_TARGET_S = 20.0          # [s] wall time of `forcecal reconstruct` on 10 min at 10 kHz
LONG_TARGET_MB = 1000.0       # [MB] its peak RSS (1 GB)
KERNEL_TARGET = 10_000_000    # [samples/s] the compiled kernel alone, 5 channels, H = 6
STREAM_TARGET_S = 3.0         # [s] `forcecal stream` of 60 s at 10.24 kHz to CSV (idle)
STREAM_TARGET_MB = 200.0      # [MB] its peak RSS on 10 minutes, CSV out


@dataclass
class Context:
    rig: Rig
    model: SpatialModel
    run: Run
    batch: ForceEstimate
    phasors: dict[str, np.ndarray]        # SI phasors 0..H of every streamed channel
    noise: dict[str, float]               # [SI] white-noise std of every channel
    work: Path


class Clock:
    """Wall and CPU seconds of a with-block."""

    def __enter__(self) -> Clock:
        self._wall, self._cpu = time.perf_counter(), time.process_time()
        return self

    def __exit__(self, *exc) -> None:
        self.wall = time.perf_counter() - self._wall
        self.cpu = time.process_time() - self._cpu


def rss_bytes() -> int:
    """Resident set size of this process [bytes] (Linux /proc; else the peak)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    except OSError:
        pass
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def fitted_order(sizes, seconds) -> float:
    """Slope of log(seconds) against log(size): the empirical order of growth."""
    return float(np.polyfit(np.log(np.asarray(sizes, float)), np.log(np.asarray(seconds)), 1)[0])


# ------------------------------------------------------------------------------ signals


def setup(work: Path) -> Context:
    out = work / "paper"
    write_simulation(out, "paper", seed=0)
    rig = load_rig(out / "rig.toml")
    model = build_spatial_model(rig, read_scan_uff(out / "scan.uff"))
    run = read_run(out / "runs" / "paper.csv")
    batch = reconstruct(rig, model, run)
    phasors = implied_phasors(rig, model, run, batch)
    cur = rig.actuator.current
    spec = NoiseSpec()
    noise = {**dict.fromkeys(rig.gauge_names, spec.gauge),
             **dict.fromkeys(rig.sensor_names, spec.probe), cur: spec.current}
    return Context(rig, model, run, batch, phasors, noise, work)


def synthetic_channels(ctx: Context, names, fs: float, n_samples: int, f0: float,
                       seed: int = 0) -> np.ndarray:
    """(n_channels, n_samples) raw samples: phasors at f0 plus the preset's noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(n_samples) / fs
    h = len(next(iter(ctx.phasors.values()))) - 1
    rot = np.exp(2j * np.pi * np.mod(np.outer(np.arange(h + 1), f0 * t), 1.0))
    scale = {g.name: g.scale for g in ctx.rig.gauges}
    scale.update({s.name: s.scale for s in ctx.rig.sensors})
    scale[ctx.rig.actuator.current] = ctx.rig.actuator.current_scale
    out = np.empty((len(names), n_samples))
    for k, name in enumerate(names):
        out[k] = ((ctx.phasors[name] @ rot).real
                  + ctx.noise[name] * rng.standard_normal(n_samples)) / scale[name]
    return out


def synthetic_run(ctx: Context, fs: float, duration: float, name: str = "synthetic") -> Run:
    names = [*ctx.rig.gauge_names, *ctx.rig.sensor_names, ctx.rig.actuator.current]
    n = round(duration * fs)
    data = synthetic_channels(ctx, names, fs, n, ctx.batch.f0, seed=11)
    return Run(channels=dict(zip(names, data, strict=True)), fs=fs, name=name)


def synthetic_scan(ctx: Context, n_points: int, n_samples: int, fs: float = 10_000.0,
                   seed: int = 0) -> Scan:
    """SLDV velocity records from the model's shapes, each point at its own start phase."""
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, ctx.rig.structure.length, n_points)
    w = 2 * np.pi * ctx.batch.f0
    t = np.arange(n_samples) / fs
    start = rng.uniform(0.0, 1.0 / ctx.batch.f0, n_points)
    response = np.zeros((n_points, n_samples))
    reference = np.full((n_points, n_samples), ctx.phasors[ctx.rig.actuator.current][0].real)
    current = ctx.phasors[ctx.rig.actuator.current]
    for n in range(1, len(current)):
        rot = np.exp(1j * n * w * (t[None, :] + start[:, None]))
        reference += (current[n] * rot).real
        if n in ctx.model.harmonics:
            k = ctx.model.index(n)
            shape = ctx.model.shape_values(n, x) * ctx.batch.coordinates.q[k]
            response += (1j * n * w * shape[:, None] * rot).real
    response += NoiseSpec().ldv * rng.standard_normal(response.shape)
    reference += NoiseSpec().current * rng.standard_normal(reference.shape)
    return Scan(points=x, response=response, reference=reference, fs=fs)


# ------------------------------------------------------------------------------ streaming


def _estimator(ctx: Context, n_harmonics: int | None = None) -> StreamEstimator:
    return StreamEstimator(ctx.rig, ctx.model, F_STREAM, FS_STREAM, n_harmonics=n_harmonics)


def _base_blocks(ctx: Context, est: StreamEstimator) -> list[np.ndarray]:
    data = synthetic_channels(ctx, est.channel_names, FS_STREAM, BASE_SAMPLES, F_STREAM)
    return [np.ascontiguousarray(data[:, s:s + BLOCK]) for s in range(0, BASE_SAMPLES, BLOCK)]


def _feed(est: StreamEstimator, blocks, n_blocks: int, start: int = 0) -> int:
    for k in range(start, start + n_blocks):
        est.process(blocks[k % len(blocks)])
    return start + n_blocks


def bench_stream(ctx: Context, n_harmonics: int, n_samples: int, repeats: int = 3) -> dict:
    """Start-up and steady throughput [samples/s] of 2 gauges + 2 probes + current."""
    est = _estimator(ctx, n_harmonics)
    blocks = _base_blocks(ctx, est)
    warm = -(-steady_count(est.lam) // BLOCK) + 1
    with Clock() as startup:
        k = _feed(est, blocks, warm)
    n_blocks = max(1, n_samples // BLOCK)
    best_wall = best_cpu = np.inf
    for _ in range(repeats):
        with Clock() as c:
            k = _feed(est, blocks, n_blocks, k)
        best_wall, best_cpu = min(best_wall, c.wall), min(best_cpu, c.cpu)
    n = n_blocks * BLOCK
    return {"harmonics": est.n_harmonics, "samples": n, "seconds_wall": best_wall,
            "seconds_cpu": best_cpu, "rate_wall": n / best_wall, "rate_cpu": n / best_cpu,
            "startup_samples": warm * BLOCK, "startup_rate_cpu": warm * BLOCK / startup.cpu,
            "startup_rate_wall": warm * BLOCK / startup.wall}


def bench_kernel(ctx: Context, n_samples: int, repeats: int = 5) -> dict:
    """The RLS kernel alone in steady state (demodulation, cumulative sums and the force
    readout, as :func:`harmonic_update` runs it in pieces of ``chunk_limit`` samples): compiled
    and NumPy, beside a plain copy of the same input array (np.copyto), best of ``repeats``."""
    est = _estimator(ctx, 6)
    data = synthetic_channels(ctx, est.channel_names, FS_STREAM, n_samples, F_STREAM)
    data *= est._scale
    warm = steady_count(est.lam) + 1
    state, _ = harmonic_update(est.state, data[:, :warm], est.lam, est._readout)
    y = np.ascontiguousarray(data[:, warm:])
    harmonic_update(state, y[:, :4096], est.lam, est._readout)        # compiled (or loaded)
    copy = np.empty_like(y)

    def best(run, count: int) -> tuple[float, float]:
        wall = cpu = np.inf
        for _ in range(count):
            with Clock() as c:
                run()
            wall, cpu = min(wall, c.wall), min(cpu, c.cpu)
        return wall, cpu

    wall, cpu = best(lambda: harmonic_update(state, y, est.lam, est._readout), repeats)
    copy_wall, copy_cpu = best(lambda: np.copyto(copy, y), 3 * repeats)
    numpy_cpu = best(lambda: harmonic_update(state, y[:, :y.shape[1] // 8], est.lam,
                                             est._readout, compiled=False), 1)[1] * 8
    n = y.shape[1]
    return {"channels": y.shape[0], "harmonics": est.n_harmonics, "samples": n,
            "seconds_wall": wall, "seconds_cpu": cpu, "rate_wall": n / wall,
            "rate_cpu": n / cpu, "numpy_rate_cpu": n / numpy_cpu,
            "copy_seconds_cpu": copy_cpu, "copy_seconds_wall": copy_wall,
            "copy_bytes": y.nbytes, "copy_gb_per_s": y.nbytes / copy_wall / 1e9,
            "times_memcpy_cpu": cpu / copy_cpu, "times_memcpy_wall": wall / copy_wall,
            "target_rate": KERNEL_TARGET}


def bench_latency(ctx: Context, n_blocks: int = 4000) -> dict:
    """Time of one process() call per block, in steady state; the estimate's own delay."""
    est = _estimator(ctx)
    blocks = _base_blocks(ctx, est)
    k = _feed(est, blocks, -(-steady_count(est.lam) // BLOCK) + 1)
    times = np.empty(n_blocks)
    for j in range(n_blocks):
        t = time.perf_counter()
        est.process(blocks[(k + j) % len(blocks)])
        times[j] = time.perf_counter() - t
    period = 1.0 / est.frequency
    return {"block": BLOCK, "block_duration_ms": 1e3 * BLOCK / FS_STREAM,
            "median_ms": 1e3 * float(np.median(times)),
            "p99_ms": 1e3 * float(np.percentile(times, 99)), "max_ms": 1e3 * float(times.max()),
            "estimate_latency_periods": est.latency_periods,
            "estimate_latency_ms": 1e3 * est.latency_periods * period,
            "settling_1e-3_periods": est.settling_periods(1e-3)}


def bench_memory(ctx: Context, minutes: float) -> dict:
    """RSS over a long stream of repeated blocks with continuing time; traced allocations."""
    est = _estimator(ctx)
    blocks = _base_blocks(ctx, est)
    per_minute = round(60 * FS_STREAM / BLOCK)
    total = round(minutes * per_minute)
    marks = sorted({max(1, round(total * f)) for f in (0.05, 0.1, 0.25, 0.5, 1.0)})
    rss, k = [], 0
    with Clock() as c:
        for mark in marks:
            k = _feed(est, blocks, mark - k, k)
            rss.append({"stream_minutes": k / per_minute, "rss_mb": rss_bytes() / 2**20})
    # allocations still held, every 1000 blocks: the state is of fixed size, the caches of
    # per-frequency tables are bounded (lru), so the level stays put
    tracemalloc.start()
    try:
        k = _feed(est, blocks, 500, k)
        traced = []
        for _ in range(6):
            k = _feed(est, blocks, 1000, k)
            traced.append(tracemalloc.get_traced_memory()[0])
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    slope = float(np.polyfit(np.arange(6) * 1000, traced, 1)[0])
    return {"stream_minutes": minutes, "samples": total * BLOCK, "rss": rss,
            "rss_growth_mb": rss[-1]["rss_mb"] - rss[0]["rss_mb"],
            "traced_bytes_every_1000_blocks": traced, "traced_bytes_per_block": slope,
            "traced_peak_bytes": peak, "seconds_wall": c.wall,
            "realtime_factor": total * BLOCK / FS_STREAM / c.wall,
            "tracked_frequency_hz": est.frequency, "true_frequency_hz": F_STREAM}


# ------------------------------------------------------------------------------ batch


def bench_campaign(ctx: Context) -> dict:
    """Batch reconstruct of every run of the 'campaign' preset."""
    out = ctx.work / "campaign"
    with Clock() as sim:
        write_simulation(out, "campaign", seed=0)
    rig = load_rig(out / "rig.toml")
    with Clock() as build:
        model = build_spatial_model(rig, read_scan_uff(out / "scan.uff"))
    seconds = []
    for path in sorted((out / "runs").glob("*.csv")):
        run = read_run(path)
        if run.name == "tare":
            continue
        with Clock() as c:
            reconstruct(rig, model, run)
        seconds.append(c.cpu)
    return {"runs": len(seconds), "samples_per_run": run.n_samples,
            "seconds_per_run_cpu": float(np.mean(seconds)), "min_cpu": float(np.min(seconds)),
            "max_cpu": float(np.max(seconds)), "simulate_seconds_wall": sim.wall,
            "scan_model_seconds_cpu": build.cpu}


def bench_reconstruct(ctx: Context, duration: float, n_harmonics: int | None = None) -> float:
    run = synthetic_run(ctx, 10_000.0, duration)
    with Clock() as c:
        reconstruct(ctx.rig, ctx.model, run, n_harmonics=n_harmonics)
    return c.cpu


def bench_scan(ctx: Context, n_points: int, n_samples: int) -> float:
    scan = synthetic_scan(ctx, n_points, n_samples)
    with Clock() as c:
        build_spatial_model(ctx.rig, scan, n_harmonics=6)
    return c.cpu


def bench_scan_per_record(ctx: Context, lengths: list[int], n_points: int = 125) -> dict:
    """Scan model CPU time against the samples per record (fixed points): the fitted order of
    growth, target about 1 (linear)."""
    seconds = [bench_scan(ctx, n_points, n) for n in lengths]
    return {"points": n_points, "samples": lengths, "seconds_cpu": seconds,
            "order_in_samples": fitted_order(lengths, seconds), "target_order": 1.0}


def long_run_file(ctx: Context, path: Path, seconds: float, fs: float = 10_000.0,
                  seed: int = 31) -> Path:
    """An HDF5 run of every channel of the simulated paper run (gauges, probes, current, flux,
    voltage: the raw file a DAQ writes), ``seconds`` long at ``fs``: each channel's Fourier
    series at the batch estimate's fundamental, fitted to the simulated run, plus white noise
    of its residual standard deviation. Written a block at a time (memory flat in the
    length); the same seed gives the same file."""
    import h5py

    run, f0 = ctx.run, ctx.batch.f0
    h = len(ctx.batch.harmonics) - 1
    fits = {name: fit_harmonics(run.channel(name), run.fs, f0, h, t0=run.t0)
            for name in run.channels}
    rng = np.random.default_rng(seed)
    n = round(seconds * fs)
    block = 1 << 18
    with h5py.File(path, "w", track_order=True) as h5:
        h5.attrs["fs"], h5.attrs["t0"] = fs, 0.0
        data = {name: h5.create_dataset(name, shape=(n,), dtype=float) for name in fits}
        for start in range(0, n, block):
            t = np.arange(start, min(n, start + block)) / fs
            for name, fit in fits.items():
                data[name][start:start + t.size] = (fit.evaluate(t) + float(fit.residual_std)
                                                    * rng.standard_normal(t.size))
    return path


def time_cli_reconstruct(ctx: Context, minutes: list[float], csv_minutes: float = 0.0) -> dict:
    """``python -m forcecal reconstruct RIG SCAN RUN -o OUT --format hdf5`` end to end on runs of
    ``minutes`` at 10 kHz (:func:`long_run_file`: 7 channels, 4.8 MB per channel-minute):
    wall time, the child's CPU time (user + system) and its peak RSS (VmHWM), each run beside
    the targets for 10 minutes;
    the time and peak extrapolated linearly to 10 minutes from the shorter runs (an upper
    estimate of the peak: reading dominates short runs and grows faster than the rest); with
    ``csv_minutes``, the same with the default CSV output."""
    work = ctx.work / "long"
    work.mkdir(exist_ok=True)
    rig_path, scan_path = ctx.work / "paper" / "rig.toml", ctx.work / "paper" / "scan.uff"
    rows = []

    def measure(m: float, fmt: str) -> dict:
        path = long_run_file(ctx, work / f"run{m:g}min.h5", 60.0 * m)
        out = work / f"out-{fmt}-{m:g}"
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        code, err, wall, peak = _run_measured(["reconstruct", str(rig_path), str(scan_path),
                                               str(path), "-o", str(out), "--format", fmt])
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        if code != 0:
            print(f"forcecal reconstruct, {m:g} min: failed (exit {code}): "
                  f"{err.strip().splitlines()[-1:] or ''}")
        row = {"minutes": m, "format": fmt, "ok": code == 0, "seconds_wall": wall,
               "seconds_cpu": (after.ru_utime - before.ru_utime
                               + after.ru_stime - before.ru_stime),
               "peak_rss_mb": peak, "input_mb": path.stat().st_size / 2**20,
               "samples": round(60.0 * m * 10_000.0)}
        path.unlink()
        return row

    for m in minutes:
        rows.append(measure(m, "hdf5"))
    short = [r for r in rows if r["minutes"] < 10.0]
    result: dict = {"runs": rows, "target_seconds": LONG_TARGET_S, "target_mb": LONG_TARGET_MB}
    if len(short) >= 2:
        x = [r["minutes"] for r in short]
        result["extrapolated_10min"] = {
            "seconds_wall": float(np.polyval(np.polyfit(x, [r["seconds_wall"] for r in short],
                                                        1), 10.0)),
            "peak_rss_mb": float(np.polyval(np.polyfit(x, [r["peak_rss_mb"] for r in short],
                                                       1), 10.0)),
            "from_minutes": x}
    if csv_minutes:
        result["csv"] = measure(csv_minutes, "csv")
    return result


# ------------------------------------------------------------------------------ CLI


_PEAK = ("import atexit, runpy, sys\n"
         "def peak():\n"
         "    for line in open('/proc/self/status'):\n"
         "        if line.startswith('VmHWM:'):\n"
         "            print('peak-rss-kb', line.split()[1], file=sys.stderr)\n"
         "atexit.register(peak)\n"
         "sys.argv = ['forcecal', *sys.argv[1:]]\n"
         "runpy.run_module('forcecal', run_name='__main__', alter_sys=True)\n")
"""Runs ``python -m forcecal ARGS`` and prints its own peak RSS (VmHWM) on leaving: the
high-water mark of the process after exec, which a fork of this (large) process does not
inflate."""


def _run_measured(argv: list[str]) -> tuple[int, str, float, float]:
    """(exit code, stderr, wall seconds, peak RSS in MB) of ``python -m forcecal ARGV``."""
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", _PEAK, *argv], stdout=subprocess.DEVNULL,
                          stderr=subprocess.PIPE, text=True, check=False)
    wall = time.perf_counter() - start
    peak = [float(line.split()[1]) / 1024 for line in done.stderr.splitlines()
            if line.startswith("peak-rss-kb")]
    return done.returncode, done.stderr, wall, peak[-1] if peak else float("nan")


def _run_cpu(argv: list[str], **env: str) -> dict:
    """:func:`_run_measured` with the child's CPU seconds (user + system), under ``env`` added
    to this process's environment."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    with _environ(**env):
        code, err, wall, peak = _run_measured(argv)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime
    if code != 0:
        print(f"forcecal {' '.join(argv[:1])} ({Path(argv[-1]).name}): failed (exit {code}): "
              f"{err.strip().splitlines()[-1:] or ''}")
    return {"ok": code == 0, "seconds_wall": wall, "seconds_cpu": cpu, "peak_rss_mb": peak}


@contextlib.contextmanager
def _environ(**env: str):
    """The environment with ``env`` set, as it was afterwards."""
    saved = {k: os.environ.get(k) for k in env}
    os.environ.update(env)
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def time_cli_stream(ctx: Context, long_minutes: float = 0.0, cold: bool = False) -> dict:
    """``python -m forcecal stream RIG MODEL RUN -o OUT`` end to end on a 60 s, 10.24 kHz HDF5
    run built from the simulated paper run's phasors: HDF5 and CSV output, wall and CPU time
    and the child's peak RSS; with ``long_minutes``, the same on a run that long, CSV and HDF5
    out (memory flat in the record's length). The first call of the command loads the compiled
    code (or compiles it): it comes first, apart (``first_call``); with ``cold``, a first call
    with an empty Numba cache (it compiles and saves) and a second (it loads)."""
    probe = subprocess.run([sys.executable, "-m", "forcecal", "stream", "--help"],
                           capture_output=True, text=True, check=False)
    if probe.returncode != 0:
        print("forcecal stream CLI: n/a (the 'stream' command is not available yet)")
        return {"available": False, "seconds_wall": None}
    fs, duration = 10_240.0, 60.0
    work = ctx.work / "cli"
    work.mkdir(exist_ok=True)
    names = [*ctx.rig.gauge_names, *ctx.rig.sensor_names, ctx.rig.actuator.current]

    def run_file(seconds: float, name: str) -> Path:
        n = round(fs * seconds)
        data = synthetic_channels(ctx, names, fs, n, ctx.batch.f0, seed=21)
        return write_run_hdf5(Run(channels=dict(zip(names, data, strict=True)), fs=fs,
                                  name=name), work / f"{name}.h5")

    run_path = run_file(duration, "cli")
    model_path = ctx.model.save(work / "model.json")
    base = ["stream", str(ctx.work / "paper" / "rig.toml"), str(model_path)]
    result: dict = {"available": True, "samples": round(fs * duration), "duration_s": duration,
                    "target_seconds": STREAM_TARGET_S, "target_mb": STREAM_TARGET_MB,
                    "first_call": _run_cpu([*base, str(run_path), "-o", str(work / "first.csv")])}
    for label, out in (("hdf5", work / "cli.forces.h5"), ("csv", work / "cli.forces.csv")):
        row = _run_cpu([*base, str(run_path), "-o", str(out)])
        row["ok"] = row["ok"] and out.is_file()
        result[label] = {**row, "rate_wall": result["samples"] / row["seconds_wall"],
                         "realtime_factor": duration / row["seconds_wall"]}
    if long_minutes:
        long_path = run_file(60.0 * long_minutes, "long")
        for label, suffix in (("long", "csv"), ("long_hdf5", "h5")):
            row = _run_cpu([*base, str(long_path), "-o", str(work / f"long.forces.{suffix}")])
            result[label] = {**row, "minutes": long_minutes, "format": suffix,
                             "input_mb": long_path.stat().st_size / 2**20}
        long_path.unlink()
    if cold:
        with tempfile.TemporaryDirectory(prefix="forcecal-numba-") as cache:
            result["numba_cache"] = {
                "first_call_empty_cache": _run_cpu([*base, str(run_path), "-o",
                                                    str(work / "cold.csv")], NUMBA_CACHE_DIR=cache),
                "second_call": _run_cpu([*base, str(run_path), "-o", str(work / "cached.csv")],
                                        NUMBA_CACHE_DIR=cache)}
    # the headline figure: HDF5 in, HDF5 out
    result.update({k: result["hdf5"][k] for k in ("ok", "seconds_wall", "rate_wall",
                                                   "realtime_factor")})
    return result


def cli_stream_rows(cli: dict) -> list[tuple[str, str]]:
    """The rows of ``forcecal stream`` end to end (:func:`time_cli_stream`)."""
    if not cli["available"]:
        return [("forcecal stream CLI, 60 s at 10.24 kHz, HDF5 in", "n/a")]

    def verdict(value: float, target: float, unit: str) -> str:
        return f"{'meets' if value <= target else 'MISSES'} <= {target:g} {unit}"

    h5, csv = cli["hdf5"], cli["csv"]
    rows = [("forcecal stream CLI, 60 s at 10.24 kHz, HDF5 in",
             f"HDF5 out {h5['seconds_wall']:.2f} s wall ({h5['seconds_cpu']:.2f} s CPU) = "
             f"{h5['realtime_factor']:.0f}x real time (target 20x), peak "
             f"{h5['peak_rss_mb']:.0f} MB; CSV out {csv['seconds_wall']:.2f} s wall "
             f"({csv['seconds_cpu']:.2f} s CPU; "
             f"{verdict(csv['seconds_wall'], cli['target_seconds'], 's')}), peak "
             f"{csv['peak_rss_mb']:.0f} MB")]
    for key in ("long", "long_hdf5"):
        if cli.get(key):
            r = cli[key]
            rows.append((f"forcecal stream CLI, {r['minutes']:g} min at 10.24 kHz, "
                         f"{r['format'].upper().replace('H5', 'HDF5')} out",
                         f"{r['seconds_wall']:.1f} s wall ({r['seconds_cpu']:.1f} s CPU), peak "
                         f"{r['peak_rss_mb']:.1f} MB (input {r['input_mb']:.0f} MB; "
                         f"{verdict(r['peak_rss_mb'], cli['target_mb'], 'MB')})"))
    cache = cli.get("numba_cache")
    if cache:
        a, b = cache["first_call_empty_cache"], cache["second_call"]
        rows.append(("forcecal stream CLI, 60 s CSV: empty Numba cache, then cached",
                     f"{a['seconds_wall']:.1f} s wall, peak {a['peak_rss_mb']:.0f} MB (compiles);"
                     f" then {b['seconds_wall']:.1f} s, peak {b['peak_rss_mb']:.0f} MB"))
    return rows


# ------------------------------------------------------------------------------ report


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shorter stream, fewer sizes")
    parser.add_argument("--only", choices=["reconstruct", "stream"],
                        help="one row alone: 'reconstruct' is `forcecal reconstruct` on 10 min "
                             f"at 10 kHz, HDF5 and CSV out (written to {ONLY_RESULTS.name}); "
                             "'stream' is `forcecal stream` on 60 s and 10 min at 10.24 kHz, "
                             "CSV and HDF5 out, and with an empty Numba cache then a full one "
                             f"(written to {STREAM_RESULTS.name})")
    args = parser.parse_args(argv)
    if args.only == "reconstruct":
        return only_reconstruct()
    if args.only == "stream":
        return only_stream()
    quick = args.quick
    res: dict = {"machine": {**machine(), "threads": os.environ.get("OPENBLAS_NUM_THREADS")}}
    with tempfile.TemporaryDirectory(prefix="forcecal-bench-") as tmp:
        say("simulating the paper preset")
        ctx = setup(Path(tmp))
        say("streaming kernel (compiled and NumPy) against a memory copy")
        res["kernel"] = bench_kernel(ctx, 2**20 if quick else 2**22)
        say("streaming throughput")
        n_main = 2**19 if quick else 2**21
        res["stream"] = bench_stream(ctx, 6, n_main)
        say("streaming latency")
        res["latency"] = bench_latency(ctx, 1000 if quick else 4000)
        say("streaming memory")
        res["memory"] = bench_memory(ctx, 1.0 if quick else 10.0)
        say("scaling of the stream")
        sizes = [2**17, 2**19] if quick else [2**17, 2**19, 2**21]
        by_n = [bench_stream(ctx, 6, n, repeats=1)["seconds_cpu"] for n in sizes]
        harm = [3, 6, 12]
        by_h = [bench_stream(ctx, h, 2**18 if quick else 2**19, repeats=1) for h in harm]
        res["stream_scaling"] = {
            "samples": sizes, "seconds_cpu": by_n, "order_in_samples": fitted_order(sizes, by_n),
            "harmonics": harm, "rate_cpu": [b["rate_cpu"] for b in by_h],
            "order_in_harmonics": fitted_order(harm, [1 / b["rate_cpu"] for b in by_h])}
        say("batch reconstruct on the campaign preset")
        res["campaign"] = bench_campaign(ctx)
        say("scaling of the batch reconstruct")
        durations = [0.5, 1.0] if quick else [0.5, 1.0, 2.0]
        by_len = [bench_reconstruct(ctx, d) for d in durations]
        by_hb = [bench_reconstruct(ctx, 1.0, h) for h in harm]
        res["reconstruct_scaling"] = {
            "samples": [round(d * 1e4) for d in durations], "seconds_cpu": by_len,
            "order_in_samples": fitted_order(durations, by_len), "harmonics": harm,
            "seconds_cpu_by_harmonics": by_hb, "order_in_harmonics": fitted_order(harm, by_hb)}
        say("scan model: 500 points x 16384 samples")
        res["scan"] = {"points": 500, "samples": 16384, "seconds_cpu": bench_scan(ctx, 500, 16384)}
        say("scaling of the scan model")
        pts = [125, 250] if quick else [125, 250, 500]
        by_p = [bench_scan(ctx, p, 16384) for p in pts[:-1]] + (
            [res["scan"]["seconds_cpu"]] if pts[-1] == 500 else [bench_scan(ctx, pts[-1], 16384)])
        lens = [4096, 8192, 16384]
        by_s = [bench_scan(ctx, 125, s) for s in lens[:-1]] + [by_p[0]]
        res["scan_scaling"] = {"points": pts, "seconds_cpu_by_points": by_p,
                               "order_in_points": fitted_order(pts, by_p),
                               "samples": lens, "seconds_cpu_by_samples": by_s,
                               "order_in_samples": fitted_order(lens, by_s)}
        say("scan model against the samples per record")
        res["scan_per_record"] = bench_scan_per_record(
            ctx, [4096, 8192, 16384] if quick else [4096, 8192, 16384, 32768])
        say("forcecal reconstruct on long runs (1, 2" + ("" if quick else ", 10") + " min)")
        res["cli_reconstruct"] = time_cli_reconstruct(ctx, [1.0, 2.0] if quick
                                                      else [1.0, 2.0, 10.0],
                                                      csv_minutes=0.0 if quick else 1.0)
        say("CLI stream")
        res["cli_stream"] = time_cli_stream(ctx, 0.0 if quick else 10.0)
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(res, indent=2, default=float) + "\n")
    print(table(res))
    print(f"\nwritten: {RESULTS}")
    return 0


def machine() -> dict:
    """What the figures were measured on: Python, NumPy, the processor, its cores and load."""
    return {"python": platform.python_version(), "numpy": np.__version__,
            "cpu": platform.processor() or platform.machine(), "cores": os.cpu_count(),
            "load_average": os.getloadavg() if hasattr(os, "getloadavg") else None}


def only_reconstruct(minutes: float = 10.0) -> int:
    """``--only reconstruct``: :func:`time_cli_reconstruct` on ``minutes`` at 10 kHz, HDF5 and
    CSV out, written to :data:`ONLY_RESULTS` (the full run's results stay as they are)."""
    res: dict = {"machine": machine()}
    with tempfile.TemporaryDirectory(prefix="forcecal-bench-") as tmp:
        say("simulating the paper preset")
        ctx = setup(Path(tmp))
        say(f"forcecal reconstruct on {minutes:g} min, HDF5 and CSV out")
        res["cli_reconstruct"] = time_cli_reconstruct(ctx, [minutes], csv_minutes=minutes)
    ONLY_RESULTS.parent.mkdir(parents=True, exist_ok=True)
    ONLY_RESULTS.write_text(json.dumps(res, indent=2, default=float) + "\n")
    rows = long_rows(res)
    width = max(len(r[0]) for r in rows)
    print("\n".join(f"{name:<{width}}  {value}" for name, value in rows))
    print(f"\nwritten: {ONLY_RESULTS}")
    return 0


def only_stream(minutes: float = 10.0) -> int:
    """``--only stream``: :func:`time_cli_stream` with a run of ``minutes`` and the Numba cache
    empty then full, written to :data:`STREAM_RESULTS` (the full run's results stay as they
    are)."""
    res: dict = {"machine": machine()}
    with tempfile.TemporaryDirectory(prefix="forcecal-bench-") as tmp:
        say("simulating the paper preset")
        ctx = setup(Path(tmp))
        say(f"forcecal stream on 60 s and {minutes:g} min, CSV and HDF5 out")
        res["cli_stream"] = time_cli_stream(ctx, minutes, cold=True)
    STREAM_RESULTS.parent.mkdir(parents=True, exist_ok=True)
    STREAM_RESULTS.write_text(json.dumps(res, indent=2, default=float) + "\n")
    rows = cli_stream_rows(res["cli_stream"])
    width = max(len(r[0]) for r in rows)
    print("\n".join(f"{name:<{width}}  {value}" for name, value in rows))
    print(f"\nwritten: {STREAM_RESULTS}")
    return 0


def say(msg: str) -> None:
    print(f"... {msg}", file=sys.stderr, flush=True)


def table(res: dict) -> str:
    s, lat, mem = res["stream"], res["latency"], res["memory"]
    sc, camp, rs = res["stream_scaling"], res["campaign"], res["reconstruct_scaling"]
    scan, ss, cli = res["scan"], res["scan_scaling"], res["cli_stream"]
    ok = "meets" if s["rate_cpu"] >= TARGET_RATE else "MISSES"
    k = res["kernel"]
    k_ok = "meets" if k["rate_cpu"] >= KERNEL_TARGET else "MISSES"
    rows = [
        (f"stream kernel, {k['channels']} ch, H={k['harmonics']} (steady, compiled)",
         f"{k['rate_cpu'] / 1e6:.1f} MS/s CPU, {k['rate_wall'] / 1e6:.1f} MS/s wall ({k_ok} "
         f"the {KERNEL_TARGET / 1e6:.0f} MS/s target); {k['times_memcpy_cpu']:.0f}x the time "
         f"of np.copyto of the same input ({k['copy_gb_per_s']:.1f} GB/s); NumPy form "
         f"{k['numpy_rate_cpu'] / 1e6:.2f} MS/s"),
        ("stream, 5 ch, H=6, block 256 (steady)",
         f"{s['rate_cpu'] / 1e6:.2f} MS/s CPU, {s['rate_wall'] / 1e6:.2f} MS/s wall "
         f"({ok} the 1 MS/s target)"),
        ("stream start-up (exact per-sample solve)",
         f"{s['startup_rate_cpu'] / 1e3:.0f} kS/s CPU over the first "
         f"{s['startup_samples'] / FS_STREAM:.1f} s of signal"),
        ("latency per block of 256 (5 ms of signal)",
         f"median {lat['median_ms']:.3f} ms, p99 {lat['p99_ms']:.3f} ms, "
         f"max {lat['max_ms']:.2f} ms"),
        ("estimate's own delay (default memory)",
         f"{lat['estimate_latency_periods']:.2f} periods = {lat['estimate_latency_ms']:.0f} ms;"
         f" step settles to 1e-3 in {lat['settling_1e-3_periods']:.1f} periods"),
        (f"memory over {mem['stream_minutes']:g} min at 51.2 kS/s",
         "RSS " + " -> ".join(f"{r['rss_mb']:.1f}" for r in mem["rss"])
         + f" MB (growth {mem['rss_growth_mb']:+.2f} MB); traced "
         f"{min(mem['traced_bytes_every_1000_blocks']) / 1e3:.0f}-"
         f"{max(mem['traced_bytes_every_1000_blocks']) / 1e3:.0f} kB over 6000 blocks, "
         f"slope {mem['traced_bytes_per_block']:+.1f} B/block; "
         f"{mem['realtime_factor']:.0f}x real time"),
        ("stream vs samples", ", ".join(f"{n}: {t:.3f} s" for n, t in
                                       zip(sc["samples"], sc["seconds_cpu"], strict=True))
         + f"  -> order {sc['order_in_samples']:.2f}"),
        ("stream vs harmonics", ", ".join(f"H={h}: {r / 1e6:.2f} MS/s" for h, r in
                                         zip(sc["harmonics"], sc["rate_cpu"], strict=True))
         + f"  -> time order {sc['order_in_harmonics']:.2f} in H"),
        (f"batch reconstruct, campaign ({camp['runs']} runs of {camp['samples_per_run']})",
         f"{camp['seconds_per_run_cpu']:.2f} s/run CPU (min {camp['min_cpu']:.2f}, "
         f"max {camp['max_cpu']:.2f})"),
        ("reconstruct vs samples", ", ".join(f"{n}: {t:.2f} s" for n, t in
                                            zip(rs["samples"], rs["seconds_cpu"], strict=True))
         + f"  -> order {rs['order_in_samples']:.2f}"),
        ("reconstruct vs harmonics", ", ".join(
            f"H={h}: {t:.2f} s" for h, t in zip(rs["harmonics"], rs["seconds_cpu_by_harmonics"],
                                                strict=True))
         + f"  -> order {rs['order_in_harmonics']:.2f}"),
        ("scan model, 500 points x 16384 samples", f"{scan['seconds_cpu']:.2f} s CPU"),
        ("scan model vs points (16384 samples)", ", ".join(
            f"{p}: {t:.2f} s" for p, t in zip(ss["points"], ss["seconds_cpu_by_points"],
                                              strict=True))
         + f"  -> order {ss['order_in_points']:.2f}"),
        ("scan model vs samples (125 points)", ", ".join(
            f"{n}: {t:.2f} s" for n, t in zip(ss["samples"], ss["seconds_cpu_by_samples"],
                                              strict=True))
         + f"  -> order {ss['order_in_samples']:.2f}"),
    ]
    rows += cli_stream_rows(cli)
    rows += long_rows(res)
    width = max(len(r[0]) for r in rows)
    return "\n".join(f"{name:<{width}}  {value}" for name, value in rows)


def long_rows(res: dict) -> list[tuple[str, str]]:
    """The rows of the long batch runs and of the scan model against its record length."""
    rows = []
    spr = res.get("scan_per_record")
    if spr:
        rows.append((f"scan model vs samples per record ({spr['points']} points)", ", ".join(
            f"{n}: {t:.2f} s" for n, t in zip(spr["samples"], spr["seconds_cpu"], strict=True))
            + f"  -> order {spr['order_in_samples']:.2f} (target ~{spr['target_order']:g})"))
    rec = res.get("cli_reconstruct")
    if not rec:
        return rows

    def verdict(seconds: float, mb: float) -> str:
        ok_t = "meets" if seconds <= rec["target_seconds"] else "MISSES"
        ok_m = "meets" if mb <= rec["target_mb"] else "MISSES"
        return (f"{ok_t} <= {rec['target_seconds']:g} s, {ok_m} <= "
                f"{rec['target_mb'] / 1000:g} GB")

    for r in rec["runs"]:
        label = f"batch reconstruct, {r['minutes']:g} min at 10 kHz"
        value = (f"HDF5 out: {r['seconds_wall']:.1f} s wall{_cpu(r)}, peak "
                 f"{r['peak_rss_mb']:.0f} MB (input {r['input_mb']:.0f} MB)" if r["ok"]
                 else "failed")
        if r["minutes"] == 10.0 and r["ok"]:
            value += f"; {verdict(r['seconds_wall'], r['peak_rss_mb'])}"
        rows.append((label, value))
    ext = rec.get("extrapolated_10min")
    if ext:
        rows.append(("batch reconstruct, 10 min extrapolated (linear) from "
                     + ", ".join(f"{m:g}" for m in ext["from_minutes"]) + " min",
                     f"{ext['seconds_wall']:.1f} s wall, peak {ext['peak_rss_mb']:.0f} MB; "
                     + verdict(ext["seconds_wall"], ext["peak_rss_mb"])))
    csv = rec.get("csv")
    if csv:
        rows.append((f"batch reconstruct, {csv['minutes']:g} min, CSV out",
                     f"{csv['seconds_wall']:.1f} s wall{_cpu(csv)}, peak "
                     f"{csv['peak_rss_mb']:.0f} MB"
                     + (f"; {'meets' if csv['peak_rss_mb'] <= rec['target_mb'] else 'MISSES'}"
                        f" <= {rec['target_mb'] / 1000:g} GB" if csv["minutes"] == 10.0 else "")
                     if csv["ok"] else "failed"))
    return rows


def _cpu(row: dict) -> str:
    """`` (S s CPU)`` of a reconstruct row that has its CPU time (user + system)."""
    return f" ({row['seconds_cpu']:.1f} s CPU)" if "seconds_cpu" in row else ""


if __name__ == "__main__":
    sys.exit(main())

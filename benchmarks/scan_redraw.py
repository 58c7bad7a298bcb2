"""Benchmark: the scan's noise alone under any drive, redrawn over seeds (the ``dwell`` preset).

The ``dwell`` run (a 20 s sweep slowly through the beam's first flexible mode, about 69 Hz at
9-10 s) is simulated once, at seed 0, and kept fixed; the chirp scan is redrawn from seeds 1..N
(``write_simulation(folder, "dwell", seed=k)``, only its ``scan.uff`` used). The ideal
``dwell`` preset draws nothing but noise: its ``rig.toml``, ``truth/simulator.json`` (the
structure, magnet, drives and noise levels), ``truth/dwell.forces.csv`` and every array of
``truth/dwell.npz`` are the same at every seed (checked on every run; the benchmark stops if
they differ), so a seed-k scan is a redraw of the same scan's noise. For each scan seed k,
``forcecal scan`` (in-process) gives model k and ``forcecal reconstruct`` the seed-0 run's
forces with it.

Every 0.5 s window (columns of the table):

- ``err %``: the total's RMS error against the truth as the estimate claims it
  (:func:`any_drive._claimed`) over the window's AC RMS of the truth, RMS over seeds;
- ``u %``: the RMS stated uncertainty ``total_std``, same units;
- ``e/u``: each seed's window error over its RMS stated uncertainty
  (:func:`any_drive._stated_windows`), RMS over seeds (1 when the statement is honest);
- ``mean/u``: the standard deviation over seeds of the window's mean error, over the RMS
  stated uncertainty;
- ``sprd/u``: the RMS over seeds and samples of each seed's deviation from the seed-mean
  estimate (times sqrt(N / (N - 1))), over the RMS stated uncertainty: the run is the same in
  every seed, so this is the scan's noise alone;
- ``scan/u``: the scan's part of the stated variance (``WindowEstimate.scan_noise``, the
  total's variance from the scan's noise, captured from :func:`reconstruct_any`), its RMS over
  the RMS stated uncertainty; ``sprd/scan`` the observed spread over it (1: the scan's part
  honest); ``ratio``: the share of the scan's part the operating shape's ratios give (the rest
  is the span shapes' coefficients), from a second estimate with the shapes' part set to zero;
- ``comm/u``: the seed-mean estimate's error (what every scan seed shares: the run's noise,
  any bias) over the RMS stated uncertainty (``e/u`` squared is about ``sprd/u`` squared plus
  ``comm/u`` squared); ``comm/rest`` the same over the stated uncertainty less the scan's part
  (the run's noise, the transfer, the ends, the type-B sources).

A second table, the same for every variant, reads the scan's points across seeds: per line, the
observed scatter of each point's response over its stated standard uncertainty
(:func:`forcecal.model.frf.scan_response`: the response's noise and the reference's, |H|^2 P_R /
(2 |R|^2), which grows with the response and dominates at the mode).

``--birge`` chooses how each line's coordinate covariance is stated
(:func:`forcecal.model.broadband._line_coordinates`, monkeypatched in-process, src untouched):

- ``on``: as shipped, the points' noise times the line's reduced chi-square off the span
  (its Birge ratio, floored at 1; about 1 now that the points' noise holds the reference's);
- ``off``: the points' noise alone;
- ``prop``: the points' noise plus an excess proportional to the fitted response at every
  point, sigma_p^2 + v |phi_p|^2, v per line from the residual's chi-square (method of
  moments, floored at 0): the shape of the reference's noise, which multiplies every point's
  response by its own relative error.

Each variant's model JSON changes with it: the table's header prints the seed-1 model's
ratio uncertainty at the mode and the stated coordinate covariance over the points' noise
alone there. A scan that ``forcecal scan`` refuses under a variant is left out and named.

``--fixed-shapes`` holds every scan's span shapes at those the seed-0 scan gives under the
variant (``broadband._span_shapes`` patched): the lines' coordinates and ratios are still each
scan's own, so the spread across seeds is the ratios' noise alone, to be read against the
ratios' part of the statement (``scan/u`` times the square root of ``ratio``). Once a variant
has been run both ways (the results keep both), a last table splits each window's observed
scan noise: the ratios' (the spread with the shapes held) over their stated part, and the
shapes' (what the free spread adds to it in quadrature) over theirs (:func:`decomposition`).

Run:  .venv/bin/python benchmarks/scan_redraw.py [--seeds N] [--birge on off prop]
      [--fixed-shapes] [--work DIR]
N scan seeds (default 8; about 8 s a seed a variant, and 10 s a seed once for the
simulations); the simulations are kept in DIR (default a temporary folder) and reused when
complete. Writes benchmarks/results/scan_redraw.json (variants of an earlier run with the same
N are kept). Nothing here draws random numbers: the simulator's are seeded by the seed, the
estimate's shape draws by its own fixed seed.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pandas as pd

import forcecal.forces.inertia_errors as inertia_errors
import forcecal.forces.transient as transient
import forcecal.model.broadband as broadband
import forcecal.model.frf as frf
from forcecal.cli.main import main
from forcecal.io.run_files import read_run
from forcecal.io.scan_files import read_scan
from forcecal.model.broadband import load_any_model
from forcecal.rig import load_rig
from forcecal.simulate.export import write_simulation

sys.path.insert(0, str(Path(__file__).parent))
from any_drive import _claimed, _stated_windows, _windows

RESULTS = Path(__file__).parent / "results"
PRESET = "dwell"
WIDTH = 0.5
"""Window [s]."""
MODE_HZ = 69.0
"""The dwell rig's first bending mode (closed loop), where the scan's part dominates."""
VARIANTS = ("on", "off", "prop")
SAME = ("rig.toml", "truth/simulator.json", f"truth/{PRESET}.forces.csv")
"""Files that must be byte for byte the same at every seed."""


# --- the simulations -------------------------------------------------------------------------

def _simulate(work: Path, seed: int) -> tuple[Path, float]:
    """The preset at ``seed`` under ``work`` (kept when a previous run completed it), and the
    seconds its simulation took (0 when reused)."""
    folder = work / f"sim-{seed}"
    done = folder / "complete"
    if done.exists():
        return folder, 0.0
    start = time.perf_counter()
    write_simulation(folder, PRESET, seed=seed)
    done.write_text("")
    return folder, time.perf_counter() - start


def _check_same(base: Path, other: Path) -> None:
    """Stop unless ``other``'s rig and truth are ``base``'s (only its noise differs)."""
    for name in SAME:
        if (base / name).read_bytes() != (other / name).read_bytes():
            raise SystemExit(f"{other / name} differs from {base / name}: the seeds' scans are "
                             "not redraws of one scan's noise")
    with np.load(base / "truth" / f"{PRESET}.npz") as a, \
            np.load(other / "truth" / f"{PRESET}.npz") as b:
        for key in a.files:
            if not np.array_equal(a[key], b[key]):
                raise SystemExit(f"truth array '{key}' of {other} differs from {base}'s")


# --- the variants ----------------------------------------------------------------------------

def _birge(basis: np.ndarray, coords: np.ndarray, good: np.ndarray, h: np.ndarray,
           std: np.ndarray, n_points: int) -> np.ndarray:
    """Each good line's Birge factor, as :func:`broadband._line_coordinates` takes it."""
    resid = h - basis @ coords[:, good]
    dof = 2 * max(n_points - basis.shape[1], 1)
    return np.maximum(np.sum(np.abs(resid) ** 2 / std**2, axis=0) / dof, 1.0)


def _proportional(basis: np.ndarray, weights: np.ndarray, values_std: np.ndarray,
                  good: np.ndarray, h: np.ndarray, std: np.ndarray, coords: np.ndarray
                  ) -> np.ndarray:
    """(n_lines, n_shapes, n_shapes): the coordinates' covariance from the points' noise plus
    an excess v |phi_p|^2 at every point (phi the line's fitted response), v per good line
    from its residual: E sum_p |r_p|^2 / s_p^2 = 2 sum_p (1 - lev_p)(1 + v |phi_p|^2 / s_p^2)
    (lev the fit's leverages), v floored at 0."""
    a = basis * weights[:, None]
    solve = np.linalg.solve(basis.T @ a, a.T)                     # (n_shapes, n_points)
    keep = 1.0 - np.einsum("pk,kp->p", basis, solve)[:, None]     # 1 - leverage
    fit = np.abs(basis @ coords) ** 2                             # (n_points, n_lines)
    chi = np.sum(np.abs(h - basis @ coords[:, good]) ** 2 / std**2, axis=0)
    excess = chi - 2.0 * float(np.sum(keep))                     # 2 (n_points - n_shapes)
    v = np.zeros(fit.shape[1])
    v[good] = np.maximum(excess / (2.0 * np.sum(keep * fit[:, good] / std**2, axis=0)), 0.0)
    var = values_std**2 + v[None, :] * fit
    return np.einsum("kp,pl,jp->lkj", solve, var, solve)


@contextlib.contextmanager
def _variant(name: str, log: list[dict]) -> Iterator[None]:
    """``broadband._line_coordinates`` as the variant states them; every call's Birge factors
    and stated covariance appended to ``log``."""
    original = broadband._line_coordinates

    def coordinates(basis, weights, values, values_std, good, h, std,  # type: ignore[no-untyped-def]
                    n_points, n_lines):
        coords, cov = original(basis, weights, values, values_std, good, h, std, n_points,
                               n_lines)
        birge = np.ones(n_lines)
        birge[good] = _birge(basis, coords, good, h, std, n_points)
        noise = cov / birge[:, None, None]
        out = {"on": cov, "off": noise}.get(name)
        if out is None:
            out = _proportional(basis, weights, values_std, good, h, std, coords)
        log.append({"birge": birge, "stated_over_noise": np.trace(out, axis1=1, axis2=2)
                    / np.trace(noise, axis1=1, axis2=2)})
        return coords, out

    broadband._line_coordinates = coordinates
    try:
        yield
    finally:
        broadband._line_coordinates = original


@contextlib.contextmanager
def _scan_share(found: list[np.ndarray]) -> Iterator[None]:
    """Keep what :func:`reconstruct_any` feeds its scan-share note: (2, N), the total's
    variance from the scan's noise and all its stated variance [N^2]."""
    original = transient.ScanNoiseShare

    class Capture(original):  # type: ignore[misc, valid-type]
        def add(self, samples: np.ndarray) -> None:
            found.append(np.array(samples))
            super().add(samples)

    transient.ScanNoiseShare = Capture
    try:
        yield
    finally:
        transient.ScanNoiseShare = original


@contextlib.contextmanager
def _without_shapes_part() -> Iterator[None]:
    """The scan's noise through the span shapes' coefficients set to zero: what is left of
    its part is the ratios'."""
    original = inertia_errors.shape_error_weights

    def zero(model, frequencies, probe_shapes, weights, basis_couplings,  # type: ignore[no-untyped-def]
             basis_probes, rows):
        return np.zeros((len(rows), len(frequencies)))

    inertia_errors.shape_error_weights = zero
    try:
        yield
    finally:
        inertia_errors.shape_error_weights = original


@contextlib.contextmanager
def _shapes_held(shapes: tuple | None, seen: list | None = None) -> Iterator[None]:
    """With ``shapes``, every scan's span shapes are those (the lines' coordinates and ratios
    then taken on them: the spread across seeds is the ratios' noise alone); the shapes each
    scan fits appended to ``seen``."""
    original = broadband._span_shapes

    def span_shapes(*args):  # type: ignore[no-untyped-def]
        fitted = original(*args)
        if seen is not None:
            seen.append(fitted)
        return fitted if shapes is None else shapes

    broadband._span_shapes = span_shapes
    try:
        yield
    finally:
        broadband._span_shapes = original


# --- one scan seed ---------------------------------------------------------------------------

def _ratio_part(sim0: Path, model: Path) -> np.ndarray:
    """(N,) [N^2]: the ratios' part of the total's variance from the scan's noise."""
    rig = load_rig(sim0 / "rig.toml")
    run = read_run(sim0 / "runs" / f"{PRESET}.csv", rig)
    tare = sim0 / "runs" / "tare.csv"
    found: list[np.ndarray] = []
    with _scan_share(found), _without_shapes_part():
        transient.reconstruct_any(rig, load_any_model(model), run,
                                  read_run(tare, rig) if tare.exists() else None)
    return found[-1][0]


def _model_facts(model: Path, log: list[dict]) -> dict:
    """What the model states at the mode: the ratio choice, the shapes, each shape's ratio
    uncertainty at the line nearest the mode, and the stated coordinate covariance over the
    points' noise alone there (trace), with the line's Birge factor."""
    doc = json.loads(model.read_text())
    f = np.asarray(doc["frequencies"])
    at = int(np.argmin(np.abs(f - MODE_HZ)))
    return {"ratio_source": doc["ratio_model"]["source"], "n_shapes": len(doc["shapes"]),
            "mode_line_hz": float(f[at]),
            "ratio_std_at_mode": [float(row[at]) for row in doc["ratio_std"]],
            "cov_over_noise_at_mode": float(log[-1]["stated_over_noise"][at]),
            "birge_at_mode": float(log[-1]["birge"][at]),
            "birge": log[-1]["birge"].tolist(), "frequencies": f.tolist()}


def _scan_seed(sim0: Path, scan: Path, folder: Path, log: list[dict]) -> dict | None:
    """Scan ``scan`` into a model, reconstruct the seed-0 run with it; the estimate, its
    statement and its scan's part, the truth as claimed, and the model's facts (None where
    ``scan`` refuses the scan)."""
    folder.mkdir(parents=True, exist_ok=True)
    model, rig = folder / "model.json", str(sim0 / "rig.toml")
    start = time.perf_counter()
    if main(["scan", "-q", rig, str(scan), "-o", str(model)]) != 0:
        return None                                     # refused: said on stderr
    tare = sim0 / "runs" / "tare.csv"
    found: list[np.ndarray] = []
    with _scan_share(found):
        if main(["reconstruct", "-q", rig, str(model), str(sim0 / "runs" / f"{PRESET}.csv"),
                 *(["--tare", str(tare)] if tare.exists() else []),
                 "-o", str(folder / "out")]) != 0:
            raise SystemExit(f"reconstruct with {model} failed")
    est = pd.read_csv(folder / "out" / f"{PRESET}.forces.csv")
    truth = pd.read_csv(sim0 / "truth" / f"{PRESET}.forces.csv")
    claimed = _claimed(sim0, model, PRESET, truth)
    ratio = _ratio_part(sim0, model)
    return {"est": est, "claimed": claimed, "scan_var": found[-1][0], "ratio_var": ratio,
            "stated_var_captured": found[-1][1], "facts": _model_facts(model, log),
            "seconds": time.perf_counter() - start}


# --- the windows -----------------------------------------------------------------------------

def _windows_over_seeds(seeds: list[dict], truth: pd.DataFrame) -> dict[str, list[float]]:
    """Every window's figures over the scan seeds (see the module docstring)."""
    t = truth["time"].to_numpy()
    n = int(round(WIDTH / (t[1] - t[0])))
    k = len(seeds)
    total = np.array([s["est"]["total"].to_numpy() for s in seeds])
    u2 = np.array([s["est"]["total_std"].to_numpy() ** 2 for s in seeds])
    claimed = np.array([s["claimed"] for s in seeds])
    scan = np.array([s["scan_var"] for s in seeds])
    ratio = np.array([s["ratio_var"] for s in seeds])
    err = total - claimed
    dev2 = (total - total.mean(axis=0)) ** 2 * k / (k - 1)
    common = total.mean(axis=0) - claimed.mean(axis=0)
    err_pct = np.array([_windows(s["est"], truth.assign(total=s["claimed"]), "total", WIDTH)
                        for s in seeds])
    ratios = np.array([_stated_windows(s["est"], s["claimed"], WIDTH) for s in seeds])
    out: dict[str, list[float]] = {key: [] for key in (
        "t0", "err", "stated", "err_over_stated", "mean_spread_over_stated",
        "spread_over_stated", "scan_over_stated", "spread_over_scan", "ratio_share",
        "common_over_stated", "common_over_rest")}
    for j, start in enumerate(range(0, t.size - n + 1, n)):
        w = slice(start, start + n)
        ac = float(np.std(truth["total"].to_numpy()[w]))
        u, s = float(np.sqrt(np.mean(u2[:, w]))), float(np.sqrt(np.mean(scan[:, w])))
        spread = float(np.sqrt(np.mean(dev2[:, w])))
        rest = float(np.sqrt(max(np.mean(u2[:, w]) - np.mean(scan[:, w]), 0.0)))
        row = {"t0": float(t[start]), "err": float(np.sqrt(np.mean(err_pct[:, j] ** 2))),
               "stated": u / ac, "err_over_stated": float(np.sqrt(np.mean(ratios[:, j] ** 2))),
               "mean_spread_over_stated": float(np.std(err[:, w].mean(axis=1), ddof=1)) / u,
               "spread_over_stated": spread / u, "scan_over_stated": s / u,
               "spread_over_scan": spread / s if s > 0 else float("nan"),
               "ratio_share": float(np.mean(ratio[:, w]) / np.mean(scan[:, w])),
               "common_over_stated": float(np.sqrt(np.mean(common[w] ** 2))) / u,
               "common_over_rest": float(np.sqrt(np.mean(common[w] ** 2))) / rest
               if rest > 0 else float("nan")}
        for key, value in row.items():
            out[key].append(value)
    return out


def _points_noise(scans: list[Path], band: tuple[float, float]) -> dict[str, list[float]]:
    """Per line, the scatter across seeds of every point's response over its stated standard
    uncertainty (RMS over the points)."""
    values, std = [], []
    for path in scans:
        resp = frf.scan_response(read_scan(path), band)
        values.append(resp.values)
        std.append(resp.std)
    h, s2 = np.array(values), np.array(std) ** 2
    k = len(scans)
    seen = np.mean(np.abs(h - h.mean(axis=0)) ** 2, axis=0) / 2.0 * k / (k - 1)  # Re, Im each
    return {"frequencies": resp.frequencies.tolist(),
            "observed_over_stated": np.sqrt(np.mean(seen, axis=0)
                                            / np.mean(s2, axis=(0, 1))).tolist()}


# --- the benchmark ---------------------------------------------------------------------------

def _variant_run(name: str, sims: list[Path], work: Path, fixed: bool) -> dict:
    """One variant over every scan seed: its windows, its models' facts and its time; with
    ``fixed``, every scan's span shapes those of the seed-0 scan (:func:`_shapes_held`)."""
    truth = pd.read_csv(sims[0] / "truth" / f"{PRESET}.forces.csv")
    folder = work / (f"{name}-fixed" if fixed else name)
    log: list[dict] = []
    held = _reference_shapes(name, sims[0], folder / "reference") if fixed else None
    seeds, refused = [], []
    with _variant(name, log), _shapes_held(held):
        for k, sim in enumerate(sims[1:], start=1):
            calls = len(log)
            seed = _scan_seed(sims[0], sim / "scan.uff", folder / f"scan-{k}", log)
            if len(log) != calls + 1:
                raise SystemExit(f"the variant '{name}' did not reach the scan of seed {k}")
            if seed is None:
                refused.append(k)
                continue
            seeds.append(seed)
            stated = np.sqrt(seed["stated_var_captured"])
            if not np.allclose(stated, seed["est"]["total_std"], rtol=1e-4, atol=1e-9):
                raise SystemExit("the captured statement is not the written one")
    birge = np.sqrt(np.median([s["facts"]["birge"] for s in seeds], axis=0))
    return {"windows": _windows_over_seeds(seeds, truth),
            "seconds_per_seed": float(np.mean([s["seconds"] for s in seeds])),
            "models": [{key: v for key, v in s["facts"].items()
                        if key not in ("birge", "frequencies")} for s in seeds],
            "sqrt_birge_median": birge.tolist(), "refused_scan_seeds": refused}


def _reference_shapes(name: str, sim0: Path, folder: Path) -> tuple:
    """The span shapes the seed-0 scan gives under the variant ``name``."""
    folder.mkdir(parents=True, exist_ok=True)
    seen: list[tuple] = []
    with _variant(name, []), _shapes_held(None, seen):
        if main(["scan", "-q", str(sim0 / "rig.toml"), str(sim0 / "scan.uff"), "-o",
                 str(folder / "model.json")]) != 0:
            raise SystemExit(f"scan of {sim0 / 'scan.uff'} failed")
    return seen[-1]


def run(n_seeds: int, variants: list[str], work: Path, fixed: bool = False) -> dict:
    """Simulate seeds 0..``n_seeds`` (checking they differ only in their noise), read the
    points' noise, and run every variant."""
    sims, sim_s = [], []
    for seed in range(n_seeds + 1):
        folder, seconds = _simulate(work, seed)
        sims.append(folder)
        sim_s.append(seconds)
        _check_same(sims[0], folder)
    band = load_rig(sims[0] / "rig.toml").band
    assert band is not None
    res: dict = {"preset": PRESET, "scan_seeds": list(range(1, n_seeds + 1)), "run_seed": 0,
                 "window_s": WIDTH,
                 "simulate_s_per_seed": float(np.mean([x for x in sim_s if x > 0]))
                 if any(sim_s) else None,
                 "same_across_seeds": [*SAME, f"truth/{PRESET}.npz (every array)"],
                 "points_noise": _points_noise([s / "scan.uff" for s in sims[1:]], band),
                 "variants": {}}
    for name in variants:
        start = time.perf_counter()
        key = f"{name}, shapes fixed" if fixed else name
        res["variants"][key] = _variant_run(name, sims, work, fixed)
        res["variants"][key]["seconds"] = time.perf_counter() - start
    return res


def report(res: dict) -> None:
    """The points' noise near the mode, then every variant's windows."""
    p = res["points_noise"]
    print(f"{PRESET}: run at seed 0, scans at seeds {res['scan_seeds'][0]}.."
          f"{res['scan_seeds'][-1]}; rig and truth the same at every seed")
    print("the scan's points across seeds, per line: observed scatter / stated std (RMS over "
          "points)")
    for f, a in zip(p["frequencies"], p["observed_over_stated"], strict=True):
        if 40.0 <= f <= 100.0:
            print(f"  {f:6.1f} Hz  {a:6.2f}")
    for name, v in res["variants"].items():
        m = v["models"]
        print(f"\n--birge {name}: {len(m)} scan seeds ({v['seconds_per_seed']:.1f} s each: scan, "
              f"reconstruct, claimed truth, ratios' part; scans refused: "
              f"{v['refused_scan_seeds'] or 'none'}); ratios "
              f"{sorted({x['ratio_source'] for x in m})}, shapes "
              f"{sorted({x['n_shapes'] for x in m})}")
        print(f"  seed 1 at {m[0]['mode_line_hz']:g} Hz: ratio std "
              + " ".join(f"{x:.3g}" for x in m[0]["ratio_std_at_mode"][1:])
              + f"; stated coordinate cov / points' noise {m[0]['cov_over_noise_at_mode']:.3g}"
              f" (Birge {m[0]['birge_at_mode']:.3g})")
        w = v["windows"]
        print(f"  {'t0 [s]':>6} {'err %':>7} {'u %':>7} {'e/u':>5} {'mean/u':>6} {'sprd/u':>6} "
              f"{'scan/u':>6} {'sprd/scan':>9} {'ratio':>5} {'comm/u':>6} {'comm/rest':>9}")
        for j, t0 in enumerate(w["t0"]):
            print(f"  {t0:6.1f} {w['err'][j]:7.3%} {w['stated'][j]:7.3%} "
                  f"{w['err_over_stated'][j]:5.2f} {w['mean_spread_over_stated'][j]:6.3f} "
                  f"{w['spread_over_stated'][j]:6.2f} {w['scan_over_stated'][j]:6.2f} "
                  f"{w['spread_over_scan'][j]:9.2f} {w['ratio_share'][j]:5.2f} "
                  f"{w['common_over_stated'][j]:6.2f} "
                  f"{w['common_over_rest'][j]:9.2f}")


def decomposition(res: dict) -> dict[str, dict[str, list[float]]]:
    """For every variant run both ways, each window's observed scan noise split in two, over
    its stated part [1]: the ratios' (the spread with the shapes held, over that run's stated
    ratios' part) and the shapes' (what the free spread adds to it in quadrature, over the free
    run's stated shapes' part); both in units of the window's AC RMS before dividing."""
    out = {}
    for name, free in res["variants"].items():
        held = res["variants"].get(f"{name}, shapes fixed")
        if held is None:
            continue
        f, h = free["windows"], held["windows"]

        def abs_(w: dict, key: str) -> np.ndarray:
            return np.asarray(w[key]) * np.asarray(w["stated"])

        spread_f, spread_h = abs_(f, "spread_over_stated"), abs_(h, "spread_over_stated")
        ratio_h = abs_(h, "scan_over_stated") * np.sqrt(h["ratio_share"])
        shapes_f = abs_(f, "scan_over_stated") * np.sqrt(1.0 - np.asarray(f["ratio_share"]))
        shapes_seen = np.sqrt(np.maximum(spread_f**2 - spread_h**2, 0.0))
        out[name] = {"t0": f["t0"], "ratios_observed_over_stated": (spread_h / ratio_h).tolist(),
                     "shapes_observed_over_stated": (shapes_seen / shapes_f).tolist(),
                     "spread_held_over_free": (spread_h / spread_f).tolist()}
    return out


def report_decomposition(parts: dict[str, dict[str, list[float]]]) -> None:
    """The split of :func:`decomposition`, window by window."""
    for name, d in parts.items():
        print(f"\n--birge {name}: the scan's observed noise over its stated part, split "
              "(shapes held at the seed-0 scan's: the ratios' alone)")
        print(f"  {'t0 [s]':>6} {'ratios':>7} {'shapes':>7} {'held/free':>9}")
        for j, t0 in enumerate(d["t0"]):
            print(f"  {t0:6.1f} {d['ratios_observed_over_stated'][j]:7.2f} "
                  f"{d['shapes_observed_over_stated'][j]:7.2f} "
                  f"{d['spread_held_over_free'][j]:9.2f}")


def _save(res: dict) -> Path:
    """Write the results, keeping the variants of an earlier run over the same seeds."""
    RESULTS.mkdir(exist_ok=True)
    path = RESULTS / "scan_redraw.json"
    if path.exists():
        old = json.loads(path.read_text())
        if old.get("scan_seeds") == res["scan_seeds"]:
            res["variants"] = {**old.get("variants", {}), **res["variants"]}
    path.write_text(json.dumps(res, indent=1))
    return path


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=8, help="scan seeds 1..N (default 8)")
    parser.add_argument("--birge", nargs="+", choices=VARIANTS, default=["on"],
                        help="how each line's coordinate covariance is stated")
    parser.add_argument("--work", type=Path, help="keep the simulations here")
    parser.add_argument("--fixed-shapes", action="store_true",
                        help="every scan's span shapes the seed-0 scan's: the ratios' noise alone")
    args = parser.parse_args()
    if args.seeds < 2:
        parser.error("--seeds: at least 2 scan seeds")
    with tempfile.TemporaryDirectory() as tmp:
        out = run(args.seeds, args.birge, args.work or Path(tmp), args.fixed_shapes)
    path = _save(out)
    out = json.loads(path.read_text())
    out["decomposition"] = decomposition(out)
    path.write_text(json.dumps(out, indent=1))
    report(out)
    report_decomposition(out["decomposition"])
    print(f"\nwrote {path}")
    sys.exit(0)

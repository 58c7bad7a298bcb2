"""Fuzzing the command line with mutated inputs: a small lab, mutators per input kind, an oracle.

Shared by ``tests/test_fuzz.py`` (a few hundred seeded cases, hypothesis) and
``benchmarks/fuzz.py`` (thousands). The contract checked (INTERFACES.md section 5): every
command either

- exits 0 with outputs that are finite, valid JSON (no NaN/Infinity) and physically bounded
  (forces within ``FORCE_FACTOR`` times the clean run's peak: :mod:`fuzz_oracle`), or
- exits 2 with exactly one line on stderr that names the file at fault (or another input file
  of the command, when the combination is at fault; for an argument, the option), and leaves
  no output file behind;

never exit 1, never an exception. For the key kinds (:data:`fuzz_keys.KEY_KINDS`: a key
misspelt, in the wrong case, moved, an unknown table, a key written twice) only the refusal is
right, and its line must name the mutated key too; exit 0 is silent.

A case is ``(kind, seed)``: :func:`make_case` draws one mutation of that kind's input with
``random.Random(seed)`` (the mutators are in :mod:`fuzz_mutations` and :mod:`fuzz_keys`) and
:func:`run_case` runs it through :func:`forcecal.cli.main` in process and classifies the
outcome (:data:`OUTCOMES`).
"""

from __future__ import annotations

import contextlib
import io
import json
import random
import shutil
import traceback
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np
from fuzz_keys import FAMILIES, KEY_KINDS, key_case, names_key, write_key_rig
from fuzz_mutations import extreme, mutate_doc, text_mutation, write_file
from fuzz_oracle import check_outputs

OK, REFUSED, UNCLEAN, INTERNAL, SILENT = "ok", "refused", "unclean", "internal", "silent"
OUTCOMES = (OK, REFUSED, UNCLEAN, INTERNAL, SILENT)
"""ok: exit 0, sound outputs; refused: exit 2, one line naming the input, no output;
unclean: a refusal that breaks the form (several lines, no name, output left behind; for a
key kind, a line that does not name the key); internal: exit 1 or an exception; silent: exit 0
with non-finite or absurd outputs, or, for a key kind, exit 0 at all."""

VALUE_KINDS = ("rig", "scan_uff", "scan_frf", "scan_h5", "scan_npz", "run_csv", "run_tdms",
               "run_h5", "manifest", "model", "calibration", "arguments")
"""Damaged values and bytes: a sound exit 0 and a clean refusal are both right."""
KINDS = (*VALUE_KINDS, *KEY_KINDS)

_RUN_DECIMATE = 4      # the lab's run: 10 kHz -> 2.5 kHz, 1 s (20 periods)
_SCAN_DECIMATE = 2     # the lab's scan: 10 kHz -> 5 kHz, 0.5 s
_SCAN_POINT_STEP = 3   # 61 points -> 21


# --------------------------------------------------------------------------------------------
# the lab


@dataclass
class Lab:
    """A small valid lab and what its clean outputs look like."""

    root: Path
    force_peak: float = 0.0
    predict_force: float = 0.0
    files: dict[str, Path] = field(default_factory=dict)


def _quiet_main(argv: list[str]) -> int:
    from forcecal.cli.main import main

    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        return main(argv)


def build_lab(root: Path) -> Lab:
    """``forcecal simulate ROOT --preset paper``, made small, in every accepted format.

    The run is decimated to 2.5 kHz and the scan to 21 points at 5 kHz so that a case runs in
    a fraction of a second; the clean model, forces and calibration are computed once.
    """
    from forcecal.io.run_files import read_run, write_run_csv, write_run_hdf5, write_run_tdms
    from forcecal.io.scan_files import read_scan, write_scan_hdf5, write_scan_npz
    from forcecal.io.uff import write_scan_uff
    from forcecal.records import Run, Scan

    root = Path(root)
    assert _quiet_main(["simulate", str(root), "--preset", "paper"]) == 0
    run = read_run(root / "runs" / "paper.csv")
    small_run = Run(channels={k: v[::_RUN_DECIMATE] for k, v in run.channels.items()},
                    fs=run.fs / _RUN_DECIMATE, t0=run.t0, name="paper")
    write_run_csv(small_run, root / "runs" / "paper.csv")
    write_run_tdms(small_run, root / "runs" / "paper.tdms")
    write_run_hdf5(small_run, root / "runs" / "paper.h5")
    scan = read_scan(root / "scan.uff")
    small_scan = Scan(points=scan.points[::_SCAN_POINT_STEP],
                      response=scan.response[::_SCAN_POINT_STEP, ::_SCAN_DECIMATE],
                      reference=scan.reference[::_SCAN_POINT_STEP, ::_SCAN_DECIMATE],
                      fs=scan.fs / _SCAN_DECIMATE, quantity=scan.quantity)
    write_scan_uff(small_scan, root / "scan.uff")
    write_scan_hdf5(small_scan, root / "scan.h5")
    write_scan_npz(small_scan, root / "scan.npz")
    rig = str(root / "rig.toml")
    assert _quiet_main(["scan", rig, str(root / "scan.uff"), "-o", str(root / "model.json")]) == 0
    assert _quiet_main(["calibrate", rig, str(root / "model.json"), "--manifest",
                        str(root / "manifest.csv"), "-o", str(root / "cal"),
                        "--no-report"]) == 0
    shutil.copy(root / "cal" / "calibration.json", root / "calibration.json")
    shutil.rmtree(root / "cal")
    out = root / "clean"
    assert _quiet_main(["reconstruct", rig, str(root / "model.json"),
                        str(root / "runs" / "paper.csv"), "-o", str(out)]) == 0
    lab = Lab(root=root)
    lab.force_peak = _table_peak(out / "paper.forces.csv")
    shutil.rmtree(out)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from forcecal.actuator import predict
        from forcecal.campaign import load_calibration

        pred = predict(load_calibration(root / "calibration.json"), [1.0], 0.0009)
    lab.predict_force = float(abs(pred.total[0]))
    _frf_scan(root)
    lab.files = {
        "rig": root / "rig.toml", "scan_uff": root / "scan.uff", "scan_h5": root / "scan.h5",
        "scan_frf": root / "scan_frf.uff", "rig_frf": root / "rig_frf.toml",
        "scan_npz": root / "scan.npz", "run_csv": root / "runs" / "paper.csv",
        "run_tdms": root / "runs" / "paper.tdms", "run_h5": root / "runs" / "paper.h5",
        "manifest": root / "manifest.csv", "model": root / "model.json",
        "calibration": root / "calibration.json", "model_frf": root / "model_frf.json",
        "rig_keys": _key_rig(root),
    }
    return lab


def _key_rig(root: Path) -> Path:
    """The rig the key kinds mutate (:func:`fuzz_keys.write_key_rig`); as it is, it must run."""
    path = write_key_rig(root)
    assert _quiet_main(["scan", str(path), str(root / "scan.npz"), "-o",
                        str(root / "model_keys.json")]) == 0, f"{path} is refused as it is"
    return path


def _frf_scan(root: Path) -> None:
    """The 'random' preset's chirp scan as FRFs with their coherence (21 points, lines up to
    300 Hz: ``scan_frf.uff``) and its broadband rig (``rig_frf.toml``, 4 averages)."""
    import dataclasses

    import tomli_w

    from forcecal.io.uff import write_frf_uff
    from forcecal.records import ScanFRF
    from forcecal.rig import rig_to_dict
    from forcecal.simulate.presets import get_preset
    from forcecal.simulate.sldv_frf import frf_export
    from forcecal.simulate.virtual_rig import build_model, public_rig, record_scan

    preset = get_preset("random")
    assert preset.band is not None
    scan = record_scan(preset, np.random.default_rng(0), build_model(preset))
    frfs, averages = frf_export(scan, preset.band, 300.0)
    step = _SCAN_POINT_STEP
    write_frf_uff(ScanFRF(points=frfs.points[::step], frequencies=frfs.frequencies,
                          values=frfs.values[::step], coherence=frfs.coherence[::step],
                          quantity=frfs.quantity), root / "scan_frf.uff")
    rig = dataclasses.replace(public_rig(preset), band=preset.band, drive="any",
                              scan_averages=averages)
    (root / "rig_frf.toml").write_text(tomli_w.dumps(rig_to_dict(rig)), encoding="utf-8")
    assert _quiet_main(["scan", str(root / "rig_frf.toml"), str(root / "scan_frf.uff"), "-o",
                        str(root / "model_frf.json")]) == 0


def _table_peak(path: Path) -> float:
    from forcecal.io.run_files import read_table_csv

    _, cols = read_table_csv(path)
    return float(max(np.max(np.abs(v)) for k, v in cols.items()))


# --------------------------------------------------------------------------------------------
# a case


@dataclass
class Case:
    """One mutated input and the command that reads it."""

    kind: str
    seed: int
    what: str                      # the mutation, for the report
    argv: list[str]
    names: tuple[str, ...]         # a refusal must name one of these
    outputs: list[Path]            # where outputs go (files or folders)
    command: str = ""
    stdout_bytes: bool = False     # stdout as strict UTF-8 bytes (a non-UTF-8 file name)
    folder: Path = Path()          # the working folder of the command
    key: str = ""                  # a key kind's mutated key: a refusal must name it


@dataclass
class Outcome:
    kind: str
    seed: int
    what: str
    outcome: str
    code: int | None
    detail: str


# ---------------------------------------------------------------------------- per kind


def _case_rig(lab: Lab, d: Path, rng: random.Random) -> Case:
    import tomllib

    import tomli_w

    target = d / "rig.toml"
    text = lab.files["rig"].read_bytes()
    if rng.random() < 0.75:
        doc = tomllib.loads(text.decode())
        what = mutate_doc(doc, rng)
        try:
            data = tomli_w.dumps(doc).encode()
        except (TypeError, ValueError):
            data, what = text.replace(b"0.6", b"1e300", 1), "length = 1e300"
    else:
        data, what = text_mutation(text, rng)
    write_file(target, data)
    # the rig is read before the scan: reconstruct from the NPZ scan (its model is rebuilt)
    out = d / "out"
    argv = ["reconstruct", str(target), str(lab.files["scan_npz"]),
            str(lab.files["run_csv"]), "-o", str(out)]
    if rng.random() < 0.3:  # scales and gaps do not enter the model: use the saved one
        argv[2] = str(lab.files["model"])
    return Case("rig", 0, what, argv, (str(target), target.name), [out], "reconstruct")


def _case_scan_arrays(lab: Lab, d: Path, rng: random.Random, fmt: str) -> Case:
    src = lab.files["scan_npz"]
    with np.load(src) as z:
        arrays: dict[str, Any] = {k: z[k] for k in z.files}
    target = d / f"scan.{fmt}"
    r = rng.random()
    if r < 0.85:
        key = rng.choice(["x", "response", "reference", "fs", "quantity", "response",
                          "reference"])
        a = arrays[key]
        q = rng.random()
        if key == "quantity":
            arrays[key] = np.str_(rng.choice(["", "acceleration", "Velocity", "x" * 1000]))
        elif key == "fs" or q < 0.15:
            arrays[key] = np.asarray(extreme(rng, float(np.ravel(a)[0]) if a.size else 1.0))
        elif q < 0.45:
            b = np.array(a, dtype=float)
            b.flat[rng.randrange(b.size)] = extreme(rng)
            arrays[key] = b
        elif q < 0.6:
            arrays[key] = np.asarray(a, dtype=float) * rng.choice([1e300, 1e-300, 0.0, -1.0])
        elif q < 0.75:
            arrays[key] = a[: rng.choice([0, 1, 3, len(a) // 2])]
        elif q < 0.85:
            arrays[key] = a[..., : rng.choice([0, 1, 10, 200])] if a.ndim else a
        elif q < 0.95:
            arrays[key] = np.asarray(a).astype(str) if a.size < 100 else a.T
        else:
            del arrays[key]
        what = f"'{key}' mutated ({q:.2f})"
        if fmt == "npz":
            with target.open("wb") as fh:
                np.savez(fh, **arrays)
        else:
            with h5py.File(target, "w") as h5:
                for k, v in arrays.items():
                    v = np.asarray(v)
                    h5.create_dataset(k, data=v.astype("S") if v.dtype.kind == "U" else v)
    else:
        base = (lab.files["scan_npz"] if fmt == "npz" else lab.files["scan_h5"]).read_bytes()
        data, what = text_mutation(base, rng)
        write_file(target, data)
    out = d / "model.json"
    argv = ["scan", str(lab.files["rig"]), str(target), "-o", str(out)]
    return Case(f"scan_{fmt}", 0, what, argv, (str(target), target.name), [out], "scan")


def _case_scan_uff(lab: Lab, d: Path, rng: random.Random, kind: str = "scan_uff",
                   rig: str = "rig") -> Case:
    target = d / "scan.uff"
    text = lab.files[kind].read_bytes()
    lines = text.split(b"\n")
    r = rng.random()
    if r < 0.35:  # a value in a data line
        k = rng.randrange(len(lines))
        while b"E" not in lines[k] and b"e" not in lines[k]:
            k = rng.randrange(len(lines))
        tokens = lines[k].split()
        j = rng.randrange(len(tokens))
        new = rng.choice([b"nan", b"+inf", b"-inf", b"1.00000000000E+300", b"9" * 30,
                          b"x", b"1.0E+308"])
        tokens[j] = new.rjust(20)
        lines[k] = b"".join(t.rjust(20) for t in tokens)
        data, what = b"\n".join(lines), f"line {k + 1}: {new.decode()!r}"
    elif r < 0.55:  # cut short at a dataset boundary (a scan of fewer points)
        ends = [k for k, ln in enumerate(lines) if ln.strip() == b"-1"]
        cut = rng.choice(ends[2:-2:2] or ends)
        data, what = b"\n".join(lines[: cut + 1]) + b"\n", f"cut after line {cut + 1}"
    elif r < 0.7:  # one dataset removed
        ends = [k for k, ln in enumerate(lines) if ln.strip() == b"-1"]
        i = rng.randrange(0, len(ends) - 1, 2)
        data = b"\n".join(lines[: ends[i]] + lines[ends[i + 1] + 1:])
        what = f"dataset at line {ends[i] + 1} removed"
    else:
        data, what = text_mutation(text, rng)
    write_file(target, data)
    out = d / "model.json"
    argv = ["scan", str(lab.files[rig]), str(target), "-o", str(out)]
    return Case(kind, 0, what, argv, (str(target), target.name), [out], "scan")


def _csv_cell_value(rng: random.Random) -> str:
    return rng.choice(["nan", "inf", "-inf", "1e308", "1e300", "-1e300", "1e299", "text", "",
                       "1" * 200_000, "0x10", "1e-320", "NaN", "1_000", " 1 "])


def _case_run_csv(lab: Lab, d: Path, rng: random.Random) -> Case:
    target = d / "paper.csv"
    text = lab.files["run_csv"].read_text()
    lines = text.splitlines()
    header = lines[0].split(",")
    r = rng.random()
    if r < 0.4:
        k = rng.randrange(1, len(lines))
        cells = lines[k].split(",")
        j = rng.randrange(len(cells))
        v = _csv_cell_value(rng)
        cells[j] = v
        lines[k] = ",".join(cells)
        what = f"row {k + 1}, column {header[j]!r} = {v[:20]!r}"
    elif r < 0.55:  # a whole column scaled
        j = rng.randrange(len(header))
        f = rng.choice([1e300, 1e-300, 0.0, 1e30, -1.0, 1e150])
        rows = [ln.split(",") for ln in lines[1:]]
        for row in rows:
            row[j] = repr(float(row[j]) * f)
        lines = [lines[0]] + [",".join(row) for row in rows]
        what = f"column {header[j]!r} x {f:g}"
    elif r < 0.65:  # a column constant (a dead or clipped sensor)
        j = rng.randrange(1, len(header))
        rows = [ln.split(",") for ln in lines[1:]]
        top = max(float(row[j]) for row in rows) * rng.choice([1.0, 0.5, 0.0])
        for row in rows:
            row[j] = repr(min(float(row[j]), top)) if top else "0.0"
        lines = [lines[0]] + [",".join(row) for row in rows]
        what = f"column {header[j]!r} clipped at {top:g}"
    elif r < 0.75:  # rows removed, repeated or cut
        n = rng.choice([5, 20, 100, 2400, 2490])
        lines = lines[: len(lines) - n] if rng.random() < 0.5 else lines[:1] + lines[1 + n:]
        what = f"{n} rows removed"
    elif r < 0.85:
        j = rng.randrange(len(header))
        header[j] = rng.choice(["", "time", "R1", "x" * 300, "Time", " s1 "])
        lines[0] = ",".join(header)
        what = f"header cell {j} = {header[j][:10]!r}"
    else:
        data, what = text_mutation(text.encode(), rng)
        write_file(target, data)
        return _run_case(lab, d, rng, target, "run_csv", what)
    write_file(target, ("\n".join(lines) + "\n").encode())
    return _run_case(lab, d, rng, target, "run_csv", what)


def _run_case(lab: Lab, d: Path, rng: random.Random, target: Path, kind: str,
              what: str) -> Case:
    r = rng.random()
    if r < 0.2:
        out = d / "paper.stream.csv"
        argv = ["stream", str(lab.files["rig"]), str(lab.files["model"]), str(target),
                "-o", str(out)]
        return Case(kind, 0, what, argv, (str(target), target.name), [out], "stream")
    out = d / "out"
    argv = ["reconstruct", str(lab.files["rig"]), str(lab.files["model"]), str(target),
            "-o", str(out)]
    return Case(kind, 0, what, argv, (str(target), target.name), [out], "reconstruct")


def _run_channels(lab: Lab) -> tuple[dict[str, np.ndarray], float, float]:
    from forcecal.io.run_files import read_run

    run = read_run(lab.files["run_h5"])
    return {k: np.array(v) for k, v in run.channels.items()}, run.fs, run.t0


def _mutate_channels(channels: dict[str, np.ndarray], rng: random.Random) -> str:
    name = rng.choice(list(channels))
    v = channels[name]
    q = rng.random()
    if q < 0.4:
        k = rng.randrange(v.size)
        v[k] = extreme(rng)
        return f"channel {name!r} sample {k} = {v[k]!r}"
    if q < 0.6:
        f = rng.choice([1e300, 1e-300, 0.0, 1e30, 1e150])
        channels[name] = v * f
        return f"channel {name!r} x {f:g}"
    if q < 0.75:
        channels[name] = v[: rng.choice([0, 1, 10, v.size - 1])]
        return f"channel {name!r} shortened"
    if q < 0.85:
        del channels[name]
        return f"channel {name!r} removed"
    channels[name] = np.minimum(v, np.max(v) * 0.5)
    return f"channel {name!r} clipped"


def _case_run_tdms(lab: Lab, d: Path, rng: random.Random) -> Case:
    from nptdms import ChannelObject, TdmsWriter

    target = d / "paper.tdms"
    if rng.random() < 0.8:
        channels, fs, t0 = _run_channels(lab)
        props = {n: {"wf_increment": 1.0 / fs, "wf_start_offset": t0,
                     "wf_samples": len(v)} for n, v in channels.items()}
        if rng.random() < 0.5:
            what = _mutate_channels(channels, rng)
        else:
            name = rng.choice(list(channels))
            key = rng.choice(["wf_increment", "wf_start_offset", "wf_increment"])
            value = rng.choice([float("nan"), 0.0, -1.0, 1e300, 1.0 / (2 * fs), 1.0 / (fs * 1.5),
                                1e-300, "text", float("inf")])
            targets = list(channels) if rng.random() < 0.3 else [name]
            for n in targets:
                props[n][key] = value
            what = f"{key} = {value!r} on {', '.join(targets)}"
        objects = [ChannelObject("g", n, np.asarray(v, dtype=float),
                                 properties=props.get(n, {})) for n, v in channels.items()]
        with TdmsWriter(str(target)) as w:
            w.write_segment(objects)
    else:
        data, what = text_mutation(lab.files["run_tdms"].read_bytes(), rng)
        write_file(target, data)
    return _run_case(lab, d, rng, target, "run_tdms", what)


def _case_run_h5(lab: Lab, d: Path, rng: random.Random) -> Case:
    target = d / "paper.h5"
    r = rng.random()
    if r < 0.8:
        channels, fs, t0 = _run_channels(lab)
        attrs: dict[str, Any] = {"fs": fs, "t0": t0}
        if rng.random() < 0.5:
            what = _mutate_channels(channels, rng)
        else:
            key = rng.choice(["fs", "t0"])
            attrs[key] = rng.choice([float("nan"), 0.0, -1.0, 1e300, "text", float("inf"),
                                     1e-300, np.array([1.0, 2.0])])
            what = f"attribute {key} = {attrs[key]!r}"
        with h5py.File(target, "w") as h5:
            for k, v in attrs.items():
                h5.attrs[k] = v
            for n, v in channels.items():
                h5.create_dataset(n, data=v)
    else:
        data = bytearray(lab.files["run_h5"].read_bytes())
        n = rng.choice([1, 10, 50])
        for _ in range(n):  # in the data (the file's tail), where HDF5 checks nothing
            k = rng.randrange(len(data) // 2, len(data))
            data[k] = rng.randrange(256)
        what = f"{n} flipped bytes"
        write_file(target, bytes(data))
    return _run_case(lab, d, rng, target, "run_h5", what)


def _case_manifest(lab: Lab, d: Path, rng: random.Random) -> Case:
    target = d / "manifest.csv"
    (d / "runs").symlink_to(lab.files["run_csv"].parent, target_is_directory=True)
    rows = [["run", "tare", "gap"], ["runs/paper.csv", "false", "0.0009"]]
    r = rng.random()
    if r < 0.5:
        v = rng.choice(["0.8", "0.9", "1e300", "0", "-0.001", "nan", "inf", "text", "0.1",
                        "1e-9", "0.5", "0.0009", "9e-4", "1e-5", "0.01"])
        rows[1][2] = v
        what = f"gap = {v}"
    elif r < 0.6:
        rows[0].append("gap_F9")
        rows[1].append("0.001")
        what = "gap_F9"
    elif r < 0.7:
        rows[0].append("gap_F1")
        rows[1].append(rng.choice(["0.8", "nan", "1e300", "0.0009"]))
        what = f"gap_F1 = {rows[1][-1]}"
    elif r < 0.8:
        rows[1][0] = rng.choice(["runs/none.csv", "", "/", "runs", "runs/paper.csv\x00"])
        what = f"run = {rows[1][0]!r}"
    elif r < 0.9:
        rows[1][1] = rng.choice(["true", "maybe", "2"])
        what = f"tare = {rows[1][1]!r}"
    else:
        data, what = text_mutation(b"\n".join(b",".join(c.encode() for c in row)
                                               for row in rows) + b"\n", rng)
        write_file(target, data)
        return _manifest_case(lab, d, target, what)
    write_file(target, ("\n".join(",".join(row) for row in rows) + "\n").encode())
    return _manifest_case(lab, d, target, what)


def _manifest_case(lab: Lab, d: Path, target: Path, what: str) -> Case:
    out = d / "out"
    argv = ["calibrate", str(lab.files["rig"]), str(lab.files["model"]), "--manifest",
            str(target), "-o", str(out), "--no-report"]
    return Case("manifest", 0, what, argv, (str(target), target.name, "paper.csv"), [out],
                "calibrate")


def _case_json(lab: Lab, d: Path, rng: random.Random, kind: str) -> Case:
    src = lab.files[kind]
    target = d / src.name
    text = src.read_bytes()
    r = rng.random()
    if r < 0.75:
        doc = json.loads(text)
        what = mutate_doc(doc, rng, numeric_bias=0.6)
        if kind == "model" and rng.random() < 0.3:
            q = rng.choice(["f0", "shapes", "harmonics", "order", "format"])
            if q == "f0":
                doc["f0_hz"] = rng.choice([0, -20.0, 1e300, 1e-300])
            elif q == "shapes":
                doc["shapes"] = doc["shapes"][:rng.choice([0, 1])]
            elif q == "harmonics":
                doc["harmonics"] = [*doc["harmonics"], 4, 5]
            elif q == "order":
                doc["shapes"][0]["order"] = rng.choice([999, 0, -1, 10**6])
            else:
                doc["format"] = rng.choice(["forcecal spatial model 9", "other", 1])
            what = f"model {q} mutated"
        data = json.dumps(doc).encode()  # NaN/Infinity as Python writes them
    else:
        data, what = text_mutation(text, rng)
    write_file(target, data)
    if kind == "model":
        out = d / "out"
        argv = ["reconstruct", str(lab.files["rig"]), str(target), str(lab.files["run_csv"]),
                "-o", str(out)]
        return Case(kind, 0, what, argv, (str(target), target.name), [out], "reconstruct")
    argv = ["predict", str(target), "--current", "1.0", "--gap", "0.0009"]
    if rng.random() < 0.5:
        argv.append("--json")
    return Case(kind, 0, what, argv, (str(target), target.name), [], "predict")


def _case_arguments(lab: Lab, d: Path, rng: random.Random) -> Case:
    rig, model, run = (str(lab.files[k]) for k in ("rig", "model", "run_csv"))
    out = d / "out"
    r = rng.randrange(9)
    if r == 0:
        v = rng.choice(["1e308", "-1e308", "nan", "inf", "1e6", "-1", "0", "abc", "1e30"])
        argv = ["predict", str(lab.files["calibration"]), "--current", v, "--gap", "0.0009"]
        opt = "--current"
    elif r == 1:
        v = rng.choice(["1e308", "0", "-0.001", "nan", "0.8", "1", "1e-12", "inf", "1e300"])
        argv = ["predict", str(lab.files["calibration"]), "--current", "1", "--gap", v]
        opt = "--gap"
    elif r == 2:
        v = rng.choice(["0", "-3", "1000000", "x", "1"])
        argv = ["reconstruct", rig, rng.choice([model, str(lab.files["scan_npz"])]), run,
                "-o", str(out), "--harmonics", v]
        opt = "--harmonics"
    elif r == 3:
        argv = ["reconstruct", rig, model, run, "-o", ""]
        opt = "-o"
        out = d / "paper.json"  # what an empty -o would write into the working folder
    elif r == 4:
        argv = ["report", rig, str(lab.files["scan_npz"]), run, "-o", str(out),
                "--truth", str(d / "nonexistent")]
        opt = "--truth"
    elif r == 5:
        v = rng.choice(["-1", "-5", "2**40", "99999999999999999999999"])
        argv = ["simulate", str(out), "--seed", v]
        opt = "--seed"
    elif r == 6:
        ext = rng.choice([".mat", ".txt", "", ".h5", ".csv", ".json"])
        out = d / f"out{ext}"
        argv = ["stream", rig, model, run, "-o", str(out)]
        opt = "-o"
    elif r == 7:
        v = rng.choice(["0", "-1", "1", "3", "100000000", "x"])
        argv = ["stream", rig, model, run, "-o", str(d / "s.csv"), "--block", v]
        out = d / "s.csv"
        opt = "--block"
    else:  # a non-UTF-8 run file name, with a strict UTF-8 stdout
        name = b"\xffpaper\xfe.csv"
        target = Path(bytes(d).decode() + "/" + name.decode("utf-8", "surrogateescape"))
        shutil.copy(lab.files["run_csv"], target)
        argv = ["reconstruct", rig, model, str(target), "-o", str(out)]
        return Case("arguments", 0, "non-UTF-8 run name", argv, ("paper",), [out],
                    "reconstruct", stdout_bytes=True)
    what = f"{argv[0]} {opt} {argv[argv.index(opt) + 1]!r}"
    return Case("arguments", 0, what, argv, (opt, "argument", "option"), [out], argv[0])


_MAKERS: dict[str, Callable[[Lab, Path, random.Random], Case]] = {
    "rig": _case_rig,
    "scan_uff": _case_scan_uff,
    "scan_frf": lambda lab, d, rng: _case_scan_uff(lab, d, rng, "scan_frf", "rig_frf"),
    "scan_h5": lambda lab, d, rng: _case_scan_arrays(lab, d, rng, "h5"),
    "scan_npz": lambda lab, d, rng: _case_scan_arrays(lab, d, rng, "npz"),
    "run_csv": _case_run_csv,
    "run_tdms": _case_run_tdms,
    "run_h5": _case_run_h5,
    "manifest": _case_manifest,
    "model": lambda lab, d, rng: _case_json(lab, d, rng, "model"),
    "calibration": lambda lab, d, rng: _case_json(lab, d, rng, "calibration"),
    "arguments": _case_arguments,
}


def make_case(lab: Lab, folder: Path, kind: str, seed: int) -> Case:
    """Draw one mutated input of ``kind`` into ``folder`` (empty or missing)."""
    folder.mkdir(parents=True, exist_ok=True)
    rng = random.Random(f"{kind}-{seed}")
    if kind in KEY_KINDS:  # seeds 0..4 draw each family once
        case = key_case(lab, folder, rng, kind, FAMILIES[seed % len(FAMILIES)])
    else:
        case = _MAKERS[kind](lab, folder, rng)
    case.seed = seed
    case.folder = folder
    return case


# --------------------------------------------------------------------------------------------
# running a case (the oracle that judges its outputs is fuzz_oracle)


def _leftovers(case: Case) -> list[Path]:
    left: list[Path] = []
    for o in case.outputs:
        if o.is_dir():
            left += [p for p in o.rglob("*") if p.is_file()]
        elif o.exists():
            left.append(o)
        if o.parent.is_dir():  # hidden temporaries beside a file output
            left += [p for p in o.parent.glob(f".{o.name}*")]
    return left


def run_case(case: Case, lab: Lab) -> Outcome:
    """Run the case's command in process and classify the outcome."""
    from forcecal.cli.main import main

    raw = io.BytesIO()
    out: io.TextIOBase
    if case.stdout_bytes:
        out = io.TextIOWrapper(raw, encoding="utf-8", errors="strict", write_through=True)
    else:
        out = io.StringIO()
    err = io.StringIO()
    code: int | None
    try:
        with (contextlib.redirect_stdout(out), contextlib.redirect_stderr(err),
              warnings.catch_warnings(), contextlib.chdir(case.folder)):
            warnings.simplefilter("default")
            code = main(case.argv)
    except BaseException as exc:
        tb = traceback.format_exception_only(type(exc), exc)[-1].strip()
        return Outcome(case.kind, case.seed, case.what, INTERNAL, None, f"raised {tb}")
    stdout = raw.getvalue().decode("utf-8", "replace") if case.stdout_bytes else out.getvalue()
    lines = [ln for ln in err.getvalue().splitlines()
             if ln.strip() and not ln.startswith(("  [", "  simulating"))]
    text = " | ".join(lines)[:300]
    if code == 0:
        bad = (f"exit 0: key '{case.key}' not refused" if case.key
               else check_outputs(case, lab, stdout))
        if bad:
            return Outcome(case.kind, case.seed, case.what, SILENT, code, bad)
        return Outcome(case.kind, case.seed, case.what, OK, code, text)
    if code != 2:
        return Outcome(case.kind, case.seed, case.what, INTERNAL, code, text)
    problems = []
    if len(lines) != 1:
        problems.append(f"{len(lines)} stderr lines")
    inputs = [a for a in case.argv[1:] if a.startswith("/") and Path(a).exists()]
    if lines and not any(n in lines[-1] for n in (*case.names, *inputs)):
        problems.append("names no input")
    if case.key and lines and not names_key(lines[-1], case.key):
        problems.append(f"names not the key '{case.key}'")
    left = _leftovers(case)
    if left:
        problems.append(f"left {', '.join(p.name for p in left[:3])}")
    if problems:
        return Outcome(case.kind, case.seed, case.what, UNCLEAN, code,
                       "; ".join(problems) + f": {text}")
    return Outcome(case.kind, case.seed, case.what, REFUSED, code, text)


def fuzz_one(lab: Lab, work: Path, kind: str, seed: int) -> Outcome:
    """Make, run and classify one case in a fresh folder under ``work``; cleans up after."""
    folder = work / f"{kind}-{seed}"
    if folder.exists():
        shutil.rmtree(folder)
    try:
        case = make_case(lab, folder, kind, seed)
    except Exception as exc:  # the harness's own failure: report it, loudly
        raise RuntimeError(f"could not make case {kind} {seed}: {exc}") from exc
    try:
        return run_case(case, lab)
    finally:
        shutil.rmtree(folder, ignore_errors=True)

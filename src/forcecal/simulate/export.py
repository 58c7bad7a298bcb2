"""Write a simulated campaign in the public formats (INTERFACES.md section 5, ``simulate``).

``OUT/rig.toml``, ``OUT/scan.uff``, ``OUT/runs/*.csv``, ``OUT/manifest.csv`` for the user's
side; ``OUT/truth/NAME.forces.csv``, ``OUT/truth/NAME.npz`` and ``OUT/truth/simulator.json``
(the parameters the lab would not know) for checking any estimate against the truth.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import tomli_w

from .._atomic import atomic_path, write_text_atomic
from ..io.manifest import write_manifest
from ..io.run_files import write_run_csv, write_table_csv
from ..io.uff import write_scan_uff
from ..rig import rig_to_dict
from .beam import natural_frequencies
from .presets import BodySpec, PlateSpec, Preset, get_preset
from .virtual_rig import Truth, build_model, public_rig, record_run, record_scan

__all__ = ["write_simulation", "write_truth"]


def write_truth(out: Path, name: str, truth: Truth) -> None:
    """The truth of one run: forces as a reconstruct-style CSV, the rest as NPZ.

    Parameters
    ----------
    out : Path
        The truth folder; ``NAME.forces.csv`` and ``NAME.npz`` are written there atomically.
    name : str
        The run's name.
    truth : Truth
        What the virtual rig did during the run.
    """
    cols = {n: truth.pole_force[k] for k, n in enumerate(truth.pole_names)}
    cols["total"] = truth.pole_force.sum(axis=0)
    write_table_csv(out / f"{name}.forces.csv", truth.t, cols)
    with atomic_path(out / f"{name}.npz") as tmp:
        with open(tmp, "wb") as fh:
            np.savez_compressed(
                fh, time=truth.t, pole_names=np.array(truth.pole_names),
                pole_force=truth.pole_force, gap=truth.gap, nodes=truth.nodes,
                w=truth.w.astype(np.float32), inertia=truth.inertia, current=truth.current,
                flux=truth.flux)


def _structure_facts(preset: Preset) -> dict:
    s = preset.beam
    if isinstance(s, BodySpec):
        return {
            "structure": "body",
            "size_m": list(s.size), "youngs_modulus_Pa": s.youngs_modulus,
            "poisson": s.poisson, "density_kg_m3": s.density, "mesh": list(s.mesh),
            "gauge_stiffness_N_m": s.gauge_stiffness,
        }
    if isinstance(s, PlateSpec):
        return {
            "structure": "plate",
            "size_m": [s.a, s.b], "thickness_m": s.thickness,
            "youngs_modulus_Pa": s.youngs_modulus, "poisson": s.poisson,
            "flexural_rigidity_Nm": s.flexural_rigidity,
            "mass_per_area_kg_m2": s.mass_per_area,
            "mesh": list(s.mesh),
            "gauge_stiffness_N_m": s.gauge_stiffness,
        }
    return {
        "bending_stiffness_Nm2": s.ei,
        "mass_per_length_kg_m": s.mass_per_length,
        "gauge_stiffness_N_m": s.gauge_stiffness,
    }


def _simulator_facts(preset: Preset) -> dict:
    model = build_model(preset)
    mag = preset.magnets[0]
    return {
        "preset": preset.name,
        "description": preset.description,
        **_structure_facts(preset),
        "damping_beta_s": model.beta,
        "natural_frequencies_Hz": natural_frequencies(model, 4).tolist(),
        "drive_frequency_Hz": preset.runs[0].drives[0].frequency,
        "nominal_frequency_Hz": preset.nominal_frequency,
        "magnet": {"turns": mag.turns, "pole_area_m2": mag.pole_area,
                   "iron_length_m": mag.iron_length, "mu_r": mag.mu_r,
                   "resistance_ohm": mag.resistance, "gap_offset_m": mag.gap_offset,
                   "ideal_K_total_Nm2_A2": mag.ideal_k},
        "noise": dict(vars(preset.noise)),
    }


def write_simulation(out: str | Path, preset_name: str = "paper", seed: int = 0,
                     progress: Callable[[str], None] | None = None,
                     binary_uff: bool = False) -> Path:
    """Simulate ``preset_name`` and write every file of the public formats under ``out``.

    Parameters
    ----------
    out : str or Path
        The output folder (see the module docstring for its layout).
    preset_name : str
        A name of :data:`forcecal.simulate.presets.PRESETS`.
    seed : int
        Seed of the measurement noise.
    progress : callable, optional
        Called with a short message before each stage.
    binary_uff : bool
        Write the scan as binary (58b) records instead of ASCII.

    Returns
    -------
    Path
        ``out``.

    Raises
    ------
    InputError
        An unknown preset.
    SimulationError
        A pole closes its gap or the magnetic circuit does not converge.
    """
    preset = get_preset(preset_name)
    out = Path(out)
    rng = np.random.default_rng(seed)
    model = build_model(preset)
    say = progress or (lambda _msg: None)

    say("scan")
    scan = record_scan(preset, rng, model)
    rig = public_rig(preset)
    write_text_atomic(out / "rig.toml", tomli_w.dumps(rig_to_dict(rig)))
    write_scan_uff(scan, out / "scan.uff", binary=binary_uff)

    rows = []
    for k, spec in enumerate(preset.runs):
        say(f"run {k + 1}/{len(preset.runs)}: {spec.name}")
        run, truth = record_run(preset, spec, rng, model)
        write_run_csv(run, out / "runs" / f"{spec.name}.csv")
        write_truth(out / "truth", spec.name, truth)
        row: dict[str, object] = {"run": f"runs/{spec.name}.csv"}
        if spec.gap is not None:
            row["gap"] = spec.gap
        row["tare"] = "true" if spec.tare else "false"
        row.update(spec.labels)
        rows.append(row)
    write_manifest(out / "manifest.csv", rows)
    write_text_atomic(out / "truth" / "simulator.json",
                      json.dumps(_simulator_facts(preset), indent=2))
    return out

"""What ``forcecal stream`` loads: the modules its command imports leave SciPy's signal,
statistics, optimization, interpolation and image packages, pandas, matplotlib and Dask unloaded
(each is imported where it is used, which a steady stream never reaches): memory and start-up
are the stream's budget."""

from __future__ import annotations

import subprocess
import sys

STREAM_MODULES = ("forcecal.cli.main", "forcecal.drives", "forcecal.io.blocks",
                  "forcecal.io.results", "forcecal.io.run_files", "forcecal.io.staging",
                  "forcecal.model.broadband", "forcecal.realtime.replay", "forcecal.rig")
"""What ``_cmd_stream`` and the command line around it import."""
NOT_LOADED = ("scipy.signal", "scipy.stats", "scipy.optimize", "scipy.interpolate",
              "scipy.ndimage", "pandas", "matplotlib", "dask", "distributed")
"""Packages a steady stream has no use for."""


def test_the_stream_command_imports_no_heavy_package_it_does_not_use():
    code = ("import importlib, sys\n"
            f"for name in {STREAM_MODULES!r}:\n"
            "    importlib.import_module(name)\n"
            f"print(','.join(m for m in {NOT_LOADED!r} if m in sys.modules))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    assert done.stdout.strip() == "", f"loaded by the stream's imports: {done.stdout.strip()}"

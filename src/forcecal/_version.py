"""The package's version, in one place: setuptools reads it from here for the distribution's
metadata (``[tool.setuptools.dynamic]`` in pyproject.toml) and :mod:`forcecal` re-exports it."""

__version__ = "0.1.0"

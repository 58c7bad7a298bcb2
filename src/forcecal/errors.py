"""The package's exceptions.

Every error forcecal raises on purpose derives from :class:`ForcecalError`; the specific
classes also inherit the matching builtin so that callers may catch either. Only the CLI
catches them, prints one line and exits with status 2.
"""

from __future__ import annotations

__all__ = [
    "ConditioningError",
    "DataError",
    "DimensionError",
    "FitError",
    "ForcecalError",
    "InputError",
    "RigError",
]


class ForcecalError(Exception):
    """Base class of every error raised on purpose by forcecal."""


class InputError(ForcecalError, ValueError):
    """A file, argument or key supplied by the user is missing or malformed."""


class RigError(InputError):
    """The rig description is missing a key or is physically inconsistent."""


class DataError(InputError):
    """A recorded signal cannot be used (NaN, clipping, too short, wrong sampling)."""


class DimensionError(ForcecalError, ValueError):
    """Arrays whose shapes do not agree."""


class ConditioningError(ForcecalError, ValueError):
    """A linear system is singular or too ill-conditioned to be trusted."""


class FitError(ForcecalError, RuntimeError):
    """A fit did not converge or is not identifiable from the data given."""

"""Small readers of run files' values: numbers in properties and attributes, the decimal
resolution of written time stamps, and npTDMS's log turned into forcecal's messages."""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np

from ..errors import InputError

__all__ = ["decimal_resolution", "finite_number", "positive_number", "tdms_log"]


@contextlib.contextmanager
def tdms_log() -> Iterator[list[str]]:
    """Collect what npTDMS logs (it prints to stderr by itself) instead of letting it print."""
    messages: list[str] = []

    class _Collect(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            messages.append(record.getMessage())

    collect = _Collect(logging.WARNING)
    names = [n for n in list(logging.root.manager.loggerDict) if n.startswith("nptdms")]
    saved = []
    for name in names:
        logger = logging.getLogger(name)
        saved.append((logger, list(logger.handlers), logger.propagate))
        logger.handlers = [collect]
        logger.propagate = False
    try:
        yield messages
    finally:
        for logger, handlers, propagate in saved:
            logger.handlers = handlers
            logger.propagate = propagate


def decimal_resolution(texts: Sequence[str], values: np.ndarray) -> np.ndarray:
    """(n,) resolution [s] of decimal numbers as the file writes them.

    A writer keeps either a fixed number of decimals ('%.6f': 1e-6 everywhere) or of
    significant digits ('%.6g', repr: 1e-5 at 9.87654, 1e-7 at 0.0123457); trailing zeros may
    be dropped. The finest decimal step seen and the most significant digits seen bound the
    resolution from below in either case; the larger of the two bounds is the resolution.
    """
    finest, digits = np.inf, 1
    for text in texts:
        mantissa, _, exponent = text.strip().lower().partition("e")
        whole, _, decimals = mantissa.lstrip("+-").partition(".")
        try:
            finest = min(finest, 10.0 ** (int(exponent or 0) - len(decimals)))
        except ValueError:
            continue
        digits = max(digits, len((whole + decimals).lstrip("0")))
    finest = 0.0 if not np.isfinite(finest) else finest
    with np.errstate(divide="ignore"):
        magnitude = np.floor(np.log10(np.abs(values)))
    relative = np.where(np.isfinite(magnitude), 10.0 ** (magnitude - digits + 1), 0.0)
    return np.maximum(finest, relative)


def finite_number(value: object, what: str, path: Path) -> float:
    """A finite number (a time offset); InputError naming ``what`` otherwise."""
    try:
        number = float(np.asarray(value, dtype=float).item())
    except (TypeError, ValueError):
        number = float("nan")
    if not np.isfinite(number):
        raise InputError(f"run '{path}': {what} is {value!r}; expected a finite number (s)")
    return number


def positive_number(value: object, what: str, path: Path) -> float:
    try:
        number = float(np.asarray(value, dtype=float).item())
    except (TypeError, ValueError):
        number = float("nan")
    if not np.isfinite(number) or number <= 0:
        raise InputError(f"run '{path}': {what} is {value!r}; expected a positive number")
    return number

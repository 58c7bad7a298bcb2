"""Atomic file output: write to a temporary name beside the target, then rename.

An interrupted command (an exception, Ctrl-C) therefore never leaves a half-written file that
looks whole.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

__all__ = ["atomic_path", "write_text_atomic"]


@contextlib.contextmanager
def atomic_path(target: str | Path) -> Iterator[Path]:
    """Yield a temporary path in the target's folder; on success rename it to ``target``.

    On any exception (KeyboardInterrupt included) the temporary file is removed and the
    exception propagates; an existing ``target`` is left untouched.

    Parameters
    ----------
    target : str or Path
        The file to write; its folder is created when missing.

    Yields
    ------
    Path
        The temporary file to write, beside ``target``.
    """
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".part", dir=target.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp_path, 0o666 & ~umask)  # as an ordinary open() would create it
    try:
        yield tmp_path
        os.replace(tmp_path, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp_path.unlink()
        raise


def write_text_atomic(target: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``target`` atomically.

    Parameters
    ----------
    target : str or Path
        The file to write; its folder is created when missing.
    text : str
        The whole content.

    Returns
    -------
    Path
        ``target``.
    """
    with atomic_path(target) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(target)

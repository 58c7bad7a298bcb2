"""Output folders that are all new or all old, whatever interrupts a command.

A command writes its files into a staging folder inside its output folder OUT
(``OUT/.forcecal-staging-<pid>-<random>``), then commits them: it writes a journal
(``OUT/.forcecal-commit.json``, atomically) listing the staged files, moves each into place
(``os.replace``, atomic per file), and removes the journal and the staging folder. Readers of
OUT see either the old files or, once the journal is gone, all the new ones; a journal present
means a commit was interrupted, and the next command writing into OUT finishes it first
(every staged file was complete before the journal was written). A failure before the commit
removes the staging folder, so OUT keeps its old files (and is removed again when the command
created it and it is still empty).

At the start of every command the leftovers of killed commands in OUT are cleaned: staging
folders of processes that no longer run, and hidden ``.*.part`` temporaries of
:func:`forcecal._atomic.atomic_path` (in OUT and its immediate subfolders) older than
:data:`STALE_PART_S` and than the current process.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

from .._atomic import write_text_atomic

__all__ = ["clean_stale", "staged_folder"]

STAGING_PREFIX = ".forcecal-staging-"
"""Name prefix of a staging folder, followed by the writing process's id."""
JOURNAL = ".forcecal-commit.json"
"""The commit journal in OUT: present only while (or if interrupted while) files move."""
STALE_PART_S = 60.0
"""A ``.part`` temporary older than this (s) and than the current process is a leftover."""

_STARTED = time.time()


@contextlib.contextmanager
def staged_folder(out: str | Path) -> Iterator[Path]:
    """Yield a staging folder inside ``out``; commit its files into ``out`` on success.

    Parameters
    ----------
    out : str or Path
        The output folder, created when missing (and removed again on failure if still empty).

    Yields
    ------
    Path
        The staging folder to write every output into (subfolders allowed).
    """
    out = Path(out)
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    clean_stale(out)
    stage = Path(tempfile.mkdtemp(prefix=f"{STAGING_PREFIX}{os.getpid()}-", dir=out))
    try:
        yield stage
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        if created:
            with contextlib.suppress(OSError):
                out.rmdir()
        raise
    _commit(stage, out)


def _commit(stage: Path, out: Path) -> None:
    files = sorted(str(p.relative_to(stage)) for p in stage.rglob("*") if p.is_file())
    journal = out / JOURNAL
    write_text_atomic(journal, json.dumps({"staging": stage.name, "files": files}))
    _move(stage, out, files)
    journal.unlink()
    shutil.rmtree(stage, ignore_errors=True)


def _move(stage: Path, out: Path, files: list[str]) -> None:
    for rel in files:
        src = stage / rel
        if src.is_file():
            (out / rel).parent.mkdir(parents=True, exist_ok=True)
            os.replace(src, out / rel)


def clean_stale(out: str | Path) -> None:
    """Finish an interrupted commit in ``out`` and remove the leftovers of killed commands.

    Parameters
    ----------
    out : str or Path
        An output folder (nothing happens when it does not exist).
    """
    out = Path(out)
    if not out.is_dir():
        return
    journal = out / JOURNAL
    if journal.is_file():
        try:
            doc = json.loads(journal.read_text(encoding="utf-8"))
            stage = out / str(doc["staging"])
            files = [str(f) for f in doc["files"]]
        except (OSError, ValueError, KeyError, TypeError):
            stage, files = out / "", []
        if files and stage.name.startswith(STAGING_PREFIX) and stage.is_dir():
            _move(stage, out, files)
        journal.unlink(missing_ok=True)
    for folder in out.glob(f"{STAGING_PREFIX}*"):
        if folder.is_dir() and not _alive(folder.name):
            shutil.rmtree(folder, ignore_errors=True)
    limit = min(_STARTED, time.time() - STALE_PART_S)
    for part in [*out.glob(".*.part"), *out.glob("*/.*.part")]:
        with contextlib.suppress(OSError):
            if part.is_file() and part.stat().st_mtime < limit:
                part.unlink()


def _alive(name: str) -> bool:
    """Whether the process that made the staging folder ``name`` still runs."""
    try:
        pid = int(name[len(STAGING_PREFIX):].split("-")[0])
    except ValueError:
        return False
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # exists but is not ours
        return True
    return True

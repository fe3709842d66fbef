"""Atomic file writes: a temp file in the target folder, then a rename, so an interrupted
write never leaves a truncated file behind."""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Any

from prehensile.errors import PrehensileError


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (parent folders are created)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.chmod(tmp, 0o644)  # mkstemp creates the file private to the owner
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def atomic_write_text(path: str | Path, text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_json(path: str | Path, data: Any) -> Path:
    """Write ``data`` as indented JSON to ``path`` atomically."""
    return atomic_write_text(path, json.dumps(data, indent=2, sort_keys=False) + "\n")


def check_writable(path: str | Path, what: str, folder: bool = False) -> Path:
    """``path`` if a file (with ``folder``: a folder) can be written there, before a long job
    ends by writing it; else PrehensileError naming ``what`` (e.g. the option) and why."""
    path = Path(path)
    if folder and path.exists() and not path.is_dir():
        raise PrehensileError(f"{what}: {path} is a file, not a folder")
    if not folder and path.is_dir():
        raise PrehensileError(f"{what}: {path} is a folder; give a file name")
    target = path if folder else path.parent
    for existing in (target, *target.parents):  # the nearest one that exists must be a writable folder
        if existing.exists():
            if not existing.is_dir():
                raise PrehensileError(f"{what}: {existing} is a file, not a folder")
            try:  # a real attempt: permission bits do not tell for root, read-only mounts or /proc
                os.rmdir(tempfile.mkdtemp(prefix=".prehensile-probe-", dir=existing))
            except OSError as error:
                where = "" if existing == target else f" (to create {target})"
                raise PrehensileError(f"{what}: cannot write in {existing}{where}: {error.strerror}") from None
            break
    return path

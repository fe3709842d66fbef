"""Atomic file writes: a temp file in the target folder, then a rename, so an interrupted
write never leaves a truncated file behind, and files written together change together."""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Any, Mapping

from prehensile.errors import PrehensileError


def atomic_write_files(files: Mapping[str | Path, bytes]) -> list[Path]:
    """Write each path's bytes atomically (parent folders are created), all at once: every file
    is written to a synced temp file beside its target first, then they are renamed in one
    go, so an interruption leaves either none or (but for microseconds) all of them new.
    Returns the paths."""
    staged: list[tuple[str, Path]] = []
    try:
        for path, data in files.items():
            path = Path(path)
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
            staged.append((tmp, path))
            with os.fdopen(fd, "wb") as handle:
                handle.write(data)
                handle.flush()
                os.fsync(handle.fileno())
            os.chmod(tmp, 0o644)  # mkstemp creates the file private to the owner
        for tmp, path in staged:
            os.replace(tmp, path)
    except BaseException:
        for tmp, _ in staged:
            Path(tmp).unlink(missing_ok=True)
        raise
    return [path for _, path in staged]


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (parent folders are created)."""
    return atomic_write_files({path: data})[0]


def atomic_write_text(path: str | Path, text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def json_bytes(data: Any) -> bytes:
    """``data`` as indented UTF-8 JSON, one trailing newline."""
    return (json.dumps(data, indent=2, sort_keys=False) + "\n").encode("utf-8")


def atomic_write_json(path: str | Path, data: Any) -> Path:
    """Write ``data`` as indented JSON to ``path`` atomically."""
    return atomic_write_bytes(path, json_bytes(data))


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

"""numba's on-disk cache of prehensile's kernels, kept in step with their sources.

numba keys a cached kernel on the source of the file that defines it, not on the files of the
kernels it inlines or calls (``kinematics/kernels.py`` inside every collision and IK kernel,
the sphere kernels inside the planners). After an edit or an upgrade that changes only such a
file, the kernels cached from the other files would keep running the old code. So importing
prehensile hashes its modules that use numba and, when that hash differs from the one stored
beside the cache, deletes the package's cached kernels (numba compiles them again on first
use) and stores the new hash.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

from prehensile.storage import atomic_write_text

PACKAGE_ROOT = Path(__file__).resolve().parent
MARKER = "prehensile-kernel-sources.sha256"


def sources_digest(root: Path) -> str:
    """SHA-256 (hex) of the names and contents of the modules under root that mention numba."""
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        text = path.read_bytes()
        if b"numba" in text:
            digest.update(path.relative_to(root).as_posix().encode() + b"\0" + text + b"\0")
    return digest.hexdigest()


def _mirrored(base: str, folder: Path) -> Path:
    """numba's cache folder under ``base`` for the sources in ``folder`` (its
    ``get_suitable_cache_subpath``: the folder's name and the SHA-1 of its path)."""
    return Path(base) / f"{folder.name}_{hashlib.sha1(str(folder).encode()).hexdigest()}"


def cache_folders(root: Path) -> list[Path]:
    """The folders where numba caches the kernels of the sources under root, root's first, in
    numba's order of choice: under ``NUMBA_CACHE_DIR`` if set, else ``__pycache__`` beside the
    sources if root is writable, else under numba's user-wide cache."""
    folders = sorted({path.parent for path in root.rglob("*.py")} | {root})
    base = os.environ.get("NUMBA_CACHE_DIR")
    if not base and os.access(root, os.W_OK):
        return [folder / "__pycache__" for folder in folders]
    if not base:
        from numba.misc.appdirs import AppDirs

        base = AppDirs(appname="numba", appauthor=False).user_cache_dir
    return [_mirrored(base, folder) for folder in folders]


def refresh(root: Path = PACKAGE_ROOT) -> int:
    """Delete the cached kernels of the sources under root unless they were cached from the
    current sources (:func:`sources_digest`, stored in root's cache folder); returns how many
    cache files it deleted."""
    folders = cache_folders(root)
    marker, digest = folders[0] / MARKER, sources_digest(root)
    try:
        if marker.read_text() == digest:
            return 0
    except OSError:
        pass  # no marker yet: caches of unknown sources
    stale = [path for folder in folders if folder.is_dir() for path in folder.glob("*.nb[ic]")]
    for path in stale:
        path.unlink(missing_ok=True)
    try:
        atomic_write_text(marker, digest)
    except OSError:
        pass  # not writable: numba cannot cache there either
    return len(stale)


def cached_kernels(root: Path = PACKAGE_ROOT) -> int:
    """How many kernels of the sources under root numba has cached (its index files)."""
    return sum(len(list(folder.glob("*.nbi"))) for folder in cache_folders(root) if folder.is_dir())

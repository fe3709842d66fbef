"""Disk cache for sphere models.

Entries live in ``$PREHENSILE_CACHE/spheres`` (default ``~/.cache/prehensile/spheres``) as
``.npz`` files named by a SHA-256 over a format version, the builder's parameters and a
fingerprint of the robot's collision geometry (shape types, sizes, poses, and the *contents*
of mesh files with their scale). Writes go to a temporary file in the same folder that is then
renamed with :func:`os.replace`, so readers never see a partial file.
"""

from __future__ import annotations

import hashlib
import json
import logging
import io
import os
from pathlib import Path
from typing import TYPE_CHECKING, Callable

import numpy as np

from prehensile.model.geometry import Mesh
from prehensile.model.robot_model import RobotModel
from prehensile.storage import atomic_write_bytes

if TYPE_CHECKING:
    from prehensile.collision.spheres import SphereModel

FORMAT_VERSION = 6  # bump whenever the fitting algorithm or the stored arrays change
log = logging.getLogger(__name__)


def cache_dir() -> Path:
    """The sphere-model cache folder (not created here)."""
    root = os.environ.get("PREHENSILE_CACHE")
    base = Path(root) if root else Path.home() / ".cache" / "prehensile"
    return base / "spheres"


def _file_digest(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def array_digest(arrays: dict[str, np.ndarray]) -> str:
    """SHA-256 over named arrays (names, dtypes, shapes and bytes)."""
    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}:{a.dtype.str}:{a.shape}".encode())
        h.update(a.tobytes() if a.dtype.kind != "U" else "|".join(a.ravel().tolist()).encode())
    return h.hexdigest()


def geometry_fingerprint(model: RobotModel) -> str:
    """SHA-256 of the model's link names and collision geometry (mesh contents included)."""
    h = hashlib.sha256()
    for name, geometries in zip(model.link_names, model.collisions):
        h.update(f"link:{name}:{len(geometries)}".encode())
        for g in geometries:
            shape = g.shape
            if isinstance(shape, Mesh) and shape.path is None:
                h.update(f"mesh-arrays:{array_digest({'v': shape.vertices, 'f': shape.faces})}:{tuple(shape.scale)}".encode())
            elif isinstance(shape, Mesh):
                h.update(f"mesh:{_file_digest(Path(shape.path))}:{tuple(shape.scale)}".encode())
            else:
                h.update(repr(shape).encode())
            h.update(np.round(np.asarray(g.T_link_geom, dtype=float), 12).tobytes())
    return h.hexdigest()


def cache_key(model: RobotModel, params: dict) -> str:
    """Cache file stem for ``model`` built with ``params`` (JSON-serialisable)."""
    text = json.dumps({"version": FORMAT_VERSION, "params": params, "geometry": geometry_fingerprint(model)},
                      sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:32]


def save_atomic(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Write ``arrays`` to ``path`` (.npz) atomically."""
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    atomic_write_bytes(path, buffer.getvalue())


def cached(model: RobotModel, params: dict, build: Callable[[], SphereModel]) -> SphereModel:
    """The sphere model for (``model``, ``params``) from the cache, or ``build()`` and store it.

    An unreadable cache entry is rebuilt and overwritten; an unwritable cache folder only
    logs a warning.
    """
    from prehensile.collision.spheres import sphere_model_from_arrays

    path = cache_dir() / f"{cache_key(model, params)}.npz"
    if path.is_file():
        try:
            with np.load(path, allow_pickle=False) as data:
                spheres = sphere_model_from_arrays(data)
            if tuple(spheres.link_names) == tuple(model.link_names):
                log.debug("sphere model loaded from %s", path)
                return spheres
        except (OSError, ValueError, KeyError) as error:
            log.warning("ignoring unreadable sphere cache %s: %s", path, error)
    spheres = build()
    try:
        save_atomic(path, spheres.arrays())
    except OSError as error:
        log.warning("could not write sphere cache %s: %s", path, error)
    return spheres

"""Find files named by ``package://`` and relative URIs in robot descriptions."""

from __future__ import annotations

import os
import re
import site
from functools import lru_cache
from pathlib import Path

from prehensile.errors import ModelError


@lru_cache(maxsize=1)
def package_search_roots() -> tuple[Path, ...]:
    """Folders that may hold ROS-style packages: ``$ROS_PACKAGE_PATH``, ``$PREHENSILE_PACKAGE_PATH``
    and the ``share`` folders of pip-installed cmeel packages (e.g. example-robot-data)."""
    roots: list[Path] = []
    for var in ("PREHENSILE_PACKAGE_PATH", "ROS_PACKAGE_PATH"):
        roots += [Path(p) for p in os.environ.get(var, "").split(os.pathsep) if p]
    roots += [Path(sp) / "cmeel.prefix" / "share" for sp in site.getsitepackages()]
    return tuple(r for r in dict.fromkeys(roots) if r.is_dir())


@lru_cache(maxsize=256)
def _package_name(folder: Path) -> str | None:
    """The <name> in ``folder/package.xml`` (a ROS package manifest), or None."""
    try:
        found = re.search(r"<name>\s*([^<\s]+)\s*</name>", (folder / "package.xml").read_text(errors="replace"))
    except OSError:
        return None
    return found.group(1) if found else None


def resolve_uri(uri: str, relative_to: Path, where: str) -> Path:
    """Resolve a mesh or include URI to an existing file.

    ``package://name/rest`` is looked up in every ancestor folder of ``relative_to`` that is
    called ``name`` or holds a ``package.xml`` naming it (a package checked out under another
    folder name), in ``relative_to/name``, ``relative_to`` and :func:`package_search_roots`;
    ``file://`` and plain paths are taken relative to ``relative_to``.

    Raises:
        ModelError: the file does not exist; names ``where`` and the places searched.
    """
    tried: list[Path] = []
    if uri.startswith("package://"):
        package, _, rest = uri[len("package://"):].partition("/")
        for ancestor in [relative_to, *relative_to.parents]:
            if ancestor.name == package or _package_name(ancestor) == package:
                tried.append(ancestor / rest)
        tried += [relative_to / package / rest, relative_to / rest]
        tried += [root / package / rest for root in package_search_roots()]
    else:
        path = Path(uri[len("file://"):] if uri.startswith("file://") else uri)
        tried.append(path if path.is_absolute() else relative_to / path)
    for candidate in tried:
        if candidate.is_file():
            return candidate
    raise ModelError(f"{where}: file '{uri}' not found (looked in: {', '.join(str(t) for t in tried)})")

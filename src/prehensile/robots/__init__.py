"""Bundled robots and loading robots by name or path.

Names:

* ``"nao"`` -- NAO V5 (H25), 25 DoF (RHipYawPitch mimics LHipYawPitch), built by
  ``tools/build_nao.py`` from the official link lengths and limits.
* ``"armar3"`` -- ARMAR-III, authored from the published Simox parameters.
* ``"panda"`` -- Franka Emika Panda with its hand from the ``example-robot-data`` package,
  8 DoF (7 arm joints and ``panda_finger_joint1``; ``panda_finger_joint2`` is its URDF mimic),
  with prehensile's own SRDF (chain ``arm`` to ``panda_hand_tcp``, end effector ``hand``).

Paths: a ``.urdf`` or an MJCF ``.xml`` (root ``<mujoco>``); an ``.srdf`` of the same stem next
to it is applied automatically unless ``srdf`` is given. Or a Simox ``.xml`` (root ``<Robot>``).

Models are immutable, so bundled ones are loaded once and shared (``functools.lru_cache``).
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from prehensile.errors import ModelError, missing_file
from prehensile.model.robot_model import RobotModel

_HERE = Path(__file__).resolve().parent
_PANDA_URDF = Path("example-robot-data") / "robots" / "panda_description" / "urdf" / "panda.urdf"


def _panda_urdf() -> Path | None:
    from prehensile.model.resources import package_search_roots

    for root in package_search_roots():
        if (root / _PANDA_URDF).is_file():
            return root / _PANDA_URDF
    return None


def _bundled() -> dict[str, tuple[Path | None, Path]]:
    """name -> (robot description or None when not installed, SRDF)."""
    return {
        "armar3": (_HERE / "armar3" / "armar3.urdf", _HERE / "armar3" / "armar3.srdf"),
        "nao": (_HERE / "nao" / "nao.urdf", _HERE / "nao" / "nao.srdf"),
        "panda": (_panda_urdf(), _HERE / "panda" / "panda.srdf"),
    }


def available() -> list[str]:
    """Names of the bundled robots whose files are present, sorted."""
    return sorted(name for name, (path, _) in _bundled().items() if path is not None and path.is_file())


def bundled_name(model: RobotModel) -> str | None:
    """The bundled name of a model loaded from a bundled robot's files (its description and
    SRDF), e.g. ``load("panda")``; None for any other model."""
    for name, (path, srdf) in _bundled().items():
        if path is not None and model.source == str(path) and model.srdf_source == str(srdf):
            return name
    return None


@lru_cache(maxsize=None)
def _load_bundled(name: str) -> RobotModel:
    path, srdf = _bundled()[name]
    if path is None or not path.is_file():
        where = "the example-robot-data package" if name == "panda" else str(path)
        raise ModelError(f"robot '{name}': its description is not installed (looked in {where})")
    return load_path(path, srdf if srdf.is_file() else None)


def _root_tag(path: Path) -> str:
    from prehensile.model.xml_utils import parse_xml

    return parse_xml(path).tag


def load_path(path: str | Path, srdf: str | Path | None = None) -> RobotModel:
    """Load a robot description file, choosing the loader by suffix and root element.

    Args:
        path: ``.urdf``, MJCF ``.xml`` (``<mujoco>``) or Simox ``.xml`` (``<Robot>``).
        srdf: semantic description to apply; for a URDF or MJCF file, ``<stem>.srdf`` next to
            it by default.

    Raises:
        ModelError: missing file, unknown suffix or root element, or any loader error.
    """
    path = Path(path)
    if not path.is_file():
        raise ModelError(f"{path}: {missing_file(path)}")
    suffix = path.suffix.lower()
    if suffix not in (".urdf", ".xml"):
        raise ModelError(f"{path}: unknown robot file type '{suffix}'; valid: .urdf, .xml (MJCF or Simox)")
    tag = "robot" if suffix == ".urdf" else _root_tag(path)
    if tag == "Robot":  # Simox XML: its own node sets and end effectors; an SRDF only if given
        from prehensile.model.simox import load_simox

        model = load_simox(path)
    elif tag in ("mujoco", "robot"):
        from prehensile.model.mjcf import load_mjcf
        from prehensile.model.urdf import load_urdf

        model = load_mjcf(path) if tag == "mujoco" else load_urdf(path)
        sibling = path.with_suffix(".srdf")
        srdf = srdf if srdf is not None or not sibling.is_file() else sibling
    else:
        raise ModelError(
            f"{path}: root element <{tag}> is not a robot description; valid: <mujoco> (MJCF), "
            "<Robot> (Simox XML), <robot> (URDF)"
        )
    if srdf is not None:
        from prehensile.model.srdf import apply_srdf

        model = apply_srdf(model, srdf)
    return model


def load(name_or_path: str | Path, srdf: str | Path | None = None) -> RobotModel:
    """A robot by bundled name (``"nao"``, ``"armar3"``, ``"panda"``) or by file path.

    Bundled robots are cached and shared; passing ``srdf`` with a bundled name loads a fresh
    model with that SRDF instead of the bundled one.

    Raises:
        ModelError: an unknown name (the message lists the valid names) or a bad file.
    """
    names = _bundled()
    if isinstance(name_or_path, str) and name_or_path in names:
        if srdf is None:
            return _load_bundled(name_or_path)
        path = names[name_or_path][0]
        if path is None:
            raise ModelError(f"robot '{name_or_path}': its description is not installed")
        return load_path(path, srdf)
    path = Path(name_or_path)
    if path.is_file():
        return load_path(path, srdf)
    if isinstance(name_or_path, str) and path.suffix == "" and len(path.parts) == 1:
        raise ModelError(
            f"unknown robot '{name_or_path}'; valid names: {', '.join(sorted(names))} "
            "(a path to a .urdf or MJCF/Simox .xml file is accepted too)"
        )
    raise ModelError(f"{path}: {missing_file(path)} (give a bundled robot name: {', '.join(sorted(names))}, or a path)")


__all__ = ["available", "load", "load_path"]

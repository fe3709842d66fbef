"""Small helpers for reading robot XML files with clear errors."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from prehensile.errors import ModelError, missing_file


def parse_xml(path: Path) -> ET.Element:
    """Root element of ``path``; a missing or malformed file is a ModelError naming it."""
    path = Path(path)
    if not path.is_file():
        raise ModelError(f"{path}: {missing_file(path)}")
    try:
        return ET.parse(path).getroot()
    except ET.ParseError as err:
        raise ModelError(f"{path}: malformed XML ({err})") from None


def floats(text: str | None, count: int, where: str, default: list[float] | None = None) -> np.ndarray:
    """Parse ``count`` whitespace-separated numbers; ``default`` when ``text`` is None."""
    if text is None:
        if default is None:
            raise ModelError(f"{where}: missing value (expected {count} numbers)")
        return np.array(default, dtype=float)
    try:
        values = np.array([float(v) for v in text.split()], dtype=float)
    except ValueError:
        raise ModelError(f"{where}: '{text}' is not a list of {count} numbers") from None
    if values.shape != (count,) or not np.all(np.isfinite(values)):
        raise ModelError(f"{where}: expected {count} finite numbers, got '{text}'")
    return values


def required(element: ET.Element, attribute: str, where: str) -> str:
    value = element.get(attribute)
    if value is None or value == "":
        raise ModelError(f"{where}: missing attribute '{attribute}'")
    return value


def number(element: ET.Element, attribute: str, where: str, default: float | None = None) -> float:
    """A float attribute; ``default`` if absent (an error if there is no default)."""
    value = element.get(attribute)
    if value is None:
        if default is None:
            raise ModelError(f"{where}: missing attribute '{attribute}'")
        return default
    try:
        result = float(value)
    except ValueError:
        raise ModelError(f"{where}: attribute '{attribute}'='{value}' is not a number") from None
    if np.isnan(result):
        raise ModelError(f"{where}: attribute '{attribute}' is NaN")
    return result

"""Exception hierarchy: one root, one subclass per kind of bad input.

"No solution" is never an exception: solvers and planners return a status.
"""

from pathlib import Path


class PrehensileError(Exception):
    """Root of every error raised by prehensile."""


class ModelError(PrehensileError):
    """A robot description is malformed: names the file, the element and the problem."""


class SceneError(PrehensileError):
    """A scene file or scene object is malformed."""


class UnknownFrameError(PrehensileError, KeyError):
    """A link, joint, chain or end effector name that the model does not have."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


def missing_file(path: str | Path, what: str = "file") -> str:
    """Why ``path``, which is not a file, cannot be read: for messages "PATH: <reason>"."""
    return f"is a directory, not a {what}" if Path(path).is_dir() else f"{what} not found"

"""The exceptions of robocal: the library's errors, with where they are."""

from typing import Optional


class RobocalError(Exception):
    """An error of robocal: its whole message, and the file, line and field it names."""

    def __init__(
        self,
        message: str,
        file: Optional[str] = None,
        line: Optional[int] = None,
        field: Optional[str] = None,
    ) -> None:
        super().__init__(message)
        self.message = message
        self.file = file
        self.line = line
        self.field = field


class InputError(RobocalError, ValueError):
    """What was given cannot be used: a file, an array, an option."""


class EstimationError(RobocalError):
    """The data cannot make the calibration asked for (too few poses, nothing identifiable)."""

"""The project's user-facing error type, and the hint it gives for a mistyped name."""

from __future__ import annotations

import difflib
from collections.abc import Iterable


class ConfigError(ValueError):
    """Bad user input: a configuration value, key, file or name. ``field`` names the culprit.

    The CLI prints these as one line and exits 2; anything else is a bug and keeps its
    traceback.
    """

    def __init__(self, message: str, field: str | None = None):
        super().__init__(message)
        self.field = field


def did_you_mean(name: object, choices: Iterable[str]) -> str:
    """`` (did you mean 'x'?)`` for the closest of ``choices`` to a mistyped ``name``, else ``""``."""
    if not isinstance(name, str):
        return ""
    close = difflib.get_close_matches(name, list(choices), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""

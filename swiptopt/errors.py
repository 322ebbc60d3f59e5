"""The project's user-facing error type."""


class ConfigError(ValueError):
    """Bad user input: a configuration value, key, file or name. ``field`` names the culprit.

    The CLI prints these as one line and exits 2; anything else is a bug and keeps its
    traceback.
    """

    def __init__(self, message: str, field: str | None = None):
        super().__init__(message)
        self.field = field

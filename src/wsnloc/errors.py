"""Error types that name what is wrong and where (file and line, or config key)."""


class WsnlocError(Exception):
    """Base class of every error this package raises on bad input."""


class ConfigError(WsnlocError):
    """A configuration value is missing, of the wrong type, or out of range.

    The message always starts with the offending key, e.g. ``config key 'runs': ...``.
    """


class IngestError(WsnlocError):
    """A raw log cannot be read at all (missing file, wrong format, missing header).

    Single unusable lines never raise: they go to the quarantine table.
    """

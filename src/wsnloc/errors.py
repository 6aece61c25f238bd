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


def did_you_mean(name: str, known) -> str:
    """' (did you mean 'x'?)' for the known names closest to a misspelled one (difflib's
    ratio >= 0.6, at most three), else ''."""
    import difflib

    close = difflib.get_close_matches(str(name), [str(k) for k in known], n=3)
    return f" (did you mean {' or '.join(repr(c) for c in close)}?)" if close else ""

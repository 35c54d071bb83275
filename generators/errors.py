"""The generators' configuration error, in a module of its own: the config loader, the scenes and the
property-sensitivity test raise it, and none of them needs to import another to do so."""

from __future__ import annotations


class ConfigError(ValueError):
    """A configuration key is unknown, of the wrong type or out of range."""


def did_you_mean(word: str, choices: list[str] | tuple[str, ...]) -> str:
    """`` (did you mean 'x'?)`` for the choice closest to a misspelt ``word`` (difflib's ratio at least 0.6, the
    closest first, at most two), else an empty string: appended to an error that lists what is allowed."""
    import difflib
    close = difflib.get_close_matches(str(word), [str(c) for c in choices], n=2, cutoff=0.6)
    return f" (did you mean {' or '.join(repr(c) for c in close)}?)" if close else ""

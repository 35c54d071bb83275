"""The generators' configuration error, in a module of its own: the config loader, the scenes and the
property-sensitivity test raise it, and none of them needs to import another to do so."""

from __future__ import annotations


class ConfigError(ValueError):
    """A configuration key is unknown, of the wrong type or out of range."""

"""Library exceptions. Each is also the matching builtin, so ``except ValueError`` still works."""

from __future__ import annotations

__all__ = ["SwarmposeError", "ShapeError", "ConfigError", "DataError", "FormatError", "option_items"]


class SwarmposeError(Exception):
    """Base class of every error raised on purpose by swarmpose."""


class ShapeError(SwarmposeError, ValueError):
    """An array has the wrong shape; the message names expected and actual shapes."""


class ConfigError(SwarmposeError, ValueError):
    """A configuration value is out of range or unknown."""


class DataError(SwarmposeError, OSError):
    """A file or folder is missing or unreadable."""


class FormatError(SwarmposeError, ValueError):
    """A file is readable but malformed; the message names the file and the line or field."""

    def __init__(self, message: str, *, path: object = None, line: int | None = None, field: str | None = None):
        where = []
        if path is not None:
            where.append(str(path))
        if line is not None:
            where.append(f"line {line}")
        if field is not None:
            where.append(f"field {field!r}")
        prefix = ": ".join([", ".join(where)]) + ": " if where else ""
        super().__init__(prefix + message)
        self.path = path
        self.line = line
        self.field = field


def option_items(text: str, what: str, form: str = "key=value") -> list[tuple[str, str]]:
    """Split a user's ``"key=value,key=value"`` text into stripped ``(key, value)`` pairs.

    Empty items are skipped; an item without ``=`` raises :class:`ConfigError` ``"{what} {item!r} is
    not {form}"``. Checking the keys and values is the caller's.
    """
    items = []
    for item in filter(None, (t.strip() for t in str(text).split(","))):
        key, sep, value = (t.strip() for t in item.partition("="))
        if not sep:
            raise ConfigError(f"{what} {item!r} is not {form}")
        items.append((key, value))
    return items

"""The tracks layer's one exception type (its own module: the loader and the compiled form both
raise it, and neither imports the other for it)."""

from __future__ import annotations


class TrackError(ValueError):
    """A track cannot be found or read; names the file and the element at fault."""

    def __init__(self, message: str, *, file: str | None = None, element: str | None = None):
        self.file = file
        self.element = element
        where = ", ".join(p for p in (file, element and f"at {element}") if p)
        super().__init__(f"{where}: {message}" if where else message)

"""The one exception type of the car layer."""

from __future__ import annotations

from madsim.torcsxml import ParamsError

__all__ = ["CarError"]


class CarError(ValueError):
    """A car cannot be found, read or accepted; names the file and the element at fault.

    Attributes: `file` (path of the file at fault, or None), `element` (section/attribute path
    such as ``Car/mass``, or None), `reason` (the message without the location prefix).
    """

    def __init__(self, reason: str, *, file: str | None = None, element: str | None = None):
        self.reason = reason
        self.file = file
        self.element = element
        where = ", ".join(p for p in (file, element and f"at {element}") if p)
        super().__init__(f"{where}: {reason}" if where else reason)

    @classmethod
    def from_params(cls, exc: ParamsError) -> "CarError":
        """Wrap a ParamsError from the XML reader, keeping its file and element."""
        text = str(exc)
        where = ", ".join(p for p in (exc.file, exc.element and f"at {exc.element}") if p)
        reason = text[len(where) + 2:] if where and text.startswith(where + ": ") else text
        return cls(reason, file=exc.file, element=exc.element)

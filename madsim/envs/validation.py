"""The config layer's error type and the checks the schema, the loader and the MADRaS
translation share: dotted key paths, nearest-name hints, numbers, ranges.

Every check raises `ConfigError` naming the dotted key path (as written in the file), the bad
value and, where one is close, the nearest valid name.
"""

from __future__ import annotations

import difflib
import math
import types
from collections.abc import Mapping
from typing import Any

__all__ = ["NO_VALUE", "ConfigError", "ConfigWarning", "as_number", "as_pair", "check_choice",
           "check_positive", "fail", "frozen_map", "join_key", "nearest", "set_field",
           "unknown_name"]

NO_VALUE = object()
"""Marks a ConfigError that carries no bad value (None is a value a file can hold)."""


class ConfigError(ValueError):
    """A scenario config is wrong. Attributes: `file`, `key` (dotted path as written),
    `value` (the bad value, if any), `hint` (nearest valid key or value), `reason`."""

    def __init__(self, reason: str, *, key: str | None = None, value: Any = NO_VALUE,
                 hint: str | None = None, file: str | None = None):
        super().__init__(reason)
        self.reason, self.key, self.value, self.hint, self.file = reason, key, value, hint, file

    def __str__(self) -> str:
        text = self.reason
        if self.value is not NO_VALUE:
            text += f" (got {self.value!r})"
        if self.hint:
            text += f"; did you mean {self.hint!r}?"
        return ": ".join([p for p in (self.file, self.key) if p] + [text])

    def under(self, prefix: str) -> ConfigError:
        """The same error with its key placed under `prefix` (a dotted path)."""
        self.key = join_key(prefix, self.key) if self.key else (prefix or None)
        return self


class ConfigWarning(UserWarning):
    """A config key was accepted but has no effect in madsim (e.g. a TORCS-only setting)."""


def join_key(path: str, key: str | int) -> str:
    """`path` extended by a mapping key (`a.b`) or a list index (`a[2]`)."""
    if isinstance(key, int):
        return f"{path}[{key}]"
    if key.startswith("["):
        return f"{path}{key}"
    return f"{path}.{key}" if path else key


def nearest(word: str, candidates) -> str | None:
    """The candidate closest to `word` (same letters in another case first), or None."""
    candidates = [str(c) for c in candidates]
    same_letters = [c for c in candidates if c.lower() == str(word).lower()]
    if same_letters:
        return same_letters[0]
    match = difflib.get_close_matches(str(word), candidates, n=1, cutoff=0.5)
    return match[0] if match else None


def unknown_name(what: str, name: str, candidates, key: str | None) -> ConfigError:
    """The error for a name that is not one of `candidates` (the nearest as hint, else all)."""
    hint = nearest(name, candidates)
    if hint:
        return ConfigError(f"unknown {what} {name!r}", key=key, hint=hint)
    yours = (" (your own? list its module under `plugins:` or pass --import)"
             if what in ("reward", "done", "traffic behaviour") else "")
    return ConfigError(f"unknown {what} {name!r}{yours}; valid: {', '.join(map(str, candidates))}",
                       key=key)


def fail(key: str | None, reason: str, value: Any = NO_VALUE, hint: str | None = None):
    """Raise ConfigError for `key`."""
    raise ConfigError(reason, key=key, value=value, hint=hint)


def set_field(obj, name: str, value) -> None:
    """Set a field of a frozen dataclass (normalisation inside `__post_init__`)."""
    object.__setattr__(obj, name, value)


def check_choice(obj, name: str, choices) -> None:
    """Field `name` of `obj` must be one of `choices`."""
    value = getattr(obj, name)
    if value not in choices:
        raise unknown_name(f"{name} value", value, choices, name)


def as_number(value, key: str) -> float:
    """A finite float from a YAML value (YAML 1.1 reads 1e-6, without a dot, as a string)."""
    if isinstance(value, str):
        try:
            value = float(value)
        except ValueError:
            fail(key, "expected a number", value)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        fail(key, "expected a finite number", value)
    return float(value)


def as_pair(value, key: str, *, ordered: bool = True) -> tuple[float, float]:
    """(low, high) from [a, b], (a, b) or {low: a, high: b}."""
    if isinstance(value, Mapping):
        extra = set(value) - {"low", "high"}
        if extra or len(value) != 2:
            fail(key, "a range needs exactly the keys low and high", dict(value))
        value = (value["low"], value["high"])
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        fail(key, "expected a pair [low, high]", value)
    out = tuple(as_number(v, join_key(key, i)) for i, v in enumerate(value))
    if ordered and out[0] > out[1]:
        fail(key, "low must not exceed high", list(value))
    return out


def check_positive(obj, *names: str, allow_zero: bool = False) -> None:
    """Fields `names` of `obj` must be > 0 (>= 0 with allow_zero) where not None."""
    for name in names:
        v = getattr(obj, name)
        if v is not None and not (v >= 0 if allow_zero else v > 0):
            fail(name, "must be >= 0" if allow_zero else "must be > 0", v)


def frozen_map(value) -> Mapping:
    """A read-only copy of a mapping (a MappingProxyType is kept as it is)."""
    return value if isinstance(value, types.MappingProxyType) else types.MappingProxyType(dict(value))

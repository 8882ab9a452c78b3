"""Name registries for pluggable components (rewards, dones): one decorator factory for all."""

from __future__ import annotations

from typing import Callable


def registrar(registry: dict, base: type, kind: str) -> Callable[[str], Callable[[type], type]]:
    """A `register_<kind>(name)` class decorator adding subclasses of `base` to `registry`.

    Registering the same class twice is a no-op; another class under a taken name is an error.
    Registration happens on import: import the defining module wherever envs are made
    (spawned workers too)."""
    def register(name: str):
        def add(cls):
            if not (isinstance(cls, type) and issubclass(cls, base)):
                raise TypeError(f"register_{kind}: {cls!r} is not a {base.__name__} subclass")
            taken = registry.get(name)
            if taken is not None and taken is not cls:
                raise ValueError(f"{kind} name {name!r} is already registered by {taken.__qualname__}")
            registry[name] = cls
            return cls
        return add
    register.__doc__ = (f"Class decorator adding a {base.__name__} subclass to the {kind} registry under "
                        f"`name`, so configs can use it (see madsim.agents.registry.registrar).")
    return register

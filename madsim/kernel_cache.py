"""numba's disk cache for madsim's kernels, renewed by an edit of any kernel module.

numba stamps a cached function with the contents of its own source file only, but madsim's
kernels call each other across modules (the contact sub-step loop compiles the physics kernel
into itself; the sensors compile the track's ray caster): after an edit of `physics/kernel.py`
the loop's cache entry would still hold the old physics, silently. Here every madsim kernel's
entry is stamped with its own file and the contents of all madsim modules that use numba, so
an edit of any of them makes every madsim kernel compile again, once. Functions outside the
package keep numba's own locators. `install()` runs from `madsim/__init__.py`, before any
kernel module is imported (numba picks a function's cache locator when it is decorated).
"""

from __future__ import annotations

import hashlib
from functools import lru_cache
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent


def sources_digest(package_dir: Path) -> bytes:
    """sha256 over the relative paths and contents of the modules below `package_dir` that
    mention numba, in path order."""
    digest = hashlib.sha256()
    for path in sorted(package_dir.rglob("*.py")):
        text = path.read_bytes()
        if b"numba" in text:
            digest.update(path.relative_to(package_dir).as_posix().encode() + b"\0")
            digest.update(text)
    return digest.digest()


@lru_cache(maxsize=1)
def kernel_sources_digest() -> bytes:
    """`sources_digest` of the madsim package as this process found it."""
    return sources_digest(PACKAGE_DIR)


def _inside_package(py_file: str) -> bool:
    try:
        return Path(py_file).resolve().is_relative_to(PACKAGE_DIR)
    except (OSError, ValueError):
        return False


def _madsim_locator(base: type) -> type:
    """`base` (a numba cache locator class) for madsim's files only, with the kernel-sources
    digest added to its source stamp."""

    class Locator(base):
        madsim_kernels = True

        def get_source_stamp(self):
            return super().get_source_stamp(), kernel_sources_digest()

        @classmethod
        def from_function(cls, py_func, py_file):
            if not _inside_package(py_file):
                return None
            return super().from_function(py_func, py_file)

    Locator.__name__ = Locator.__qualname__ = "Madsim" + base.__name__
    return Locator


def install() -> None:
    """Put madsim's locators in front of numba's (idempotent; a no-op if numba's caching
    internals are not what this was written for)."""
    try:
        from numba.core import caching

        def named(name):   # numba < 0.62 spells these with a leading underscore
            return getattr(caching, name, None) or getattr(caching, "_" + name)

        impl = named("CacheImpl")
        bases = tuple(named(n) for n in ("UserProvidedCacheLocator", "InTreeCacheLocator",
                                         "UserWideCacheLocator"))
    except (ImportError, AttributeError):
        return
    if any(getattr(c, "madsim_kernels", False) for c in impl._locator_classes):
        return
    impl._locator_classes[:0] = [_madsim_locator(b) for b in bases]

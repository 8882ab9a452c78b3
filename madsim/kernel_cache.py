"""numba's disk cache for madsim's kernels, renewed by an edit of any kernel module.

numba stamps a cached function with the contents of its own source file only, but madsim's
kernels call each other across modules (the contact sub-step loop compiles the physics kernel
into itself; the sensors compile the track's ray caster): after an edit of `physics/kernel.py`
the loop's cache entry would still hold the old physics, silently. Here every madsim kernel's
entry is stamped with its own file and the contents of all madsim modules that use numba, so
an edit of any of them makes every madsim kernel compile again, once. Functions outside the
package keep numba's own locators. `install()` runs from `madsim/__init__.py`, before any
kernel module is imported (numba picks a function's cache locator when it is decorated).

Start-up (issue 13): before numba loads any function from its disk cache, it loads every
typing and lowering registry it has (imports of most of numba, a BLAS probe that imports
`scipy.linalg`: about 0.5 s on a 2-core AMD EPYC), none of which running compiled code needs.
`light_cache_loads` makes a load of a madsim kernel set up only what the code it loads calls
into (numba's runtime and the hash secrets); the first compile in the process still loads all
registries, as before. `defer_blas_probe` makes numba's BLAS probe (when `numba.np.arraymath`
is imported) look for scipy's BLAS module instead of importing `scipy.linalg` (madsim's kernels
use no BLAS). And a locator checks that its cache folder is writable once per folder and
process, not once per kernel.
"""

from __future__ import annotations

import hashlib
import os
import sys
from functools import lru_cache
from importlib.machinery import PathFinder
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


@lru_cache(maxsize=None)
def _inside_package(py_file: str) -> bool:
    try:
        return Path(py_file).resolve().is_relative_to(PACKAGE_DIR)
    except (OSError, ValueError):
        return False


_WRITABLE_CACHE_PATHS: set[str] = set()   # cache folders proven writable in this process


def _madsim_locator(base: type) -> type:
    """`base` (a numba cache locator class) for madsim's files only, with the kernel-sources
    digest added to its source stamp."""

    class Locator(base):
        madsim_kernels = True

        def get_source_stamp(self):
            return super().get_source_stamp(), kernel_sources_digest()

        def ensure_cache_path(self):
            # numba creates and deletes a file per kernel to prove the folder writable
            path = self.get_cache_path()
            if path not in _WRITABLE_CACHE_PATHS:
                super().ensure_cache_path()
                _WRITABLE_CACHE_PATHS.add(path)

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
    light_cache_loads()
    defer_blas_probe()


def light_cache_loads() -> None:
    """Load madsim's cached kernels without the full registry set-up numba's `Cache.load_overload`
    does first (`target_context.refresh()`): cached code is machine code that calls numba's
    runtime (NRT), its C helpers and math functions (in place once a target context exists) and
    the hash secrets (`numba.cpython.hashing` puts them in place when imported); typing and
    lowering registries are for compiling, and every compile refreshes them itself (numba's
    compiler does). Other packages' cached functions load as numba loads them. A no-op if
    numba's internals are not what this was written for."""
    try:
        from numba.core import caching
        from numba.core.runtime import rtsys
        load = caching.Cache.load_overload
    except (ImportError, AttributeError):
        return
    if getattr(load, "madsim_light", False) or not all(
            hasattr(caching.Cache, n) for n in ("_load_overload", "_guard_against_spurious_io_errors")):
        return

    def load_overload(self, sig, target_context):
        locator = getattr(getattr(self, "_impl", None), "locator", None)
        if not getattr(type(locator), "madsim_kernels", False):
            return load(self, sig, target_context)
        import numba.cpython.hashing  # noqa: F401  (its import puts the hash secrets in place)

        rtsys.initialize(target_context)
        with self._guard_against_spurious_io_errors():
            return self._load_overload(sig, target_context)

    load_overload.madsim_light = True
    caching.Cache.load_overload = load_overload


def scipy_blas_present() -> bool:
    """Whether scipy's BLAS module (`scipy.linalg.cython_blas`) is installed, found without
    importing `scipy.linalg`."""
    try:
        import scipy
    except ImportError:
        return False
    linalg = os.path.join(os.path.dirname(scipy.__file__), "linalg")
    return PathFinder.find_spec("cython_blas", [linalg]) is not None


def _probe_blas() -> None:
    """numba's `ensure_blas` as `numba.np.arraymath` calls it at import, to set `_HAVE_BLAS`."""
    if not scipy_blas_present():
        raise ImportError("scipy.linalg.cython_blas not found")


class _BlasProbeLoader:
    """The loader of `numba.np.arraymath`, run with `_probe_blas` in place of `ensure_blas`."""

    def __init__(self, loader):
        self._loader = loader

    def __getattr__(self, name):          # get_code, get_source, ... as the real loader's
        return getattr(self._loader, name)

    def create_module(self, spec):
        return self._loader.create_module(spec)

    def exec_module(self, module):
        from numba.np import linalg

        ensure_blas = linalg.ensure_blas
        linalg.ensure_blas = _probe_blas
        try:
            self._loader.exec_module(module)
        finally:
            linalg.ensure_blas = ensure_blas
            if getattr(module, "ensure_blas", None) is _probe_blas:
                module.ensure_blas = ensure_blas


class _ArraymathFinder:
    """Finds `numba.np.arraymath`, once, for `_BlasProbeLoader` (an import-system finder)."""

    def find_spec(self, name, path=None, target=None):
        if name != "numba.np.arraymath":
            return None
        if self in sys.meta_path:
            sys.meta_path.remove(self)
        spec = PathFinder.find_spec(name, path, target)
        if spec is not None and hasattr(spec.loader, "exec_module"):
            spec.loader = _BlasProbeLoader(spec.loader)
        return spec


def defer_blas_probe() -> None:
    """Make numba's import-time BLAS probe (`numba.np.arraymath._HAVE_BLAS`, which decides
    whether `np.convolve`-like functions may call BLAS) look for scipy's BLAS module instead of
    importing `scipy.linalg`; every use of BLAS still goes through numba's own `ensure_blas`,
    which imports and checks scipy then. `numba.np.arraymath` is imported by numba's registry
    load (the first compile) or by a cached kernel whose code came from it; a no-op once it is
    imported."""
    if "numba.np.arraymath" in sys.modules:
        return
    if not any(isinstance(f, _ArraymathFinder) for f in sys.meta_path):
        sys.meta_path.insert(0, _ArraymathFinder())

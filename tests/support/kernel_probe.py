"""Code for fresh-process probes of numba's disk cache (tests/net/test_start_up.py,
tests/physics/test_batch_start_up.py): `dispatchers()` yields ("module.name", dispatcher) for every
madsim kernel the probe process has imported; its `stats` tell cache hits from compiles."""

DISPATCHERS = r"""
import sys as _sys
import numba as _numba

def dispatchers():
    for name, mod in list(_sys.modules.items()):
        if name.startswith("madsim."):
            for attr, obj in vars(mod).items():
                if isinstance(obj, _numba.core.dispatcher.Dispatcher) and obj.__module__ == name:
                    yield f"{name}.{attr}", obj
"""

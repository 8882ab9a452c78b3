"""Physics: `World` (world.py), the compiled vehicle kernel (kernel.py), contact and sensors.

`from madsim.physics import World, SensorSuite, SensorFrame` (imported on first use).
"""

_EXPORTS = {"World": "madsim.physics.world", "SensorSuite": "madsim.physics.sensors",
            "SensorFrame": "madsim.physics.sensors", "TorcsClock": "madsim.physics.schedule",
            "make_clock": "madsim.physics.schedule"}
__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    mod = _EXPORTS.get(name)
    if mod is None:
        raise AttributeError(f"module 'madsim.physics' has no attribute {name!r}")
    import importlib
    return getattr(importlib.import_module(mod), name)

"""Cars: TORCS car + category XML merged into an immutable `CarSpec` in SI units.

`load_car(name_or_path)` finds a bundled car, an installed TORCS car or a file;
`madsim.cars.catalog` lists cars and converts them (JSON, standalone XML).
Imports nothing of madsim above `madsim.torcsxml`.
"""

from madsim.cars.errors import CarError
from madsim.cars.loader import load_car
from madsim.cars.merge import merge_sections
from madsim.cars.spec import CarSpec

__all__ = ["CarError", "CarSpec", "load_car", "merge_sections"]

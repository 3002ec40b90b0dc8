"""Built-in example parts and a scan simulator, generated in code (no data files).

* :func:`blade`, :func:`flat_plate`, :func:`doubly_curved_panel` (:mod:`.parts`): Jaeger's
  helicopter-blade section, an analytic flat reference, a convex panel.
* :func:`wheel_hub` (:mod:`.hub`): a dished hub face with five spoke windows and a rim (Wang).
* :func:`large_panel` (:mod:`.large`): a smooth panel of about 500k faces for scale benchmarks.
* :func:`simulate_laser_scan` (:mod:`.scansim`): a noisy point-laser scan of a patch or surface.

``example_part(name)`` builds the parts the CLI knows as ``example:NAME``.
"""

from collections.abc import Callable

from ..errors import InputError
from ..surface import Surface
from ..surface.exact_shapes import naca00_thickness
from ..surface.grid import grid_faces
from .hub import wheel_hub
from .large import large_panel
from .parts import blade, doubly_curved_panel, flat_plate

#: Built-in parts by name, as the CLI knows them (``example:NAME``).
PARTS: dict[str, Callable[[], Surface]] = {"blade": blade, "plate": flat_plate, "panel": doubly_curved_panel, "hub": wheel_hub}


def example_part(name: str):
    """The built-in part called ``name`` (see :data:`PARTS`)."""
    try:
        return PARTS[name]()
    except KeyError:
        raise InputError(f"unknown example part {name!r}; choose one of {', '.join(PARTS)}") from None


__all__ = ["PARTS", "blade", "doubly_curved_panel", "example_part", "flat_plate", "grid_faces", "large_panel",
           "naca00_thickness", "wheel_hub"]

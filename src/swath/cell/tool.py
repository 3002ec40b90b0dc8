"""The tool on the flange: the TCP and the bodies that must not touch the part or the cell.

The pad is not a collision body (it is meant to touch the part).  A gap of :attr:`ToolBody.pad_gap`
between the lowest checked body and the TCP holds the pad and its backing plate.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .bodies import Body, Cylinder


@dataclass(frozen=True, eq=False)
class ToolBody:
    """The tool's collision bodies, posed in the flange frame.

    Attributes
    ----------
    bodies : tuple of Body
        Holder, spindle, motor … (``body2frame`` = body2flange), m.
    tcp2flange : (4, 4) float
        The TCP's pose in the flange frame, m.
    description : str
        What the tool is (shown in warnings and the report).
    """

    bodies: tuple
    tcp2flange: np.ndarray
    description: str = ""


#: The default tool: a 3-inch (76.2 mm) random-orbital sander on a compliant holder, sizes in m.
SANDER_3IN = {
    "holder_radius": 0.045, "holder_length": 0.050,      # flange adapter / compliance unit, Ø90 x 50 mm
    "spindle_radius": 0.035, "spindle_length": 0.095,    # motor and orbit housing, Ø70 x 95 mm
    "pad_stack": 0.030,                                  # backing plate + pad below the housing, 30 mm
    "pad_radius": 0.0381,                                # Ø76.2 mm pad
}


def default_sander() -> ToolBody:
    """A 3-inch random-orbital sander: a Ø90 x 50 mm holder on the flange, a Ø70 x 95 mm spindle
    housing below it, and 30 mm of backing plate and pad; the TCP at the pad face centre, 175 mm
    from the flange along its z, axes aligned with the flange.  These are typical sizes of robotic
    3-inch orbital sanders (pneumatic or electric), not a particular product."""
    s = SANDER_3IN
    holder = np.eye(4)
    holder[2, 3] = s["holder_length"] / 2
    spindle = np.eye(4)
    spindle[2, 3] = s["holder_length"] + s["spindle_length"] / 2
    tcp2flange = np.eye(4)
    tcp2flange[2, 3] = s["holder_length"] + s["spindle_length"] + s["pad_stack"]
    bodies = (Body("tool holder", Cylinder(s["holder_radius"], s["holder_length"]), holder),
              Body("tool spindle", Cylinder(s["spindle_radius"], s["spindle_length"]), spindle))
    return ToolBody(bodies=bodies, tcp2flange=tcp2flange,
                    description=f"3-inch random-orbital sander (holder Ø90x50 mm, spindle Ø70x95 mm, pad Ø76.2 mm; "
                                f"TCP {1e3 * tcp2flange[2, 3]:.0f} mm out along the flange's z axis)")

"""The ``cell`` stage: the robot's workcell and collision queries in it.

* :mod:`.frames` — rigid transforms named ``A2B`` (pytransform3d: ``p_B = A2B @ p_A``), checked on input.
* :mod:`.cell` — the :class:`Cell` record: ``part2base``, ``tcp2flange``, the tool body, table, fixtures.
* :mod:`.bodies`, :mod:`.tool` — boxes, cylinders, capsules, meshes; the default 3-inch sander.
* :mod:`.positioner` — a rotary positioner (external axis) that turns the part.
* :mod:`.file` — the TOML cell file (``--cell``).
* :mod:`.collide` — :class:`CollisionScene`, culled collision queries through coal.
"""

from .bodies import Body, Box, Capsule, Cylinder, Mesh, Table, default_table
from .cell import Cell
from .collide import CollisionHits, CollisionScene, MovingBody
from .file import cell_from_mapping, read_cell_file
from .frames import check_transform, format_pose, invert_transform, parse_pose
from .positioner import Positioner, positioner_from_mapping
from .tool import SANDER_3IN, ToolBody, default_sander

__all__ = ["SANDER_3IN", "Body", "Box", "Capsule", "Cell", "CollisionHits", "CollisionScene", "Cylinder", "Mesh",
           "MovingBody", "Positioner", "Table", "ToolBody", "cell_from_mapping", "check_transform", "default_sander",
           "default_table", "format_pose", "invert_transform", "parse_pose", "positioner_from_mapping", "read_cell_file"]

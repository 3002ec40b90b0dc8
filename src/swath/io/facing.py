"""Which way a loaded part faces: a part whose normals point down, away from a tool that comes from
above, would be planned from underneath, so it gets a warning that names the fix.

swath plans on the side the surface normals point to (the tool comes from that side).  A mesh read
without ``--side`` keeps the file's own orientation, and many exports wind their faces the other
way: the plan is then laid on the underside, with the pad pressed from below (on bezier_dac_cad with
its faces flipped the removal CoV goes from 0.21 to 0.40).  The check compares the part's area
facing up (the table's up, +z in the part frame unless told otherwise) with its area facing down.
"""

from __future__ import annotations

import numpy as np

#: |n · up| above which a face counts as facing up or down (as the closed-solid cut's threshold).
FACING_DOT = 0.2


def facing_shares(surface, up=(0.0, 0.0, 1.0)) -> tuple[float, float, float]:
    """Area shares of ``surface`` facing up and down, and its area-weighted mean ``n · up``.

    Parameters
    ----------
    surface : Surface
        Normals toward the tool.
    up : (3,) float
        The table's up direction in the part frame (any length > 0).

    Returns
    -------
    up_share, down_share : float
        Area shares with ``n · up > FACING_DOT`` and ``n · up < -FACING_DOT``.
    mean_dot : float
        ``Σ a_i n_i · up / Σ a_i`` over the faces, in [-1, 1].
    """
    u = np.asarray(up, float)
    u = u / np.linalg.norm(u)
    areas = np.asarray(surface.face_areas, float)
    dots = np.asarray(surface.face_normals, float) @ u
    total = float(areas.sum())
    return (float(areas[dots > FACING_DOT].sum() / total), float(areas[dots < -FACING_DOT].sum() / total),
            float(areas @ dots / total))


def facing_warning(surface, *, side=None, up=(0.0, 0.0, 1.0)) -> str | None:
    """A warning when ``surface`` faces away from a tool coming from ``up``, else None.

    The part faces away when its mean normal points down (``mean n · up < -FACING_DOT``) and more of
    its area faces down than up.  A part with a tool side given (``side``, the user's ``--side``)
    is oriented as asked and never warns; a wall or a part facing both ways as much (mean near 0)
    does not warn either.

    Parameters
    ----------
    surface : Surface
    side : str or (3,) float, optional
        The tool side the part was loaded with; not None: no warning.
    up : (3,) float
        The table's up direction in the part frame.

    Returns
    -------
    str or None
        The message, naming the shares and the ``--side`` options that fix it.
    """
    if side is not None:
        return None
    up_share, down_share, mean_dot = facing_shares(surface, up)
    if not (mean_dot < -FACING_DOT and down_share > up_share):
        return None
    name = surface.name or "the part"
    return (f"{name} faces away from a tool coming from above: {100 * down_share:.0f} % of its area faces down and "
            f"{100 * up_share:.0f} % up (mean normal · up = {mean_dot:+.2f}), so it will be planned from underneath; "
            "if the tool comes from above, load it with --side +z (side='+z'), which turns its faces toward the tool, "
            "or with --side -z if it really is worked from below")

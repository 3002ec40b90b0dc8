"""The robot cell in the report's 3D view: the table, the fixtures and where collisions happen.

Everything is drawn in the part frame (the 3D view's frame): a body posed ``body2base`` in the
base frame is drawn at ``base2part @ body2base``.  The table is cut to the part's footprint plus a
margin, so that a table under the robot's whole reach does not shrink the part to a speck.
"""

from __future__ import annotations

import math

import numpy as np

_BOX_FACES = np.array([[0, 1, 2], [0, 2, 3], [4, 6, 5], [4, 7, 6], [0, 4, 5], [0, 5, 1],
                       [1, 5, 6], [1, 6, 2], [2, 6, 7], [2, 7, 3], [3, 7, 4], [3, 4, 0]])


def _box_mesh(lo, hi):
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    v = np.array([[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0],
                  [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]], dtype=float)
    return v, _BOX_FACES


def _prism_mesh(radius, length, n=24):
    a = np.linspace(0, 2 * math.pi, n, endpoint=False)
    ring = np.column_stack([radius * np.cos(a), radius * np.sin(a)])
    v = np.vstack([np.column_stack([ring, np.full(n, -length / 2)]), np.column_stack([ring, np.full(n, length / 2)]),
                   [[0, 0, -length / 2], [0, 0, length / 2]]])
    f = []
    for i in range(n):
        j = (i + 1) % n
        f += [[i, j, n + j], [i, n + j, n + i], [2 * n, j, i], [2 * n + 1, n + i, n + j]]
    return v, np.array(f)


def body_mesh(body):
    """(v, f) triangles of a cell body in its own frame (boxes, prisms for cylinders/capsules, meshes)."""
    from ..cell import Box, Mesh

    shape = body.shape
    if isinstance(shape, Box):
        half = np.asarray(shape.size) / 2
        return _box_mesh(-half, half)
    if isinstance(shape, Mesh):
        return shape.vertices, shape.faces
    return _prism_mesh(shape.radius, shape.length + (2 * shape.radius if type(shape).__name__ == "Capsule" else 0))


def cell_traces(cell, collisions=(), *, part_vertices=None, margin: float = 0.15) -> list:
    """Plotly traces of the cell in the part frame.

    Parameters
    ----------
    cell : swath.cell.Cell
        Its ``table`` and ``fixtures`` are drawn.
    collisions : sequence of dict
        Collision records (``point_part_m``, ``body_a``, ``body_b``, ``pass``, ``t_start_s``) as
        metrics.json holds them; each is marked with a red cross.
    part_vertices : (n, 3) float, optional
        The part (part frame, m): the table is cut to its footprint plus ``margin`` (m).

    Returns
    -------
    list of plotly traces
    """
    import plotly.graph_objects as go

    base2part = cell.base2part
    traces = []

    def mesh_trace(v, f, name, color, opacity):
        return go.Mesh3d(x=v[:, 0], y=v[:, 1], z=v[:, 2], i=f[:, 0], j=f[:, 1], k=f[:, 2], name=name,
                         color=color, opacity=opacity, showlegend=True, hovertemplate=f"{name}<extra></extra>")

    if cell.table is not None:
        table = cell.table.body()
        v, f = body_mesh(table)
        v_part = v @ (base2part @ table.body2frame)[:3, :3].T + (base2part @ table.body2frame)[:3, 3]
        if part_vertices is not None and abs(base2part[2, 2]) > 1 - 1e-9:
            # the table's top is level in the part frame too: cut it to the part's footprint
            lo = np.asarray(part_vertices).min(axis=0) - margin
            hi = np.asarray(part_vertices).max(axis=0) + margin
            v_part[:, :2] = np.clip(v_part[:, :2], lo[:2], hi[:2])
        traces.append(mesh_trace(v_part, f, "table" + (" (assumed)" if cell.table.assumed else ""),
                                 "rgb(181,155,120)", 0.35))
    for body in cell.fixtures:
        v, f = body_mesh(body)
        t = base2part @ body.body2frame
        traces.append(mesh_trace(v @ t[:3, :3].T + t[:3, 3], f, body.name, "rgb(90,110,160)", 0.55))
    pts = [c for c in collisions if c.get("point_part_m") is not None]
    if pts:
        p = np.array([c["point_part_m"] for c in pts], dtype=float)
        text = [f"{c['body_a']} hits {c['body_b']}<br>"
                + (f"pass {c['pass']}" if c["pass"] >= 0 else "air move") + f", t = {c['t_start_s']:.2f} s"
                for c in pts]
        traces.append(go.Scatter3d(x=p[:, 0], y=p[:, 1], z=p[:, 2], mode="markers", name="collisions",
                                   marker=dict(size=7, symbol="x", color="rgb(220,20,20)"), text=text,
                                   hovertemplate="%{text}<extra></extra>"))
    return traces

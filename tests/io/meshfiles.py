"""Mesh files generated in code for the io tests: plates, fins, relative-index OBJ, bad inputs."""

from __future__ import annotations

import struct

import numpy as np


def grid(nx=5, ny=4, size=(0.2, 0.1), origin=(0.0, 0.0, 0.0)):
    """A flat plate in z = origin[2], faces wound +z: ``(vertices (nx*ny, 3), faces (2(nx-1)(ny-1), 3))``."""
    x, y = np.meshgrid(np.linspace(0, size[0], nx), np.linspace(0, size[1], ny), indexing="ij")
    v = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1) + np.asarray(origin, float)
    idx = np.arange(nx * ny).reshape(nx, ny)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    f = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return v, f


def plate_with_fin(*, n=16, size=0.3, fin_y=0.14, fin_x=(0.1, 0.2), fin_height=0.03):
    """A square plate (``n`` x ``n`` grid, ``size`` m) with a vertical fin standing on the grid line ``y = fin_y``.

    The fin is one row of quads (two triangles each) from ``fin_x[0]`` to ``fin_x[1]``, ``fin_height``
    tall; its bottom triangles share the plate's edges, which become shared by three faces.  With the
    defaults each fin triangle (3e-4 m²) is larger than a plate triangle (2e-4 m²).

    Returns
    -------
    vertices : (k, 3) float
    faces : (m, 3) int
        The plate's ``2 (n-1)²`` faces first, then the fin's.
    n_plate_faces : int
    """
    v, f = grid(n, n, size=(size, size))
    step = size / (n - 1)
    on_line = np.flatnonzero(np.isclose(v[:, 1], fin_y) & (v[:, 0] >= fin_x[0] - 1e-12) & (v[:, 0] <= fin_x[1] + 1e-12))
    if not np.isclose(fin_y / step, round(fin_y / step)) or len(on_line) < 2:
        raise ValueError("the fin must stand on a grid line of the plate")
    bottom = on_line[np.argsort(v[on_line, 0])]
    top = len(v) + np.arange(len(bottom))
    v = np.vstack([v, v[bottom] + [0.0, 0.0, fin_height]])
    fin = [[bottom[i], bottom[i + 1], top[i + 1]] for i in range(len(bottom) - 1)]
    fin += [[bottom[i], top[i + 1], top[i]] for i in range(len(bottom) - 1)]
    return v, np.vstack([f, fin]), len(f)


def obj_text(vertices, faces, *, relative_groups=None, normals=None) -> str:
    """OBJ text; with ``relative_groups=k`` the faces are written in k groups, each after its own copy of
    the vertices it uses and referring to them with negative (relative) indices, as some exporters do."""
    v = np.asarray(vertices, float)
    f = np.asarray(faces)
    if relative_groups is None:
        lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in v.tolist()]
        if normals is not None:
            lines += [f"vn {x!r} {y!r} {z!r}" for x, y, z in np.asarray(normals, float).tolist()]
            lines += ["f " + " ".join(f"{i + 1}//{i + 1}" for i in row) for row in f]
        else:
            lines += ["f " + " ".join(str(int(i) + 1) for i in row) for row in f]
        return "\n".join(lines) + "\n"
    lines = ["# faces refer to vertices with negative (relative) indices"]
    for g, chunk in enumerate(np.array_split(f, relative_groups)):
        used, local = np.unique(chunk, return_inverse=True)
        local = local.reshape(chunk.shape)
        lines.append(f"o group{g}")
        lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in v[used].tolist()]
        lines += ["f " + " ".join(str(int(i) - len(used)) for i in row) for row in local]
    return "\n".join(lines) + "\n"


def ply_ascii_lines(vertices, faces=None, normals=None) -> list[str]:
    """The lines of an ASCII PLY (doubles; optional per-vertex normals and faces)."""
    v = np.asarray(vertices, float)
    lines = ["ply", "format ascii 1.0", f"element vertex {len(v)}",
             "property double x", "property double y", "property double z"]
    if normals is not None:
        lines += ["property double nx", "property double ny", "property double nz"]
    if faces is not None:
        lines += [f"element face {len(faces)}", "property list uchar int vertex_indices"]
    lines.append("end_header")
    data = v if normals is None else np.hstack([v, normals])
    lines += [" ".join(repr(float(x)) for x in row) for row in data]
    if faces is not None:
        lines += [f"{len(row)} " + " ".join(str(int(i)) for i in row) for row in faces]
    return lines


def ply_binary_bytes(vertices, faces) -> bytes:
    """A binary little-endian PLY with double positions."""
    v = np.asarray(vertices, dtype="<f8")
    f = np.asarray(faces)
    face = np.empty(len(f), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    face["n"], face["i"] = 3, f
    header = ("ply\nformat binary_little_endian 1.0\n"
              f"element vertex {len(v)}\nproperty double x\nproperty double y\nproperty double z\n"
              f"element face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n")
    return header.encode() + v.tobytes() + face.tobytes()


def stl_binary_bytes(vertices, faces) -> bytes:
    tri = np.asarray(vertices, float)[np.asarray(faces)]
    rec = np.zeros(len(tri), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["v"] = tri
    return b"\0" * 80 + struct.pack("<I", len(tri)) + rec.tobytes()


def box(extents=(0.2, 0.1, 0.05)):
    """A closed box centred at the origin, outward winding: 8 vertices, 12 faces."""
    hx, hy, hz = np.asarray(extents, float) / 2
    v = np.array([[x, y, z] for x in (-hx, hx) for y in (-hy, hy) for z in (-hz, hz)])
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return v, f

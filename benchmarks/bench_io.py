"""Mesh reading speed: swath's exact OBJ / ASCII PLY parsers against trimesh's, and the whole load_mesh.

    PYTHONPATH=src python benchmarks/bench_io.py [--faces 200000 1000000]

For each size, plates of about that many faces are written (OBJ absolute and relative indices,
ASCII PLY, binary PLY, binary STL) to a temporary folder; the table gives the time of the raw
reader (``swath.io.mesh_read.read_mesh_file``), of trimesh's loader for the same bytes, and of
the whole :func:`swath.io.load_mesh` (cleaning, repair, orientation), and the faces each read.
"""

from __future__ import annotations

import argparse
import io
import sys
import tempfile
import time
from pathlib import Path

import common

sys.path.insert(0, str(common.REPO / "tests" / "io"))

from meshfiles import (
    grid,
    obj_text,
    ply_ascii_lines,
    ply_binary_bytes,
    stl_binary_bytes,
)


def _trimesh_faces(path: Path, ext: str):
    from trimesh.exchange import obj, ply, stl

    loader = {".stl": stl.load_stl, ".ply": ply.load_ply, ".obj": obj.load_obj}[ext]
    kw = loader(io.BytesIO(path.read_bytes()))
    parts = list(kw["geometry"].values()) if "geometry" in kw else [kw]
    return sum(len(p["faces"]) for p in parts if p.get("faces") is not None)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--faces", type=int, nargs="+", default=[200_000, 1_000_000])
    args = parser.parse_args(argv)
    from swath.io import load_mesh
    from swath.io.mesh_read import read_mesh_file

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n_faces in args.faces:
            n = round((n_faces / 2) ** 0.5) + 1
            v, f = grid(n, n, size=(0.3, 0.3))
            files = {
                "obj": ("plate.obj", obj_text(v, f).encode()),
                "obj relative": ("plate_rel.obj", obj_text(v, f, relative_groups=100).encode()),
                "ply ascii": ("plate_a.ply", ("\n".join(ply_ascii_lines(v, f)) + "\n").encode()),
                "ply binary": ("plate_b.ply", ply_binary_bytes(v, f)),
                "stl binary": ("plate.stl", stl_binary_bytes(v, f)),
            }
            for kind, (name, data) in files.items():
                path = Path(tmp) / name
                path.write_bytes(data)
                t0 = time.perf_counter()
                _, faces, _ = read_mesh_file(path, path.suffix)
                t_read = time.perf_counter() - t0
                t0 = time.perf_counter()
                tm_faces = _trimesh_faces(path, path.suffix)
                t_trimesh = time.perf_counter() - t0
                t0 = time.perf_counter()
                surface = load_mesh(path)
                t_load = time.perf_counter() - t0
                rows.append({"file": kind, "faces": len(f), "MB": len(data) / 1e6, "read_s": t_read,
                             "read_faces": len(faces), "trimesh_s": t_trimesh, "trimesh_faces": tm_faces,
                             "load_mesh_s": t_load, "loaded_faces": len(surface.faces)})
                path.unlink()
    common.print_table(rows, [("file", ""), ("faces", "d"), ("MB", ".1f"), ("read_s", ".2f"), ("read_faces", "d"),
                              ("trimesh_s", ".2f"), ("load_mesh_s", ".2f"),
                              ("loaded_faces", "d")])
    print(f"peak RSS {common.max_rss_mb():.0f} MB")


if __name__ == "__main__":
    main()

"""Read STEP and IGES B-reps through Open CASCADE (OCP) into a :class:`~swath.io.part.Part`.

The B-rep is kept where it matters: every face is tessellated by ``BRepMesh_IncrementalMesh`` to a
stated chordal tolerance (the largest distance of a triangle from the exact face), and the normal
at every tessellation vertex is evaluated on the face's exact surface (plane, cylinder, B-spline,
... with its trimming) at the vertex's (u, v), flipped for a reversed face so that it points out
of the solid.  Faces keep their ids, their names (STEP ``ADVANCED_FACE`` names) and colours (XCAF
surface colours) where the file has them.  Lengths come in the file's own unit and leave in metres.

Open CASCADE comes from the optional extra ``swath[cad]`` (``cadquery-ocp-novtk``); without it
:func:`load_step` refuses with a message naming the extra.
"""

from __future__ import annotations

import logging
import re
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..errors import InputError
from .checks import check_extent, check_file
from .part import ExactNormalSurface, Part, PartFace

log = logging.getLogger("swath.io")

#: File extensions read as CAD B-reps.
STEP_EXTENSIONS = (".step", ".stp")
IGES_EXTENSIONS = (".iges", ".igs")
CAD_EXTENSIONS = STEP_EXTENSIONS + IGES_EXTENSIONS

#: Default chordal tolerance of the tessellation, m.
DEFAULT_CHORDAL_TOLERANCE = 1e-4
#: Default angular tolerance of the tessellation (largest angle between neighbouring facets), rad.
DEFAULT_ANGULAR_TOLERANCE = 0.25
#: A STEP face entity with a name (``ADVANCED_FACE('tube_outer', ...)``; unnamed ones are ``''`` or ``'NONE'``).
_NAMED_FACE = re.compile(rb"ADVANCED_FACE\s*\(\s*'(?!'|NONE')")
#: Default longest triangle edge of the tessellation, m.
DEFAULT_MAX_EDGE = 1e-2
#: Tessellation vertices of different faces closer than this (m) are the same point of a shared edge.
WELD_TOLERANCE = 1e-7

_KINDS = {"GeomAbs_Plane": "plane", "GeomAbs_Cylinder": "cylinder", "GeomAbs_Cone": "cone",
          "GeomAbs_Sphere": "sphere", "GeomAbs_Torus": "torus", "GeomAbs_BezierSurface": "bezier",
          "GeomAbs_BSplineSurface": "bspline", "GeomAbs_SurfaceOfRevolution": "revolution",
          "GeomAbs_SurfaceOfExtrusion": "extrusion", "GeomAbs_OffsetSurface": "offset"}

#: Open CASCADE's session length unit (``xstep.cascade.unit``) in metres: readers convert the
#: file's own unit to it.
_CASCADE_UNITS = {"MM": 1e-3, "M": 1.0, "CM": 1e-2, "KM": 1e3, "IN": 0.0254, "FT": 0.3048, "MI": 1609.344,
                  "UM": 1e-6, "MIL": 2.54e-5, "UIN": 2.54e-8}


def require_ocp():
    """Import OCP (Open CASCADE) or refuse, naming the extra to install."""
    try:
        import OCP  # noqa: F401
    except ImportError as exc:
        raise InputError("reading STEP/IGES files needs Open CASCADE's Python bindings: install the cad extra "
                         "(pip install 'swath[cad]', which brings cadquery-ocp-novtk), or export the part "
                         "as STL/PLY/OBJ") from exc
    _quiet()


def _quiet() -> None:
    """Keep Open CASCADE's translators from writing statistics to the console (the library logs)."""
    from OCP.Message import Message

    messenger = Message.DefaultMessenger_s()
    printers = messenger.Printers()
    while printers.Size():
        messenger.RemovePrinter(printers.First())
        printers = messenger.Printers()


def load_step(path, *, chordal_tolerance: float = DEFAULT_CHORDAL_TOLERANCE,
              angular_tolerance: float = DEFAULT_ANGULAR_TOLERANCE, max_edge: float | None = DEFAULT_MAX_EDGE,
              force_units: bool = False) -> Part:
    """Read a STEP or IGES file as a :class:`Part` (all of its faces; metres, part frame).

    Parameters
    ----------
    path : str or Path
        ``.step``/``.stp`` or ``.iges``/``.igs`` file.  Lengths are read in the file's unit.
    chordal_tolerance : float
        Largest distance of the tessellation from the exact faces, m (default 0.1 mm).
    angular_tolerance : float
        Largest angle between neighbouring facets of a face, rad.
    max_edge : float or None
        Longest triangle edge, m (default 10 mm; see :func:`tessellate`).
    force_units : bool
        Accept a part whose largest extent is outside 5 mm .. 20 m.

    Returns
    -------
    Part
        Its surface an :class:`ExactNormalSurface` (normals out of the solid, evaluated on the
        exact faces), ``face_ids`` per triangle, one :class:`PartFace` per B-rep face.

    Raises
    ------
    InputError
        Without OCP (names the ``cad`` extra), for an unreadable file, a file without faces, a
        non-positive tolerance or an implausible size.
    """
    path = Path(path)
    suffix = check_file(path, CAD_EXTENSIONS, "CAD (STEP or IGES)")
    for key, value in (("chordal tolerance", chordal_tolerance), ("angular tolerance", angular_tolerance)):
        if not (np.isfinite(value) and value > 0):
            raise InputError(f"the {key} must be positive, got {value!r}")
    require_ocp()
    shape, names, colours = _read(path, suffix in STEP_EXTENSIONS)
    from OCP.Interface import Interface_Static

    unit = Interface_Static.CVal_s("xstep.cascade.unit") or "MM"
    scale = _CASCADE_UNITS.get(unit.upper(), 1e-3)
    part = tessellate(shape, chordal_tolerance=chordal_tolerance, angular_tolerance=angular_tolerance,
                      scale=scale, max_edge=max_edge, names=names, colours=colours, name=path.stem)
    extent = float(np.ptp(part.surface.vertices, axis=0).max())
    check_extent(extent, "m", force_units, path.name)
    return Part(part.surface, part.face_ids, part.faces, closed=part.closed, source=path.name,
                chordal_tolerance=chordal_tolerance)


def _read(path: Path, step: bool):
    """The file's shape, and per-face names and colours (dicts keyed by the face's 0-based index in :func:`_faces`' order)."""
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDocStd import TDocStd_Document
    from OCP.XCAFDoc import XCAFDoc_DocumentTool

    doc = TDocStd_Document(TCollection_ExtendedString("XmlXCAF"))
    if step:
        from OCP.STEPCAFControl import STEPCAFControl_Reader

        reader = STEPCAFControl_Reader()
    else:
        from OCP.IGESCAFControl import IGESCAFControl_Reader

        reader = IGESCAFControl_Reader()
    reader.SetColorMode(True)
    reader.SetNameMode(True)
    if reader.ReadFile(str(path)) != IFSelect_RetDone:
        raise InputError(f"{path.name}: Open CASCADE could not read it as a {'STEP' if step else 'IGES'} file; "
                         "re-export it from the CAD system")
    if not reader.Transfer(doc):
        raise InputError(f"{path.name}: no shape could be transferred from the file; re-export it")
    shapes = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    colour_tool = XCAFDoc_DocumentTool.ColorTool_s(doc.Main())
    from OCP.BRep import BRep_Builder
    from OCP.collections import Sequence_TDF_Label
    from OCP.TopoDS import TopoDS_Compound

    labels = Sequence_TDF_Label()
    shapes.GetFreeShapes(labels)
    builder = BRep_Builder()
    compound = TopoDS_Compound()
    builder.MakeCompound(compound)
    for i in range(1, labels.Length() + 1):
        builder.Add(compound, shapes.GetShape_s(labels.Value(i)))
    faces = _faces(compound)
    if not faces:
        raise InputError(f"{path.name} holds no faces (wires or points only); export the part's surfaces")
    from OCP.Quantity import Quantity_Color
    from OCP.XCAFDoc import XCAFDoc_ColorGen, XCAFDoc_ColorSurf

    names, colours = {}, {}
    for key, face in enumerate(faces):
        colour = Quantity_Color()
        if colour_tool.GetColor(face, XCAFDoc_ColorSurf, colour) or colour_tool.GetColor(face, XCAFDoc_ColorGen,
                                                                                         colour):
            colours[key] = "#{:02x}{:02x}{:02x}".format(*(int(round(255 * c)) for c in
                                                          (colour.Red(), colour.Green(), colour.Blue())))
    if step:
        names = _step_face_names(path, reader.Reader().WS(), faces)
    return compound, names, colours


def _step_face_names(path: Path, session, faces) -> dict:
    """Names of the STEP ``ADVANCED_FACE`` entities of ``faces``, keyed by the face's 0-based index.

    The file's text is searched first for a named face at all (most exports name none); only then
    is each face's entity looked up (a search per face).
    """
    transfer = session.TransferReader()
    named = _NAMED_FACE.search(path.read_bytes()) is not None
    names: dict = {}
    if not named:
        return names
    for key, face in enumerate(faces):
        entity = transfer.EntityFromShapeResult(face, 1)
        if entity is not None and hasattr(entity, "Name") and entity.Name() is not None:
            text = entity.Name().ToCString()
            if text and text != "NONE":
                names[key] = text
    return names


def _faces(shape) -> list:
    """The distinct faces of ``shape`` in Open CASCADE's order (a face shared by two solids once)."""
    from OCP.collections import IndexedMap_TopoDS_Shape_TopTools_ShapeMapHasher
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp
    from OCP.TopoDS import TopoDS

    found = IndexedMap_TopoDS_Shape_TopTools_ShapeMapHasher()
    TopExp.MapShapes_s(shape, TopAbs_FACE, found)
    return [TopoDS.Face(found.FindKey(i)) for i in range(1, found.Extent() + 1)]


def tessellate(shape, *, chordal_tolerance: float = DEFAULT_CHORDAL_TOLERANCE,
               angular_tolerance: float = DEFAULT_ANGULAR_TOLERANCE, scale: float = 1e-3,
               max_edge: float | None = DEFAULT_MAX_EDGE, names: dict | None = None, colours: dict | None = None,
               name: str = "") -> Part:
    """Tessellate an Open CASCADE shape into a :class:`Part` with exact vertex normals.

    Parameters
    ----------
    shape : OCP.TopoDS.TopoDS_Shape
        A solid, shell, compound or face, in Open CASCADE's session unit.
    chordal_tolerance : float
        Largest distance of the triangles from the exact faces, m.
    angular_tolerance : float
        Largest angle between neighbouring facets, rad.
    scale : float
        Metres per unit of the shape's coordinates (1e-3 for Open CASCADE's default millimetres).
    max_edge : float or None
        Longest triangle edge, m: longer edges are split and the new vertices take the exact normal
        at their projection onto the face (None: the mesher's triangles as they are, which on a
        cylinder run its whole length).
    names, colours : dict, optional
        Face names / ``"#rrggbb"`` colours keyed by the face's 0-based index in :func:`_faces`' order.
    name : str
        The part's name.

    Returns
    -------
    Part
        Vertices welded along shared edges; every triangle keeps its own face's exact normals at its
        corners (a vertex on a sharp edge takes the mean of its corners').
    """
    from OCP.BRep import BRep_Tool
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.BRepLProp import BRepLProp_SLProps
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.TopAbs import TopAbs_REVERSED
    from OCP.TopLoc import TopLoc_Location

    names = names or {}
    colours = colours or {}
    BRepMesh_IncrementalMesh(shape, chordal_tolerance / scale, False, angular_tolerance, True)
    verts, norms, tris, ids, faces = [], [], [], [], []
    offset = 0
    for number, face in enumerate(_faces(shape), start=1):
        location = TopLoc_Location()
        triangulation = BRep_Tool.Triangulation_s(face, location)
        adaptor = BRepAdaptor_Surface(face)
        kind = _KINDS.get(adaptor.GetType().name, "other")
        key = number - 1
        if triangulation is None or triangulation.NbTriangles() == 0:
            log.warning("%s: face %d (%s) could not be tessellated; it is left out", name, number, kind)
            faces.append(PartFace(number, names.get(key, ""), kind, colours.get(key), 0.0))
            continue
        trsf = location.Transformation()
        n_nodes = triangulation.NbNodes()
        xyz = np.empty((n_nodes, 3))
        normal = np.full((n_nodes, 3), np.nan)
        props = BRepLProp_SLProps(adaptor, 1, 1e-9)
        has_uv = triangulation.HasUVNodes()
        plane = kind == "plane"                      # one normal: evaluated once
        for i in range(1, n_nodes + 1):
            p = triangulation.Node(i).Transformed(trsf)
            xyz[i - 1] = (p.X(), p.Y(), p.Z())
            if has_uv and (not plane or i == 1):
                uv = triangulation.UVNode(i)
                props.SetParameters(uv.X(), uv.Y())
                if props.IsNormalDefined():
                    d = props.Normal()
                    normal[i - 1] = (d.X(), d.Y(), d.Z())
        if plane:
            normal[:] = normal[0]
        n_tri = triangulation.NbTriangles()
        tri = np.empty((n_tri, 3), np.int64)
        for i in range(1, n_tri + 1):
            tri[i - 1] = triangulation.Triangle(i).Get()
        tri -= 1
        if max_edge is not None:
            xyz, tri, normal = _refine(face, adaptor, props, xyz, tri, normal, max_edge / scale)
        if face.Orientation() == TopAbs_REVERSED:
            normal = -normal
            tri = tri[:, ::-1]
        xyz *= scale
        if np.isnan(normal).any():
            normal = _fill_normals(xyz, tri, normal)
        faces.append(PartFace(number, names.get(key, ""), kind, colours.get(key), 0.0))
        verts.append(xyz)
        norms.append(normal[tri])
        tris.append(tri + offset)
        ids.append(np.full(len(tri), number, np.int64))
        offset += len(xyz)
    if not tris:
        raise InputError(f"{name or 'the shape'}: no face could be tessellated")
    xyz = np.vstack(verts)
    corners = np.vstack(norms)
    tri = np.vstack(tris)
    face_id = np.concatenate(ids)
    tri, corners = _agree_winding(xyz, tri, corners)
    areas = 0.5 * np.linalg.norm(_facet_normals(xyz, tri), axis=1)
    per_face = np.bincount(face_id, weights=areas, minlength=len(faces) + 1)
    faces = [replace(f, area=float(per_face[f.id])) for f in faces]
    xyz, tri, kept = _weld(xyz, tri)
    used, tri = np.unique(tri, return_inverse=True)
    tri = tri.reshape(-1, 3)
    surface = ExactNormalSurface(xyz[used], tri, corner_normals=corners[kept], name=name)
    return Part(surface, face_id[kept], tuple(faces), closed=not surface.boundary_loops, source=name,
                chordal_tolerance=chordal_tolerance)


def _refine(face, adaptor, props, xyz, tri, normal, max_edge):
    """Split the face's triangle edges longer than ``max_edge`` (the shape's unit); a new vertex
    gets the exact normal at its projection onto the face's surface."""
    from OCP.BRep import BRep_Tool
    from OCP.gp import gp_Pnt
    from OCP.ShapeAnalysis import ShapeAnalysis_Surface

    from ..surface.subdivide import split_long_edges

    fine_xyz, fine_tri = split_long_edges(xyz, tri, max_edge)
    n_old = len(xyz)
    if len(fine_xyz) == n_old:
        return xyz, tri, normal
    new = fine_xyz[n_old:]

    kind = adaptor.GetType().name
    if kind == "GeomAbs_Plane":                      # one normal (the natural one, before orientation)
        d = adaptor.Plane().Axis().Direction()
        return fine_xyz, fine_tri, np.vstack([normal, np.tile((d.X(), d.Y(), d.Z()), (len(new), 1))])
    if kind == "GeomAbs_Cylinder":                   # radial, outward of the natural parametrisation
        cylinder = adaptor.Cylinder()
        axis = cylinder.Axis()
        o, d = axis.Location(), axis.Direction()
        origin, direction = np.array([o.X(), o.Y(), o.Z()]), np.array([d.X(), d.Y(), d.Z()])
        radial = new - origin
        radial -= np.outer(radial @ direction, direction)
        radial /= np.linalg.norm(radial, axis=1, keepdims=True)
        sign = 1.0 if cylinder.Direct() else -1.0
        return fine_xyz, fine_tri, np.vstack([normal, sign * radial])
    analysis = ShapeAnalysis_Surface(BRep_Tool.Surface_s(face))
    added = np.full((len(new), 3), np.nan)
    for k, p in enumerate(new):
        uv = analysis.ValueOfUV(gp_Pnt(*p), 1e-7)
        props.SetParameters(uv.X(), uv.Y())
        if props.IsNormalDefined():
            d = props.Normal()
            added[k] = (d.X(), d.Y(), d.Z())
    return fine_xyz, fine_tri, np.vstack([normal, added])


def _facet_normals(xyz, tri):
    n = np.cross(xyz[tri[:, 1]] - xyz[tri[:, 0]], xyz[tri[:, 2]] - xyz[tri[:, 0]])
    return n


def _fill_normals(xyz, tri, normal):
    """Normals where the exact surface has none (a cone's apex, a sphere's pole, no UV): the
    area-weighted facet normals there."""
    missing = ~np.isfinite(normal).all(axis=1)
    if missing.any():
        acc = np.zeros_like(xyz)
        fn = _facet_normals(xyz, tri)
        for k in range(3):
            np.add.at(acc, tri[:, k], fn)
        normal = normal.copy()
        normal[missing] = acc[missing]
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    return normal / np.maximum(length, 1e-300)


def _agree_winding(xyz, tri, corners):
    """Flip the triangles whose winding disagrees with the exact normals ``(m, 3, 3)`` at their corners."""
    fn = _facet_normals(xyz, tri)
    agree = np.einsum("ij,ij->i", fn, corners.sum(axis=1))
    flip = agree < 0
    if flip.any():
        tri, corners = tri.copy(), corners.copy()
        tri[flip] = tri[flip][:, ::-1]
        corners[flip] = corners[flip][:, ::-1]
    return tri, corners


def _weld(xyz, tri):
    """Merge the copies of a shared edge's vertices.  Returns the vertices, the triangles left
    and which triangles were kept."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    pairs = cKDTree(xyz).query_pairs(WELD_TOLERANCE, output_type="ndarray")
    n = len(xyz)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n)) if len(pairs) else \
        coo_matrix((n, n))
    _, label = connected_components(graph, directed=False)
    first = np.full(label.max() + 1, -1)
    first[label[::-1]] = np.arange(n)[::-1]
    new_tri = label[tri]
    keep = (new_tri[:, 0] != new_tri[:, 1]) & (new_tri[:, 1] != new_tri[:, 2]) & (new_tri[:, 0] != new_tri[:, 2])
    if not keep.all():      # a sphere's pole or a cone's apex: triangles with two corners at one point
        log.debug("%d degenerate triangles (two corners at one point) left out", int((~keep).sum()))
    return xyz[first], new_tri[keep], keep

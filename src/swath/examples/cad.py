"""CAD example parts built with Open CASCADE and written as STEP (or IGES), so that tests,
benchmarks and tutorials need no downloaded file.

- :func:`tube_with_flange`: a 300 mm tube (Ø100 mm, 5 mm wall) with a Ø180 × 10 mm flange at one
  end; its faces are named (``tube_outer``, ``bore``, ``flange_top``, ...) and the flange coloured.
- :func:`capped_cylinder`: a closed cylinder (Ø80 × 200 mm), a handle's grip.
- :func:`rounded_box`: a 200 × 100 × 60 mm box with 10 mm rounded edges.
- :func:`plate_grid`: ``n × n`` small plates fused into one shell, for load-time benchmarks.

Every builder takes metres and returns an ``OCP`` shape in Open CASCADE's millimetres;
:func:`write_step` writes it with face names and colours.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import InputError


def _ocp():
    """Import OCP or refuse, naming the extra to install."""
    try:
        import OCP  # noqa: F401
    except ImportError as exc:
        raise InputError("the CAD examples are built with Open CASCADE: install the cad extra "
                         "(pip install 'swath[cad]')") from exc
    from OCP.Message import Message

    messenger = Message.DefaultMessenger_s()       # no translator statistics on the console
    printers = messenger.Printers()
    while printers.Size():
        messenger.RemovePrinter(printers.First())
        printers = messenger.Printers()


def _faces(shape) -> list:
    """The distinct faces of ``shape`` in Open CASCADE's order (as :func:`swath.io.step.load_step` numbers them)."""
    from OCP.collections import IndexedMap_TopoDS_Shape_TopTools_ShapeMapHasher
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp
    from OCP.TopoDS import TopoDS

    found = IndexedMap_TopoDS_Shape_TopTools_ShapeMapHasher()
    TopExp.MapShapes_s(shape, TopAbs_FACE, found)
    return [TopoDS.Face(found.FindKey(i)) for i in range(1, found.Extent() + 1)]


def _mm(x: float) -> float:
    return float(x) * 1e3


def tube_with_flange(*, length: float = 0.3, radius: float = 0.05, wall: float = 0.005,
                     flange_radius: float = 0.09, flange_thickness: float = 0.01):
    """A tube along +z from z = 0 (the flange side) to ``length`` (m), open bore, as an OCP solid."""
    _ocp()
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut, BRepAlgoAPI_Fuse
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeCylinder
    from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt

    if not 0 < wall < radius < flange_radius or not 0 < flange_thickness < length:
        raise InputError("expected 0 < wall < radius < flange_radius and 0 < flange_thickness < length")
    axis = gp_Ax2(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1))
    outer = BRepPrimAPI_MakeCylinder(axis, _mm(radius), _mm(length)).Shape()
    flange = BRepPrimAPI_MakeCylinder(axis, _mm(flange_radius), _mm(flange_thickness)).Shape()
    bore = BRepPrimAPI_MakeCylinder(axis, _mm(radius - wall), _mm(length)).Shape()
    return BRepAlgoAPI_Cut(BRepAlgoAPI_Fuse(outer, flange).Shape(), bore).Shape()


def capped_cylinder(*, radius: float = 0.04, length: float = 0.2):
    """A closed cylinder along +z from z = 0 to ``length`` (m) as an OCP solid."""
    _ocp()
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeCylinder
    from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt

    return BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1)), _mm(radius), _mm(length)).Shape()


def rounded_box(*, size=(0.2, 0.1, 0.06), fillet: float = 0.01):
    """A box ``size`` (m) with its corner at the origin and every edge rounded to ``fillet`` (m)."""
    _ocp()
    from OCP.BRepFilletAPI import BRepFilletAPI_MakeFillet
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    box = BRepPrimAPI_MakeBox(*(_mm(s) for s in size)).Shape()
    maker = BRepFilletAPI_MakeFillet(box)
    explorer = TopExp_Explorer(box, TopAbs_EDGE)
    while explorer.More():
        maker.Add(_mm(fillet), TopoDS.Edge(explorer.Current()))
        explorer.Next()
    return maker.Shape()


def plate_grid(n: int, *, cell: float = 0.01, thickness: float = 0.002):
    """``n × n`` boxes of ``cell`` (m) side in a grid, as one compound (about ``6 n²`` faces)."""
    _ocp()
    from OCP.BRep import BRep_Builder
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox
    from OCP.gp import gp_Pnt
    from OCP.TopoDS import TopoDS_Compound

    builder = BRep_Builder()
    compound = TopoDS_Compound()
    builder.MakeCompound(compound)
    for i in range(n):
        for j in range(n):
            corner = gp_Pnt(_mm(1.1 * i * cell), _mm(1.1 * j * cell), 0.0)
            builder.Add(compound, BRepPrimAPI_MakeBox(corner, _mm(cell), _mm(cell), _mm(thickness)).Shape())
    return compound


def tube_face_names(shape, *, length: float = 0.3, radius: float = 0.05, wall: float = 0.005,
                    flange_thickness: float = 0.01) -> list[str]:
    """Names of :func:`tube_with_flange`'s faces in the order Open CASCADE lists them:
    ``tube_outer``, ``bore``, ``flange_rim``, ``flange_top``, ``flange_bottom``, ``tube_end``."""
    from OCP.BRepAdaptor import BRepAdaptor_Surface

    names = []
    for face in _faces(shape):
        s = BRepAdaptor_Surface(face)
        if s.GetType().name == "GeomAbs_Cylinder":
            r = s.Cylinder().Radius() * 1e-3
            names.append("tube_outer" if abs(r - radius) < 1e-6 else "bore" if abs(r - radius + wall) < 1e-6
                         else "flange_rim")
        else:
            z = s.Plane().Location().Z() * 1e-3
            names.append("flange_bottom" if abs(z) < 1e-9 else "flange_top" if abs(z - flange_thickness) < 1e-9
                         else "tube_end")
    return names


def write_step(shape, path, *, names=None, colours=None) -> Path:
    """Write ``shape`` as a STEP file (AP214, millimetres) with optional face names and colours.

    Parameters
    ----------
    shape : OCP.TopoDS.TopoDS_Shape
    path : str or Path
    names : sequence of str, optional
        One name per face, in the order Open CASCADE lists the faces.
    colours : dict, optional
        ``{face_index: (r, g, b)}`` (0-based index in that order; components 0..1).
    """
    _ocp()
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.Quantity import Quantity_Color, Quantity_TOC_RGB
    from OCP.STEPCAFControl import STEPCAFControl_Writer
    from OCP.STEPConstruct import STEPConstruct
    from OCP.STEPControl import STEPControl_AsIs
    from OCP.TCollection import TCollection_ExtendedString, TCollection_HAsciiString
    from OCP.TDocStd import TDocStd_Document
    from OCP.XCAFDoc import XCAFDoc_ColorSurf, XCAFDoc_DocumentTool

    faces = _faces(shape)
    doc = TDocStd_Document(TCollection_ExtendedString("XmlXCAF"))
    shapes = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    colour_tool = XCAFDoc_DocumentTool.ColorTool_s(doc.Main())
    label = shapes.AddShape(shape, False)
    for index, rgb in (colours or {}).items():
        sub = shapes.AddSubShape(label, faces[index])
        colour_tool.SetColor(sub, Quantity_Color(*rgb, Quantity_TOC_RGB), XCAFDoc_ColorSurf)
    writer = STEPCAFControl_Writer()
    writer.SetColorMode(True)
    writer.SetNameMode(True)
    if not writer.Transfer(doc, STEPControl_AsIs):
        raise InputError("Open CASCADE could not translate the shape to STEP")
    if names is not None:
        finder = writer.Writer().WS().TransferWriter().FinderProcess()
        for face, name in zip(faces, names):
            entity = STEPConstruct.FindEntity_s(finder, face)
            if entity is not None:
                entity.SetName(TCollection_HAsciiString(name))
    path = Path(path)
    if writer.Write(str(path)) != IFSelect_RetDone:
        raise InputError(f"could not write {path}")
    return path


def write_iges(shape, path) -> Path:
    """Write ``shape`` as an IGES file (millimetres, B-rep faces)."""
    _ocp()
    from OCP.IGESControl import IGESControl_Writer

    path = Path(path)
    writer = IGESControl_Writer("MM", 1)
    writer.AddShape(shape)
    writer.ComputeModel()
    if not writer.Write(str(path)):
        raise InputError(f"could not write {path}")
    return path

"""The area to finish: faces selected by id, name or colour, keep-outs the pad must not touch, and
the edge margin.

- :func:`parse_selection` reads ``"3,5"``, ``"tube_outer,bore"``, ``"#0000ff"`` or
  ``"box:xmin,ymin,zmin,xmax,ymax,zmax"`` (part frame; lengths with optional unit suffix, bare
  numbers in metres; several terms separated by ``;``) into a per-triangle mask of a
  :class:`~swath.io.part.Part`.
- :func:`select` returns the part with its selection and keep-outs set.
- :func:`keep_clear` cuts the passes of a tool path where the pad (radius plus margin) would reach a
  keep-out triangle, or where its centre comes closer than the edge margin to the selected area's
  open edge: every planner's output goes through it, so every planner honours the keep-outs.
- :func:`area_metrics` judges a removal map on the part: coverage of the selected area, removal on
  the keep-outs.
"""

from __future__ import annotations

import logging
import re

import numpy as np

from ..core.toolpath import Pass, ToolPath
from ..errors import InputError
from ..io.part import Part
from ..surface.surface import farther_from_boundary
from ..units import parse_quantity
from .regions import is_region_term, region_mask

log = logging.getLogger(__name__)

#: Pieces of a pass shorter than this many points are dropped when a pass is cut.
MIN_PASS_POINTS = 3


def parse_selection(part: Part, text: str, *, what: str = "--faces", units: str = "m") -> np.ndarray:
    """The triangles of ``part`` a selection text names, as an ``(m,) bool`` mask.

    Parameters
    ----------
    part : Part
    text : str
        Terms separated by ``;``: a comma list of face ids (``3,5``), names (``tube_outer``) or
        colours (``#0000ff``); or ``box:xmin,ymin,zmin,xmax,ymax,zmax`` in the part frame (m, or
        with unit suffixes such as ``10mm``), which takes the triangles whose centroid is inside;
        or a region drawn on the part, ``polygon:...`` or ``mask:...``
        (:mod:`swath.segment.regions`).
    what : str
        The option's name, for messages.
    units : str
        The unit of a mask mesh's coordinates unless the term states one (the job's ``units``).

    Raises
    ------
    InputError
        For an unknown id, name or colour (listing the faces), a malformed box, or a selection
        with no triangle.
    """
    mask = np.zeros(len(part.face_ids), bool)
    for term in (t.strip() for t in str(text).split(";")):
        if not term:
            continue
        if is_region_term(term):
            mask |= region_mask(part, term, what=what, units=units)
            continue
        if term.lower().startswith("box:"):
            mask |= _box_mask(part, term[4:], what)
            continue
        for item in (i.strip() for i in term.split(",")):
            if item:
                ids = _face_ids(part, item, what)
                mask |= np.isin(part.face_ids, ids)
    if not mask.any():
        raise InputError(f"{what} {text!r} selects no triangle of the part")
    return mask


def _face_ids(part: Part, item: str, what: str) -> list[int]:
    if re.fullmatch(r"\d+", item):
        face_id = int(item)
        if not any(f.id == face_id for f in part.faces):
            raise InputError(f"{what}: the part has no face {face_id}; its faces are 1..{len(part.faces)}")
        return [face_id]
    if item.startswith("#"):
        colour = item.lower()
        ids = [f.id for f in part.faces if f.colour is not None and f.colour.lower() == colour]
        if not ids:
            known = sorted({f.colour for f in part.faces if f.colour})
            raise InputError(f"{what}: no face has colour {item}; the part's colours: "
                             f"{', '.join(known) if known else 'none (the file has no face colours)'}")
        return ids
    ids = [f.id for f in part.faces if f.name == item]
    if not ids:
        known = sorted({f.name for f in part.faces if f.name})
        raise InputError(f"{what}: no face is named {item!r}; the part's face names: "
                         f"{', '.join(known) if known else 'none (select by id 1..' + str(len(part.faces)) + ')'}")
    return ids


def _box_mask(part: Part, text: str, what: str) -> np.ndarray:
    values = [v.strip() for v in text.split(",")]
    if len(values) != 6:
        raise InputError(f"{what}: a box is box:xmin,ymin,zmin,xmax,ymax,zmax (six lengths), got {text!r}")
    box = np.array([parse_quantity(v, "length") for v in values]).reshape(2, 3)
    if not (box[1] > box[0]).all():
        raise InputError(f"{what}: a box's maxima must exceed its minima, got {text!r}")
    centroid = part.surface.vertices[part.surface.faces].mean(axis=1)
    return ((centroid >= box[0]) & (centroid <= box[1])).all(axis=1)


def select(part: Part, *, faces: str | None = None, keep_out: str | None = None, keep_out_margin: float = 0.0,
           edge_margin: float = 0.0, units: str = "m") -> Part:
    """``part`` with the area to finish (``faces``; default all) and the keep-outs set.

    Parameters
    ----------
    part : Part
    faces, keep_out : str, optional
        Selection texts (:func:`parse_selection`).
    keep_out_margin : float
        Clearance (m) the pad keeps from the keep-outs beyond its radius.
    edge_margin : float
        Distance (m) the pad's centre keeps in from the selected area's open edges.
    units : str
        The unit of mask meshes' coordinates unless a term states one (the job's ``units``).

    Raises
    ------
    InputError
        When nothing is left to finish once the keep-outs are taken out.
    """
    selected = np.ones(len(part.face_ids), bool) if faces is None else parse_selection(part, faces, what="--faces", units=units)
    kept_out = np.zeros(len(part.face_ids), bool) if keep_out is None else \
        parse_selection(part, keep_out, what="--keep-out", units=units)
    out = part.with_selection(selected=selected, keep_out=kept_out, keep_out_margin=keep_out_margin,
                              edge_margin=edge_margin)
    if not out.work_triangles.any():
        raise InputError("the keep-outs cover the whole selection; nothing is left to finish")
    return out


def work_surface(part: Part, pad_radius: float | None = None):
    """The sub-surface to plan on: the selected triangles minus the keep-outs (the whole surface
    when everything is selected).

    With ``pad_radius`` (m), the triangles with a corner closer than ``pad_radius +
    part.keep_out_margin`` to a keep-out are left out too (:func:`clear_triangles`): the planners
    then lay their edge passes along the clearance line instead of having passes cut there.
    """
    work = part.work_triangles
    if pad_radius is not None:
        work = work & clear_triangles(part, pad_radius)
        if not work.any():
            raise InputError(f"no triangle of the area to finish lies {(pad_radius + part.keep_out_margin) * 1e3:.3g} mm "
                             "(pad radius + keep-out margin) from the keep-outs; select a larger area")
    if work.all():
        return part.surface
    return part.surface.sub_surface(np.flatnonzero(work), name=part.surface.name)


def clear_triangles(part: Part, pad_radius: float) -> np.ndarray:
    """(m,) bool: triangles whose corners all lie at least ``pad_radius + part.keep_out_margin`` (m)
    from every keep-out triangle (all True without keep-outs)."""
    clear = np.ones(len(part.face_ids), bool)
    if not part.keep_out.any():
        return clear
    keep_out_surface = part.surface.sub_surface(np.flatnonzero(part.keep_out))
    _, distance, _ = keep_out_surface.closest_points(part.surface.vertices)
    near = distance < float(pad_radius) + part.keep_out_margin
    return ~near[part.surface.faces].any(axis=1)


def keep_clear(toolpath: ToolPath, part: Part, pad_radius: float, *, point_spacing: float | None = None) -> ToolPath:
    """Cut ``toolpath``'s passes where the pad would touch a keep-out or cross the edge margin.

    A pass point is dropped when it lies within ``pad_radius + part.keep_out_margin`` (in space) of
    a keep-out triangle, or within ``part.edge_margin`` of the open edge of the area to finish;
    a pass is split where points are dropped, and pieces shorter than :data:`MIN_PASS_POINTS`
    points are left out.

    Parameters
    ----------
    toolpath : ToolPath
        The planner's passes (before ordering).
    part : Part
        With its keep-outs and margins set (:func:`select`).
    pad_radius : float
        Pad radius, m.
    point_spacing : float, optional
        Step (m) at which the open edge is sampled for the edge margin (default: its vertices).

    Returns
    -------
    ToolPath
        The kept passes; ``metadata`` gains ``keep_out_clearance_m``, ``edge_margin_m`` and
        ``passes_cut`` (passes shortened or split).
    """
    clearance = float(pad_radius) + part.keep_out_margin
    keep_out_surface = None
    if part.keep_out.any():
        keep_out_surface = part.surface.sub_surface(np.flatnonzero(part.keep_out))
    work = work_surface(part) if part.edge_margin > 0 else None
    passes, cut = [], 0
    for p in toolpath.passes:
        keep = np.ones(len(p.points), bool)
        if keep_out_surface is not None:
            _, distance, _ = keep_out_surface.closest_points(p.points)
            keep &= distance >= clearance
        if work is not None:
            keep &= farther_from_boundary(p.points, work, part.edge_margin, step=point_spacing)
        if keep.all():
            passes.append(p)
            continue
        cut += 1
        for run in _runs(keep):
            if len(run) >= MIN_PASS_POINTS:
                passes.append(Pass(p.points[run], p.normals[run], level=p.level, region=p.region, kind=p.kind))
    if not passes:
        raise InputError(f"no pass is left once the pad keeps {clearance * 1e3:.3g} mm from the keep-outs and "
                         f"{part.edge_margin * 1e3:.3g} mm from the edges; select a larger area or lower the margins")
    if cut:
        log.info("%d passes cut to keep the pad off the keep-outs / inside the edge margin", cut)
    metadata = dict(toolpath.metadata, keep_out_clearance_m=clearance if keep_out_surface is not None else 0.0,
                    edge_margin_m=part.edge_margin, passes_cut=cut)
    return toolpath.replace(passes=tuple(passes), metadata=metadata)


def _runs(keep: np.ndarray) -> list[np.ndarray]:
    """Index arrays of the consecutive True runs of ``keep``."""
    idx = np.flatnonzero(keep)
    if len(idx) == 0:
        return []
    breaks = np.flatnonzero(np.diff(idx) > 1) + 1
    return np.split(idx, breaks)


def area_metrics(part: Part, points: np.ndarray, areas: np.ndarray, depth: np.ndarray) -> dict:
    """Judge removal samples on the part: coverage of the selected area, removal on the keep-outs.

    Parameters
    ----------
    part : Part
    points : (k, 3) float
        Removal sample positions on ``part.surface``, m.
    areas : (k,) float
        Area each sample stands for, m².
    depth : (k,) float
        Removal depth at each sample, m.

    Returns
    -------
    dict
        ``selected_area_m2``, ``selected_coverage_fraction`` (area fraction of the selection minus
        the keep-outs with depth > 0), ``keep_out_area_m2``, ``keep_out_touched_area_m2``,
        ``keep_out_max_removal_m``, and ``unselected_touched_area_m2`` (removal outside both).
    """
    points = np.asarray(points, float)
    areas = np.asarray(areas, float)
    depth = np.asarray(depth, float)
    _, _, tri = part.surface.closest_points(points)
    work = part.work_triangles[tri]
    out = part.keep_out[tri]
    touched = depth > 0
    sel_area = float(areas[work].sum())
    metrics = {
        "selected_area_m2": sel_area,
        "selected_coverage_fraction": float(areas[work & touched].sum() / sel_area) if sel_area > 0 else 0.0,
        "keep_out_area_m2": float(areas[out].sum()),
        "keep_out_touched_area_m2": float(areas[out & touched].sum()),
        "keep_out_max_removal_m": float(depth[out].max()) if out.any() else 0.0,
        "unselected_touched_area_m2": float(areas[~work & ~out & touched].sum()),
    }
    return metrics

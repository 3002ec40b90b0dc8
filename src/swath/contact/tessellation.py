"""How far a mesh's flat facets stand off a smooth surface, at the scale the pad feels.

FORMATS.md's contact model presses the pad on the mesh as given: the pressure at a point is
``k·h`` with ``h`` its height above the sunk pad face, and on a flat surface the pad sinks by the
depression ``e = F / (k π R²)``.  A coarse CAD tessellation (long flat facets meeting at kinks of
a few degrees) therefore carries its own pressure pattern: where the pad straddles a convex kink
the facets fall away from the ridge, and the force collects on it.  The removal shows streaks
along the facet edges that no spacing, lead or feed of the planner can take out, because the
planner's swath model reads the curvature at pad scale and sees a smooth part.

For every edge shared by two faces, :func:`facet_kinks` gives

* ``θ``, the angle between the two facet normals (rad);
* ``w``, the width of the facets across the edge: the mean of the two triangles' heights over it (m);
* ``δ = θ · min(w / 8, R / 2)``, the *kink height* (m): how far the flat facets stand off a smooth
  surface through the same vertices where the pad feels it.  Facets narrower than ``4R``: a pad
  spans the kink and its neighbours, and the facets lie off a smooth surface of the same turning
  (``θ / w`` per metre) by its chord error ``w θ / 8`` (a cylinder of radius ``r`` cut into facets of
  width ``w``: ``w² / (8 r)``).  Wider facets: the pad centred on the kink sees each facet fall
  ``R θ / 2`` below its face at its rim, while a smooth surface of that turning would hardly bend
  over the pad.

The pressure under the pad moves by about ``k δ`` where the flat face would press ``k e``, so
``δ / e`` is the pressure's relative swing across a kink.  :func:`tessellation_check` states the
edge-length-weighted 90th percentile of ``δ / e`` and, when it is above
:data:`KINK_DEPRESSION_RATIO`, the chord tolerance and angle a finer export needs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .tool import Tool

#: Kink height over depression (``δ / e``, 90th percentile by edge length) above which a mesh is
#: called too coarse for the pad.  A cylinder of radius 0.15 m tessellated to 24, 48 and 192 facets
#: round (default pad, 20 N) gives ``δ / e`` of 2.0, 0.50 and 0.031 (see the guide page
#: ``docs/guide/coarse-tessellation.md`` for the removal these give).
KINK_DEPRESSION_RATIO = 0.2
#: Percentile of ``δ / e`` over the edges (weighted by length) that the check reads.
KINK_PERCENTILE = 90.0


@dataclass(frozen=True)
class FacetKinks:
    """The kinks between neighbouring facets of a mesh, edge by edge (module notes).

    Attributes
    ----------
    edges : (m, 2) int
        Vertex indices of each edge shared by exactly two faces.
    length : (m,) float
        Edge length, m.
    angle : (m,) float
        Angle between the two facet normals, rad (unsigned: convex and concave kinks alike).
    width : (m,) float
        Mean height of the two triangles over the edge, m.
    height : (m,) float
        Kink height ``δ = angle · min(width / 8, R / 2)``, m.
    depression : float
        The pad's depression on flat at its force, m.
    """

    edges: np.ndarray
    length: np.ndarray
    angle: np.ndarray
    width: np.ndarray
    height: np.ndarray
    depression: float

    def percentile(self, values: np.ndarray, q: float) -> float:
        """The edge-length-weighted ``q``-th percentile (0..100) of ``values`` ``(m,)``; NaN without edges."""
        if len(values) == 0 or not self.length.sum() > 0:
            return float("nan")
        order = np.argsort(values)
        cum = np.cumsum(self.length[order])
        k = int(np.searchsorted(cum, q / 100.0 * cum[-1]))
        return float(values[order][min(k, len(order) - 1)])

    @property
    def ratio(self) -> np.ndarray:
        """(m,) kink height over the depression, ``δ / e``."""
        return self.height / self.depression


def shared_edges(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Edges shared by exactly two faces.

    Parameters
    ----------
    faces : (f, 3) int

    Returns
    -------
    edges : (m, 2) int
        Sorted vertex pairs.
    pair : (m, 2) int
        The two faces of each edge, the lower index first.
    """
    from ..surface.topology import mesh_edges

    edges, face_edges = mesh_edges(faces)           # the project's one edge table
    ids = face_edges.ravel()                         # corner edge k of face i at 3 i + k
    count = np.bincount(ids, minlength=len(edges))
    order = np.argsort(ids, kind="stable")           # each edge's faces together, in face order
    start = np.concatenate([[0], np.cumsum(count)[:-1]])
    # an edge of three or more faces (non-manifold) is left out: only the exact pairs
    two = np.flatnonzero(count == 2)
    return edges[two], np.stack([order[start[two]] // 3, order[start[two] + 1] // 3], axis=1)


def facet_kinks(surface, tool: Tool) -> FacetKinks:
    """The kink between the two facets of every shared edge, at the pad's scale (module notes).

    Parameters
    ----------
    surface : Surface
        The part as meshed (part frame).
    tool : Tool
        The pad: its radius ``R`` and its depression on flat at its force.

    Returns
    -------
    FacetKinks
    """
    v = surface.vertices
    edges, pair = shared_edges(surface.faces)
    fn, fa = surface.face_normals, surface.face_areas
    length = np.linalg.norm(v[edges[:, 1]] - v[edges[:, 0]], axis=1)
    cos = np.clip(np.einsum("ij,ij->i", fn[pair[:, 0]], fn[pair[:, 1]]), -1.0, 1.0)
    angle = np.arccos(cos)
    with np.errstate(divide="ignore", invalid="ignore"):
        width = np.where(length > 0, (fa[pair[:, 0]] + fa[pair[:, 1]]) / np.maximum(length, 1e-300), 0.0)
    R = tool.pad_radius
    height = angle * np.minimum(width / 8.0, R / 2.0)
    return FacetKinks(edges, length, angle, width, height, float(tool.flat_depression))


@dataclass(frozen=True)
class TessellationCheck:
    """What :func:`tessellation_check` found.

    Attributes
    ----------
    ratio : float
        Edge-length-weighted 90th percentile of the kink height over the depression, ``δ / e``.
    kink_height_m : float
        The same percentile of the kink height ``δ``, m.
    angle_deg : float
        The edge-length-weighted 90th percentile of the angle between neighbouring facets, degrees.
    depression_m : float
        The pad's depression on flat, m.
    chord_tolerance_m : float
        The chord tolerance a finer export needs: ``KINK_DEPRESSION_RATIO · e``, m.
    angle_tolerance_deg : float
        The angle between neighbouring facets a finer export needs so that a wide facet's kink
        stays under the same height: ``2 · KINK_DEPRESSION_RATIO · e / R``, degrees.
    coarse : bool
        Whether ``ratio`` is above :data:`KINK_DEPRESSION_RATIO`.
    """

    ratio: float
    kink_height_m: float
    angle_deg: float
    depression_m: float
    chord_tolerance_m: float
    angle_tolerance_deg: float
    coarse: bool

    def metrics(self) -> dict:
        """The figures for ``metrics.json`` (units in the key names)."""
        return {"tessellation_kink_over_depression_ratio": self.ratio,
                "tessellation_kink_height_m": self.kink_height_m,
                "tessellation_kink_angle_deg": self.angle_deg,
                "tessellation_coarse": self.coarse}

    def warnings(self, name: str = "the part") -> list[str]:
        """The warning to give when the mesh is coarse for the pad (``[W-MESH-COARSE]``), or none."""
        if not self.coarse:
            return []
        return [f"{name}: the mesh's facets kink by {self.angle_deg:.1f} deg (90th percentile), standing "
                f"{self.kink_height_m * 1e3:.2f} mm off a smooth surface at the pad's scale, "
                f"{self.ratio:.1f}x of the pad's {self.depression_m * 1e3:.2f} mm depression: the pressure collects "
                f"on the facet edges and the removal streaks along them, whatever the passes; export the CAD finer "
                f"(chord tolerance {self.chord_tolerance_m * 1e3:.2g} mm or less and angle "
                f"{self.angle_tolerance_deg:.2g} deg or less) or give the STEP file, which swath tessellates "
                f"itself (--chordal-tol) [W-MESH-COARSE]"]


def tessellation_check(surface, tool: Tool, *, ratio: float = KINK_DEPRESSION_RATIO,
                       percentile: float = KINK_PERCENTILE) -> TessellationCheck:
    """Whether the mesh's facets kink more than the pad's depression at the pad's scale (module notes).

    Parameters
    ----------
    surface : Surface
        The part as meshed.
    tool : Tool
    ratio : float
        Kink height over depression above which the mesh is coarse for this pad.
    percentile : float
        Percentile (0..100, weighted by edge length) of the kink height that is compared.

    Returns
    -------
    TessellationCheck
    """
    if not (math.isfinite(ratio) and ratio > 0):
        raise InputError(f"the kink-to-depression ratio must be positive, got {ratio!r}")
    if not (0.0 <= percentile <= 100.0):
        raise InputError(f"percentile must lie in 0..100, got {percentile!r}")
    kinks = facet_kinks(surface, tool)
    e = kinks.depression
    height = kinks.percentile(kinks.height, percentile)
    angle = kinks.percentile(kinks.angle, percentile)
    r = height / e if np.isfinite(height) else 0.0
    return TessellationCheck(
        ratio=float(r), kink_height_m=float(height) if np.isfinite(height) else 0.0,
        angle_deg=math.degrees(angle) if np.isfinite(angle) else 0.0, depression_m=e,
        chord_tolerance_m=ratio * e, angle_tolerance_deg=math.degrees(2.0 * ratio * e / tool.pad_radius),
        coarse=bool(r > ratio))


def warn_if_coarse(surface, tool: Tool, *, name: str | None = None) -> TessellationCheck:
    """:func:`tessellation_check` of ``surface``, logging its ``W-MESH-COARSE`` warning when the mesh is coarse."""
    import logging

    check = tessellation_check(surface, tool)
    for text in check.warnings(name or getattr(surface, "name", "") or "the part"):
        logging.getLogger(__name__).warning("%s", text)
    return check

"""The result of rigid registration (:class:`Registration`) and the rotation helpers it uses."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


# --------------------------------------------------------------------------------------------
# result record
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Registration:
    """The result of a rigid registration.

    Attributes
    ----------
    matrix : (4, 4) float
        Homogeneous transform from the source frame to the target frame (``cad2scan`` when the
        CAD surface is the source and the scan the target); translation in metres.
    rms : float
        Root-mean-square point-to-plane residual over the inliers, m.
    inlier_fraction : float
        Fraction of the (subsampled) source points within ``inlier_distance`` of the target.
    inlier_distance : float
        Distance (m) under which a source point counts as an inlier.
    iterations : int
        ICP steps taken by the fine stages (after the coarse search).
    converged : bool
        Whether the last step moved every source point by less than the tolerance.
    point_indices : (k,) int
        Indices into the source points of the points used (all of them unless subsampled).
    residuals : (k,) float
        Signed point-to-plane residual of each used point after registration, m (positive on the
        side the target normal points to); NaN where the target is farther than 10 % of the
        source size.
    inliers : (k,) bool
        Which used points are inliers (see ``inlier_distance`` of :func:`register_rigid`).
    dof : int
        Degrees of freedom solved for (6 general, 3 or 4 on a table).
    score : float
        How well the chosen pose fits, as an RMS distance (m), before the final polish: the
        ``trim`` fraction of closest source points' distances to the target, plus on a table the
        weighted in-plane distances of the perimeter points to the target's perimeter.  It
        ranked the refined candidate poses.
    runner_up_score : float or None
        The same for the best refined pose distinct from the chosen one; within a few percent of
        ``score`` means the part is (nearly) symmetric and the answer ambiguous.
    runner_up_angle, runner_up_shift : float or None
        Rotation (rad) and source-centroid distance (m) between the chosen pose and that one.
    source_centroid : (3,) float
        Weighted centroid of the used source points, source frame, m.
    sigma_rotation, sigma_translation : float
        One-sigma uncertainty of the rotation (rad) and of the translation at the source centroid
        (m), from the least-squares covariance; residuals are treated as independent, so a CAD
        that differs in shape from the scan is less certain than this says.
    weakest_motion : str
        The least-determined motion, in words (what a nearly symmetric part slides along).
    warnings : tuple of str
        What makes the answer poor (few inliers, a large rms) or ambiguous (a second pose that
        fits almost as well, a poorly determined pose); empty when nothing does.
    """

    matrix: np.ndarray
    rms: float
    inlier_fraction: float
    inlier_distance: float
    iterations: int
    converged: bool
    point_indices: np.ndarray = field(repr=False)
    residuals: np.ndarray = field(repr=False)
    inliers: np.ndarray = field(repr=False)
    dof: int = 6
    score: float = 0.0
    runner_up_score: float | None = None
    runner_up_angle: float | None = None
    runner_up_shift: float | None = None
    source_centroid: np.ndarray = field(default_factory=lambda: np.zeros(3), repr=False)
    sigma_rotation: float = 0.0
    sigma_translation: float = 0.0
    weakest_motion: str = ""
    warnings: tuple[str, ...] = ()

    @property
    def rotation(self) -> np.ndarray:
        """(3, 3) rotation part of :attr:`matrix`."""
        return self.matrix[:3, :3]

    @property
    def translation(self) -> np.ndarray:
        """(3,) translation part of :attr:`matrix`, m."""
        return self.matrix[:3, 3]

    @property
    def angle(self) -> float:
        """Total rotation angle of :attr:`matrix`, rad."""
        return rotation_angle(self.rotation)

    def transform(self, points) -> np.ndarray:
        """Source-frame points ``(n, 3)`` (m) expressed in the target frame ``(n, 3)``."""
        p = np.asarray(points, dtype=float)
        return p @ self.rotation.T + self.translation

    def to_dict(self) -> dict:
        """A JSON-ready summary (no per-point arrays): the transform and its quality."""
        r = np.abs(self.residuals[self.inliers]) if self.inliers.any() else np.zeros(1)
        return {
            "matrix": np.round(self.matrix, 12).tolist(),
            "frames": {"from": "source (cad)", "to": "target (scan)", "name": "cad2scan"},
            "rotation_deg": float(np.degrees(self.angle)),
            "translation_m": self.translation.tolist(),
            "rms_m": float(self.rms),
            "residual_p95_m": float(np.percentile(r, 95)),
            "residual_max_m": float(r.max()),
            "inlier_fraction": float(self.inlier_fraction),
            "inlier_distance_m": float(self.inlier_distance),
            "points_used": int(len(self.point_indices)),
            "iterations": int(self.iterations),
            "converged": bool(self.converged),
            "dof": int(self.dof),
            "centroid_shift_m": (self.transform(self.source_centroid[None])[0] - self.source_centroid).tolist(),
            "sigma_rotation_deg": float(np.degrees(self.sigma_rotation)),
            "sigma_translation_m": float(self.sigma_translation),
            "weakest_motion": self.weakest_motion,
            "score_m": float(self.score),
            "runner_up_score_m": None if self.runner_up_score is None else float(self.runner_up_score),
            "runner_up_rotation_deg": (None if self.runner_up_angle is None
                                       else float(np.degrees(self.runner_up_angle))),
            "runner_up_shift_m": None if self.runner_up_shift is None else float(self.runner_up_shift),
            "warnings": list(self.warnings),
        }


def rotation_angle(rotation) -> float:
    """Angle (rad) of a rotation matrix ``(3, 3)``."""
    c = (np.trace(np.asarray(rotation)) - 1.0) / 2.0
    return float(np.arccos(np.clip(c, -1.0, 1.0)))


def rigid_matrix(rotation, translation) -> np.ndarray:
    """A homogeneous transform ``(4, 4)`` from a rotation ``(3, 3)`` and a translation ``(3,)`` (m)."""
    m = np.eye(4)
    m[:3, :3] = rotation
    m[:3, 3] = translation
    return m

"""The ``segment`` stage: regions that parallel sweep lines cross without breaks (Wang §1)."""

from .boundary import alpha_boundary, surface_boundary
from .sweep import Region, segment

__all__ = ["Region", "alpha_boundary", "segment", "surface_boundary"]

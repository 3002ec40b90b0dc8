"""The ``scan`` stage: measured scans made usable (Jaeger ch. 3).

:func:`fit_patch` fits a least-squares B-spline patch (:class:`~swath.surface.BSplinePatch`) to a
noisy scan, skinning along the scan's rows when it has them, and returns a :class:`FitReport`;
:func:`register_rigid` (6 DOF) and :func:`register_on_table` (a part resting on a table) place a
nominal CAD surface on a scan and return a :class:`Registration` (``cad2scan``);
:func:`resample_rows` respaces a scan's rows by Jaeger's curvature distribution before a fit.
"""

from .fit import FitReport, fit_patch
from .register import Registration, register_on_table, register_rigid
from .resample import resample_rows, row_distribution

__all__ = ["FitReport", "fit_patch", "Registration", "register_on_table", "register_rigid", "resample_rows",
           "row_distribution"]

"""The process as a shop knows it: the pad's wear along a job, media changes and the feed that
compensates the wear (:mod:`swath.process.media`).

The tool record itself is :class:`swath.contact.Tool`; the design of experiments and the
Preston/wear calibration are :mod:`swath.simulate.preston_doe` and :mod:`swath.simulate.calibrate`.
"""

from .media import MediaSchedule, compensate_wear, media_schedule, program_lines, trajectory_with_media

__all__ = ["MediaSchedule", "compensate_wear", "media_schedule", "program_lines", "trajectory_with_media"]

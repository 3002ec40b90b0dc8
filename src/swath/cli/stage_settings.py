"""Per-stage settings records: the share of :class:`~swath.cli.jobsettings.JobSettings` each
pipeline stage reads.

A stage takes its own small, typed, frozen record instead of the whole job::

    process = ProcessSettings.of(settings)      # settings: JobSettings (or already a ProcessSettings)
    process.media_change, process.wear_compensation

Every JobSettings field belongs to exactly one stage (its ``stage`` in :func:`swath.cli.schema.setting`)
and is a field of that stage's record here, with the same type: ``tests/cli/test_settings_schema.py``
checks both ways, so a new setting fails that test until its name and type are listed in its
stage's record.  Values are JobSettings' (SI units, None for automatic or off).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, ClassVar, Self


@dataclass(frozen=True)
class StageSettings:
    """Base of the stage records: :meth:`of` copies the stage's fields out of a JobSettings."""

    STAGE: ClassVar[str] = ""

    @classmethod
    def of(cls, settings: Any) -> Self:
        """This stage's record of ``settings`` (a JobSettings; a record of this stage is returned as is)."""
        if isinstance(settings, cls):
            return settings
        return cls(**{f.name: getattr(settings, f.name) for f in dataclasses.fields(cls)})


@dataclass(frozen=True)
class JobOutputSettings(StageSettings):
    """The job as a whole: where it writes, how much memory it may use, what it must reach."""

    STAGE: ClassVar[str] = "job"
    out: str
    overwrite: bool
    memory_budget: float | None
    target_cov: float | None
    allow_unusual_process: bool


@dataclass(frozen=True)
class PartSettings(StageSettings):
    """Reading the part (io) and selecting the area to finish (segment.select)."""

    STAGE: ClassVar[str] = "part"
    part: str
    units: str
    side: str | None
    all_pieces: bool
    force_units: bool
    fit: bool
    parameterization: str
    surface_spacing: float | None
    faces: str | None
    keep_out: str | None
    keep_out_margin: float
    edge_margin: float
    chordal_tol: float


@dataclass(frozen=True)
class ToolSettings(StageSettings):
    """The pad, its force and its calibration (contact)."""

    STAGE: ClassVar[str] = "tool"
    pad_radius: float
    force: float
    depression: float | None
    stiffness: float | None
    motion: str | None
    calibration: str | None
    grit: str | None
    pad_thickness: float | None
    spindle_speed: float | None
    orbit_radius: float | None
    pad_damping: float
    depression_force: float | None


@dataclass(frozen=True)
class PlanSettings(StageSettings):
    """Path planning: the planner and where its passes go."""

    STAGE: ClassVar[str] = "plan"
    planner: str
    spacing: float | None
    direction: float | None
    point_spacing: float
    overlap: float | None
    segment: str | None
    planner_options: dict


@dataclass(frozen=True)
class OrderSettings(StageSettings):
    """The order the passes are visited in and how they are joined."""

    STAGE: ClassVar[str] = "order"
    order: str | None
    join_gap: float | None
    order_groups: str
    order_objective: str


@dataclass(frozen=True)
class FeedSettings(StageSettings):
    """Feed and spacing optimisation for even removal."""

    STAGE: ClassVar[str] = "feed"
    optimise_feed: bool
    target_depth: float | None
    target_map: str | None
    depth_tolerance: float | None
    optimise_spacing: str | None
    length_budget: float
    feed_simulate_check: bool
    target_floor: str
    constant_feed: bool
    cycle_time_factor: float


@dataclass(frozen=True)
class TrajectorySettings(StageSettings):
    """Timing the trajectory: the feed, the robot-realistic limits, the links and the lead angle."""

    STAGE: ClassVar[str] = "trajectory"
    feed: float
    clearance: float
    max_centripetal: float | None
    max_angular: float | None
    max_accel: float | None
    lead_angle: float | str | None

    def constraints(self) -> list:
        """The trajectory constraints: the feed and whichever limits are on (by default all three of
        :data:`swath.cli.jobsettings.DEFAULT_LIMITS`)."""
        from ..trajectory import AngularSpeedLimit, CentripetalLimit, FeedLimit, TangentialAccelLimit

        out: list = [FeedLimit(self.feed)]
        if self.max_centripetal is not None:
            out.append(CentripetalLimit(self.max_centripetal))
        if self.max_angular is not None:
            out.append(AngularSpeedLimit(self.max_angular))
        if self.max_accel is not None:
            out.append(TangentialAccelLimit(self.max_accel))
        return out

    def links(self):
        """How the tool moves between passes."""
        from ..trajectory import LinkSettings

        return LinkSettings(clearance=self.clearance)


@dataclass(frozen=True)
class SimulateSettings(StageSettings):
    """Removal simulation and the force-controlled run."""

    STAGE: ClassVar[str] = "simulate"
    removal_sampling: str
    force_control: bool
    part_offset: tuple | None
    tool_mass: float
    tool_tilt: float
    gravity_compensation: bool
    sample_spacing: float | None


@dataclass(frozen=True)
class ProcessSettings(StageSettings):
    """Pad wear along the trajectory and media changes (swath.process)."""

    STAGE: ClassVar[str] = "process"
    wear_rate: float | None
    media_change: float | None
    media_change_loss: float | None
    wear_compensation: bool


@dataclass(frozen=True)
class RobotSettings(StageSettings):
    """The robot, its cell, placement and the programs written."""

    STAGE: ClassVar[str] = "robot"
    robot: str | None
    base: str | None
    tcp: str | None
    programs: tuple
    place: bool
    table_z: float
    cell: str | None
    allow_collisions: bool
    tip: str | None
    robot_keep_out: float | None
    force_program: str
    robot_strict: bool


#: Stage name -> its record, in pipeline order (the stages of :data:`swath.cli.schema.STAGES`).
STAGE_RECORDS: dict[str, type[StageSettings]] = {
    cls.STAGE: cls for cls in (JobOutputSettings, PartSettings, ToolSettings, PlanSettings, OrderSettings,
                               FeedSettings, TrajectorySettings, SimulateSettings, ProcessSettings, RobotSettings)
}


def stage_records(settings: Any) -> dict[str, StageSettings]:
    """Every stage's record of ``settings`` (a JobSettings), by stage name."""
    return {name: cls.of(settings) for name, cls in STAGE_RECORDS.items()}

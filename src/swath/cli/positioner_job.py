"""`swath plan` with a rotary positioner in the cell file: the wrap planner about its axis, the arm and
the axis in one program (:mod:`swath.robot.positioner`).

* ``--side all`` with a ``[positioner]`` in the ``--cell`` file plans the closed part all round in
  one program with the wrap planner (instead of setups on a table); ``--planner wrap`` does the same
  on the faces selected.
* The wrap planner turns about the positioner's axis (in the part frame, from ``part2faceplate``)
  and keeps the pad clear of the whole part, not only of the faces selected.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import PurePath

from ..errors import InputError
from .settings import JobSettings


def job_positioner(settings: JobSettings):
    """The cell file's :class:`~swath.cell.Positioner`, or None (no ``--cell``, or none in it).

    Raises
    ------
    InputError
        ``--base`` or ``--place`` with a positioner (the positioner places the part), or a program
        format that cannot carry the axis (URScript).
    """
    if not settings.cell:
        return None
    from ..cell import read_cell_file

    positioner = read_cell_file(settings.cell).positioner
    if positioner is not None and settings.base:
        raise InputError("--base places a fixed part, but the cell file puts the part on a positioner: its "
                         "[positioner] axis and part2faceplate place the part; drop --base")
    if positioner is not None and settings.place:
        raise InputError("--place searches where a fixed part should stand; with a positioner the part's place is "
                         "the positioner's axis and part2faceplate in the cell file: drop --place")
    if positioner is not None:
        from ..robot.external_axis import check_axis_formats

        check_axis_formats(settings.programs or ())
    return positioner


def positioner_axis(settings: JobSettings):
    """``(point, direction)`` of the positioner's axis in the part frame (m), or None without one."""
    positioner = job_positioner(settings)
    return None if positioner is None else positioner.axis_in_part()


def all_round_settings(settings: JobSettings) -> JobSettings:
    """The settings of ``--side all`` on a positioner: the wrap planner on every face of the closed part
    (or the ``--faces`` given), in one program."""
    if settings.planner not in ("raster", "wrap"):
        raise InputError(f"--side all with a positioner plans with the wrap planner (passes that go round the axis); "
                         f"drop --planner {settings.planner} or give --planner wrap")
    if PurePath(settings.part).suffix.lower() not in (".step", ".stp", ".iges", ".igs"):
        raise InputError("--side all with a positioner reads STEP or IGES parts (their faces say what is outside); "
                         "for a mesh, plan it with --planner wrap and --side pointing away from the axis, or convert "
                         "it to STEP")
    return replace(settings, planner="wrap")


def positioner_robot_stage(trajectory, surface, settings: JobSettings, options: dict, *, progress=None):
    """The robot stage of a job on a positioner: :func:`swath.robot.positioner.run_positioner_stage`,
    then the collision check with the part at its turned pose (no program on a collision unless
    ``--allow-collisions``).  Returns ``(trajectory in the part frame, RobotResult, metrics)``."""
    from ..robot.collision import CollisionError
    from ..robot.positioner import check_positioner_collisions, run_positioner_stage

    result = run_positioner_stage(trajectory, **options, out_dir=None, force=settings.force, warn=False,
                                  progress=None if progress is None else (lambda m, d, n: progress(m, d, n)))
    metrics = {k if k.startswith(("robot", "positioner")) else f"robot_{k}": v for k, v in result.metrics.items()}
    base_run, _ = result.program_view
    report = check_positioner_collisions(base_run, result.solution, result.model, result.cell,
                                         part_vertices=surface.vertices, part_faces=surface.faces)
    metrics.update(report.metrics())
    metrics["robot_table"] = result.cell.table.as_record() if result.cell.table is not None else None
    warnings = list(result.warnings) + list(result.cell.notes)
    if report.events:
        if not settings.allow_collisions:
            raise CollisionError(f"collision check: {report.message()}; no program written. Move the positioner or "
                                 "the part on it (the cell file's [positioner]), change the tool or the path, or pass "
                                 "--allow-collisions to write the programs anyway")
        warnings.append(f"cell: {report.message()}; the programs are written anyway (--allow-collisions) "
                        "[W-CELL-COLLISION]")
    return result.trajectory, replace(result, warnings=warnings), metrics

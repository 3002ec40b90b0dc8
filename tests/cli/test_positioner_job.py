"""`swath plan` with a rotary positioner in the cell file: the tube all round in one program."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from swath.errors import InputError

pytest.importorskip("OCP")

from swath.examples import cad  # noqa: E402

CELL = """robot = "irb4600"

[tool]
tcp2flange = "0,0,175mm,0,0,0"
[[tool.body]]
name = "spindle"
shape = "cylinder"
radius = "35mm"
length = "120mm"
pose = "0,0,60mm,0,0,0"

[positioner]
axis_point = ["1200mm", "-100mm", "700mm"]
axis_direction = [0, 1, 0]
max_speed = "180deg/s"
max_accel = "720deg/s2"
"""


@pytest.fixture(scope="module")
def tube_job(tmp_path_factory):
    d = tmp_path_factory.mktemp("positioner")
    shape = cad.tube_with_flange(length=0.15, radius=0.025, wall=0.004, flange_radius=0.045, flange_thickness=0.008)
    step = cad.write_step(shape, d / "tube.step", names=cad.tube_face_names(
        shape, length=0.15, radius=0.025, wall=0.004, flange_thickness=0.008))
    cell = d / "cell.toml"
    cell.write_text(CELL, encoding="utf-8")
    return step, cell, d


def _run(argv):
    from swath.cli.main import main

    return main(argv)


def test_side_all_on_a_positioner_is_one_program_all_round(tube_job):
    step, cell, d = tube_job
    out = d / "out"
    code = _run(["plan", str(step), "--side", "all", "--faces", "tube_outer", "--cell", str(cell),
                 "--program", "rapid,csv", "--chordal-tol", "0.2mm", "--out", str(out)])
    assert code == 0
    m = json.loads((out / "metrics.json").read_text())["metrics"]
    assert m["coverage_fraction"] >= 0.99                      # the selected outer cylinder, on its tessellation
    assert m["robot_branch_changes_in_contact"] == 0 and m["collision_count"] == 0
    assert m["robot_max_fk_position_error_m"] < 1e-5
    assert m["positioner_max_speed_ratio"] <= 1.0
    with open(out / "trajectory.csv", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert "positioner" in rows[0]
    on = [r for r in rows if r["contact"] == "1"]
    assert {r["pass"] for r in on} == {"0"}                   # one continuous pass
    r = np.array([math.hypot(float(x["x"]), float(x["y"])) for x in on])
    assert np.abs(r - 0.025).max() < 2e-4                     # the part frame, on the tube's skin
    z = np.array([float(x["z"]) for x in on])
    assert z.min() >= 0.008 + 0.0381                          # one pad radius clear of the flange (not selected)
    theta = np.array([float(x["positioner"]) for x in rows])
    assert np.ptp(theta) > 2 * math.pi                        # the part turned round more than once
    mods = list((out / "robot").glob("*.mod"))
    assert len(mods) == 1 and "eax_a" in mods[0].read_text()


@pytest.mark.parametrize("extra, words", [
    (["--base", "1,0,0,0,0,0"], "drop --base"),
    (["--place"], "drop --place"),
    (["--program", "urscript", "--robot", "ur10e"], "URScript has no standard external axis"),
    (["--planner", "uniform"], "wrap planner"),
])
def test_positioner_jobs_refuse_what_cannot_work(tube_job, extra, words):
    from swath.cli.job import run_job
    from swath.cli.settings import settings_from_mapping

    step, cell, d = tube_job
    argv = {"part": str(step), "out": str(d / "refused"), "side": "all", "faces": "tube_outer", "cell": str(cell)}
    values = dict(argv)
    i = 0
    while i < len(extra):
        key = extra[i].lstrip("-").replace("-", "_")
        if i + 1 < len(extra) and not extra[i + 1].startswith("--"):
            values[key] = extra[i + 1]
            i += 2
        else:
            values[key] = True
            i += 1
    if "program" in values:
        values["programs"] = values.pop("program")
    with pytest.raises(InputError, match=words):
        run_job(settings_from_mapping(values))

"""The feed figures drawn by a forked child beside the report's own keep their place among the
job's figures, and a figure drawn beside is the file drawn here."""

from pathlib import Path

from swath.cli.jobwrap import FEED_PLOTS as _FEED_PLOTS
from swath.cli.jobwrap import in_place as _in_place
from swath.core.beside import Beside


def test_the_figures_drawn_beside_take_the_place_kept_for_them():
    figures = {"joints": Path("robot/joints.png"), _FEED_PLOTS: None, "force": Path("force.png")}
    drawn = {"feed_along_passes": Path("a.png"), "depth_vs_target": Path("b.png")}
    out = _in_place(figures, lambda: drawn)
    assert list(out) == ["joints", "feed_along_passes", "depth_vs_target", "force"]
    assert out["depth_vs_target"] == Path("b.png") and out["joints"] == Path("robot/joints.png")


def _write(path: Path, text: str) -> dict:
    path.write_text(text)
    return {"note": path}


def test_a_file_written_beside_is_there_when_its_result_is_read(tmp_path):
    job = Beside(_write, tmp_path / "note.txt", "drawn beside")
    assert _in_place({_FEED_PLOTS: None}, job.result) == {"note": tmp_path / "note.txt"}
    assert (tmp_path / "note.txt").read_text() == "drawn beside"

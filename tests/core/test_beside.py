"""swath.core.beside: a function computed in a forked child gives the answer computed here."""

import os

import numpy as np
import pytest

from swath.core import beside
from swath.core.beside import Beside
from swath.surface import Surface

PARENT = os.getpid()


def _child_pid_and_sum(values):
    return os.getpid(), float(np.sum(values))


def _raises(message):
    raise ValueError(message)


def _dies_in_a_child(value):
    if os.getpid() != PARENT:
        os._exit(3)             # the child ends without answering
    return value * 2


@pytest.fixture
def two_cpus(monkeypatch):
    monkeypatch.setattr(beside, "usable_cpus", lambda: 2)
    if not beside.can_fork():
        pytest.skip("forking is only used on Linux")


def test_the_answer_comes_from_a_child_and_equals_the_one_computed_here(two_cpus):
    values = np.linspace(0.0, 1.0, 1001)
    work = Beside(_child_pid_and_sum, values)
    pid, total = work.result()
    assert work.result() == (pid, total)           # asked again: the same answer, not a second run
    assert pid != PARENT
    assert total == _child_pid_and_sum(values)[1] == pytest.approx(500.5)


def _large_answer(n):
    rng = np.random.default_rng(7)
    return {"widths": rng.random((n, 3)), "index": np.arange(n, dtype=np.int64), "strided": np.arange(10.0)[::3],
            "loops": [np.arange(5), np.arange(3)], "name": "widths"}


def test_a_large_answer_travels_through_a_mapped_file_that_is_then_removed(two_cpus, monkeypatch, tmp_path):
    monkeypatch.setattr(beside, "_shared_dir", lambda: str(tmp_path))
    kinds, received = [], beside._received
    monkeypatch.setattr(beside, "_received", lambda message: kinds.append(message[0]) or received(message))
    expected = _large_answer(100_000)                  # 3.2 MB of arrays: over FILE_BYTES
    got = Beside(_large_answer, 100_000).result()
    assert kinds == ["file"]
    assert got.keys() == expected.keys() and got["name"] == "widths"
    for key in ("widths", "index", "strided"):
        assert got[key].dtype == expected[key].dtype and np.array_equal(got[key], expected[key])
    assert all(np.array_equal(a, b) for a, b in zip(got["loops"], expected["loops"]))
    assert got["widths"].ctypes.data % 64 == 0            # aligned in the file
    got["widths"][0, 0] = -1.0                            # writable, copy-on-write
    assert list(tmp_path.iterdir()) == []                 # the hand-over file is gone
    kinds.clear()
    assert Beside(_large_answer, 10).result()["index"].tolist() == list(range(10))
    assert kinds == ["ok"]                                # a small answer comes through the pipe


def test_a_large_answer_comes_through_the_pipe_when_no_file_can_be_written(two_cpus, monkeypatch, tmp_path):
    # e.g. a container's /dev/shm too small for the arrays: the write fails, the pipe carries them
    monkeypatch.setattr(beside, "_shared_dir", lambda: str(tmp_path / "missing"))
    kinds, received = [], beside._received
    monkeypatch.setattr(beside, "_received", lambda message: kinds.append(message[0]) or received(message))
    got = Beside(_large_answer, 100_000).result()
    assert kinds == ["ok"]
    np.testing.assert_array_equal(got["widths"], _large_answer(100_000)["widths"])
    # the folder is there but fills up while writing: the partial file is removed, the pipe carries them
    monkeypatch.setattr(beside, "_shared_dir", lambda: str(tmp_path))
    real_fdopen = os.fdopen

    class _Full:
        def __init__(self, fd, mode):
            self._f = real_fdopen(fd, mode)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self._f.close()

        def tell(self):
            return self._f.tell()

        def write(self, data):
            if len(data) > 1000:
                raise OSError(28, "No space left on device")
            return self._f.write(data)

    monkeypatch.setattr(beside.os, "fdopen", _Full)
    kinds.clear()
    got = Beside(_large_answer, 100_000).result()
    assert kinds == ["ok"] and list(tmp_path.iterdir()) == []
    np.testing.assert_array_equal(got["index"], np.arange(100_000))


def test_not_allowed_or_one_cpu_computes_here(monkeypatch):
    pid, _ = Beside(_child_pid_and_sum, np.ones(3), allowed=False).result()
    assert pid == PARENT
    monkeypatch.setattr(beside, "usable_cpus", lambda: 1)
    pid, total = Beside(_child_pid_and_sum, np.ones(3)).result()
    assert (pid, total) == (PARENT, 3.0)


def test_an_exception_in_the_child_is_raised_here(two_cpus):
    work = Beside(_raises, "the width model failed")
    with pytest.raises(ValueError, match="the width model failed"):
        work.result()


def test_a_child_that_dies_without_answering_is_replaced_by_computing_here(two_cpus, caplog):
    assert Beside(_dies_in_a_child, 21).result() == 42
    assert "exit code 3" in caplog.text


def test_surface_adopts_cached_values_and_refuses_other_names():
    plate = Surface(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]]), np.array([[0, 1, 2]]))
    given = np.tile([0.0, 0.0, 1.0], (3, 1))
    plate.adopt(normals=given)
    assert plate.normals is given and not plate.normals.flags.writeable
    plate.adopt(normals=np.zeros((3, 3)))          # a value already there is kept
    assert plate.normals is given
    with pytest.raises(TypeError, match="not a derived"):
        plate.adopt(vertices=np.zeros((3, 3)))

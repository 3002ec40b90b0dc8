import os

from swath.core.cpus import usable_cpus


def test_omp_num_threads_sets_the_share(monkeypatch):
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    assert usable_cpus() == 1
    monkeypatch.setenv("OMP_NUM_THREADS", "3")
    assert usable_cpus() == 3


def test_without_a_share_the_allowed_cpus(monkeypatch):
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    assert usable_cpus() == len(os.sched_getaffinity(0))
    monkeypatch.setenv("OMP_NUM_THREADS", "zero")        # not a count: ignored
    assert usable_cpus() == len(os.sched_getaffinity(0))

"""The first job after installing or upgrading swath says that numba compiles its kernels as they are
first used (the stages' estimates are for compiled kernels); later jobs say nothing."""

from types import SimpleNamespace

import swath.contact.kernels  # noqa: F401  (registered before any test swaps the registry)
from swath.cli import jobwrap
from swath.surface import cells


def _kernel(module: str, held):
    """A stand-in for a numba dispatcher whose disk cache index holds ``held`` (an exception: unreadable)."""
    def load_index():
        if isinstance(held, Exception):
            raise held
        return held
    return SimpleNamespace(__name__="k", py_func=SimpleNamespace(__module__=module),
                           _cache=SimpleNamespace(_cache_file=SimpleNamespace(_load_index=load_index)))


def _heard(monkeypatch, kernels) -> list:
    monkeypatch.setattr(cells, "_KERNELS", kernels)
    heard: list = []
    said = jobwrap.first_run_notice(lambda *a: heard.append(a))
    assert said == bool(heard)
    return heard


def test_a_fresh_install_is_told_that_the_kernels_compile_as_they_are_first_used(monkeypatch):
    sim = jobwrap.SIMULATION_KERNELS
    heard = _heard(monkeypatch, [_kernel(sim, {}), _kernel(sim, {}), _kernel("swath.plan.gaps", {("sig",): 1})])
    assert heard == [(f"{jobwrap.FIRST_RUN_STAGE} (this run only: up to about {jobwrap.FIRST_RUN_EXTRA_S} s more)",
                      0, 1)]
    # one simulation kernel in the cache: a job has run since; the others compile quietly
    assert _heard(monkeypatch, [_kernel(sim, {}), _kernel(sim, {("sig",): 1})]) == []
    # numba's cache unreadable (its private layout changed): nothing is claimed
    assert _heard(monkeypatch, [_kernel(sim, {}), _kernel(sim, RuntimeError("layout"))]) == []
    assert cells.kernels_to_compile(sim) == []
    # only the simulation's kernels count (the planners' compile on a first uniform job)
    assert _heard(monkeypatch, [_kernel("swath.plan.gaps", {})]) == []


def test_the_real_kernels_are_registered_with_their_modules():
    import importlib

    importlib.import_module(jobwrap.SIMULATION_KERNELS)
    ours = [k for k in cells._KERNELS if k.py_func.__module__ == jobwrap.SIMULATION_KERNELS]
    assert len(ours) >= 5
    assert set(cells.kernels_to_compile(jobwrap.SIMULATION_KERNELS)) <= {k.__name__ for k in ours}


def test_without_a_writable_cache_every_run_compiles_and_the_line_says_how_to_fix_it(monkeypatch):
    sim = jobwrap.SIMULATION_KERNELS
    in_memory = SimpleNamespace(__name__="k", py_func=SimpleNamespace(__module__=sim), _cache=SimpleNamespace())
    heard = _heard(monkeypatch, [in_memory, in_memory])
    assert len(heard) == 1 and "every run" in heard[0][0] and "NUMBA_CACHE_DIR" in heard[0][0]

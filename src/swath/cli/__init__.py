"""The ``swath`` command line and the jobs it runs (the top layer: it drives every stage).

* :mod:`.main` — argument parsing, one subcommand per job kind; ``main(argv) -> exit status``.
* :mod:`.job` — a whole planning job from one settings record (``swath plan``, ``swath run``).
* :mod:`.fitjob` — the fit and register jobs.
"""

from .main import build_parser, main

__all__ = ["build_parser", "main"]

"""Core records every stage reads: the :class:`ToolPath` (passes and links).

Errors (:mod:`swath.errors`) and units (:mod:`swath.units`) sit at this layer too.
"""

from .toolpath import PASS_KINDS, Link, Pass, ToolPath

__all__ = ["Link", "PASS_KINDS", "Pass", "ToolPath"]

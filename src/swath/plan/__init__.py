"""The ``plan`` stage: planners that cover a surface with passes, each returning a ToolPath."""

from .toolpath import Pass, ToolPath

__all__ = ["Pass", "ToolPath"]

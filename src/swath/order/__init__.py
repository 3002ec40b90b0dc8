"""The ``order`` stage: the visiting order and path type of pass groups (Wang §4)."""

from .tour import order_toolpath

__all__ = ["order_toolpath"]

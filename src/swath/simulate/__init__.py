"""The ``simulate`` stage: predicted material removal and the plan's metrics."""

from .removal import RemovalMap, coverage_lower_bound, plan_metrics, simulate_removal

__all__ = ["RemovalMap", "coverage_lower_bound", "plan_metrics", "simulate_removal"]

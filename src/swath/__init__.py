"""swath — plan robotic surface finishing (sanding, polishing, grinding) on free-form parts.

Pipeline (one stage, one subpackage; imports point down only)::

    io -> surface -> segment -> plan -> order -> trajectory -> robot -> simulate -> report   (cli drives them)

The stage functions are re-exported here (imported when first used, so ``import swath`` stays light)::

    import swath
    part = swath.example_part("panel")             # or swath.load_mesh("part.stl", units="mm")
    tool = swath.Tool(pad_radius=0.0381, force=20.0, depression=1e-3)
    path = swath.order_toolpath(swath.raster(part, tool))
    trajectory = swath.time_path(path, [swath.FeedLimit(0.05), swath.AngularSpeedLimit(1.0)])
    removal = swath.simulate_removal(trajectory, part, tool)

SI units everywhere inside the library: metres, seconds, radians, newtons, pascals.
"""

import importlib
import logging

from .errors import InfeasibleError, InputError, SwathError, UnreachableError

__version__ = "0.2.0"

logging.getLogger(__name__).addHandler(logging.NullHandler())

#: Public name -> the module that defines it (imported on first use).
_EXPORTS = {
    "load_mesh": "swath.io.mesh", "load_points": "swath.io.points",
    "Surface": "swath.surface", "fit_patch": "swath.scan.fit", "register_rigid": "swath.scan.register",
    "example_part": "swath.examples", "wheel_hub": "swath.examples",
    "Tool": "swath.contact",
    "raster": "swath.plan", "uniform": "swath.plan", "equidistant": "swath.plan", "PLANNERS": "swath.plan",
    "plan_regions": "swath.plan.regions",
    "Pass": "swath.core", "ToolPath": "swath.core",
    "order_toolpath": "swath.order",
    "time_path": "swath.trajectory", "FeedLimit": "swath.trajectory", "AngularSpeedLimit": "swath.trajectory",
    "CentripetalLimit": "swath.trajectory", "TangentialAccelLimit": "swath.trajectory",
    "FeedProfile": "swath.trajectory", "Trajectory": "swath.trajectory", "read_csv": "swath.trajectory",
    "run_robot_stage": "swath.robot",
    "simulate_removal": "swath.simulate", "simulate_force": "swath.simulate.force",
    "calibrate": "swath.simulate.calibrate",
    "write_report": "swath.report",
    "run_job": "swath.cli.job", "settings_from_mapping": "swath.cli.settings",
}


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'swath' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(list(globals()) + list(_EXPORTS))


__all__ = ["SwathError", "InputError", "InfeasibleError", "UnreachableError", "__version__", *_EXPORTS]

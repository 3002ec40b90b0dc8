"""swath — plan robotic surface finishing (sanding, polishing, grinding) on free-form parts.

Pipeline (one stage, one subpackage)::

    io -> surface -> plan -> trajectory -> simulate -> report      (cli drives them all)

SI units everywhere inside the library: metres, seconds, radians, newtons, pascals.
"""

import logging

from .errors import InfeasibleError, InputError, SwathError, UnreachableError

__version__ = "0.1.0"

logging.getLogger(__name__).addHandler(logging.NullHandler())

__all__ = ["SwathError", "InputError", "InfeasibleError", "UnreachableError", "__version__"]

"""The exceptions swath raises.

Every error a user can cause derives from :class:`SwathError`, so a caller (or the CLI) can catch
one type and print its message.  Messages name the problem and, where there is one, the fix.
"""


class SwathError(Exception):
    """Root of every error swath raises on purpose."""


class InputError(SwathError, ValueError):
    """The input (a file, an array, a setting) is malformed or out of range."""


class InfeasibleError(SwathError):
    """The request is well formed but cannot be met (e.g. no pass fits the region)."""


class UnreachableError(SwathError):
    """A pose lies outside what the robot or tool can reach."""

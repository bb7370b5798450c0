"""Exceptions raised by zeroset."""

__all__ = [
    "InputError",
    "InspectionError",
    "MissingExtraError",
    "ReconstructionError",
    "SurfaceWarning",
    "ZerosetError",
]


class ZerosetError(Exception):
    """Base class of every error zeroset raises on purpose."""


class InputError(ZerosetError, ValueError):
    """An input file or array cannot be used: missing, unreadable, malformed or degenerate."""


class InspectionError(InputError):
    """A mesh (and its points) that cannot be inspected as a pipe: no tube in it, or too
    little of the circle covered to fit one; the message says what would make it run."""


class MissingExtraError(ZerosetError, ImportError):
    """A feature's optional dependency is not installed; the message names the extra."""


class ReconstructionError(ZerosetError, RuntimeError):
    """Valid input that cannot support a surface with the chosen parameters."""


class SurfaceWarning(UserWarning):
    """The surface differs from what Hoppe's method gives alone: a hole closed, a gap
    bridged, a component dropped, a hint not trusted. Each has a count in the stats and
    an option that turns it off."""

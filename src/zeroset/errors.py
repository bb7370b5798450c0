"""Exceptions raised by zeroset."""

__all__ = ["InputError", "ReconstructionError", "ZerosetError"]


class ZerosetError(Exception):
    """Base class of every error zeroset raises on purpose."""


class InputError(ZerosetError, ValueError):
    """An input file or array cannot be used: missing, unreadable, malformed or degenerate."""


class ReconstructionError(ZerosetError, RuntimeError):
    """Valid input that cannot support a surface with the chosen parameters."""

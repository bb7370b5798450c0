"""Joints and other ring features: where the wall changes all round the pipe at once."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["JOINT_KINDS", "Joint"]

#: Kinds of ring feature: a gap (missing or recessed wall), an offset (the pipe beyond
#: steps sideways), a bead (a ring standing into the bore).
JOINT_KINDS = ("gap", "offset", "bead")


@dataclass(frozen=True)
class Joint:
    """A ring feature of the wall: a joint between two pipe lengths, or a weld's bead.

    Lengths are metres, angles degrees on the clock.

    Attributes
    ----------
    kind : {"gap", "offset", "bead"}
    axial : float
        Position along the centreline.
    size : float
        A gap's axial width, an offset's step, a bead's height into the bore.
    uncertainty : float
        One standard deviation of `size`.
    clock : float
        An offset's direction: the clock angle towards which the pipe beyond the joint
        moved; NaN for the other kinds.
    depth : float
        A gap's recess, outward from the wall (NaN where the wall is missing, or for the
        other kinds).
    """

    kind: str
    axial: float
    size: float
    uncertainty: float
    clock: float = float("nan")
    depth: float = float("nan")

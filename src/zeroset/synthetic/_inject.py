"""Dents, bulges and joints of known size put into a real scan's points: truth for scans that
have none."""

from __future__ import annotations

import numpy as np

from .._validate import as_points, as_viewpoints
from ..errors import InputError
from ._wall import Defect, Joint, _Wall

__all__ = ["inject"]

#: The clock convention of injected features: the inspection's, not the synthetic pipes'.
CLOCK_CONVENTION = (
    "Clock angles are degrees clockwise looking along the fitted centreline (see "
    "zeroset.inspect): 12 o'clock (0) is the world's up projected onto the first section"
)
#: A point whose beam meets the wall more obliquely than this cosine is moved along the
#: radius rather than along its beam: a beam along the wall would carry it far round.
GRAZING = 0.2


def inject(points, pipe, *, defects=(), joints=(), viewpoints=None) -> tuple[np.ndarray, dict]:
    """Move a scan's points as the wall would be with `defects` and `joints` in it.

    Each point's radial change is that of `zeroset.synthetic.Defect` and
    `zeroset.synthetic.Joint` (the profiles `zeroset.synthetic.pipe_run` draws) at its
    axial position and clock on `pipe`, whose frame the features' positions are given in.
    A point is moved along its beam, where its range noise lies, when its sensor position
    is known and the beam meets the wall at a cosine of `GRAZING` or more; else towards
    the axis. The noise, the texture and the holes of the scan stay as they were.

    Parameters
    ----------
    points : (N, 3) array_like
        The scan, metres.
    pipe : zeroset.inspect.Pipe
        Its fitted pipe (`zeroset.inspect.fit_pipe`): axial positions are metres along its
        centreline from where the data start, clocks degrees in its convention.
    defects : sequence of zeroset.synthetic.Defect
        Dents and bulges; a wide one (tens of centimetres) is a deformation of the section.
    joints : sequence of zeroset.synthetic.Joint
        Gaps, offsets and beads.
    viewpoints : (3,) or (N, 3) array_like, optional
        Each point's sensor position (rows of NaN where not known).

    Returns
    -------
    moved : (N, 3) float64
    truth : dict
        JSON-able: the pipe's ``radius``, the ``defects`` and ``joints`` as
        `zeroset.synthetic.pipe_run`'s truth records list them (each with its ``centre``
        on the nominal wall, a joint's on the centreline), the ``clock_convention``, and
        ``moved``, how many points moved by more than a micrometre.

    Raises
    ------
    InputError
        If a feature is not a `Defect` or a `Joint`, or lies beyond the pipe's ends.
    """
    points = as_points(points, "points")
    defects, joints = tuple(defects), tuple(joints)
    for feature, kind in [*((d, Defect) for d in defects), *((j, Joint) for j in joints)]:
        if not isinstance(feature, kind):
            raise InputError(f"expected a zeroset.synthetic.{kind.__name__}; got {feature!r}")
        if not 0.0 <= feature.axial <= pipe.length:
            raise InputError(
                f"{feature.kind} at {feature.axial:g} m lies beyond the scan's pipe "
                f"(0 to {pipe.length:.3f} m along it)"
            )
    wall = _Wall(pipe.radius, None, defects, 0.0, 0.0, (0.0, 0.0), joints)
    axial, clock, _ = pipe.locate(points)
    inside = np.isfinite(axial)
    change = np.zeros(points.shape[0])
    change[inside] = wall.radius_at(np.radians(clock[inside]), axial[inside]) - pipe.radius
    radial = np.zeros_like(points)
    radial[inside] = pipe.directions(axial[inside], clock[inside])[1]
    step = change[:, None] * radial
    if viewpoints is not None:
        sensors = np.broadcast_to(as_viewpoints(viewpoints, points.shape[0]), points.shape)
        with np.errstate(invalid="ignore", divide="ignore"):
            beam = points - sensors
            beam /= np.linalg.norm(beam, axis=1, keepdims=True)
            facing = np.einsum("ij,ij->i", beam, radial)
        along = np.isfinite(facing) & (np.abs(facing) >= GRAZING)
        step[along] = (change[along] / facing[along])[:, None] * beam[along]
    moved = points + step
    truth = {
        "radius": pipe.radius,
        "clock_convention": CLOCK_CONVENTION,
        "defects": [d.record(pipe.position([d.axial], d.clock)[0]) for d in defects],
        "joints": [j.record(pipe.position([j.axial], 0.0, 0.0)[0]) for j in joints],
        "moved": int(np.count_nonzero(np.abs(change) > 1e-6)),
    }
    return moved, truth

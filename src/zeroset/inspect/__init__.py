"""Pipe inspection: centreline, deviation, ovality and defects of a pipe from its scan.

`inspect_pipe` does it all; its stages are public too:

- `fit_pipe`: the centreline and nominal radius. Every normal of a pipe's wall points at
  the axis, so the vertices pushed inward along their normals by the radius (from the
  wall's mean curvature) gather on the centreline; a smooth curve through them, moved
  onto the centres of circles fitted per station, is the centreline.
- `deviation`: the signed distance of any position from the nominal pipe, negative
  inward (a dent or a deposit), positive outward (a bulge or wall loss).
- `ovality`: ``(D_max - D_min) / D_nominal`` per station.
- `unroll` and `find_defects`: the wall unrolled into axial position by clock angle and
  smoothed, and its connected regions beyond the points' own noise.
- `find_joints`: ring features (gaps, offsets, beads); `check_stations`: the stretches
  whose sections the fit does not explain, never judged for defects.
- `LiveInspection`: the inspection grown while `zeroset.live.LiveReconstruction` finishes
  blocks, in windows stitched along the robot's path.
- `inspection_summary`, `inspection_lines`, `write_defects_csv`, `write_joints_csv`,
  `write_ovality_csv`: the numbers as JSON, printed lines and tables; `deviation_map`,
  `ovality_plot` and `mesh_picture`: the pictures, as PNG bytes.

Clock convention: 12 o'clock (0 degrees) is the world's `up` (default +z) projected onto
the first cross-section, or +y when the pipe starts within 30 degrees of `up` (a vertical
pipe, such as the synthetic pipes of `zeroset.synthetic`, which run along +z). It is
carried along the centreline without twisting, and the clock runs clockwise seen looking
along the centreline, so 3 o'clock (90 degrees) is ``tangent x up``. Axial positions are
metres along the centreline from where the data start; the centreline runs the positive
way of the largest component of its end-to-end vector (a pipe along z runs towards +z).
Lengths are metres throughout.
"""

from ._centreline import Pipe, Unreliable, beam_steps, check_stations, fit_pipe
from ._defects import Branch, Defect, Defects, find_defects
from ._files import (
    inspection_lines,
    inspection_summary,
    write_defects_csv,
    write_joints_csv,
    write_ovality_csv,
)
from ._frame import UP
from ._inspection import Inspection, inspect_pipe
from ._joints import JOINT_KINDS, Joint, find_joints
from ._live import LIVE_FILES, LiveInspection, Stretch
from ._measure import Ovality, deviation, ovality
from ._pictures import clock_label, deviation_map, mesh_picture, ovality_plot
from ._unrolled import WallMap, unroll

__all__ = [
    "JOINT_KINDS",
    "LIVE_FILES",
    "UP",
    "Branch",
    "Defect",
    "Defects",
    "Inspection",
    "Joint",
    "LiveInspection",
    "Ovality",
    "Pipe",
    "Stretch",
    "Unreliable",
    "WallMap",
    "beam_steps",
    "check_stations",
    "clock_label",
    "deviation",
    "deviation_map",
    "find_defects",
    "find_joints",
    "fit_pipe",
    "inspect_pipe",
    "inspection_lines",
    "inspection_summary",
    "mesh_picture",
    "ovality",
    "ovality_plot",
    "unroll",
    "write_defects_csv",
    "write_joints_csv",
    "write_ovality_csv",
]

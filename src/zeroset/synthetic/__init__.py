"""Seeded synthetic point clouds with ground truth, for tests, benchmarks and demos.

Every generator takes ``rng`` (a numpy Generator, an integer seed or None) and returns a
`Sample`: the points, the true surface normals, the distance to the true surface (exact, or
as close as the generator's Notes say), its area, a dense truth mesh built from the analytic
parametrisation (``truth_mesh(spacing)``, built lazily; ``truth`` is the default one) and,
for simulated scans, each point's sensor position (``viewpoints``).

- Surface samples, uniform in area: `sample_cylinder`, `sample_sphere`, `sample_torus`,
  `two_spheres`, `sample_elbow` (a 90 degree pipe bend), `sample_tee` (a T-junction).
- A simulated in-pipe scan: `scan_pipe` (a rotating Hokuyo URG-04LX-like 2D scanner,
  strongly non-uniform density, range-dependent noise); `scan_pipe_size` gives its size.
- Damaged pipes: `damaged_pipe` (a straight pipe or an elbow with `Defect` dents and bulges
  and ovality) and `scan_damaged_pipe` (the in-pipe scan of a damaged straight pipe or
  elbow from several stations); their ``truth_record`` lists the defects.
- Pipe runs: a `PipePath` (straight legs and circular bends, its 12 o'clock carried along
  without twist) with dents and bulges, ovality, `Joint` rings (gaps, offsets, weld beads)
  and `Tee` branches; `pipe_run` samples its walls, `scan_pipe_run` scans it from stations
  along it, and `random_pipe_run` draws one (a `RunSpec`) from a seed. Their
  ``truth_record`` holds the path, the true centreline, the defects, joints and tees.
- Truth for a real scan: `inject` moves its points as the wall would be with dents,
  bulges and joints of known size in it (along the beams where the sensor positions are
  known, else towards the fitted axis).
- `add_noise`, `add_outliers`, and `write_sample` (points and truth mesh as PLY, the truth
  record as JSON).

Units are metres. The same seed gives identical arrays.
"""

from ._damage import damaged_pipe, scan_damaged_pipe
from ._inject import inject
from ._path import PipePath
from ._pipes import sample_elbow, sample_tee
from ._runs import RUN_CLOCK_CONVENTION, RunSpec, Tee, pipe_run, random_pipe_run, scan_pipe_run
from ._sample import Sample, add_noise, add_outliers, write_sample
from ._scanner import hokuyo_accuracy, scan_pipe, scan_pipe_size
from ._shapes import sample_cylinder, sample_sphere, sample_torus, two_spheres
from ._truth import MAX_FACES
from ._wall import CLOCK_CONVENTION, DEFECT_KINDS, JOINT_KINDS, Defect, Joint

__all__ = [
    "CLOCK_CONVENTION",
    "DEFECT_KINDS",
    "Defect",
    "JOINT_KINDS",
    "Joint",
    "MAX_FACES",
    "PipePath",
    "RUN_CLOCK_CONVENTION",
    "RunSpec",
    "Sample",
    "Tee",
    "add_noise",
    "add_outliers",
    "damaged_pipe",
    "hokuyo_accuracy",
    "inject",
    "pipe_run",
    "random_pipe_run",
    "sample_cylinder",
    "sample_elbow",
    "sample_sphere",
    "sample_tee",
    "sample_torus",
    "scan_damaged_pipe",
    "scan_pipe",
    "scan_pipe_run",
    "scan_pipe_size",
    "two_spheres",
    "write_sample",
]

"""How good is a mesh: distances to a reference or to scan points, and mesh quality.

Every function returns plain data. The report functions return JSON-ready dicts (Python
floats, ints, lists, strings and None) that :func:`format_report` prints as a table.
"""

from __future__ import annotations

import numbers

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import connected_components

from ._kernels import evaluate as _kernels
from ._kernels import triangles as _triangles
from ._unique import distinct
from ._validate import as_faces, as_points, positive, require_rng
from .errors import InputError
from .topology import corner_fans, edge_ids, face_components
from .types import Mesh

__all__ = [
    "closest_points_on_mesh",
    "closest_points_on_triangles",
    "compare_to_points",
    "compare_to_reference",
    "evaluate",
    "format_report",
    "mesh_quality",
    "points_to_mesh_distance",
    "sample_surface",
    "smallest_angles",
]

_TAU_UNITS = ("diagonal", "absolute")
_UNITS = "data units (those of the vertex coordinates)"


# --------------------------------------------------------------------------- distances


def closest_points_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray):
    """Return the closest point (N, 3) on triangle (a_i, b_i, c_i) to each p_i.

    All inputs are (N, 3) float64. Where the projection of p onto the triangle's plane has
    no negative barycentric coordinate it is the answer; otherwise the nearest of the
    closest points on the three edges is (Ericson, *Real-Time Collision Detection*, 2005,
    §3.4 and §5.1.5). A degenerate triangle (height below 1e-8 of its longest edge) is
    treated as its three edges, which are then within that height of the answer: its
    plane is too ill-defined for a projection to be more accurate.
    """
    p, a, b, c = (np.ascontiguousarray(x, dtype=np.float64) for x in (p, a, b, c))
    distance2, bary = np.zeros(p.shape[0]), np.zeros((p.shape[0], 3))
    _triangles.closest_point_rows(p, a, b, c, distance2, bary)
    return bary[:, :1] * a + bary[:, 1:2] * b + bary[:, 2:] * c


def closest_points_on_mesh(points, mesh: Mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Find the closest point of a triangle mesh to each query point, exactly.

    Used by every distance in this module. Triangles are searched through a bounding-volume
    hierarchy, so the answer is the minimum over all faces, also on meshes whose triangles
    differ widely in size (a CAD reference, a mesh with slivers).

    Parameters
    ----------
    points : (N, 3) array_like of float
        Query points.
    mesh : Mesh
        Triangle mesh with at least one face.

    Returns
    -------
    closest : (N, 3) float64
        Closest point of the mesh surface to each query point.
    face : (N,) int64
        Face that holds it (one of them, where several are equally close).
    distance : (N,) float64
        Euclidean distance from each point to `closest`, in data units.

    Raises
    ------
    TypeError
        If `mesh` is not a :class:`~zeroset.types.Mesh`.
    ValueError
        If `points` is not (N, 3) and finite, or the mesh has no faces.

    See Also
    --------
    points_to_mesh_distance : the distances only.

    Notes
    -----
    The hierarchy is a balanced binary tree of axis-aligned boxes, built by median splits
    of the triangles' box centres, four triangles per leaf. Each query walks it nearer
    box first and skips every box no nearer than the best triangle found so far; box
    distances are lower bounds, so no closer triangle is skipped and the result is the
    minimum over all faces, up to rounding. On one triangle, the closest point is the
    projection onto its plane when that falls inside, else the closest point on an edge
    (see :func:`closest_points_on_triangles`). A degenerate face (height below 1e-8 of its
    longest edge, zero-area faces included) counts as its three edges.

    On two cores, a million points within 1 % of the size of a 100 000-face mesh take
    one to two seconds; points far from the surface take longer, as many more
    triangles are then nearly as close as the closest one.

    References
    ----------
    C. Ericson, *Real-Time Collision Detection*, Morgan Kaufmann, 2005, §3.4, §5.1.5, §6.

    Examples
    --------
    >>> from zeroset.types import Mesh
    >>> mesh = Mesh(vertices=np.eye(3), faces=np.array([[0, 1, 2]]))
    >>> closest, face, distance = closest_points_on_mesh([[0.0, 0.0, 0.0]], mesh)
    >>> np.round(closest, 4).tolist(), face.tolist(), round(float(distance[0]), 4)
    ([[0.3333, 0.3333, 0.3333]], [0], 0.5774)
    """
    points = as_points(points)
    vertices, faces = _as_mesh(mesh)
    return closest_on_arrays(points, vertices, faces)


def points_to_mesh_distance(points, mesh: Mesh) -> np.ndarray:
    """Return the exact distance (N,) float64 from each point (N, 3) to the mesh surface.

    A thin wrapper of :func:`closest_points_on_mesh`; see there for parameters and errors.

    Examples
    --------
    >>> from zeroset.types import Mesh
    >>> mesh = Mesh(vertices=np.eye(3), faces=np.array([[0, 1, 2]]))
    >>> points_to_mesh_distance([[2.0, 0.0, 0.0]], mesh).round(4).tolist()
    [1.0]
    """
    return closest_points_on_mesh(points, mesh)[2]


# --------------------------------------------------------------------------- sampling


def sample_surface(mesh: Mesh, n: int, *, rng=None) -> tuple[np.ndarray, np.ndarray]:
    """Draw points uniformly by area from the surface of a mesh, with their face normals.

    The surface samples for :func:`compare_to_reference`; they also make exact test data.

    Parameters
    ----------
    mesh : Mesh
        Triangle mesh with a positive total area.
    n : int
        Number of samples.
    rng : numpy.random.Generator or int or None
        Random generator or seed.

    Returns
    -------
    points : (n, 3) float64
        Samples; a face is chosen with probability proportional to its area and a point
        uniformly inside it. Degenerate faces (see :func:`mesh_quality`) are not drawn.
    normals : (n, 3) float64
        Unit normal of each sample's face, following the face's vertex order
        (counter-clockwise seen from the side it points to).

    Raises
    ------
    TypeError
        If `mesh` is not a Mesh or `rng` is not a Generator, seed or None.
    ValueError
        If `n` is not a positive integer or the mesh has no area.

    Notes
    -----
    Inside a triangle (a, b, c), ``(1 - sqrt(r1)) a + sqrt(r1) (1 - r2) b + sqrt(r1) r2 c``
    with r1, r2 uniform on [0, 1) is uniform (Osada et al. 2002, §4.2).

    References
    ----------
    R. Osada, T. Funkhouser, B. Chazelle, D. Dobkin, "Shape distributions", ACM Transactions
    on Graphics 21(4), 2002. https://doi.org/10.1145/571647.571648

    Examples
    --------
    >>> from zeroset.types import Mesh
    >>> mesh = Mesh(vertices=np.eye(3), faces=np.array([[0, 1, 2]]))
    >>> points, normals = sample_surface(mesh, 100, rng=0)
    >>> points.shape, np.round(points.sum(axis=1), 12).tolist() == [1.0] * 100
    ((100, 3), True)
    """
    vertices, faces = _as_mesh(mesh)
    n = positive(n, "n", integer=True)
    return _sample(vertices, faces, n, require_rng(rng), "mesh")


# --------------------------------------------------------------------------- comparisons


def compare_to_reference(
    mesh: Mesh,
    reference: Mesh,
    *,
    n_samples: int = 100_000,
    taus=(0.01, 0.005),
    tau_unit: str = "diagonal",
    rng=0,
) -> dict:
    """Compare a mesh with a reference surface: distances both ways, F-score, normals.

    The measure of a reconstruction against the truth (a synthetic or scanned reference
    mesh). Both surfaces are sampled uniformly by area and each sample is measured to the
    other *surface* (not to its samples), so the scores do not depend on the reference's
    sampling density.

    Parameters
    ----------
    mesh : Mesh
        The reconstruction.
    reference : Mesh
        The ground truth.
    n_samples : int
        Samples drawn from each surface.
    taus : sequence of float
        Distance thresholds for precision, recall and F-score.
    tau_unit : {"diagonal", "absolute"}
        ``"diagonal"``: `taus` are fractions of the reference's bounding-box diagonal;
        ``"absolute"``: `taus` are in data units.
    rng : numpy.random.Generator or int or None
        Random generator or seed for the samples; the default makes reports repeatable.

    Returns
    -------
    dict
        JSON-ready; every distance in data units (the vertex coordinates' unit):

        ``units`` : str
        ``n_samples`` : int, per surface
        ``diagonal`` : float, the reference's bounding-box diagonal
        ``accuracy`` : dict with ``mean``, ``median``, ``p95``, ``max`` of the distances
        from the mesh samples to the reference
        ``completeness`` : the same from the reference samples to the mesh
        ``chamfer_l1`` : float, mean of the two mean distances
        ``chamfer_l2`` : float, mean of the two mean squared distances (squared units)
        ``hausdorff`` : float, the larger of the two maximum distances
        ``normal_consistency`` : float in [0, 1], or None
        ``thresholds`` : list of dicts, one per tau, with ``tau`` (data units),
        ``tau_fraction`` (of the diagonal), ``precision``, ``recall``, ``f_score``

    Raises
    ------
    TypeError
        If `mesh` or `reference` is not a Mesh.
    ValueError
        If a mesh has no faces or no area, `n_samples` is not a positive integer, a tau is
        not positive, or `tau_unit` is not one of the two choices.

    See Also
    --------
    compare_to_points : for real scans without a reference surface.
    mesh_quality : counts and triangle shapes of one mesh.
    evaluate : all of these at once.

    Notes
    -----
    With mesh samples X, reference samples Y, d(x, S) the distance from x to surface S:

    - accuracy: d(x, reference) for x in X; completeness: d(y, mesh) for y in Y;
    - ``chamfer_l1 = (mean_X d + mean_Y d) / 2`` (Chamfer-L1 of Mescheder et al. 2019);
      ``chamfer_l2 = (mean_X d^2 + mean_Y d^2) / 2``;
    - ``hausdorff = max(max_X d, max_Y d)``, from samples, so a lower bound of the true one;
    - precision(tau) = share of X with d < tau, recall(tau) = share of Y with d < tau,
      ``f_score = 2 P R / (P + R)`` (0 when both are 0), as in Tanks and Temples
      (Knapitsch et al. 2017, §4), with distances measured to the other surface;
    - normal consistency: mean of ``|n(x) . n'(x)|`` over X, with n(x) the normal of the
      sample's face and n'(x) that of the closest reference face, the same over Y, and
      the two means averaged (Mescheder et al. 2019, §4). Orientation does not matter.
      Samples whose closest face is degenerate have no normal and are left out; the value
      is None when none is left.

    References
    ----------
    A. Knapitsch, J. Park, Q.-Y. Zhou, V. Koltun, "Tanks and Temples: benchmarking
    large-scale scene reconstruction", ACM Transactions on Graphics 36(4), 2017.
    https://doi.org/10.1145/3072959.3073599

    L. Mescheder, M. Oechsle, M. Niemeyer, S. Nowozin, A. Geiger, "Occupancy networks:
    learning 3D reconstruction in function space", CVPR 2019.
    https://doi.org/10.1109/CVPR.2019.00459

    Examples
    --------
    >>> from zeroset.types import Mesh
    >>> mesh = Mesh(vertices=np.eye(3), faces=np.array([[0, 1, 2]]))
    >>> report = compare_to_reference(mesh, mesh, n_samples=1000)
    >>> report["thresholds"][0]["f_score"], report["hausdorff"] < 1e-12
    (1.0, True)
    """
    m_vertices, m_faces = _as_mesh(mesh)
    r_vertices, r_faces = _as_mesh(reference, "reference")
    options = _reference_options(n_samples, taus, tau_unit)
    return _compare_to_reference(
        m_vertices, m_faces, r_vertices, r_faces, *options, require_rng(rng)
    )


def compare_to_points(mesh: Mesh, points, *, tau: float | None = None) -> dict:
    """Measure how well a mesh explains scan points: distances and coverage.

    For real scans, where no reference surface exists: each point is measured to the mesh.
    Large distances mean the mesh missed or smoothed away part of what was scanned (or
    that the points hold outliers).

    Parameters
    ----------
    mesh : Mesh
    points : (N, 3) array_like of float
        The scan.
    tau : float, optional
        Coverage threshold in data units; default 1 % of the points' bounding-box diagonal.

    Returns
    -------
    dict
        JSON-ready, distances in data units:

        ``units`` : str
        ``n_points`` : int
        ``distance`` : dict with ``mean``, ``median``, ``p95``, ``max`` of the distances
        from the points to the mesh
        ``tau`` : float, the coverage threshold used
        ``tau_fraction`` : float, `tau` over the points' bounding-box diagonal (None if
        the points span no distance)
        ``coverage`` : float, share of the points closer than `tau` to the mesh

    Raises
    ------
    TypeError
        If `mesh` is not a Mesh.
    ValueError
        If the points are not (N, 3) and finite, the mesh has no faces, `tau` is not
        positive, or `tau` is None and all points coincide.

    See Also
    --------
    compare_to_reference : when a reference surface exists.

    Examples
    --------
    >>> from zeroset.types import Mesh
    >>> mesh = Mesh(vertices=np.eye(3), faces=np.array([[0, 1, 2]]))
    >>> compare_to_points(mesh, np.eye(3))["coverage"]
    1.0
    """
    vertices, faces = _as_mesh(mesh)
    points = as_points(points)
    tau = positive(tau, "tau", allow_none=True)
    return _compare_to_points(vertices, faces, points, tau)


def mesh_quality(mesh: Mesh) -> dict:
    """Count what is wrong with a mesh and describe its triangles.

    Topology (boundaries, non-manifold edges and vertices, components, Euler
    characteristic) and triangle shape (aspect ratio, smallest angle, degenerate faces).
    It works on any triangle soup: non-manifold and inconsistently oriented input is
    counted, not rejected.

    Parameters
    ----------
    mesh : Mesh

    Returns
    -------
    dict
        JSON-ready:

        ``vertices``, ``unreferenced_vertices``, ``faces``, ``edges`` : int
        ``boundary_edges`` : int, edges of one face
        ``boundary_loops`` : int, see Notes
        ``non_manifold_edges`` : int, edges of three faces or more
        ``non_manifold_vertices`` : int, vertices whose faces form more than one fan
        ``euler_characteristic`` : int, V - E + F over the vertices that faces use
        ``components`` : int, face components connected through shared vertices
        ``degenerate_faces`` : int, faces of zero area up to rounding: height below 1e-8
        of the longest edge, repeated vertices included
        ``aspect_ratio`` : dict with ``min``, ``median``, ``p95``, ``max`` of
        circumradius / (2 inradius) over the other faces, 1 for an equilateral triangle;
        None if every face is degenerate
        ``min_angle_degrees`` : dict with ``min`` and ``p5`` of each face's smallest angle
        over the same faces; None likewise
        ``area`` : float, total area in squared data units

    Raises
    ------
    TypeError
        If `mesh` is not a Mesh.
    ValueError
        If the mesh has no faces or its faces index missing vertices.

    See Also
    --------
    zeroset.topology : the counts on their own.
    zeroset.repair.split_nonmanifold_vertices : turns bow-ties into separate vertices.

    Notes
    -----
    A *fan* of vertex v is a set of faces around v connected through edges at v (faces
    across a non-manifold edge included); a bow-tie vertex has two fans. Vertices on a
    non-manifold edge are not counted as non-manifold vertices unless they are bow-ties
    as well: that edge is counted under ``non_manifold_edges``.

    Boundary loops are counted on the mesh with each fan given its own copy of the vertex,
    as :func:`~zeroset.repair.split_nonmanifold_vertices` does, so two holes touching at a
    bow-tie count twice. A loop is a connected set of boundary edges; on an edge-manifold
    mesh this is ``len(topology.boundary_loops(split_faces))``, and it stays defined where
    a non-manifold edge gives one vertex more than two boundary edges.

    Edges are counted as :func:`zeroset.topology.edge_face_counts` counts them, so a face
    that repeats a vertex index also adds an edge from that vertex to itself.

    The aspect ratio R / (2 r) = abc (a + b + c) / (16 A^2) for sides a, b, c and area A
    is 1 for an equilateral triangle and grows without bound as a triangle flattens
    (Shewchuk 2002, §3).

    References
    ----------
    J. R. Shewchuk, "What is a good linear finite element? Interpolation, conditioning,
    anisotropy, and quality measures", 2002.
    https://people.eecs.berkeley.edu/~jrs/papers/elemj.pdf

    Examples
    --------
    >>> from zeroset.types import Mesh
    >>> mesh = Mesh(vertices=np.eye(3), faces=np.array([[0, 1, 2]]))
    >>> quality = mesh_quality(mesh)
    >>> quality["boundary_loops"], round(quality["aspect_ratio"]["max"], 12)
    (1, 1.0)
    """
    vertices, faces = _as_mesh(mesh)
    return _mesh_quality(vertices, faces)


def smallest_angles(mesh: Mesh) -> np.ndarray:
    """Return the smallest interior angle of every face, in degrees.

    Parameters
    ----------
    mesh : Mesh

    Returns
    -------
    (F,) float64
        In [0, 60]; 0 for a degenerate face.

    Raises
    ------
    TypeError
        If `mesh` is not a Mesh.
    ValueError
        If the mesh has no faces or its faces index missing vertices.

    Examples
    --------
    >>> from zeroset.types import Mesh
    >>> mesh = Mesh(vertices=np.eye(3), faces=np.array([[0, 1, 2]]))
    >>> smallest_angles(mesh).round(6)
    array([60.])
    """
    vertices, faces = _as_mesh(mesh)
    return _smallest_angle_degrees(*(vertices[faces[:, i]] for i in range(3)))


def evaluate(
    mesh: Mesh,
    *,
    reference: Mesh | None = None,
    points=None,
    n_samples: int = 100_000,
    taus=(0.01, 0.005),
    tau_unit: str = "diagonal",
    points_tau: float | None = None,
    rng=0,
) -> dict:
    """Evaluate a mesh: its quality, and how it compares with a reference and with points.

    All inputs are checked before any work starts.

    Parameters
    ----------
    mesh : Mesh
    reference : Mesh, optional
        Ground-truth surface for :func:`compare_to_reference`.
    points : (N, 3) array_like of float, optional
        Scan points for :func:`compare_to_points`.
    n_samples, taus, tau_unit, rng
        As in :func:`compare_to_reference`.
    points_tau : float, optional
        The `tau` of :func:`compare_to_points`.

    Returns
    -------
    dict
        ``{"quality": ...}`` from :func:`mesh_quality`, plus ``"reference"`` and
        ``"points"`` when those were given; JSON-ready, printable with :func:`format_report`.

    Raises
    ------
    TypeError, ValueError
        As the three functions do.

    Examples
    --------
    >>> from zeroset.types import Mesh
    >>> mesh = Mesh(vertices=np.eye(3), faces=np.array([[0, 1, 2]]))
    >>> sorted(evaluate(mesh, reference=mesh, points=np.eye(3), n_samples=100))
    ['points', 'quality', 'reference']
    """
    vertices, faces = _as_mesh(mesh)
    if reference is not None:
        r_vertices, r_faces = _as_mesh(reference, "reference")
        options = _reference_options(n_samples, taus, tau_unit)
        rng = require_rng(rng)
    if points is not None:
        points = as_points(points)
        points_tau = positive(points_tau, "points_tau", allow_none=True)
    report = {"quality": _mesh_quality(vertices, faces)}
    if reference is not None:
        report["reference"] = _compare_to_reference(
            vertices, faces, r_vertices, r_faces, *options, rng
        )
    if points is not None:
        report["points"] = _compare_to_points(vertices, faces, points, points_tau)
    return report


def format_report(report: dict) -> str:
    """Render an evaluation report as aligned plain text for a terminal.

    Parameters
    ----------
    report : dict
        From :func:`evaluate` (sections ``reference``, ``points``, ``quality``, whichever
        are present), or one section on its own, as :func:`compare_to_reference`,
        :func:`compare_to_points` or :func:`mesh_quality` return it.

    Returns
    -------
    str
        One block per section, without a trailing newline.

    Raises
    ------
    TypeError
        If `report` is not a dict.
    ValueError
        If it holds no section this module writes.

    Examples
    --------
    >>> from zeroset.types import Mesh
    >>> mesh = Mesh(vertices=np.eye(3), faces=np.array([[0, 1, 2]]))
    >>> format_report(mesh_quality(mesh)).splitlines()[:3]
    ['quality', '  vertices                     3', '  unreferenced vertices        0']
    """
    if not isinstance(report, dict):
        raise TypeError(f"report must be a dict from evaluate(); got {type(report).__name__}")
    sections = {key: report[key] for key in ("reference", "points", "quality") if key in report}
    if not sections:
        for key, marker in (
            ("reference", "thresholds"),
            ("points", "coverage"),
            ("quality", "euler_characteristic"),
        ):
            if marker in report:
                sections = {key: report}
    if not sections:
        raise InputError(
            "report holds none of the sections 'reference', 'points', 'quality'; "
            f"got keys {sorted(report)}"
        )
    writers = {"reference": _reference_lines, "points": _points_lines, "quality": _quality_lines}
    blocks = ["\n".join(writers[key](section)) for key, section in sections.items()]
    return "\n\n".join(blocks)


# --------------------------------------------------------------------------- private cores


def _as_mesh(mesh, name: str = "mesh") -> tuple[np.ndarray, np.ndarray]:
    """Return validated vertices (M, 3) float64 and faces (F, 3) int64, F >= 1, of `mesh`."""
    if not isinstance(mesh, Mesh):
        raise TypeError(f"{name} must be a zeroset Mesh; got {type(mesh).__name__}")
    vertices = as_points(mesh.vertices, f"{name} vertices")
    faces = as_faces(mesh.faces, vertices.shape[0], f"{name} faces")
    if faces.shape[0] == 0:
        raise InputError(f"{name} has no faces; at least one triangle is needed")
    return vertices, faces


def _reference_options(n_samples, taus, tau_unit) -> tuple[int, np.ndarray, str]:
    """Check the options of compare_to_reference; return n_samples, taus (T,), tau_unit."""
    n_samples = positive(n_samples, "n_samples", integer=True)
    if isinstance(taus, numbers.Real):
        taus = (taus,)
    try:
        values = [positive(tau, "each tau") for tau in taus]
    except TypeError as exc:
        raise TypeError(f"taus must be a sequence of numbers; got {taus!r}") from exc
    if not values:
        raise InputError("taus is empty; give at least one threshold, e.g. taus=(0.01,)")
    if tau_unit not in _TAU_UNITS:
        raise InputError(f"tau_unit must be 'diagonal' or 'absolute'; got {tau_unit!r}")
    return n_samples, np.array(values), tau_unit


def closest_on_arrays(points, vertices, faces, *, in_order=False, hierarchy=None, within=None):
    """closest_points_on_mesh on validated arrays (N, 3), (M, 3), (F, 3); no checks.
    `in_order`, `hierarchy` and `within` (N,) as for
    `zeroset._kernels.closest_points_on_mesh`: a point with no face nearer than its bound
    gets face -1, a closest point of NaN and the bound as its distance."""
    face, bary, distance2 = _kernels.closest_points_on_mesh(
        points, vertices, faces, in_order=in_order, hierarchy=hierarchy, within=within
    )
    closest = np.einsum("ni,nij->nj", bary, vertices[faces[face]])
    if within is not None:
        closest[face < 0] = np.nan
    return closest, face, np.sqrt(distance2)


def _sample(vertices, faces, n, rng, name):
    """sample_surface on validated arrays."""
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    cross = np.cross(b - a, c - a)
    double_area = np.linalg.norm(cross, axis=1)
    double_area[_degenerate(a, b, c)] = 0.0
    total = double_area.sum()
    if not total > 0:
        raise InputError(f"{name} has zero area; it cannot be sampled")
    face = rng.choice(faces.shape[0], size=n, p=double_area / total)
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)
    points = (
        (1.0 - s)[:, None] * a[face]
        + (s * (1.0 - r2))[:, None] * b[face]
        + (s * r2)[:, None] * c[face]
    )
    normals = cross[face] / double_area[face, None]
    return points, normals


def _compare_to_reference(m_vertices, m_faces, r_vertices, r_faces, n, taus, tau_unit, rng):
    """compare_to_reference on validated arrays and options."""
    used = r_vertices[distinct(r_faces)]
    diagonal = float(np.linalg.norm(used.max(axis=0) - used.min(axis=0)))
    taus = taus * diagonal if tau_unit == "diagonal" else taus
    m_points, m_normals = _sample(m_vertices, m_faces, n, rng, "mesh")
    r_points, r_normals = _sample(r_vertices, r_faces, n, rng, "reference")
    _, r_face, accuracy = closest_on_arrays(m_points, r_vertices, r_faces)
    _, m_face, completeness = closest_on_arrays(r_points, m_vertices, m_faces)
    consistency = [
        _normal_agreement(normals, vertices, faces, face)
        for normals, vertices, faces, face in (
            (m_normals, r_vertices, r_faces, r_face),
            (r_normals, m_vertices, m_faces, m_face),
        )
    ]
    consistency = [value for value in consistency if value is not None]
    thresholds = []
    for tau in taus:
        precision = float(np.mean(accuracy < tau))
        recall = float(np.mean(completeness < tau))
        total = precision + recall
        thresholds.append(
            {
                "tau": float(tau),
                "tau_fraction": float(tau / diagonal) if diagonal > 0 else None,
                "precision": precision,
                "recall": recall,
                "f_score": 2.0 * precision * recall / total if total > 0 else 0.0,
            }
        )
    return {
        "units": _UNITS,
        "n_samples": int(n),
        "diagonal": diagonal,
        "accuracy": _summary(accuracy),
        "completeness": _summary(completeness),
        "chamfer_l1": float(0.5 * (accuracy.mean() + completeness.mean())),
        "chamfer_l2": float(0.5 * (np.mean(accuracy**2) + np.mean(completeness**2))),
        "hausdorff": float(max(accuracy.max(), completeness.max())),
        "normal_consistency": float(np.mean(consistency)) if consistency else None,
        "thresholds": thresholds,
    }


def _compare_to_points(vertices, faces, points, tau):
    """compare_to_points on validated arrays."""
    diagonal = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    if tau is None:
        if diagonal == 0:
            raise InputError("points all coincide, so tau cannot default to 1 % of their extent")
        tau = 0.01 * diagonal
    distance = closest_on_arrays(points, vertices, faces)[2]
    return {
        "units": _UNITS,
        "n_points": int(points.shape[0]),
        "distance": _summary(distance),
        "tau": float(tau),
        "tau_fraction": float(tau / diagonal) if diagonal > 0 else None,
        "coverage": float(np.mean(distance < tau)),
    }


def _mesh_quality(vertices, faces):
    """mesh_quality on validated arrays."""
    edge_of_half, counts = edge_ids(faces, vertices.shape[0])
    fan, n_fans = corner_fans(faces, edge_of_half)
    corner_vertex = faces.reshape(-1)
    fan_vertex = np.zeros(n_fans, dtype=np.int64)
    fan_vertex[fan] = corner_vertex
    fans_per_vertex = np.bincount(fan_vertex, minlength=vertices.shape[0])
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    degenerate = _degenerate(a, b, c)
    proper = ~degenerate
    aspect = min_angle = None
    if proper.any():
        ratio = _aspect_ratio(a[proper], b[proper], c[proper])
        angle = _smallest_angle_degrees(a[proper], b[proper], c[proper])
        aspect = {"min": float(ratio.min()), **_summary(ratio)}
        min_angle = {"min": float(angle.min()), "p5": float(np.percentile(angle, 5))}
    return {
        "vertices": int(vertices.shape[0]),
        "unreferenced_vertices": int(np.count_nonzero(fans_per_vertex == 0)),
        "faces": int(faces.shape[0]),
        "edges": int(counts.size),
        "boundary_edges": int(np.count_nonzero(counts == 1)),
        "boundary_loops": _count_boundary_loops(fan, n_fans, counts[edge_of_half] == 1),
        "non_manifold_edges": int(np.count_nonzero(counts > 2)),
        "non_manifold_vertices": int(np.count_nonzero(fans_per_vertex > 1)),
        # topology.euler_characteristic, without finding the edges a second time.
        "euler_characteristic": int(np.count_nonzero(fans_per_vertex) - counts.size + len(faces)),
        "components": face_components(faces, vertices.shape[0])[0],
        "degenerate_faces": int(np.count_nonzero(degenerate)),
        "aspect_ratio": aspect,
        "min_angle_degrees": min_angle,
        "area": float(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum()),
    }


# --------------------------------------------------------------------------- private helpers


def _dot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Row-wise dot product of two (N, 3) arrays."""
    return np.einsum("ij,ij->i", u, v)


def _degenerate(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Whether each triangle (a, b, c) has zero area up to rounding, (N,) bool."""
    n = a.shape[0]
    degenerate = np.zeros(n, dtype=np.bool_)
    _triangles.triangle_rows(a, b, c, np.zeros((n, 15)), degenerate)
    return degenerate


def _summary(values: np.ndarray) -> dict:
    """Mean, median, 95th percentile and maximum of (N,) values, as floats."""
    return {
        "mean": float(values.mean()),
        "median": float(np.median(values)),
        "p95": float(np.percentile(values, 95)),
        "max": float(values.max()),
    }


def _normal_agreement(normals, vertices, faces, face) -> float | None:
    """Mean |n . n'| between sample normals (N, 3) and the normals of their closest faces."""
    a, b, c = (vertices[faces[face, i]] for i in range(3))
    cross = np.cross(b - a, c - a)
    length = np.linalg.norm(cross, axis=1)
    defined = ~_degenerate(a, b, c)
    if not defined.any():
        return None
    other = cross[defined] / length[defined, None]
    return float(np.mean(np.abs(_dot(normals[defined], other))))


def _aspect_ratio(a, b, c) -> np.ndarray:
    """Circumradius over twice the inradius, abc (a + b + c) / (16 A^2), of proper triangles."""
    la, lb, lc = (np.linalg.norm(u - v, axis=1) for u, v in ((b, c), (c, a), (a, b)))
    cross = np.cross(b - a, c - a)
    cross2 = _dot(cross, cross)  # (2A)^2
    return la * lb * lc * (la + lb + lc) / (4.0 * cross2)


def _smallest_angle_degrees(a, b, c) -> np.ndarray:
    """Smallest interior angle (N,) of each triangle, in degrees."""
    angles = [
        np.arctan2(np.linalg.norm(np.cross(u - o, v - o), axis=1), _dot(u - o, v - o))
        for o, u, v in ((a, b, c), (b, c, a), (c, a, b))
    ]
    return np.degrees(np.min(angles, axis=0))


def _count_boundary_loops(fan: np.ndarray, n_fans: int, border: np.ndarray) -> int:
    """Connected sets of boundary half-edges (`border`, (3F,) bool) once fans are split."""
    if not border.any():
        return 0
    tail = np.flatnonzero(border)
    head = 3 * (tail // 3) + (tail % 3 + 1) % 3
    rows, cols = fan[tail], fan[head]
    graph = sparse.coo_matrix((np.ones(rows.size), (rows, cols)), shape=(n_fans, n_fans))
    _, label = connected_components(graph, directed=False)
    return int(distinct(label[rows]).size)


def _table(rows: list[list[str]], indent: str = "  ") -> list[str]:
    """Align rows of cells: the first column to the left, the others to the right."""
    n_columns = max(len(row) for row in rows)
    widths = [max(len(row[i]) for row in rows if i < len(row)) for i in range(n_columns)]
    lines = []
    for row in rows:
        cells = [row[0].ljust(widths[0])]
        cells += [cell.rjust(width) for cell, width in zip(row[1:], widths[1:], strict=False)]
        lines.append((indent + "  ".join(cells)).rstrip())
    return lines


def _length(value) -> str:
    """A distance (or any measured value) for the table."""
    return "-" if value is None else f"{value:.4g}"


def _share(value) -> str:
    """A share in [0, 1] for the table."""
    return "-" if value is None else f"{value:.4f}"


_STATS = ("mean", "median", "p95", "max")


def _reference_lines(section: dict) -> list[str]:
    """The reference section of format_report."""
    rows = [
        ["distance to the other surface", *_STATS],
        *(
            [name, *(_length(section[name][stat]) for stat in _STATS)]
            for name in ("accuracy", "completeness")
        ),
        ["chamfer L1, L2", _length(section["chamfer_l1"]), _length(section["chamfer_l2"])],
        ["hausdorff", _length(section["hausdorff"])],
        ["normal consistency", _share(section["normal_consistency"])],
        ["tau (share of diagonal)", "precision", "recall", "F-score"],
    ]
    for item in section["thresholds"]:
        fraction = item["tau_fraction"]
        share = "" if fraction is None else f" ({100 * fraction:.3g} %)"
        rows.append(
            [
                f"{_length(item['tau'])}{share}",
                _share(item["precision"]),
                _share(item["recall"]),
                _share(item["f_score"]),
            ]
        )
    title = (
        f"reference: {section['n_samples']:,} samples per surface, bounding-box diagonal "
        f"{_length(section['diagonal'])}, distances in {section['units']}"
    )
    return [title, *_table(rows)]


def _points_lines(section: dict) -> list[str]:
    """The points section of format_report."""
    fraction = section["tau_fraction"]
    share = "" if fraction is None else f" ({100 * fraction:.3g} % of their extent)"
    rows = [
        ["distance to the mesh", *_STATS],
        ["points", *(_length(section["distance"][stat]) for stat in _STATS)],
        ["coverage (closer than tau)", _share(section["coverage"])],
    ]
    title = (
        f"points: {section['n_points']:,} scan points, tau {_length(section['tau'])}{share}, "
        f"distances in {section['units']}"
    )
    return [title, *_table(rows)]


_QUALITY_LABELS = {
    "vertices": "vertices",
    "unreferenced_vertices": "unreferenced vertices",
    "faces": "faces",
    "edges": "edges",
    "boundary_edges": "boundary edges",
    "boundary_loops": "boundary loops",
    "non_manifold_edges": "non-manifold edges",
    "non_manifold_vertices": "non-manifold vertices",
    "euler_characteristic": "Euler characteristic",
    "components": "components",
    "degenerate_faces": "degenerate faces",
}


def _quality_lines(section: dict) -> list[str]:
    """The quality section of format_report."""
    rows = [[label, f"{section[key]:,}"] for key, label in _QUALITY_LABELS.items()]
    rows.append(["area", _length(section["area"])])
    aspect, angle = section["aspect_ratio"], section["min_angle_degrees"]
    if aspect is not None:
        rows += [
            ["", "min", "median", "p95", "max"],
            ["aspect ratio", *(f"{aspect[stat]:.3f}" for stat in ("min", "median", "p95", "max"))],
            ["", "min", "p5"],
            ["smallest angle, degrees", f"{angle['min']:.2f}", f"{angle['p5']:.2f}"],
        ]
    return ["quality", *_table(rows)]

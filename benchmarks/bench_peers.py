"""Benchmark zeroset against Open3D, PyMeshLab, PoissonRecon and VTK, for docs/benchmarks.md.

Run by hand from the repository root (needs the ``bench`` extra, and Debian's libusb-1.0-0
for Open3D). Every tool at 20k and 200k points took an hour on 2 cores; 1M points for the
pipe and the scan with the Poisson tools at depth 8 took six minutes more::

    python benchmarks/bench_peers.py --sizes 20000 200000 --timeout 300
    python benchmarks/bench_peers.py --datasets pipe scan --sizes 1000000 --json more.json \
        --tools zeroset open3d-poisson8 pymeshlab-poisson poissonrecon-d8-t5 ...

Several runs' ``--json`` files are merged by rows with ``--from-json A.json B.json``.

Datasets: noisy synthetic surfaces with an exact truth mesh (the pipes ``pipe``, ``scan``,
``elbow``, ``tee`` and the closed ``sphere`` and ``torus``, from `zeroset.synthetic` with fixed
seeds) and real scans without truth (``bunny``, ``gargoyle``, ``sick``, from the shared data
folder, see ``--data``). Where the true surface has a sign (pipe, scan, sphere, torus), the
*signed bias* is the area-weighted mean signed distance from the mesh to it, positive outside.

Every tool runs in its own child process (this script with the hidden ``--child JOB`` flag)
under a wall-clock limit: the parent writes the cloud to ``points.npy`` in a temporary folder,
the child reads it, reconstructs, writes ``JOB.npz`` there and prints one JSON line with the
seconds per stage and its peak resident set size (``VmHWM``). A child that runs past the
limit is killed and recorded as a timeout. Open3D's and PyMeshLab's Poisson and ball-pivoting
variants share one normal estimation per library and cloud: a ``*-normals`` child runs it
once, and each variant's row adds its times and takes the larger peak RSS of the processes.
PoissonRecon's rows chain two such shared children: Open3D's normals, then one untrimmed
reconstruction per depth (``poissonrecon-d8``, ``-d9``) that each trim row only trims. The
parent measures every mesh against the truth (`zeroset.evaluate`), draws one picture per
dataset into ``docs/images/`` and replaces the section between
``<!-- peers:begin -->`` and ``<!-- peers:end -->`` of the Markdown report, keeping the rest
of the file (see ``_docfile.py``); a hand-written summary between ``<!-- peers-summary:begin
-->`` and ``<!-- peers-summary:end -->`` inside that section is carried over.

Each tool's settings live in one small function below (``zeroset_run``, ``open3d_normals``,
``open3d_poisson``, ``open3d_ball_pivoting``, ``pymeshlab_normals``, ``pymeshlab_poisson``,
``pymeshlab_ball_pivoting``, ``poissonrecon``, ``poissonrecon_trim``, ``vtk_hoppe``).
"""

from __future__ import annotations

import argparse
import contextlib
import heapq
import io
import json
import math
import os
import resource
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path

import numpy as np
from _docfile import markers, replace_section, write_atomic
from bench_phase1 import machine_lines

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUTPUT = ROOT / "docs" / "benchmarks.md"
DEFAULT_IMAGES = ROOT / "docs" / "images"
DEFAULT_DATA = Path("/work/shared/data")
DEFAULT_SIZES = (20_000, 200_000, 1_000_000)
DEFAULT_TIMEOUT = 300.0
DEFAULT_MEMORY_GIB = 16.0  # per child, as RLIMIT_DATA
SEED = 0
WARMUP_POINTS = 5_000
IMAGE_SIZE = 200_000  # pictures show this size, or the largest run below it
IMAGE_FACES = 30_000  # faces drawn per mesh, a random subset
SUMMARY = "peers-summary"

# --------------------------------------------------------------------------------------
# Tool settings: one function per tool, run inside the child process.
# --------------------------------------------------------------------------------------

OPEN3D_NORMAL_RADIUS = 5.0  # x mean nearest-neighbour spacing, for KDTreeSearchParamHybrid
OPEN3D_MAX_NN = 30  # Open3D's default neighbour count for normals
OPEN3D_ORIENT_K = 15  # k of orient_normals_consistent_tangent_plane
OPEN3D_DENSITY_QUANTILE = 0.05  # Poisson vertices below this density quantile are removed
OPEN3D_BPA_RADII = (1.0, 2.0, 4.0)  # x mean nearest-neighbour spacing
PYMESHLAB_NORMAL_K = 10  # compute_normal_for_point_clouds default
PYMESHLAB_DEPTH = 8
POISSONRECON_DEPTHS = (8, 9)
POISSONRECON_TRIMS = (5, 6, 7)  # SurfaceTrimmer --trim values
POISSONRECON_POINT_WEIGHT = 2.0  # PoissonRecon's default, 2 x B-spline degree (pypoisson2's is 4)
POISSONRECON_SCALE = 1.1  # PoissonRecon's --scale default (bounding cube / bounding box)
POISSONRECON_SAMPLES_PER_NODE = 1.5  # PoissonRecon's --samplesPerNode default
POISSONRECON_ISLAND_RATIO = 0.001  # SurfaceTrimmer's --aRatio default
VTK_SAMPLE_SPACING = 2.0  # x mean nearest-neighbour spacing
VTK_NEIGHBOURS = 20  # vtkSurfaceReconstructionFilter's default NeighborhoodSize


class Stopwatch:
    """Wall seconds per named stage (`time.perf_counter`)."""

    def __init__(self) -> None:
        self.stages: dict[str, float] = {}

    @contextlib.contextmanager
    def __call__(self, name: str):
        start = time.perf_counter()
        try:
            yield
        finally:
            self.stages[name] = self.stages.get(name, 0.0) + time.perf_counter() - start


def zeroset_run(points, viewpoints=None, surface="jets"):
    """zeroset defaults: every parameter is estimated from the data.

    ``viewpoints`` orients the normals towards each point's sensor instead of by the minimum
    spanning tree; ``surface="planes"`` is Hoppe's nearest tangent plane (the thesis'
    method) instead of the default blended jets. The stages are
    ``Reconstruction.timings``; *(outside stages)* is the rest of the wall time of
    ``reconstruct()`` (input checks, final statistics).
    """
    import zeroset

    start = time.perf_counter()
    result = zeroset.reconstruct(points, viewpoints=viewpoints, surface=surface)
    total = time.perf_counter() - start
    stages = dict(result.timings)
    stages["(outside stages)"] = max(total - sum(stages.values()), 0.0)
    parameters = result.parameters
    params = {"rho_delta": parameters.rho_delta, "cube_size": parameters.cube_size}
    if "fit_support" in result.stats:
        params["fit_support"] = result.stats["fit_support"]
    return result.mesh.vertices, result.mesh.faces, stages, params


def _mean_spacing_scipy(points) -> float:
    from scipy.spatial import cKDTree  # imported by the caller before timing

    distances, _ = cKDTree(points).query(points, k=2, workers=-1)
    return float(distances[:, 1].mean())


def open3d_normals(points):
    """Open3D normals as its tutorials make them, with scales from the point spacing.

    Spacing: the mean nearest-neighbour distance (``compute_nearest_neighbor_distance``).
    Normals: ``estimate_normals(KDTreeSearchParamHybrid(radius=5 x spacing, max_nn=30))``.
    Orientation: ``orient_normals_consistent_tangent_plane(15)`` (Hoppe's Riemannian-graph
    MST; k = 15).
    """
    import open3d as o3d

    watch = Stopwatch()
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    with watch("spacing"):
        spacing = float(np.mean(np.asarray(cloud.compute_nearest_neighbor_distance())))
    with watch("normals"):
        cloud.estimate_normals(
            o3d.geometry.KDTreeSearchParamHybrid(
                radius=OPEN3D_NORMAL_RADIUS * spacing, max_nn=OPEN3D_MAX_NN
            )
        )
    with watch("orientation"):
        cloud.orient_normals_consistent_tangent_plane(OPEN3D_ORIENT_K)
    return np.asarray(cloud.normals).copy(), watch.stages, {"spacing": spacing}


def _open3d_cloud(points, normals):
    import open3d as o3d

    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    cloud.normals = o3d.utility.Vector3dVector(normals)
    return cloud


def _open3d_arrays(mesh):
    return np.asarray(mesh.vertices), np.asarray(mesh.triangles)


def open3d_poisson(points, normals, depth):
    """Open3D screened Poisson at `depth`, then the usual density trimming.

    ``create_from_point_cloud_poisson(cloud, depth=depth)`` with its other defaults (scale
    1.1, point weight 2, all threads), then ``remove_vertices_by_mask`` on the vertices
    whose density is below the 5 % quantile, as Open3D's Poisson tutorial does.
    """
    import open3d as o3d

    watch = Stopwatch()
    cloud = _open3d_cloud(points, normals)
    with watch("poisson"):
        mesh, densities = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(
            cloud, depth=depth
        )
    with watch("trimming"):
        densities = np.asarray(densities)
        mesh.remove_vertices_by_mask(densities < np.quantile(densities, OPEN3D_DENSITY_QUANTILE))
    vertices, faces = _open3d_arrays(mesh)
    return vertices, faces, watch.stages, {"depth": depth}


def open3d_ball_pivoting(points, normals, spacing):
    """Open3D ball pivoting with radii 1, 2 and 4 x the mean nearest-neighbour spacing."""
    import open3d as o3d

    watch = Stopwatch()
    cloud = _open3d_cloud(points, normals)
    radii = [factor * spacing for factor in OPEN3D_BPA_RADII]
    with watch("ball pivoting"):
        mesh = o3d.geometry.TriangleMesh.create_from_point_cloud_ball_pivoting(
            cloud, o3d.utility.DoubleVector(radii)
        )
    vertices, faces = _open3d_arrays(mesh)
    return vertices, faces, watch.stages, {"radii": radii}


def pymeshlab_normals(points):
    """MeshLab's point-cloud normals: ``compute_normal_for_point_clouds(k=10)``.

    Its defaults: plane fit to 10 neighbours, no smoothing, orientation by propagation over
    the neighbour graph (no viewpoint).
    """
    import pymeshlab

    watch = Stopwatch()
    meshes = pymeshlab.MeshSet()
    meshes.add_mesh(pymeshlab.Mesh(vertex_matrix=points))
    with watch("normals"):
        meshes.compute_normal_for_point_clouds(k=PYMESHLAB_NORMAL_K)
    normals = np.asarray(meshes.current_mesh().vertex_normal_matrix(), dtype=np.float64)
    return normals, watch.stages, {}


def _pymeshlab_set(points, normals):
    import pymeshlab

    meshes = pymeshlab.MeshSet()
    meshes.add_mesh(pymeshlab.Mesh(vertex_matrix=points, v_normals_matrix=normals))
    return meshes


def _pymeshlab_arrays(meshes):
    mesh = meshes.current_mesh()
    return (
        np.asarray(mesh.vertex_matrix(), dtype=np.float64),
        np.asarray(mesh.face_matrix(), dtype=np.int64),
    )


def pymeshlab_poisson(points, normals):
    """MeshLab screened Poisson: ``generate_surface_reconstruction_screened_poisson(depth=8)``.

    Its other defaults (scale 1.1, point weight 4, 8 solver iterations, all threads); no
    trimming, as MeshLab's filter has no density output.
    """
    watch = Stopwatch()
    meshes = _pymeshlab_set(points, normals)
    with watch("poisson"):
        meshes.generate_surface_reconstruction_screened_poisson(depth=PYMESHLAB_DEPTH)
    vertices, faces = _pymeshlab_arrays(meshes)
    return vertices, faces, watch.stages, {"depth": PYMESHLAB_DEPTH}


def pymeshlab_ball_pivoting(points, normals):
    """MeshLab ball pivoting with its defaults: ``generate_surface_reconstruction_ball_pivoting()``.

    The ball radius is MeshLab's own guess from the bounding box and point count
    (``ballradius`` 0 %), clustering 20 %, crease angle 90 degrees.
    """
    watch = Stopwatch()
    meshes = _pymeshlab_set(points, normals)
    with watch("ball pivoting"):
        meshes.generate_surface_reconstruction_ball_pivoting()
    vertices, faces = _pymeshlab_arrays(meshes)
    return vertices, faces, watch.stages, {}


def poissonrecon(points, normals, depth):
    """Kazhdan's PoissonRecon 18.74 (pypoisson2) at `depth`, untrimmed, with vertex densities.

    ``poisson.poisson_reconstruction(points, normals, depth=depth, point_weight=2,
    output_density=True)``: the executable's defaults (degree 1, Neumann boundary, scale 1.1,
    1.5 samples per node, 8 iterations) with its point weight of 2 x degree; pypoisson2's
    own default is 4. The density of a vertex is PoissonRecon's ``--density`` value: the
    octree depth at which the kernel density estimate holds 1.5 samples per node, about
    ``log4`` of the local sample count, so the trim values of SurfaceTrimmer read as depths.

    pypoisson2 1.0.0 returns 1.0 for every vertex: its wrapper never sets
    ``LevelSetExtractionParameters::outputDensity``, so the extractor gets no density
    estimator and writes its default. When the densities come back constant, they are
    recomputed by `poissonrecon_density`; its seconds are in ``params["density_s"]``, not in
    the stages, since PoissonRecon computes them itself at no visible cost.
    """
    from poisson import poisson_reconstruction

    watch = Stopwatch()
    with watch("poisson"):
        vertices, faces, values = poisson_reconstruction(
            points,
            normals,
            depth=depth,
            point_weight=POISSONRECON_POINT_WEIGHT,
            output_density=True,
        )
    vertices, faces = np.asarray(vertices, np.float64), np.asarray(faces, np.int64)
    values = np.asarray(values, np.float64)
    params = {"depth": depth, "point_weight": POISSONRECON_POINT_WEIGHT}
    if len(values) and np.ptp(values) == 0:
        params["density"] = f"recomputed (pypoisson2 gave {values[0]:g} for all)"
        start = time.perf_counter()
        values = poissonrecon_density(points, vertices, depth)
        params["density_s"] = time.perf_counter() - start
    else:
        params["density"] = "pypoisson2"
    return vertices, faces, values, watch.stages, params


def _bspline2(t):
    """Quadratic B-spline weights (..., 3) of the nodes at offsets -1, 0, 1 at `t` in [0, 1)."""
    return np.stack([0.5 * (1.0 - t) ** 2, 0.5 + t - t * t, 0.5 * t * t], axis=-1)


_OFFSETS = np.array([(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)])


def _kernel_weights(t):
    """Tensor B-spline weights (M, 27) of the 3 x 3 x 3 nodes around positions `t` (M, 3)."""
    v = _bspline2(t)
    return v[:, 0, _OFFSETS[:, 0] + 1] * v[:, 1, _OFFSETS[:, 1] + 1] * v[:, 2, _OFFSETS[:, 2] + 1]


def _density_scale_value(res: int = 10) -> float:
    """PoissonRecon's ``FEMTree::_GetScaleValue<CoDim=1, Degree=2>(10)``: about 1.8247.

    The factor that makes a plane of samples, one per node, read 1 sample per node: the
    inverse of the kernel sum at a point from its plane's splats, averaged over a 10 x 10 x 10
    grid of positions in the node. The B-splines sum to 1 along the plane, so that sum is
    ``sum_i b_i(x)^2`` across it and only the positions across the plane matter.
    """
    weights = _bspline2((np.arange(res) + 0.5) / res)
    return float(np.mean(1.0 / (weights**2).sum(axis=1)))


def poissonrecon_density(points, vertices, depth):
    """PoissonRecon 18.74's ``--density`` value at `vertices`, recomputed from `points`.

    A NumPy port of ``setDensityEstimator`` and ``_getSampleDepthAndWeight``: the points go
    to PoissonRecon's unit cube (the bounding box's centre, 1.1 x its largest side); at each
    depth d up to the kernel depth ``depth - 2``, every node splats its point count, at the
    points' mean, with quadratic B-splines (times `_density_scale_value`) into its
    3 x 3 x 3 neighbours. At a vertex, the splatted sum at the kernel depth gives the samples
    per node s; if s >= 1.5 the value is ``d + log4(s / 1.5)``, else it goes up the depths
    until s reaches 1.5 and interpolates ``log(s / 1.5)`` between the last two. Nodes past
    the unit cube hold nothing. One simplification: the evaluation always starts at the
    kernel depth, where PoissonRecon starts at the vertex's leaf when that is coarser (far
    from the samples). With the older scale constant of PoissonRecon 12 (1 / 0.59375) this
    reproduces Open3D's Poisson densities on its own meshes to +-0.05 (5th-95th percentile).
    """
    lo, hi = points.min(axis=0), points.max(axis=0)
    side = POISSONRECON_SCALE * float((hi - lo).max())
    origin = (lo + hi) / 2.0 - side / 2.0
    unit_points, unit_vertices = (points - origin) / side, (vertices - origin) / side
    kernel = max(depth - 2, 0)
    scale_value = _density_scale_value()

    def cells(x, res):
        cell = np.clip(np.floor(x * res).astype(np.int64), 0, res - 1)
        return cell, (cell[:, 0] * res + cell[:, 1]) * res + cell[:, 2]

    def around(cell, res):
        nb = cell[:, None, :] + _OFFSETS[None]
        inside = np.all((nb >= 0) & (nb < res), axis=2)
        return (nb[..., 0] * res + nb[..., 1]) * res + nb[..., 2], inside

    levels = []  # per depth: sorted node keys and their splatted weights
    for d in range(kernel + 1):
        res = 1 << d
        _, key = cells(unit_points, res)
        nodes, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
        mean = np.zeros((len(nodes), 3))
        np.add.at(mean, inverse.ravel(), unit_points)
        mean /= counts[:, None]
        cell = np.stack([nodes // (res * res), nodes // res % res, nodes % res], axis=1)
        weights = _kernel_weights(mean * res - cell) * (scale_value * counts)[:, None]
        keys, inside = around(cell, res)
        splat, where = np.unique(keys[inside], return_inverse=True)
        levels.append((splat, np.bincount(where.ravel(), weights[inside], len(splat))))

    def samples_per_node(d, x):
        res = 1 << d
        cell, _ = cells(x, res)
        keys, inside = around(cell, res)
        splat, weights = levels[d]
        at = np.minimum(np.searchsorted(splat, keys), len(splat) - 1)
        found = inside & (splat[at] == keys)
        return np.where(found, _kernel_weights(x * res - cell) * weights[at], 0.0).sum(axis=1)

    target = POISSONRECON_SAMPLES_PER_NODE
    coarse = samples_per_node(kernel, unit_vertices)
    fine = coarse.copy()
    level = np.full(len(vertices), kernel)
    with np.errstate(divide="ignore", invalid="ignore"):
        values = kernel + np.log(coarse / target) / (2.0 * math.log(2.0))
        sparse = np.flatnonzero(coarse < target)
        climbing = sparse
        while len(climbing):
            climbing = climbing[(coarse[climbing] < target) & (level[climbing] > 0)]
            if not len(climbing):
                break
            level[climbing] -= 1
            fine[climbing] = coarse[climbing]
            coarse[climbing] = samples_per_node(int(level[climbing[0]]), unit_vertices[climbing])
        values[sparse] = level[sparse] + np.log(coarse[sparse] / target) / np.log(
            coarse[sparse] / fine[sparse]
        )
    return np.where(np.isnan(values), -np.inf, values)


def surface_trim(vertices, faces, values, trim):
    """PoissonRecon's SurfaceTrimmer ``--trim trim`` with its defaults (``--aRatio 0.001``).

    As SurfaceTrimmer 18.74 does: a vertex is kept where its value is above `trim`
    (strictly); triangles are clipped along the ``value = trim`` line, the new vertices
    linearly interpolated on the crossing edges; the pieces above and below form connected
    components (through shared edges) and, smallest first, every component with neighbours
    and an area below 0.001 of the total is merged into its neighbours, which takes their
    side (small holes in the kept part are kept, small kept islands in the trimmed part are
    trimmed); isolated islands stay (no ``--removeIslands``); the part above is returned,
    without unused vertices. Clipped quadrilaterals are split along one diagonal (the
    trimmer picks the minimal-area one; both have the same area in the plane).
    """
    values = np.nan_to_num(np.asarray(values, np.float64), nan=-1e30, neginf=-1e30)
    above = values > trim
    count = above[faces].sum(axis=1)
    edges = faces[:, [[0, 1], [1, 2], [2, 0]]]  # edge i joins corners i and i + 1
    crossing = above[edges[..., 0]] != above[edges[..., 1]]
    pairs, where = np.unique(np.sort(edges[crossing], axis=1), axis=0, return_inverse=True)
    a, b = pairs.T if len(pairs) else (np.zeros(0, np.int64),) * 2
    fraction = (values[a] - trim) / (values[a] - values[b])
    points = np.concatenate(
        [vertices, vertices[a] + fraction[:, None] * (vertices[b] - vertices[a])]
    )
    on_edge = np.full(edges.shape[:2], -1, dtype=np.int64)
    on_edge[crossing] = len(vertices) + where.ravel()

    split = np.flatnonzero((count == 1) | (count == 2))
    odd = np.where(
        count[split] == 1,
        np.argmax(above[faces[split]], axis=1),
        np.argmax(~above[faces[split]], axis=1),
    )
    rows = split[:, None]
    corner = faces[rows, (odd[:, None] + np.arange(3)) % 3]  # odd, next, next but one
    x_first = on_edge[split, odd]  # on the edge odd -> next
    x_last = on_edge[split, (odd + 2) % 3]  # on the edge next but one -> odd
    tip = np.column_stack([corner[:, 0], x_first, x_last])
    quad = np.concatenate(
        [
            np.column_stack([x_first, corner[:, 1], corner[:, 2]]),
            np.column_stack([x_first, corner[:, 2], x_last]),
        ]
    )
    tip_above = count[split] == 1
    whole = np.flatnonzero((count == 0) | (count == 3))
    triangles = np.concatenate([faces[whole], tip, quad])
    side = np.concatenate([count[whole] == 3, tip_above, ~tip_above, ~tip_above])
    side = _merge_small_components(points, triangles, side)
    kept = triangles[side]
    used, kept = np.unique(kept, return_inverse=True)
    return points[used], kept.reshape(-1, 3)


def _merge_small_components(points, triangles, side):
    """SurfaceTrimmer's island step: the side (above or not) of each triangle after merging.

    Components are the triangles of one side joined through shared edges; two components
    are neighbours where one has the half-edge (u, v) and the other (v, u). Repeatedly the
    smallest component with neighbours, if its area is below 0.001 of the total, is merged
    with all its neighbours into one component of their side.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    if len(triangles) == 0:
        return side
    n = len(triangles)
    half = triangles[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2)
    owner = np.repeat(np.arange(n), 3)
    key = np.sort(half, axis=1)
    order = np.lexsort((owner, key[:, 1], key[:, 0]))
    same = np.all(key[order[1:]] == key[order[:-1]], axis=1)
    first, second = owner[order[:-1]][same], owner[order[1:]][same]  # triangles sharing an edge
    joined = side[first] == side[second]
    graph = coo_matrix((np.ones(joined.sum()), (first[joined], second[joined])), shape=(n, n))
    _, component = connected_components(graph, directed=False)
    a, b = component[first[~joined]], component[second[~joined]]
    corners = points[triangles]
    area = 0.5 * np.linalg.norm(
        np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1
    )
    areas = np.bincount(component, area).tolist()
    components = len(areas)
    limit = POISSONRECON_ISLAND_RATIO * sum(areas)
    neighbours = [set() for _ in range(components)]
    for u, v in set(zip(a.tolist(), b.tolist(), strict=True)):
        if u != v:
            neighbours[u].add(v)
            neighbours[v].add(u)
    sides = np.zeros(components, dtype=bool)
    sides[component] = side
    parent = list(range(components))
    heap = [(areas[c], c) for c in range(components) if neighbours[c]]
    heapq.heapify(heap)
    while heap:
        size, c = heapq.heappop(heap)
        if parent[c] != c or size != areas[c] or not neighbours[c]:
            continue  # merged away, grown since, or left without neighbours
        if size >= limit:
            break
        into, *others = sorted(neighbours[c])
        for other in neighbours[c]:
            neighbours[other].discard(c)
        for other in others:
            areas[into] += areas[other]
            parent[other] = into
            for far in neighbours[other]:
                neighbours[far].discard(other)
                if far != into:
                    neighbours[far].add(into)
                    neighbours[into].add(far)
            neighbours[other] = set()
        areas[into] += areas[c]
        parent[c] = into
        neighbours[c] = set()
        heapq.heappush(heap, (areas[into], into))
    root = np.arange(components)
    for c in range(components):
        while parent[root[c]] != root[c]:
            root[c] = parent[root[c]]
    return sides[root[component]]


def poissonrecon_trim(vertices, faces, values, trim):
    """Trim one PoissonRecon mesh at `trim` (`surface_trim`): the author's recipe for open scans."""
    watch = Stopwatch()
    with watch("trimming"):
        vertices, faces = surface_trim(vertices, faces, values, trim)
    return vertices, faces, watch.stages, {"trim": trim, "island_ratio": POISSONRECON_ISLAND_RATIO}


def vtk_hoppe(points):
    """VTK's Hoppe 1992: ``vtkSurfaceReconstructionFilter`` + ``vtkContourFilter`` at 0.

    The filter fits a plane to each point's 20 nearest neighbours, orients the planes over
    the neighbour graph and samples the signed distance on a dense grid (no undefined
    region); the sample spacing is 2 x the mean nearest-neighbour spacing (SciPy k-d tree).
    """
    import scipy.spatial  # noqa: F401  (import outside the timed spacing stage)
    from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkPolyData
    from vtkmodules.vtkFiltersCore import vtkContourFilter
    from vtkmodules.vtkImagingHybrid import vtkSurfaceReconstructionFilter

    watch = Stopwatch()
    with watch("spacing"):
        spacing = _mean_spacing_scipy(points)
    vtk_points = vtkPoints()
    vtk_points.SetData(numpy_to_vtk(np.ascontiguousarray(points), deep=True))
    cloud = vtkPolyData()
    cloud.SetPoints(vtk_points)
    surface = vtkSurfaceReconstructionFilter()
    surface.SetInputData(cloud)
    surface.SetNeighborhoodSize(VTK_NEIGHBOURS)
    surface.SetSampleSpacing(VTK_SAMPLE_SPACING * spacing)
    with watch("signed distance grid"):
        surface.Update()
    contour = vtkContourFilter()
    contour.SetInputConnection(surface.GetOutputPort())
    contour.SetValue(0, 0.0)
    with watch("contour"):
        contour.Update()
    output = contour.GetOutput()
    dims = surface.GetOutput().GetDimensions()
    if output.GetNumberOfPoints() == 0:
        vertices, faces = np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    else:
        vertices = vtk_to_numpy(output.GetPoints().GetData()).astype(np.float64)
        faces = vtk_to_numpy(output.GetPolys().GetConnectivityArray()).astype(np.int64)
        faces = faces.reshape(-1, 3)
    params = {"sample_spacing": VTK_SAMPLE_SPACING * spacing, "grid": list(dims)}
    return vertices, faces, watch.stages, params


# --------------------------------------------------------------------------------------
# Jobs: what a child runs. A row of the report is one mesh-making job.
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Job:
    key: str
    label: str
    library: str
    preps: tuple[str, ...] = ()  # children, run in order, whose outputs this job reads
    viewpoints: bool = False  # only for clouds with sensor positions


POISSONRECON_ROWS = {  # job key -> (depth, trim)
    f"poissonrecon-d{depth}-t{trim}": (depth, trim)
    for depth in POISSONRECON_DEPTHS
    for trim in POISSONRECON_TRIMS
}
JOBS = (
    Job("zeroset", "zeroset", "zeroset"),
    Job("zeroset-viewpoints", "zeroset, viewpoints", "zeroset", viewpoints=True),
    Job("zeroset-planes", "zeroset, planes (Hoppe)", "zeroset"),
    Job("open3d-poisson8", "Open3D Poisson d8", "Open3D", preps=("open3d-normals",)),
    Job("open3d-poisson9", "Open3D Poisson d9", "Open3D", preps=("open3d-normals",)),
    Job("open3d-bpa", "Open3D ball pivoting", "Open3D", preps=("open3d-normals",)),
    Job("pymeshlab-poisson", "PyMeshLab Poisson d8", "PyMeshLab", preps=("pymeshlab-normals",)),
    Job("pymeshlab-bpa", "PyMeshLab ball pivoting", "PyMeshLab", preps=("pymeshlab-normals",)),
    *(
        Job(
            key,
            f"PoissonRecon d{depth} t{trim}",
            "PoissonRecon",
            preps=("open3d-normals", f"poissonrecon-d{depth}"),
        )
        for key, (depth, trim) in POISSONRECON_ROWS.items()
    ),
    Job("vtk", "VTK Hoppe", "VTK"),
)
JOB_KEYS = tuple(job.key for job in JOBS)
NORMAL_PREPS = ("open3d-normals", "pymeshlab-normals")
POISSONRECON_PREPS = {f"poissonrecon-d{depth}": depth for depth in POISSONRECON_DEPTHS}
PREPS = (*NORMAL_PREPS, *POISSONRECON_PREPS)
COLOURS = {
    "truth": "#9a9a9a",
    "zeroset": "#1f77b4",
    "Open3D": "#ff7f0e",
    "PyMeshLab": "#2ca02c",
    "PoissonRecon": "#d62728",
    "VTK": "#9467bd",
}


def _peak_rss_mib() -> float:
    """Peak resident set size of this process, in MiB.

    On Linux this is ``VmHWM`` from ``/proc/self/status``: ``ru_maxrss`` carries the
    parent's resident size at the fork over the ``exec``, so a child of a large parent
    reports the parent's peak. Elsewhere it is ``ru_maxrss``.
    """
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024  # kB
    except OSError:
        pass
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (1024 * 1024) if sys.platform == "darwin" else peak / 1024  # bytes vs kB


def run_child(key: str, folder: Path, memory_gib: float) -> dict:
    """Run job or prep `key` on ``folder/points.npy``; save its output; return the report.

    The process's data segment is limited to `memory_gib` (``RLIMIT_DATA``), so a tool that
    asks for more fails with an allocation error instead of waking the OOM killer.
    """
    limit = int(memory_gib * 2**30)
    _, hard = resource.getrlimit(resource.RLIMIT_DATA)
    if hard == resource.RLIM_INFINITY or limit < hard:
        resource.setrlimit(resource.RLIMIT_DATA, (limit, hard))
    points = np.load(folder / "points.npy")
    params: dict = {}
    if key.startswith("zeroset"):
        import zeroset
        from zeroset.synthetic import sample_cylinder

        viewpoints = np.load(folder / "viewpoints.npy") if key == "zeroset-viewpoints" else None
        warm = sample_cylinder(WARMUP_POINTS, noise=0.002, rng=SEED).points
        warm_viewpoints = None if viewpoints is None else np.tile([0.0, 0.0, 0.5], (len(warm), 1))
        zeroset.reconstruct(warm, viewpoints=warm_viewpoints)  # compile every Numba kernel
        surface = "planes" if key == "zeroset-planes" else "jets"
        vertices, faces, stages, params = zeroset_run(points, viewpoints, surface)
    elif key in NORMAL_PREPS:
        make = open3d_normals if key == "open3d-normals" else pymeshlab_normals
        normals, stages, params = make(points)
        np.save(folder / f"{key}.npy", normals)
        return {"stages": stages, "params": params, "peak_rss_mib": _peak_rss_mib()}
    elif key in POISSONRECON_PREPS:
        normals = np.load(folder / "open3d-normals.npy")
        vertices, faces, values, stages, params = poissonrecon(
            points, normals, POISSONRECON_PREPS[key]
        )
        np.savez(folder / f"{key}.npz", vertices=vertices, faces=faces, values=values)
        return {"stages": stages, "params": params, "peak_rss_mib": _peak_rss_mib()}
    elif key == "vtk":
        vertices, faces, stages, params = vtk_hoppe(points)
    elif key in POISSONRECON_ROWS:
        depth, trim = POISSONRECON_ROWS[key]
        with np.load(folder / f"poissonrecon-d{depth}.npz") as mesh:
            untrimmed = mesh["vertices"], mesh["faces"], mesh["values"]
        vertices, faces, stages, params = poissonrecon_trim(*untrimmed, trim)
    else:
        job = next(job for job in JOBS if job.key == key)
        normals = np.load(folder / f"{job.preps[0]}.npy")
        if key == "open3d-poisson8":
            vertices, faces, stages, params = open3d_poisson(points, normals, 8)
        elif key == "open3d-poisson9":
            vertices, faces, stages, params = open3d_poisson(points, normals, 9)
        elif key == "open3d-bpa":
            with open(folder / "open3d-normals.json", encoding="utf-8") as file:
                spacing = json.load(file)["params"]["spacing"]
            vertices, faces, stages, params = open3d_ball_pivoting(points, normals, spacing)
        elif key == "pymeshlab-poisson":
            vertices, faces, stages, params = pymeshlab_poisson(points, normals)
        elif key == "pymeshlab-bpa":
            vertices, faces, stages, params = pymeshlab_ball_pivoting(points, normals)
        else:
            raise ValueError(f"unknown job {key!r}")
    np.savez(folder / f"{key}.npz", vertices=vertices, faces=faces)
    return {
        "stages": stages,
        "params": params,
        "peak_rss_mib": _peak_rss_mib(),
        "faces": int(len(faces)),
    }


def spawn(key: str, folder: Path, limit: float, memory_gib: float) -> dict:
    """Run one child under a wall-clock `limit`; return its report or a failure status."""
    command = [sys.executable, str(Path(__file__).resolve()), "--child", key, str(folder)]
    command += ["--memory", f"{memory_gib:g}"]
    start = time.perf_counter()
    process = subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group, killed as a whole on timeout
    )
    try:
        stdout, stderr = process.communicate(timeout=max(limit, 1.0))
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        process.communicate()
        return {"status": "timeout", "wall_s": time.perf_counter() - start}
    wall = time.perf_counter() - start
    lines = [line for line in stdout.splitlines() if line.startswith("{")]
    if process.returncode != 0 or not lines:
        if process.returncode < 0:
            why = f"killed by signal {-process.returncode}"
            if -process.returncode == signal.SIGKILL:
                why += " (out of memory?)"
        else:
            tail = [line for line in stderr.strip().splitlines() if line.strip()]
            why = tail[-1][:160] if tail else f"exit code {process.returncode}"
        return {"status": "failed", "error": why, "wall_s": wall}
    report = json.loads(lines[-1])
    report["status"] = "ok"
    report["wall_s"] = wall
    with open(folder / f"{key}.json", "w", encoding="utf-8") as file:
        json.dump(report, file)
    return report


# --------------------------------------------------------------------------------------
# Datasets
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Dataset:
    name: str
    title: str
    description: str
    synthetic: bool
    max_size: int | None = None  # synthetic: largest size run
    view: tuple[float, float] = (25.0, -60.0)  # elevation, azimuth of the pictures
    up: str = "z"  # the data's up axis; pictures put it up
    unit: tuple[float, str] = (1000.0, "mm")  # distances in tables: x scale, label


DATASETS = (
    Dataset(
        "pipe",
        "Open pipe",
        "`sample_cylinder(n, radius=0.25, length=1.0, noise=0.002, rng=0)`: the open side wall "
        "of a cylinder, uniform samples, Gaussian noise 2 mm per axis. Truth: 1 component, "
        "2 boundary loops.",
        True,
        view=(28.0, -60.0),
    ),
    Dataset(
        "scan",
        "Simulated in-pipe laser scan",
        "`scan_pipe(rotation_step=s, rng=0)`: a Hokuyo URG-04LX-like 2D scanner turning inside "
        "an open pipe (radius 0.25 m, length 2 m, 5 cm off-axis), Hokuyo noise model (10 mm up "
        "to 1 m), strongly non-uniform density, each point's sensor position known. The "
        "rotation step is the one whose point count (`scan_pipe_size`) is nearest the size. "
        "Truth: 1 component, 2 boundary loops.",
        True,
        view=(28.0, -60.0),
    ),
    Dataset(
        "elbow",
        "Pipe elbow",
        "`sample_elbow(n, noise=0.002, rng=0)`: a 90 degree bend (radius 0.25 m, bend radius "
        "0.6 m, legs 0.5 m), noise 2 mm. Truth: 1 component, 2 boundary loops. Run up to "
        "200,000 points only, to keep the run under an hour.",
        True,
        max_size=200_000,
        view=(20.0, -70.0),
    ),
    Dataset(
        "tee",
        "Pipe tee",
        "`sample_tee(n, noise=0.002, rng=0)`: a T-junction (main radius 0.25 m, branch "
        "0.15 m), noise 2 mm. Truth: 1 component, 3 boundary loops. Run up to 200,000 points "
        "only, to keep the run under an hour.",
        True,
        max_size=200_000,
        view=(20.0, -60.0),
    ),
    Dataset(
        "sphere",
        "Sphere",
        "`sample_sphere(n, radius=0.37, noise=0.001, rng=0)`: a closed sphere, uniform samples, "
        "noise 1 mm. Truth: 1 component, no boundary. Run up to 200,000 points only.",
        True,
        max_size=200_000,
    ),
    Dataset(
        "torus",
        "Torus",
        "`sample_torus(n, major=0.42, minor=0.13, noise=0.002, rng=0)`: a closed z-axis torus "
        "(tube radius 0.13 m about a 0.42 m circle), uniform samples, noise 2 mm. Truth: 1 "
        "component, no boundary. Run up to 200,000 points only.",
        True,
        max_size=200_000,
        view=(35.0, -60.0),
    ),
    Dataset(
        "bunny",
        "Stanford bunny, one range scan",
        "`stanford_bunny/data/bun000.ply`: one Cyberware range image (40,256 points, metres, "
        "noise about 50 um, y up). An open, single-view surface with holes.",
        False,
        view=(15.0, -90.0),
        up="y",
    ),
    Dataset(
        "gargoyle",
        "SRB gargoyle",
        "`srb_gargoyle_scan/gargoyle.ply`: the Surface Reconstruction Benchmark gargoyle input "
        "(95,435 points of a virtual scan of a closed object, simulated noise, about 70 units "
        "across). Its normals are ignored: every tool estimates its own.",
        False,
        view=(10.0, -90.0),
        up="y",
        unit=(1.0, "units"),
    ),
    Dataset(
        "sick",
        "3DTK rotating SICK scan",
        "`3dtk_rotating_sick/scan000.3d`: a real outdoor/indoor scan of a rotating 2D SICK "
        "(text `x y z` in cm, left-handed, y up; converted to metres, right-handed, z up; "
        "the points at the 32.76 m maximum range dropped). Sensor at the origin, so zeroset "
        "also runs with viewpoints.",
        False,
        view=(35.0, -120.0),
    ),
)
DATASET_NAMES = tuple(dataset.name for dataset in DATASETS)


@dataclass
class Cloud:
    points: np.ndarray
    viewpoints: np.ndarray | None
    truth: object | None  # zeroset.types.Mesh, dense, for the metrics
    note: str = ""
    coarse_truth: object | None = None  # a coarser truth mesh for the picture
    signed: object | None = None  # (M, 3) -> (M,) signed distance to the truth, + outside


# Signed distances to the true surfaces, positive outside (away from a pipe's axis). The
# Samples' own `distance` is unsigned; these are exact for the sphere and torus. For the
# open pipes it is the radial error, distance from the axis minus the radius, also past the
# ends (where a closed mesh's caps count with their radial error). The elbow and tee have
# none here.


def signed_pipe(radius: float):
    """Radial error of a z-axis pipe: distance from the axis minus `radius`."""

    def signed(x):
        return np.hypot(x[:, 0], x[:, 1]) - radius

    return signed


def signed_sphere(radius: float, centre=(0.0, 0.0, 0.0)):
    """Signed distance to a sphere: ``|x - centre| - radius``."""

    def signed(x):
        return np.linalg.norm(x - np.asarray(centre), axis=1) - radius

    return signed


def signed_torus(major: float, minor: float):
    """Signed distance to a z-axis torus: distance from the tube's centre circle minus `minor`."""

    def signed(x):
        return np.hypot(np.hypot(x[:, 0], x[:, 1]) - major, x[:, 2]) - minor

    return signed


def scan_rotation_step(n: int) -> float:
    """The `scan_pipe` rotation step (degrees) whose point count is nearest `n`."""
    from zeroset.synthetic import scan_pipe_size

    per_line = scan_pipe_size(rotation_step=360.0)
    lines = max(1, round(n / per_line))
    step = 360.0 / lines
    while math.floor(360.0 / step) < lines:  # rounding can lose the last line
        step = np.nextafter(step, 0.0)
    return float(step)


def read_sick(path: Path) -> np.ndarray:
    """A 3DTK ``.3d`` scan in metres, right-handed, z up, without max-range points."""
    raw = np.loadtxt(path, dtype=np.float64, ndmin=2)[:, :3]
    keep = np.linalg.norm(raw, axis=1) < 3275.0  # max range 32.76 m reads 3275.9-3276.7 cm
    x, y, z = raw[keep].T / 100.0
    return np.ascontiguousarray(np.column_stack([z, -x, y]))  # uos -> right-handed z up


def load(dataset: Dataset, n: int | None, data: Path) -> Cloud:
    """The cloud of `dataset` at size `n` (synthetic) or as stored (real)."""
    from zeroset import synthetic
    from zeroset.io import read_points

    signed = None
    if dataset.name == "pipe":
        sample = synthetic.sample_cylinder(n, radius=0.25, length=1.0, noise=0.002, rng=SEED)
        signed = signed_pipe(0.25)
    elif dataset.name == "scan":
        step = scan_rotation_step(n)
        sample = synthetic.scan_pipe(rotation_step=step, rng=SEED)  # radius 0.25, z axis
        cloud = Cloud(np.array(sample.points), np.array(sample.viewpoints), sample.truth)
        cloud.note = f"rotation step {step:.4f} degrees"
        cloud.coarse_truth = _coarse_truth(sample)
        cloud.signed = signed_pipe(0.25)
        return cloud
    elif dataset.name == "elbow":
        sample = synthetic.sample_elbow(n, noise=0.002, rng=SEED)
    elif dataset.name == "tee":
        sample = synthetic.sample_tee(n, noise=0.002, rng=SEED)
    elif dataset.name == "sphere":
        sample = synthetic.sample_sphere(n, radius=0.37, noise=0.001, rng=SEED)
        signed = signed_sphere(0.37)
    elif dataset.name == "torus":
        sample = synthetic.sample_torus(n, major=0.42, minor=0.13, noise=0.002, rng=SEED)
        signed = signed_torus(0.42, 0.13)
    elif dataset.name == "bunny":
        return Cloud(read_points(data / "stanford_bunny/data/bun000.ply").points, None, None)
    elif dataset.name == "gargoyle":
        return Cloud(read_points(data / "srb_gargoyle_scan/gargoyle.ply").points, None, None)
    elif dataset.name == "sick":
        points = read_sick(data / "3dtk_rotating_sick/scan000.3d")
        return Cloud(points, np.zeros_like(points), None, "sensor at the origin")
    else:
        raise ValueError(f"unknown dataset {dataset.name!r}")
    return Cloud(
        np.array(sample.points),
        None,
        sample.truth,
        coarse_truth=_coarse_truth(sample),
        signed=signed,
    )


def _coarse_truth(sample):
    """The truth mesh with edges of 1/80 of its diagonal: solid in a picture."""
    vertices = sample.truth.vertices
    return sample.truth_mesh(np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0)) / 80)


# --------------------------------------------------------------------------------------
# Measuring
# --------------------------------------------------------------------------------------


SIGNED_SAMPLES = 100_000  # area-uniform samples of a mesh for its signed bias


def measure(vertices, faces, cloud: Cloud) -> dict:
    """Metrics of one mesh: against the truth when there is one, else against the points.

    With a signed distance to the truth, ``signed_bias`` is its mean over
    `SIGNED_SAMPLES` points drawn uniformly by area from the mesh (`sample_surface`): the
    area-weighted mean signed distance from the mesh to the truth, positive outside.
    """
    from zeroset.evaluate import (
        compare_to_points,
        compare_to_reference,
        mesh_quality,
        sample_surface,
    )
    from zeroset.types import Mesh

    mesh = Mesh(vertices=vertices, faces=faces)
    metrics = {"quality": mesh_quality(mesh)}
    if cloud.truth is not None:
        metrics["reference"] = compare_to_reference(mesh, cloud.truth, rng=SEED)
        if cloud.signed is not None:
            samples, _ = sample_surface(mesh, SIGNED_SAMPLES, rng=SEED)
            metrics["signed_bias"] = float(np.mean(cloud.signed(samples)))
    else:
        metrics["points"] = compare_to_points(mesh, cloud.points)
    return metrics


@dataclass
class Row:
    dataset: str
    size: int
    job: str
    status: str  # ok, timeout, failed, skipped, empty
    note: str = ""
    stages: dict = field(default_factory=dict)
    peak_rss_mib: float | None = None
    faces: int | None = None
    params: dict = field(default_factory=dict)
    metrics: dict = field(default_factory=dict)

    @property
    def total(self) -> float:
        return sum(self.stages.values())


def run_cloud(dataset, size, cloud, jobs, limits, timed_out, keep_meshes):
    """Run every job on one cloud; return the rows and, if asked, the meshes."""
    timeout, memory_gib = limits
    rows, meshes, preps = [], {}, {}
    with tempfile.TemporaryDirectory(prefix="bench-peers-") as temporary:
        folder = Path(temporary)
        np.save(folder / "points.npy", cloud.points)
        if cloud.viewpoints is not None:
            np.save(folder / "viewpoints.npy", cloud.viewpoints)
        for job in jobs:
            row = Row(dataset.name, size, job.key, "ok")
            blockers = [timed_out.get(key) for key in (job.key, *job.preps)]
            blocker = next((b for b in blockers if b is not None and size >= b[0]), None)
            if blocker is not None:
                row.status = "skipped"
                row.note = f"timed out on {blocker[1]} at {blocker[0]:,} points"
                rows.append(row)
                print(f"  {job.label:<26} skipped ({row.note})", flush=True)
                continue
            limit, prep_rss, failed = timeout, 0.0, None
            for key in job.preps:
                if key not in preps:
                    preps[key] = spawn(key, folder, limit, memory_gib)
                prep = preps[key]
                if prep["status"] != "ok":
                    failed = key
                    break
                row.stages.update(prep["stages"])
                row.params.update(prep["params"])
                prep_rss = max(prep_rss, prep["peak_rss_mib"])
                limit -= prep["wall_s"]
            if failed is not None:
                prep = preps[failed]
                row.status = prep["status"]
                row.note = f"in {failed}" + (f": {prep['error']}" if "error" in prep else "")
                if prep["status"] == "timeout":
                    timed_out.setdefault(failed, (size, dataset.name))
                rows.append(row)
                print(f"  {job.label:<26} {_status(row, timeout)}", flush=True)
                continue
            report = spawn(job.key, folder, limit, memory_gib)
            if report["status"] != "ok":
                row.status = report["status"]
                row.note = report.get("error", "")
                if row.status == "timeout":
                    timed_out.setdefault(job.key, (size, dataset.name))
                rows.append(row)
                print(f"  {job.label:<26} {_status(row, timeout)}", flush=True)
                continue
            row.stages.update(report["stages"])
            row.params.update(report["params"])
            row.peak_rss_mib = max(prep_rss, report["peak_rss_mib"])
            row.faces = report["faces"]
            with np.load(folder / f"{job.key}.npz") as mesh:
                vertices, faces = mesh["vertices"], mesh["faces"]
            start = time.perf_counter()
            if len(faces) == 0:
                row.status, row.note = "empty", "no faces"
            else:
                try:
                    row.metrics = measure(vertices, faces, cloud)
                except ValueError as error:  # e.g. a mesh of zero area
                    row.status, row.note = "failed", f"evaluation: {error}"
                if keep_meshes:
                    meshes[job.key] = (vertices, faces)
            seconds = time.perf_counter() - start
            rows.append(row)
            print(
                f"  {job.label:<26} {row.status:<7} {row.total:8.2f} s "
                f"{row.peak_rss_mib:7.0f} MiB {row.faces:>9,} faces "
                f"{_headline(row, dataset)} (evaluated in {seconds:.1f} s)",
                flush=True,
            )
    return rows, meshes


def _headline(row: Row, dataset: Dataset) -> str:
    if "reference" in row.metrics:
        reference = row.metrics["reference"]
        bias = row.metrics.get("signed_bias")
        return (
            f"Chamfer-L1 {reference['chamfer_l1'] * 1000:.2f} mm, "
            f"F@0.5% {reference['thresholds'][1]['f_score']:.3f}"
            + ("" if bias is None else f", bias {bias * 1000:+.2f} mm")
        )
    if "points" in row.metrics:
        scale, unit = dataset.unit
        points = row.metrics["points"]
        return f"points->mesh mean {points['distance']['mean'] * scale:.3f} {unit}"
    return ""


# --------------------------------------------------------------------------------------
# Pictures
# --------------------------------------------------------------------------------------


def _display(xyz: np.ndarray, up: str) -> np.ndarray:
    """Coordinates for the picture, the data's up axis as z."""
    if up == "y":
        return np.column_stack([xyz[:, 0], -xyz[:, 2], xyz[:, 1]])
    return xyz


def draw(path: Path, dataset: Dataset, size: int, cloud: Cloud, panels: list) -> None:
    """One PNG: the truth (or the points) and every tool's mesh, same view and scale."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import to_rgb
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection
    from PIL import Image

    rng = np.random.default_rng(SEED)
    points = _display(cloud.points, dataset.up)
    low, high = np.percentile(points, [0.5, 99.5], axis=0)
    pad = 0.05 * (high - low).max()
    low, high = low - pad, high + pad
    elevation, azimuth = np.radians(dataset.view)
    eye = np.array(
        [
            np.cos(elevation) * np.cos(azimuth),
            np.cos(elevation) * np.sin(azimuth),
            np.sin(elevation),
        ]
    )
    light = eye + np.array([0.3, 0.2, 0.6])
    light /= np.linalg.norm(light)

    columns = 3 if len(panels) <= 9 else 4
    rows = math.ceil(len(panels) / columns)
    height = 3.0 * rows + 0.5
    figure = plt.figure(figsize=(3.0 * columns, height), dpi=90)
    figure.suptitle(f"{dataset.title}: {size:,} points", fontsize=10, y=1 - 0.12 / height)
    for index, (title, colour, content) in enumerate(panels):
        axes = figure.add_subplot(rows, columns, index + 1, projection="3d")
        axes.view_init(elev=dataset.view[0], azim=dataset.view[1])
        axes.set_xlim(low[0], high[0])
        axes.set_ylim(low[1], high[1])
        axes.set_zlim(low[2], high[2])
        axes.set_box_aspect(high - low)
        axes.set_axis_off()
        if isinstance(content, str):
            axes.text2D(0.5, 0.5, content, ha="center", va="center", transform=axes.transAxes)
        elif isinstance(content, np.ndarray):  # points
            pick = rng.choice(len(content), min(len(content), 30_000), replace=False)
            shown = _display(content[pick], dataset.up)
            axes.scatter(*shown.T, s=0.05, c=colour, linewidths=0, depthshade=False)
        else:
            vertices, faces = content
            count = len(faces)
            if count > IMAGE_FACES:
                faces = faces[rng.choice(count, IMAGE_FACES, replace=False)]
                title = f"{title}\n({IMAGE_FACES:,} of {count:,} faces)"
            triangles = _display(vertices, dataset.up)[faces]
            normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
            lengths = np.linalg.norm(normals, axis=1)
            normals /= np.where(lengths > 0, lengths, 1.0)[:, None]
            shade = 0.3 + 0.7 * np.abs(normals @ light)
            colours = np.clip(shade[:, None] * np.array(to_rgb(colour)), 0.0, 1.0)
            collection = Poly3DCollection(
                triangles,
                facecolors=colours,
                edgecolors=colours if count > IMAGE_FACES else "none",
                linewidths=0.7 if count > IMAGE_FACES else 0.0,  # fill the gaps of a subset
            )
            axes.add_collection3d(collection)
        axes.set_title(title, fontsize=8)
    figure.subplots_adjust(left=0, right=1, bottom=0, top=1 - 0.75 / height, wspace=0, hspace=0.15)
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png")
    plt.close(figure)
    buffer.seek(0)
    image = Image.open(buffer).convert("RGB")
    image = image.quantize(colors=256, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)
    packed = io.BytesIO()
    image.save(packed, format="PNG", optimize=True)
    write_atomic(path, packed.getvalue())


# --------------------------------------------------------------------------------------
# Report
# --------------------------------------------------------------------------------------


def machine_info() -> dict:
    from bench_phase1 import machine_info as base

    info = base()
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no", "src"],
            cwd=ROOT,
            capture_output=True,
            text=True,
        ).stdout.strip()
        info["commit"] = (commit or "unknown") + (
            " with uncommitted changes in src/" if dirty else ""
        )
    except OSError:
        info["commit"] = "unknown"
    for package in ("open3d", "pymeshlab", "pypoisson2", "vtk", "matplotlib"):
        try:
            info[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            info[package] = "not installed"
    return info


def _label(key: str) -> str:
    return next(job.label for job in JOBS if job.key == key)


def _fmt(value, digits=2) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def _best(rows: list[Row], value, smaller: bool | None = True):
    """The best value of a column: the smallest, the largest, or (`smaller` None) nearest 0."""
    values = [value(row) for row in rows if row.status == "ok"]
    values = [v for v in values if v is not None]
    if not values:
        return None
    if smaller is None:
        return min(abs(v) for v in values)
    return min(values) if smaller else max(values)


def _bold(text: str, value, best, smaller: bool | None = True) -> str:
    if value is not None and smaller is None:
        value = abs(value)
    return f"**{text}**" if best is not None and value is not None and value == best else text


def _reference_table(rows: list[Row], timeout: float) -> list[str]:
    def ref(row):
        return row.metrics.get("reference", {})

    def quality(row):
        return row.metrics.get("quality", {})

    columns = {
        "total s": (lambda r: r.total, True, 2, 1.0),
        "peak MiB": (lambda r: r.peak_rss_mib, True, 0, 1.0),
        "accuracy mm": (lambda r: ref(r).get("accuracy", {}).get("mean"), True, 2, 1000.0),
        "completeness mm": (lambda r: ref(r).get("completeness", {}).get("mean"), True, 2, 1000),
        "Chamfer-L1 mm": (lambda r: ref(r).get("chamfer_l1"), True, 2, 1000.0),
        "signed bias mm": (lambda r: r.metrics.get("signed_bias"), None, 2, 1000.0),
        "Hausdorff mm": (lambda r: ref(r).get("hausdorff"), True, 1, 1000.0),
        "F@1%": (lambda r: _f_score(r, 0), False, 3, 1.0),
        "F@0.5%": (lambda r: _f_score(r, 1), False, 3, 1.0),
        "normal consistency": (lambda r: ref(r).get("normal_consistency"), False, 3, 1.0),
    }
    header = (
        "| tool | total s | peak MiB | faces | components | boundary loops | non-manifold "
        "edges | non-manifold vertices | accuracy mm | completeness mm | Chamfer-L1 mm | "
        "signed bias mm | Hausdorff mm | F@1% | F@0.5% | normal consistency |"
    )
    out = [header, "|---" + "|---:" * 15 + "|"]
    best = {name: _best(rows, spec[0], spec[1]) for name, spec in columns.items()}
    for row in rows:
        if row.status != "ok":
            out.append(f"| {_label(row.job)} | {_status(row, timeout)} |" + " - |" * 14)
            continue
        q = quality(row)
        cells = {}
        for name, (value, smaller, digits, scale) in columns.items():
            v = value(row)
            text = _fmt(None if v is None else v * scale, digits)
            if name == "signed bias mm" and v is not None:
                text = f"{v * scale:+.{digits}f}"
            cells[name] = _bold(text, v, best[name], smaller)
        out.append(
            f"| {_label(row.job)} | {cells['total s']} | {cells['peak MiB']} | {row.faces:,} | "
            f"{q['components']:,} | {q['boundary_loops']:,} | {q['non_manifold_edges']:,} | "
            f"{q['non_manifold_vertices']:,} | {cells['accuracy mm']} | "
            f"{cells['completeness mm']} | {cells['Chamfer-L1 mm']} | {cells['signed bias mm']} "
            f"| {cells['Hausdorff mm']} | {cells['F@1%']} | {cells['F@0.5%']} "
            f"| {cells['normal consistency']} |"
        )
    return out


def _f_score(row: Row, index: int):
    thresholds = row.metrics.get("reference", {}).get("thresholds")
    return thresholds[index]["f_score"] if thresholds else None


def _points_table(rows: list[Row], dataset: Dataset, timeout: float) -> list[str]:
    scale, unit = dataset.unit

    def dist(row, key):
        return row.metrics.get("points", {}).get("distance", {}).get(key)

    columns = {
        "total s": (lambda r: r.total, True, 2, 1.0),
        "peak MiB": (lambda r: r.peak_rss_mib, True, 0, 1.0),
        "mean": (lambda r: dist(r, "mean"), True, 3, scale),
        "median": (lambda r: dist(r, "median"), True, 3, scale),
        "p95": (lambda r: dist(r, "p95"), True, 3, scale),
        "coverage": (lambda r: r.metrics.get("points", {}).get("coverage"), False, 3, 1.0),
    }
    out = [
        "| tool | total s | peak MiB | faces | components | boundary loops | non-manifold "
        f"edges | non-manifold vertices | points to mesh, mean {unit} | median {unit} | "
        f"p95 {unit} | coverage@1% |",
        "|---" + "|---:" * 11 + "|",
    ]
    best = {name: _best(rows, spec[0], spec[1]) for name, spec in columns.items()}
    for row in rows:
        if row.status != "ok":
            out.append(f"| {_label(row.job)} | {_status(row, timeout)} |" + " - |" * 10)
            continue
        q = row.metrics["quality"]
        cells = {}
        for name, (value, _, digits, factor) in columns.items():
            v = value(row)
            cells[name] = _bold(_fmt(None if v is None else v * factor, digits), v, best[name])
        out.append(
            f"| {_label(row.job)} | {cells['total s']} | {cells['peak MiB']} | {row.faces:,} | "
            f"{q['components']:,} | {q['boundary_loops']:,} | {q['non_manifold_edges']:,} | "
            f"{q['non_manifold_vertices']:,} | {cells['mean']} | {cells['median']} | "
            f"{cells['p95']} | {cells['coverage']} |"
        )
    return out


def _status(row: Row, timeout: float) -> str:
    if row.status == "timeout":
        return f"**timeout** (> {timeout:.0f} s" + (f", {row.note}" if row.note else "") + ")"
    return f"**{row.status}**" + (f": {row.note}" if row.note else "")


def _stage_lines(rows: list[Row]) -> list[str]:
    out = ["<details><summary>Seconds per stage, and the chosen scales</summary>", ""]
    for row in rows:
        if row.status != "ok":
            continue
        stages = ", ".join(f"{name} {seconds:.2f}" for name, seconds in row.stages.items())
        params = ", ".join(
            f"{name} {_param(value)}" for name, value in row.params.items() if name != "grid"
        )
        if "grid" in row.params:
            params += ", grid " + " x ".join(str(v) for v in row.params["grid"])
        out.append(
            f"- {_label(row.job)}: {stages}; total {row.total:.2f}"
            + (f" ({params})" if params else "")
        )
    return out + ["", "</details>"]


def _param(value) -> str:
    if isinstance(value, list):
        return "[" + ", ".join(_param(v) for v in value) + "]"
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def _glance(rows: list[Row], sizes: dict, truths: dict) -> list[str]:
    """Per synthetic dataset and size: zeroset against the best peer."""
    out = [
        "| dataset | points | zeroset s | fastest peer s | zeroset Chamfer-L1 mm | best peer "
        "Chamfer-L1 mm | best PoissonRecon (oracle) Chamfer-L1 mm | zeroset F@0.5% | best "
        "peer F@0.5% | zeroset components / loops (truth) |",
        "|---|---:|---:|---|---:|---|---|---:|---|---|",
    ]
    for dataset in DATASETS:
        if not dataset.synthetic:
            continue
        for size in sizes.get(dataset.name, []):
            group = [r for r in rows if r.dataset == dataset.name and r.size == size]
            mine = next((r for r in group if r.job == "zeroset" and r.status == "ok"), None)
            peers = [r for r in group if r.status == "ok" and not r.job.startswith("zeroset")]
            if mine is None:
                continue
            fastest = min(peers, key=lambda r: r.total, default=None)
            closest = min(peers, key=lambda r: r.metrics["reference"]["chamfer_l1"], default=None)
            oracle = min(
                (r for r in peers if r.job in POISSONRECON_ROWS),
                key=lambda r: r.metrics["reference"]["chamfer_l1"],
                default=None,
            )
            sharpest = max(peers, key=lambda r: _f_score(r, 1), default=None)
            truth = truths.get(f"{dataset.name}/{size}", {})
            q = mine.metrics["quality"]
            out.append(
                f"| {dataset.name} | {size:,} | {mine.total:.2f} | "
                + (f"{fastest.total:.2f} ({_label(fastest.job)})" if fastest else "-")
                + f" | {mine.metrics['reference']['chamfer_l1'] * 1000:.2f} | "
                + (
                    f"{closest.metrics['reference']['chamfer_l1'] * 1000:.2f} "
                    f"({_label(closest.job)})"
                    if closest
                    else "-"
                )
                + " | "
                + (
                    f"{oracle.metrics['reference']['chamfer_l1'] * 1000:.2f} "
                    f"({_label(oracle.job).removeprefix('PoissonRecon ')})"
                    if oracle
                    else "-"
                )
                + f" | {_f_score(mine, 1):.3f} | "
                + (f"{_f_score(sharpest, 1):.3f} ({_label(sharpest.job)})" if sharpest else "-")
                + f" | {q['components']} / {q['boundary_loops']} "
                f"({truth.get('components', '?')} / {truth.get('boundary_loops', '?')}) |"
            )
    return out


def old_summary(path: Path) -> str | None:
    """The hand-written summary kept between the summary markers, if the file has one."""
    if not path.exists():
        return None
    text = path.read_text(encoding="utf-8")
    begin, end = markers(SUMMARY)
    if begin not in text or end not in text:
        return None
    return text[text.index(begin) + len(begin) : text.index(end)].strip()


def render(results: dict, summary: str | None) -> str:
    """The Markdown text of the peers section."""
    rows, sizes, notes = results["rows"], results["sizes"], results["notes"]
    machine, timeout, images = results["machine"], results["timeout"], results["images"]
    command = results["command"]
    begin, end = markers(SUMMARY)
    out = [
        "## Peers: zeroset against Open3D, PyMeshLab, PoissonRecon and VTK",
        "",
        "zeroset with its defaults against the tools a user would otherwise pick, on the same "
        "clouds: synthetic pipes, a sphere and a torus with an exact truth mesh, and real "
        "scans without one.",
        "",
        "```",
        command,
        "```",
        "",
        *machine_lines(
            machine,
            f", Open3D {machine['open3d']}, PyMeshLab {machine['pymeshlab']}, pypoisson2 "
            f"{machine.get('pypoisson2', 'not installed')} (PoissonRecon 18.74), "
            f"VTK {machine['vtk']}",
        ),
        f"- zeroset source: commit {machine.get('commit', 'unknown')}",
        "",
        "### Summary",
        "",
        begin,
        summary or "_No summary yet: write one here from the tables below; re-runs keep it._",
        end,
        "",
        "### Tools and settings",
        "",
        "Every tool runs with its defaults except for the scales, which come from the mean "
        "nearest-neighbour spacing *s* of the cloud, as a user would set them.",
        "",
        "| row | calls | settings |",
        "|---|---|---|",
        "| zeroset | `zeroset.reconstruct(points)` | defaults: every parameter estimated |",
        "| zeroset, viewpoints | `zeroset.reconstruct(points, viewpoints=...)` | normals "
        "oriented towards each point's sensor (scan and sick only) |",
        "| Open3D Poisson d8, d9 | `estimate_normals`, "
        "`orient_normals_consistent_tangent_plane`, `create_from_point_cloud_poisson`, "
        "`remove_vertices_by_mask` | `KDTreeSearchParamHybrid(radius="
        f"{OPEN3D_NORMAL_RADIUS:g} s, max_nn={OPEN3D_MAX_NN})`, k = {OPEN3D_ORIENT_K}, "
        f"depth 8 or 9, vertices below the {OPEN3D_DENSITY_QUANTILE:.0%} density quantile "
        "removed |",
        "| Open3D ball pivoting | the same normals, `create_from_point_cloud_ball_pivoting` | "
        "radii " + ", ".join(f"{f:g}" for f in OPEN3D_BPA_RADII) + " x s |",
        "| PyMeshLab Poisson d8 | `compute_normal_for_point_clouds`, "
        "`generate_surface_reconstruction_screened_poisson` | "
        f"k = {PYMESHLAB_NORMAL_K}, depth {PYMESHLAB_DEPTH}, no trimming |",
        "| PyMeshLab ball pivoting | the same normals, "
        "`generate_surface_reconstruction_ball_pivoting` | MeshLab's automatic radius |",
        "| PoissonRecon d8, d9 t5, t6, t7 | Open3D's normals (above), pypoisson2's "
        "`poisson_reconstruction(..., output_density=True)`, then SurfaceTrimmer's `--trim` "
        "(in NumPy, `surface_trim`) | depth "
        + " or ".join(map(str, POISSONRECON_DEPTHS))
        + f", point weight {POISSONRECON_POINT_WEIGHT:g} (the executable's default), other "
        "defaults; trim "
        + ", ".join(map(str, POISSONRECON_TRIMS))
        + f", `--aRatio {POISSONRECON_ISLAND_RATIO:g}`: the author's recipe for open scans |",
        "| VTK Hoppe | `vtkSurfaceReconstructionFilter`, `vtkContourFilter` at 0 | "
        f"{VTK_NEIGHBOURS} neighbours, sample spacing {VTK_SAMPLE_SPACING:g} s |",
        "",
        "### Method",
        "",
        f"- Each tool runs in a fresh child process under a {timeout:.0f} s wall-clock limit "
        "(killed and reported as a timeout past it) and a "
        f"{results.get('memory_gib', DEFAULT_MEMORY_GIB):g} GiB data-segment limit "
        "(`RLIMIT_DATA`: an allocation past it fails, reported as *failed*). Open3D's and "
        "PyMeshLab's rows share one normal estimation per cloud, run once in its own "
        "child: their times add its stages "
        "and the limit covers both children; their peak RSS is the larger of the two "
        "processes'.",
        "- A tool that timed out at some size is not run again at that size or larger, on "
        "that dataset or a later one (marked *skipped*); this keeps the run under an hour.",
        "- *total s* is the sum of the timed stages (each a `time.perf_counter()` interval "
        "inside the child): the work from points to mesh. Interpreter start, imports, "
        "reading the points and writing the mesh are excluded. zeroset reconstructs a "
        f"{WARMUP_POINTS:,}-point pipe first, so Numba JIT compilation is excluded.",
        "- *peak MiB* is the child's peak resident set size (interpreter, library, cloud "
        "and result): `VmHWM` from `/proc/self/status`. Not `ru_maxrss`, which on Linux "
        "keeps the parent's resident size from before the `exec`, and the parent holds the "
        "truth meshes and the evaluation.",
        "- Threads: zeroset (Numba), Open3D and PyMeshLab's Poisson use both cores; VTK's "
        "filter and both ball-pivoting implementations run on one.",
        "- Metrics (`zeroset.evaluate`): against the truth mesh, `compare_to_reference` with "
        "100,000 samples per surface; *accuracy* is the mean distance from the mesh to the "
        "truth, *completeness* from the truth to the mesh, *Chamfer-L1* their mean, "
        "*Hausdorff* the largest sampled distance; F-scores at 1 % and 0.5 % of the truth's "
        "bounding-box diagonal; *normal consistency* the mean |cos| between matched faces. "
        "`mesh_quality` gives components, boundary loops and non-manifold edges and vertices. "
        "Real scans have no truth: `compare_to_points` gives the distance from every scan "
        "point to the mesh and the share within 1 % of the diagonal (*coverage*).",
        "- *signed bias* is the mean signed distance from the mesh to the truth over "
        f"{SIGNED_SAMPLES:,} points drawn uniformly by area from the mesh, positive outside: "
        "exact for the sphere and torus; for the pipe and scan the radial error (distance "
        "from the axis minus the radius, also past the ends, so a closed pipe's caps pull it "
        "down); none for the elbow and tee. Bold marks the one nearest zero.",
        "- The truth pipes are open. Poisson closes every surface, which shows as poor "
        "accuracy and a large Hausdorff distance: a closed pipe is the wrong answer here. "
        "PoissonRecon's author trims open scans by the sampling density written with each "
        "vertex (`--density`, then `SurfaceTrimmer --trim T`): the density is an octree "
        "depth, about 0.5 x log2 of the local samples per node, so a trim value that suits "
        "one size removes everything at a smaller one.",
        "- pypoisson2 1.0.0 returns a density of 1 for every vertex (its wrapper never asks "
        "PoissonRecon's extractor for densities), so the script recomputes PoissonRecon "
        "18.74's density estimator in NumPy (`poissonrecon_density`, outside the timed "
        "stages) and trims with it.",
        "- *best PoissonRecon (oracle)* is the PoissonRecon row with the lowest Chamfer-L1 "
        "at that size: a depth and trim picked with the truth, which a user cannot do.",
        "- Bold marks the best value of a column among the rows that ran.",
        "",
        "### At a glance",
        "",
    ]
    out += _glance(rows, sizes, results["truths"])
    for dataset in DATASETS:
        if dataset.name not in sizes:
            continue
        out += ["", f"### {dataset.title} (`{dataset.name}`)", "", dataset.description, ""]
        if dataset.name in images:
            out += [f"![{dataset.title}]({images[dataset.name]})", ""]
        for size in sizes[dataset.name]:
            group = [r for r in rows if r.dataset == dataset.name and r.size == size]
            note = notes.get(f"{dataset.name}/{size}", "")
            heading = f"#### {size:,} points" + (f" ({note})" if note else "")
            out += [heading, ""]
            if dataset.synthetic:
                out += _reference_table(group, timeout)
            else:
                out += _points_table(group, dataset, timeout)
            out += [""] + _stage_lines(group) + [""]
    return "\n".join(out).rstrip() + "\n"


# --------------------------------------------------------------------------------------
# Main
# --------------------------------------------------------------------------------------


def _picture(dataset: Dataset, cloud: Cloud, rows: list[Row], meshes: dict, folder: Path):
    """Draw the picture of one dataset; return its path."""
    if cloud.coarse_truth is not None:
        truth = cloud.coarse_truth
        panels = [("truth (coarse)", COLOURS["truth"], (truth.vertices, truth.faces))]
    else:
        panels = [("points", "#505050", cloud.points)]
    for row in rows:
        job = next(job for job in JOBS if job.key == row.job)
        content = meshes.get(row.job)
        if content is None:
            content = row.status if row.status != "failed" else "failed"
        panels.append((job.label, COLOURS[job.library], content))
    path = folder / f"peers-{dataset.name}.png"
    draw(path, dataset, len(cloud.points), cloud, panels)
    return path


def merge_results(saved: list[dict]) -> dict:
    """One set of results from several runs' ``--json``: later rows replace earlier ones with
    the same dataset, size and job; sizes, notes, truths and pictures are joined."""
    merged = saved[0]
    for extra in saved[1:]:
        keys = {(row["dataset"], row["size"], row["job"]) for row in extra["rows"]}
        merged["rows"] = [
            row for row in merged["rows"] if (row["dataset"], row["size"], row["job"]) not in keys
        ] + extra["rows"]
        for dataset, sizes in extra["sizes"].items():
            merged["sizes"][dataset] = sorted(set(merged["sizes"].get(dataset, [])) | set(sizes))
        for name in ("notes", "truths", "images"):
            merged[name] = {**extra.get(name, {}), **merged.get(name, {})}
    return merged


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--datasets", nargs="+", choices=DATASET_NAMES, default=DATASET_NAMES)
    parser.add_argument("--sizes", type=int, nargs="+", default=list(DEFAULT_SIZES))
    parser.add_argument("--tools", nargs="+", choices=JOB_KEYS, default=JOB_KEYS)
    parser.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT, help="seconds per tool")
    parser.add_argument(
        "--memory", type=float, default=DEFAULT_MEMORY_GIB, help="GiB per tool (RLIMIT_DATA)"
    )
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA, help="real scans folder")
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT)
    parser.add_argument("--images", type=Path, default=DEFAULT_IMAGES, help="PNG folder")
    parser.add_argument("--json", type=Path, default=None, help="also save the raw results here")
    parser.add_argument(
        "--from-json",
        type=Path,
        nargs="+",
        default=None,
        help="only rewrite the report from saved results; rows of later files replace those "
        "of earlier ones for the same dataset, size and tool",
    )
    parser.add_argument("--child", nargs=2, metavar=("JOB", "FOLDER"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)

    if args.child is not None:
        key, folder = args.child
        print(json.dumps(run_child(key, Path(folder), args.memory)), flush=True)
        return 0

    if args.from_json is not None:
        results = merge_results(
            [json.loads(path.read_text(encoding="utf-8")) for path in args.from_json]
        )
        results["rows"] = [Row(**row) for row in results["rows"]]
        replace_section(args.output, "peers", render(results, old_summary(args.output)))
        print(f"wrote {args.output}")
        return 0

    if any(n < 1 for n in args.sizes) or args.timeout <= 0:
        parser.error("--sizes and --timeout must be positive")
    sizes_asked = sorted(set(args.sizes))
    jobs = [job for job in JOBS if job.key in args.tools]
    command = "python benchmarks/bench_peers.py " + " ".join(
        ["--datasets", *args.datasets, "--sizes", *map(str, sizes_asked)]
        + ["--timeout", f"{args.timeout:g}", "--memory", f"{args.memory:g}"]
    )
    results = {
        "rows": [],
        "sizes": {},  # dataset -> sizes run (the point count for real scans)
        "notes": {},  # "dataset/size" -> how the cloud was made
        "truths": {},  # "dataset/size" -> components and boundary loops of the truth
        "images": {},  # dataset -> picture path relative to the report
        "machine": machine_info(),
        "command": command,
        "timeout": args.timeout,
        "memory_gib": args.memory,
    }
    timed_out: dict[str, tuple[int, str]] = {}
    started = time.perf_counter()
    for dataset in DATASETS:
        if dataset.name not in args.datasets:
            continue
        if not dataset.synthetic and not args.data.is_dir():
            print(f"{dataset.name}: skipped, no data folder {args.data}", flush=True)
            continue
        if dataset.synthetic:
            limit = dataset.max_size or max(sizes_asked)
            dataset_sizes = [n for n in sizes_asked if n <= limit] or [min(sizes_asked)]
            picture_size = max([n for n in dataset_sizes if n <= IMAGE_SIZE] or dataset_sizes)
        else:
            dataset_sizes, picture_size = [None], None
        for size in dataset_sizes:
            cloud = load(dataset, size, args.data)
            picture = size == picture_size
            size = size or len(cloud.points)
            key = f"{dataset.name}/{size}"
            results["sizes"].setdefault(dataset.name, []).append(size)
            if dataset.name == "scan":
                results["notes"][key] = f"{len(cloud.points):,} points, {cloud.note}"
            elif cloud.note:
                results["notes"][key] = cloud.note
            if cloud.truth is not None:
                from zeroset.evaluate import mesh_quality

                quality = mesh_quality(cloud.truth)
                results["truths"][key] = {
                    name: quality[name] for name in ("faces", "components", "boundary_loops")
                }
            elapsed = time.perf_counter() - started
            print(f"{dataset.name}: {len(cloud.points):,} points [{elapsed:.0f} s]", flush=True)
            wanted = [job for job in jobs if not job.viewpoints or cloud.viewpoints is not None]
            rows, meshes = run_cloud(
                dataset,
                size,
                cloud,
                wanted,
                (args.timeout, args.memory),
                timed_out,
                keep_meshes=picture,
            )
            results["rows"] += rows
            if picture:
                start = time.perf_counter()
                path = _picture(dataset, cloud, rows, meshes, args.images)
                results["images"][dataset.name] = os.path.relpath(path, args.output.parent)
                print(
                    f"  picture {path} ({path.stat().st_size / 1024:.0f} KiB, "
                    f"{time.perf_counter() - start:.0f} s)",
                    flush=True,
                )
            del meshes, cloud
            if args.json is not None:
                saved = {**results, "rows": [row.__dict__ for row in results["rows"]]}
                write_atomic(args.json, json.dumps(saved, indent=1))
    replace_section(args.output, "peers", render(results, old_summary(args.output)))
    print(f"wrote {args.output} [{time.perf_counter() - started:.0f} s]")
    return 0


if __name__ == "__main__":
    sys.exit(main())

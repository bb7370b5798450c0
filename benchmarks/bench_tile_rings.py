"""The rings of faces a tile refines around its own: with how many the tiles give the
untiled mesh.

Run by hand from the repository root (needs the ``tiles`` extra; about six minutes on
2 cores)::

    python benchmarks/bench_tile_rings.py

Eight tiled runs (the clouds and grids of the tiles' equality test: a torus, a T-junction,
a wavy sheet, a sparse in-pipe scan; and `bench_tiles`' pipe rack at 64,000 points), dense
meshes (tolerance 0), on a local cluster of two single-threaded workers, with
``zeroset.tiles.REFINE_RINGS`` set to 0-3 in turn (the client cuts the parts, so setting it
there is enough). For each: how many runs
give the untiled mesh (vertices within 1e-9, the same faces), and the largest distance
between two tiles' copies of a vertex, in cubes. The section between
``<!-- tile-rings:begin -->`` and ``<!-- tile-rings:end -->`` of docs/benchmarks.md is
replaced.
"""

from __future__ import annotations

import warnings

import numpy as np
from _docfile import replace_section
from bench_phase1 import DEFAULT_OUTPUT, machine_info, reproduce_lines
from bench_tiles import pipe_rack
from scipy.spatial import cKDTree

import zeroset.tiles
from zeroset import reconstruct
from zeroset.synthetic import sample_tee, sample_torus, scan_pipe

RINGS = (0, 1, 2, 3)


def wavy_sheet(n: int, seed: int) -> np.ndarray:
    """z = 0.15 sin 3x cos 2y over [-1, 1]^2 with 3 mm noise (its tiles must be flipped)."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-1.0, 1.0, (n, 2))
    z = 0.15 * np.sin(3 * xy[:, 0]) * np.cos(2 * xy[:, 1]) + rng.normal(0.0, 0.003, n)
    return np.column_stack([xy, z])


def cases() -> list:
    """(name, points, tiles) of the eight runs."""
    torus = sample_torus(30_000, noise=0.005, rng=3).points
    tee = sample_tee(40_000, rng=4).points
    scan = scan_pipe(radius=0.35, rotation_step=4.0, offset=0.05, rng=5).points
    return [
        ("torus", torus, (3, 3, 3)),
        ("torus", torus, (2, 2, 2)),
        ("tee", tee, (3, 3, 3)),
        ("tee", tee, (2, 2, 2)),
        ("sheet", wavy_sheet(40_000, 1), (4, 4, 1)),
        ("sparse scan", scan, (2, 2, 2)),
        ("sparse scan", scan, (3, 3, 3)),
        ("rack", pipe_rack(64_000, seed=2), (3, 3, 1)),
    ]


def same_mesh(mesh, expected) -> bool:
    """Whether the vertices match one to one within 1e-9 and the oriented faces agree."""
    if (mesh.n_vertices, mesh.n_faces) != (expected.n_vertices, expected.n_faces):
        return False
    distance, match = cKDTree(expected.vertices).query(mesh.vertices)
    if distance.max(initial=0.0) > 1e-9 or np.unique(match).size != mesh.n_vertices:
        return False
    return rows(match[mesh.faces]).tolist() == rows(expected.faces).tolist()


def rows(faces: np.ndarray) -> np.ndarray:
    """Each face from its least vertex, orientation kept, the rows sorted."""
    turn = np.argmin(faces, axis=1)
    faces = np.take_along_axis(faces, (turn[:, None] + np.arange(3)) % 3, axis=1)
    return faces[np.lexsort(faces.T[::-1])]


def main() -> None:
    import distributed

    warnings.simplefilter("ignore")
    runs = cases()
    untiled = [reconstruct(points, tolerance=0.0).mesh for _, points, _ in runs]
    lines = []
    with (
        distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        for rings in RINGS:
            zeroset.tiles.REFINE_RINGS = rings
            same, gap, differ = 0, 0.0, []
            for (name, points, tiles), whole in zip(runs, untiled, strict=True):
                tiled = zeroset.tiles.reconstruct_tiled(
                    points, tiles=tiles, client=client, tolerance=0.0
                )
                gap = max(gap, tiled.stats["seam_vertex_gap"] / tiled.parameters.cube_size)
                if same_mesh(tiled.mesh, whole):
                    same += 1
                else:
                    differ.append(f"{name} {'x'.join(map(str, tiles))}")
            lines.append(
                f"| {rings} | {same} of {len(runs)} | {gap:.1e} | {', '.join(differ) or '-'} |"
            )
            print(lines[-1], flush=True)
    text = "\n".join(
        [
            "## Refinement rings in tiles",
            "",
            "Each tile refines its own faces with rings of faces around them (`REFINE_RINGS`,",
            "3): a vertex's projection is held back where one of its faces turns over, which",
            "depends on its neighbours. Eight tiled dense meshes against the untiled ones",
            "(the tiles' equality test's clouds and grids; `bench_tiles`' rack at 64k points):",
            "",
            "| rings | the untiled mesh | largest seam gap (cubes) | differ |",
            "|---|---|---|---|",
            *lines,
            "",
            *reproduce_lines("python benchmarks/bench_tile_rings.py", machine_info()),
        ]
    )
    replace_section(DEFAULT_OUTPUT, "tile-rings", text)


if __name__ == "__main__":
    main()

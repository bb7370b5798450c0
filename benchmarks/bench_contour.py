"""Compare zeroset's sparse-band marching cubes with scikit-image's dense one on the same field.

Run by hand: ``python benchmarks/bench_contour.py [--points 1000000]`` (needs the ``bench``
extra for scikit-image). scikit-image needs a dense volume over the band's bounding box;
undefined values are masked out with its ``mask`` argument.
"""

import argparse
import time

import numpy as np

from zeroset import reconstruct
from zeroset.contour import marching_cubes
from zeroset.synthetic import sample_cylinder


def _median_seconds(function, repeat):
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        result = function()
        times.append(time.perf_counter() - start)
    return float(np.median(times)), result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--length", type=float, default=1.0, help="pipe length in metres")
    parser.add_argument("--tilt", action="store_true", help="lay the pipe along the diagonal")
    args = parser.parse_args()
    from skimage.measure import marching_cubes as skimage_marching_cubes

    points = sample_cylinder(args.points, length=args.length, noise=0.002, rng=0).points
    if args.tilt:
        axis = np.array([1.0, 1.0, 1.0]) / np.sqrt(3.0)
        rotation, _ = np.linalg.qr(np.c_[axis, [1.0, -1.0, 0.0], [0.0, 1.0, -1.0]])
        points = points @ np.c_[rotation[:, 1:], rotation[:, 0]].T
    field = reconstruct(points).field
    ours_s, mesh = _median_seconds(lambda: marching_cubes(field), args.repeat)

    def dense():
        lo = field.vertices_ijk.min(axis=0)
        shape = tuple(field.vertices_ijk.max(axis=0) - lo + 1)
        volume = np.full(shape, 1.0)
        mask = np.zeros(shape, bool)
        idx = tuple((field.vertices_ijk - lo).T)
        defined = ~np.isnan(field.values)
        volume[tuple(i[defined] for i in idx)] = field.values[defined]
        mask[tuple(i[defined] for i in idx)] = True
        return skimage_marching_cubes(volume, 0.0, mask=mask), volume.size

    dense_s, ((verts, faces, _, _), cells) = _median_seconds(dense, args.repeat)
    shape = "diagonal " if args.tilt else ""
    print(f"{args.length} m {shape}pipe, {args.points:,} points")
    print(f"band vertices {field.values.size:,}; dense volume {cells:,}")
    print(f"zeroset sparse band : {ours_s:.3f} s, {mesh.n_faces:,} faces")
    print(f"skimage dense+mask  : {dense_s:.3f} s, {len(faces):,} faces")


if __name__ == "__main__":
    main()

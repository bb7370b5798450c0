"""A tiled mesh written as one mesh per tile and a manifest, and read back whole.

Each face goes to the tile that owns the lattice cube holding its centroid (`face_tiles`),
the cubes being the plan's (`zeroset.tiles.plan_tiles`: every cube belongs to exactly one
tile). A tile's file holds its faces and the vertices they use; a vertex on a seam is
written by every tile that uses it, with the same coordinates. The manifest
(``MANIFEST``, JSON) names each tile's file with its place in the grid, the box it owns
and the box of its vertices, and each seam: the two tiles and the vertices they share.
Tools that stream meshes can load it piece by piece; `read_tile_meshes` welds the pieces
back into the one mesh, checking every seam against the manifest.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from . import io
from ._lattice import LIMIT
from ._unique import distinct
from .errors import InputError
from .types import Mesh

__all__ = [
    "FORMAT",
    "MANIFEST",
    "check_folder",
    "cut",
    "face_tiles",
    "point_tiles",
    "read_tile_meshes",
    "weld",
    "weld_coincident",
    "write_tile_meshes",
]

#: The manifest's file name in the output folder.
MANIFEST = "tiles.json"
#: The manifest's ``format``: what it holds, and the version of its layout.
FORMAT = "zeroset tiled mesh 1"


def face_tiles(mesh: Mesh, tiles, offset, cube_size: float) -> np.ndarray:
    """(F,) int64 the position in `tiles` (a plan of `zeroset.tiles.Tile`) of the tile that
    owns the cube holding each face's centroid; `mesh` in input coordinates, the lattice
    of cubes of `cube_size` from `offset` (3,)."""
    return point_tiles(mesh.vertices[mesh.faces].mean(axis=1), tiles, offset, cube_size)


def point_tiles(points: np.ndarray, tiles, offset, cube_size: float) -> np.ndarray:
    """(N,) int64 the position in `tiles` of the tile that owns the cube holding each point
    (N, 3), as `face_tiles`."""
    cubes = np.floor((np.reshape(points, (-1, 3)) - offset) / cube_size).astype(np.int64)
    # The tiles form a grid: per axis, the first cube of each of its slices.
    place = np.zeros((cubes.shape[0], 3), dtype=np.int64)
    for axis in range(3):
        starts = np.unique([tile.owned[0][axis] for tile in tiles])
        place[:, axis] = np.searchsorted(starts, cubes[:, axis], side="right") - 1
    grid = 1 + np.max([tile.index for tile in tiles], axis=0)
    position = np.full(int(np.prod(grid)), -1, dtype=np.int64)
    position[np.ravel_multi_index(np.array([t.index for t in tiles]).T, grid)] = np.arange(
        len(tiles)
    )
    return position[np.ravel_multi_index(place.T, grid)]


def check_folder(folder) -> Path:
    """`folder` as a Path, once it is known that `write_tile_meshes` can write into it (it
    is a folder or missing, and its parent exists); InputError naming it otherwise."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise InputError(f"{folder}: is a file; per-tile output goes to a folder")
    if not folder.parent.is_dir():
        raise InputError(f"{folder}: directory {folder.parent} does not exist")
    return folder


def write_tile_meshes(folder, mesh: Mesh, tiles, offset, cube_size: float, *, binary=True) -> Path:
    """Write `mesh` as one PLY file per tile of `tiles` that holds a face, then the
    manifest (`MANIFEST`), into `folder`, which is created if missing (its parent must
    exist). Every file is written atomically, the manifest last: a folder without one
    holds no complete output. Returns the manifest's path.

    `mesh` in input coordinates; `tiles`, `offset` (3,) and `cube_size` the plan it was
    reconstructed with (`zeroset.tiles.TiledReconstruction`).
    """
    folder = check_folder(folder)
    folder.mkdir(exist_ok=True)
    entries, users = [], []
    pieces = cut(mesh, face_tiles(mesh, tiles, offset, cube_size), len(tiles))
    for position, (tile, (piece, used)) in enumerate(zip(tiles, pieces, strict=True)):
        entry = {"index": list(tile.index), "owned": _owned_box(tile, offset, cube_size)}
        if piece is None:
            entries.append(entry | {"file": None, "vertices": 0, "faces": 0, "bounds": None})
            continue
        name = "tile-{}-{}-{}.ply".format(*tile.index)
        io.write_mesh(folder / name, piece, binary=binary)
        bounds = np.r_[piece.vertices.min(axis=0), piece.vertices.max(axis=0)]
        sizes = {"vertices": piece.n_vertices, "faces": piece.n_faces}
        entries.append(entry | {"file": name, **sizes, "bounds": bounds.tolist()})
        users.append(np.column_stack([used, np.full(used.size, position)]))
    manifest = {
        "format": FORMAT,
        "grid": (1 + np.max([t.index for t in tiles], axis=0)).tolist(),
        "vertices": int(mesh.n_vertices),
        "faces": int(mesh.n_faces),
        "tiles": entries,
        "seams": _seams(np.concatenate(users) if users else np.zeros((0, 2), np.int64)),
    }
    return io.write_json(folder / MANIFEST, manifest)


def read_tile_meshes(path) -> Mesh:
    """The mesh of a folder that `write_tile_meshes` wrote (or of its manifest), its
    pieces welded where they share vertices (same coordinates), in manifest order.

    Raises
    ------
    InputError
        If the manifest is missing or not one, a tile's file is missing or unreadable, or
        the welded mesh's vertices, faces or seams differ from what the manifest states.
        The message starts with the manifest's path.
    """
    path = Path(path)
    manifest_path = path / MANIFEST if path.is_dir() else path
    try:
        manifest = json.loads(manifest_path.read_text())
    except OSError as error:
        raise InputError(f"{manifest_path}: cannot read ({error.strerror or error})") from error
    except json.JSONDecodeError as error:
        raise InputError(f"{manifest_path}: not JSON ({error})") from error
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT:
        raise InputError(f"{manifest_path}: not a manifest of a tiled mesh ({FORMAT!r})")
    try:
        files = [entry["file"] for entry in manifest["tiles"]]
        stated = (manifest["vertices"], manifest["faces"], manifest["seams"])
    except (KeyError, TypeError) as error:
        raise InputError(f"{manifest_path}: a malformed manifest ({error!r})") from error
    pieces, positions = [], []
    for position, name in enumerate(files):
        if name is not None:
            pieces.append(io.read_mesh(manifest_path.parent / name))
            positions.append(position)
    if not pieces:
        raise InputError(f"{manifest_path}: no tile holds a face")
    mesh, index = weld_coincident(pieces)  # the seams' copies of a vertex are one
    tile_of = np.repeat(positions, [piece.n_vertices for piece in pieces])
    seams = _seams(np.column_stack([index, tile_of]))
    if (mesh.n_vertices, mesh.n_faces, seams) != stated:
        raise InputError(
            f"{manifest_path}: the tiles weld into {mesh.n_vertices} vertices, {mesh.n_faces} "
            f"faces and {len(seams)} seams; the manifest states {stated[0]}, {stated[1]} and "
            f"{len(stated[2])} (a tile's file was changed, or two vertices coincide)"
        )
    return mesh


def cut(mesh: Mesh, owner: np.ndarray, n_pieces: int) -> list:
    """For each piece k < `n_pieces`, (Mesh of the faces whose `owner` (F,) is k, with the
    vertices they use; those vertices' indices in `mesh`), or (None, None) where it has
    no face."""
    pieces = []
    for k in range(n_pieces):
        faces = mesh.faces[owner == k]
        if faces.shape[0] == 0:
            pieces.append((None, None))
            continue
        used = distinct(faces)
        piece = Mesh(vertices=mesh.vertices[used], faces=np.searchsorted(used, faces))
        pieces.append((piece, used))
    return pieces


def weld(pieces: list, keys: list) -> tuple[Mesh, np.ndarray]:
    """One mesh of the meshes `pieces`, their vertices of the same key merged, in the
    order they first appear; `keys` holds an int64 array (V_k,) for each piece, -1 for a
    vertex of its own. Returns the mesh and the index (V,) in it of every piece's vertex
    in turn."""
    starts = np.cumsum([0] + [piece.n_vertices for piece in pieces])
    vertices = np.concatenate([piece.vertices for piece in pieces])
    shifted = zip(pieces, starts[:-1], strict=True)
    faces = np.concatenate([piece.faces + start for piece, start in shifted])
    key = np.concatenate(keys)
    own = key < 0
    key[own] = key.max(initial=-1) + 1 + np.arange(np.count_nonzero(own))
    _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    index = rank[inverse]
    return Mesh(vertices=vertices[first[order]], faces=index[faces]), index


def weld_coincident(pieces: list) -> tuple[Mesh, np.ndarray]:
    """`weld` of the meshes `pieces`, their vertices of the same coordinates merged."""
    vertices = np.concatenate([piece.vertices for piece in pieces])
    same = np.unique(vertices, axis=0, return_inverse=True)[1].reshape(-1)
    cuts = np.cumsum([piece.n_vertices for piece in pieces])[:-1]
    return weld(pieces, np.split(same, cuts))


def _owned_box(tile, offset, cube_size: float) -> list:
    """``[[xmin, ymin, zmin], [xmax, ymax, zmax]]`` of the cubes `tile` owns, in input
    coordinates, None on a side that reaches without end (the outermost tiles')."""
    low, high = (offset + cube_size * np.asarray(ends, dtype=np.float64) for ends in tile.owned)
    return [
        [None if i <= -LIMIT else float(x) for i, x in zip(tile.owned[0], low, strict=True)],
        [None if i >= LIMIT else float(x) for i, x in zip(tile.owned[1], high, strict=True)],
    ]


def _seams(users: np.ndarray) -> list:
    """``[{"tiles": [a, b], "vertices": n}, ...]`` for the (vertex, tile) rows `users`
    (U, 2): each pair of tiles a < b and the vertices both use, in order of a, then b."""
    users = users[np.lexsort((users[:, 1], users[:, 0]))]
    vertex, tile = users[:, 0], users[:, 1]
    pairs = [np.zeros((0, 2), dtype=np.int64)]
    most = int(np.unique(vertex, return_counts=True)[1].max(initial=1))
    for step in range(1, most):  # the rows of one vertex lie together, `most` at most
        same = vertex[step:] == vertex[:-step]
        pairs.append(np.column_stack([tile[:-step][same], tile[step:][same]]))
    pairs = np.concatenate(pairs)
    found, count = np.unique(pairs, axis=0, return_counts=True)
    return [
        {"tiles": [int(a), int(b)], "vertices": int(n)}
        for (a, b), n in zip(found, count, strict=True)
    ]

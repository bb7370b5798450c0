"""Vertices onto the surface, and triangles small enough for its curvature.

Marching cubes puts each vertex where the field, interpolated linearly along a lattice
edge, changes sign, and its flat triangles cut the chords of a curved surface: a convex
surface comes out too small by up to L^2 kappa / 8 for edges of length L. Projecting the
vertices onto the zero set of a smooth local surface (`zeroset.surface`, the blended jets
by default) removes the first error;
splitting the edges that sag too far and projecting the new vertices removes the second,
only where the surface bends. Topology and boundaries are kept: a split
edge keeps its faces, a boundary edge stays a boundary.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .surface import Surface
from .thresholds import CHORD_NOISE, CHORD_RELATIVE, MAX_LEVELS, PROJECTION_STEPS
from .topology import face_area_vectors, undirected_edges, undo_turned_faces
from .types import Mesh

__all__ = [
    "MIDPOINT_KEYS",
    "Refined",
    "midpoint_keys",
    "project_to_surface",
    "refine_mesh",
    "refine_traced",
    "sag_tolerance",
    "sagging_edges",
    "split_edges",
]

#: Least key `midpoint_keys` gives: keys below it are free for the vertices refined.
MIDPOINT_KEYS = 1 << 62


def sag_tolerance(curvature, noise: float) -> np.ndarray:
    """(N,) chord sag allowed, in data units, where the largest curvature is `curvature` (N,).

    ``CHORD_RELATIVE / kappa`` or ``CHORD_NOISE * noise``, whichever is larger.
    """
    kappa = np.maximum(np.asarray(curvature, dtype=np.float64), 1e-300)
    return np.maximum(CHORD_RELATIVE / kappa, CHORD_NOISE * noise)


def project_to_surface(mesh: Mesh, surface: Surface, *, steps: int = PROJECTION_STEPS):
    """Move every vertex onto the zero set of `surface`; no triangle may turn over.

    Each step is ``x <- x - f(x) g / |g|^2`` with f the surface's distance and g its
    gradient. A triangle whose normal turns by more than 90 degrees brings its three
    vertices back to where they were before the step; this repeats until no triangle turns.

    Parameters
    ----------
    mesh : Mesh
    surface : Surface

    Returns
    -------
    mesh : Mesh
        The same faces with projected vertices.
    held : int
        Vertices kept back so that no triangle turned over.
    """
    projected, held = _project(mesh, surface, steps)
    return projected, int(np.count_nonzero(held))


def _project(mesh: Mesh, surface: Surface, steps: int) -> tuple[Mesh, np.ndarray]:
    """`project_to_surface`, with the (V,) bool mask of the vertices held back."""
    vertices = mesh.vertices.copy()
    faces = mesh.faces
    before = face_area_vectors(vertices, faces)
    held = np.zeros(vertices.shape[0], dtype=bool)
    for _ in range(steps):
        values, gradients = surface.evaluate(vertices)
        squared = np.einsum("ij,ij->i", gradients, gradients)
        step = np.where(squared > 0.25, values / np.maximum(squared, 0.25), 0.0)
        moved = vertices - step[:, None] * gradients
        moved[held] = vertices[held]
        vertices, back = undo_turned_faces(moved, vertices, faces, before)
        held |= back
    return Mesh(vertices=vertices, faces=faces), held


def split_edges(mesh: Mesh, marked: np.ndarray) -> Mesh:
    """Split the marked edges at their midpoints and re-triangulate each face (orientation kept).

    A face with three marked edges becomes four, with two becomes three (the quad cut by
    its shorter diagonal), with one becomes two. Faces on both sides of an edge see the
    same mark, so the result has no T-junction.

    Parameters
    ----------
    mesh : Mesh
    marked : (E,) bool
        One per edge of `zeroset.topology.undirected_edges(mesh.faces)`.

    Returns
    -------
    Mesh
        The old vertices first, then one per marked edge in edge order; the faces with no
        marked edge first, in their order, then the pieces of the others.
    """
    return _split(mesh, marked, *undirected_edges(mesh.faces)[:2])[0]


def _split(mesh: Mesh, marked, edges, corner_edge) -> tuple[Mesh, np.ndarray]:
    """`split_edges` with the mesh's `undirected_edges` (E, 2) and (F, 3), and the (F',)
    int64 face of `mesh` each new face lies in."""
    faces = mesh.faces
    middle = np.full(edges.shape[0], -1, dtype=np.int64)
    middle[marked] = mesh.n_vertices + np.arange(np.count_nonzero(marked))
    vertices = np.concatenate(
        [mesh.vertices, (mesh.vertices[edges[marked, 0]] + mesh.vertices[edges[marked, 1]]) / 2]
    )
    # Edge i of a face joins its corners i and i + 1; its midpoint or -1.
    mid = middle[corner_edge]
    count = np.count_nonzero(mid >= 0, axis=1)
    # Turn each face so that a single marked edge is edge 0 and a single unmarked one edge 2.
    lone = np.where(count == 1, np.argmax(mid >= 0, axis=1), np.argmax(mid < 0, axis=1) + 1)
    turn = np.where(count % 3 == 0, 0, lone % 3)
    order = (np.arange(3)[None, :] + turn[:, None]) % 3
    a, b, c = np.take_along_axis(faces, order, axis=1).T
    ab, bc, ca = np.take_along_axis(mid, order, axis=1).T
    pieces = [np.stack([a, b, c], axis=1)[count == 0]]
    parents = [np.flatnonzero(count == 0)]
    one = count == 1
    pieces += [np.stack(t, axis=1)[one] for t in ((a, ab, c), (ab, b, c))]
    parents += 2 * [np.flatnonzero(one)]
    two = count == 2
    # The quad a, ab, bc, c: cut along ab-c or a-bc, whichever is shorter.
    short = np.linalg.norm(vertices[ab] - vertices[c], axis=1) <= np.linalg.norm(
        vertices[a] - vertices[bc], axis=1
    )
    pieces.append(np.stack([ab, b, bc], axis=1)[two])
    pieces += [np.stack(t, axis=1)[two & short] for t in ((a, ab, c), (ab, bc, c))]
    pieces += [np.stack(t, axis=1)[two & ~short] for t in ((a, ab, bc), (a, bc, c))]
    parents += [np.flatnonzero(two)] + 2 * [np.flatnonzero(two & short)]
    parents += 2 * [np.flatnonzero(two & ~short)]
    three = count == 3
    pieces += [
        np.stack(t, axis=1)[three] for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))
    ]
    parents += 4 * [np.flatnonzero(three)]
    return Mesh(vertices=vertices, faces=np.concatenate(pieces)), np.concatenate(parents)


def sagging_edges(mesh: Mesh, surface: Surface, *, noise: float) -> np.ndarray:
    """(E,) bool: the edges of `zeroset.topology.undirected_edges` whose chords sag too far.

    A chord of length L sags ``L^2 kappa / 8``, with kappa the curvature of `surface` at its
    midpoint (`zeroset.surface.Surface.curvature_at`); it sags too far beyond
    `sag_tolerance`.

    Parameters
    ----------
    mesh : Mesh
    surface : Surface
    noise : float
        Noise level sigma of one point, in data units.
    """
    return _sagging(mesh.vertices[undirected_edges(mesh.faces)[0]], surface, noise)


def _sagging(ends: np.ndarray, surface: Surface, noise: float) -> np.ndarray:
    """`sagging_edges` of the edges whose ends lie at `ends` (E, 2, 3)."""
    length = np.linalg.norm(ends[:, 0] - ends[:, 1], axis=1)
    kappa = np.maximum(surface.curvature_at(ends.mean(axis=1)), 1e-300)
    return length**2 * kappa / 8.0 > sag_tolerance(kappa, noise)


def refine_mesh(mesh: Mesh, surface: Surface, *, noise: float, levels: int | None = None):
    """Project the vertices, then split and project the edges whose chords sag too far.

    A chord of length L on a surface of curvature kappa sags ``L^2 kappa / 8`` below it.
    An edge is split while that exceeds 0.01 % of the radius ``1 / kappa`` or 10 % of the
    `noise`, whichever is larger, with kappa the surface's curvature at the edge's
    midpoint (`sagging_edges`); at most three times.

    Parameters
    ----------
    mesh : Mesh
    surface : Surface
        Smooth (``surface.smooth``).
    noise : float
        Noise level sigma of one point, in data units.
    levels : int, optional
        Split every edge this many times instead.

    Returns
    -------
    mesh : Mesh
    counts : dict
        ``refine_levels`` (rounds of splits), ``edges_split`` and ``projection_held``
        (vertices held back so that no triangle turned over).
    """
    refined = refine_traced(mesh, surface, noise=noise, levels=levels)
    return refined.mesh, refined.counts


@dataclass(frozen=True, eq=False)
class Refined:
    """A refined mesh (`refine_traced`) and where each of its parts came from.

    Attributes
    ----------
    mesh : Mesh
    keys : (V',) int64
        Each vertex's key: an input vertex keeps its own, a midpoint has `midpoint_keys`
        of its edge's ends.
    parent : (F',) int64
        The input face each face lies in.
    held : (V',) int64
        Projections in which each vertex was held back so that no triangle turned over.
    rounds : int
        Rounds of splits.
    """

    mesh: Mesh
    keys: np.ndarray
    parent: np.ndarray
    held: np.ndarray
    rounds: int

    @property
    def counts(self) -> dict:
        """``refine_levels``, ``edges_split`` and ``projection_held`` (`refine_mesh`)."""
        return {
            "refine_levels": self.rounds,
            "edges_split": int(np.count_nonzero(self.keys >= MIDPOINT_KEYS)),
            "projection_held": int(self.held.sum()),
        }


def refine_traced(
    mesh: Mesh, surface: Surface, *, noise: float, levels: int | None = None, keys=None
) -> Refined:
    """`refine_mesh`, with the key of every vertex and the input face of every face.

    Two meshes that share a patch with the same `keys` (V,) int64 (below
    ``MIDPOINT_KEYS``; their indices by default) refine it to the same vertices, of the
    same keys, wherever the patch and the few rings around it are the same: pieces of one
    mesh refined apart weld by their keys (`zeroset.tiles`).
    """
    keys = np.arange(mesh.n_vertices, dtype=np.int64) if keys is None else np.asarray(keys)
    if keys.size and (keys.min() < 0 or keys.max() >= MIDPOINT_KEYS):
        raise ValueError(f"vertex keys must lie in [0, {MIDPOINT_KEYS}); got another")
    parent = np.arange(mesh.n_faces, dtype=np.int64)
    mesh, held = _project(mesh, surface, PROJECTION_STEPS)
    held = held.astype(np.int64)
    rounds = 0
    for _ in range(MAX_LEVELS if levels is None else levels):
        edges, corner_edge, _ = undirected_edges(mesh.faces)
        if levels is None:
            marked = _sagging(mesh.vertices[edges], surface, noise)
        else:
            marked = np.ones(edges.shape[0], dtype=bool)
        if not marked.any():
            break
        split, within = _split(mesh, marked, edges, corner_edge)
        keys = np.concatenate([keys, midpoint_keys(keys[edges[marked, 0]], keys[edges[marked, 1]])])
        parent = parent[within]
        mesh, more = _project(split, surface, PROJECTION_STEPS)
        held = np.concatenate([held, np.zeros(split.n_vertices - held.size, np.int64)]) + more
        rounds += 1
    return Refined(mesh=mesh, keys=keys, parent=parent, held=held, rounds=rounds)


def midpoint_keys(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(M,) int64 the key of the midpoint of each edge whose ends have keys `a`, `b` (M,):
    the same in either order, in ``[MIDPOINT_KEYS, 2**63)``; a 64-bit mix of the two
    (SplitMix64's finaliser), so that two edges share one with odds of about 1e-7 among a
    million."""
    with np.errstate(over="ignore"):
        low = np.minimum(a, b).astype(np.uint64)
        high = np.maximum(a, b).astype(np.uint64)
        mixed = _mix(_mix(low) + high)
    return ((mixed >> np.uint64(2)) | np.uint64(MIDPOINT_KEYS)).astype(np.int64)


def _mix(z: np.ndarray) -> np.ndarray:
    """SplitMix64's finaliser of each uint64 of `z` (wrapping)."""
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))

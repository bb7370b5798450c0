"""Local moves of the mesh optimisation: edge collapse, split and swap (Hoppe et al. 1993, §4).

The mesh lives in flat arrays with spare capacity, bundled in one named tuple ``state``
(:class:`State`; Numba compiles attribute access to its fields):

    V (Vc, 3) float64    vertex positions          alive_v (Vc,) bool
    F (Fc, 3) int64      faces, counter-clockwise   alive_f (Fc,) bool
    vf (Vc, W) int64     faces around each vertex   deg (Vc,) int64 (how many)
    X (N, 3) float64     data points
    L2 (N,) float64      squared distance each point may lie from the mesh (inf: any)
    pf (N,) int64        face each point is assigned to (its projection)
    pb (N, 3) float64    barycentric coordinates of the projection in that face
    pd (N,) float64      squared distance to the projection
    head (Fc,) int64     first point of each face's list (-1: none)
    nxt, prv (N,) int64  doubly linked point lists per face
    count (Fc,) int64    points per face
    sizes (5,) int64     next free vertex slot, next free face slot, live vertices, and
                         the ends of the vertex and face slots this state may fill

A pass works in a :class:`Scratch` of buffers allocated once, sized for the largest move
(the point buffers for every point, though only the points of one move's faces are ever
written), so that a move allocates nothing.

A move is evaluated locally (Hoppe 1993, §4.3): only the points on the faces it changes are
projected again, onto the new faces only, and only the new vertex is optimised (a few
alternations of projection and a one-vertex least-squares solve). Projecting onto a subset
of the faces over-estimates each distance, so an accepted move lowers the true energy at
least as much as computed.
"""

from collections import namedtuple

import numpy as np

from ._jit import jit
from .triangles import closest_point_on_triangle, set_triangle

ACCEPTED = 0
ENERGY_INCREASE = 1
ILLEGAL_TOPOLOGY = 2
BAD_DIHEDRAL = 3

COLLAPSE = 0
SPLIT = 1
SWAP = 2

H = -1  # corner index standing for the new vertex in candidate faces
# Alternations of projection and vertex solve per candidate start (typed: a literal would
# compile _fit_vertex once more).
_LOCAL_ITERATIONS = np.int64(2)
_HELD = np.int64(0)  # none: the new vertex keeps its start

State = namedtuple("State", "V F alive_v alive_f vf deg X L2 pf pb pd head nxt prv count sizes")
Scratch = namedtuple(
    "Scratch",
    "pts face bary d2 trial_face trial_bary trial_d2 ring_i ring_j ring seen region new_faces "
    "global_face near fold_faces triangles degenerate sphere edge probe position trial_position",
)


# ------------------------------------------------------------------ building and reading


@jit
def build_state(
    vertices, faces, points, limits2, face_of_point, bary, distance2, width, spare_v, spare_f
):  # fmt: skip
    """Return the State for a mesh and an assignment of points to faces, and the points'
    squared limits (N,) (see `State`).

    `width` is the most faces a vertex may have; `spare_v`, `spare_f` the extra slots that
    splits may fill. Faces with a vertex of more than `width` faces are not allowed.
    """
    n_v, n_f, n_p = vertices.shape[0], faces.shape[0], points.shape[0]
    vc, fc = n_v + spare_v, n_f + spare_f
    V = np.zeros((vc, 3))
    F = np.full((fc, 3), -1, dtype=np.int64)
    _copy_rows(V, vertices, n_v)
    _copy_rows(F, faces, n_f)
    alive_v = np.zeros(vc, dtype=np.bool_)
    alive_f = np.zeros(fc, dtype=np.bool_)
    alive_f[:n_f] = True
    vf = np.full((vc, width), -1, dtype=np.int64)
    deg = np.zeros(vc, dtype=np.int64)
    n_alive = 0
    for f in range(n_f):
        for corner in range(3):
            v = faces[f, corner]
            n_alive += not alive_v[v]
            alive_v[v] = True
            vf[v, deg[v]] = f
            deg[v] += 1
    head = np.full(fc, -1, dtype=np.int64)
    nxt = np.full(n_p, -1, dtype=np.int64)
    prv = np.full(n_p, -1, dtype=np.int64)
    count = np.zeros(fc, dtype=np.int64)
    pf = face_of_point.copy()
    _link(head, nxt, prv, count, pf, np.arange(n_p))
    sizes = np.array([n_v, n_f, n_alive, vc, fc], dtype=np.int64)
    return State(
        V, F, alive_v, alive_f, vf, deg, points, limits2, pf, bary.copy(),
        distance2.copy(), head, nxt, prv, count, sizes,
    )  # fmt: skip


@jit
def make_scratch(n_points, width):
    """Return the Scratch for moves on a mesh of vertex `width` with `n_points` points."""
    faces = 2 * width  # a collapse's region: the faces around both ends of its edge
    return Scratch(
        np.empty(n_points, dtype=np.int64),
        np.empty(n_points, dtype=np.int64),
        np.empty((n_points, 3)),
        np.empty(n_points),
        np.empty(n_points, dtype=np.int64),
        np.empty((n_points, 3)),
        np.empty(n_points),
        np.zeros(faces, dtype=np.int64),
        np.zeros(faces, dtype=np.int64),
        np.zeros(2 * faces, dtype=np.int64),
        np.zeros(faces, dtype=np.int64),
        np.zeros(faces, dtype=np.int64),
        np.zeros((faces, 3), dtype=np.int64),
        np.zeros(faces, dtype=np.int64),
        np.zeros((faces, faces), dtype=np.bool_),
        np.zeros((faces, 3), dtype=np.int64),
        np.zeros((faces, 15)),
        np.zeros(faces, dtype=np.bool_),
        np.zeros((faces, 4)),
        np.zeros(4, dtype=np.int64),
        np.zeros(4, dtype=np.int64),
        np.zeros(3),
        np.zeros(3),
    )


@jit
def _copy(dst, src):
    # dst[:] = src for 1-d arrays of one length; a slice assignment from an array would
    # compile NumPy's shape-mismatch message (seconds of string formatting on a fresh
    # install).
    for k in range(src.shape[0]):
        dst[k] = src[k]


@jit
def _copy_rows(dst, src, n):
    # dst[:n] = src[:n] for 2-d arrays of one width (see `_copy`).
    for r in range(n):
        for c in range(src.shape[1]):
            dst[r, c] = src[r, c]


@jit
def _link(head, nxt, prv, count, pf, pts):
    # Put each point p of pts at the front of the list of its face pf[p], in order.
    for q in range(pts.shape[0]):
        p = pts[q]
        f = pf[p]
        prv[p] = -1
        nxt[p] = head[f]
        if head[f] >= 0:
            prv[head[f]] = p
        head[f] = p
        count[f] += 1


@jit
def edges_of(state):
    """Return the (3F, 2) undirected edges (a < b) of the live faces, one per face side
    (an edge between two faces twice)."""
    F, alive_f = state.F, state.alive_f
    n = 0
    out = np.zeros((3 * F.shape[0], 2), dtype=np.int64)
    for f in range(F.shape[0]):
        if not alive_f[f]:
            continue
        for c in range(3):
            a, b = F[f, c], F[f, (c + 1) % 3]
            out[n, 0], out[n, 1] = min(a, b), max(a, b)
            n += 1
    return out[:n]


# ------------------------------------------------------------------ topology queries


@jit
def _has(values, n, x):
    for k in range(n):
        if values[k] == x:
            return True
    return False


@jit
def _contains(F, f, v):
    return F[f, 0] == v or F[f, 1] == v or F[f, 2] == v


@jit
def _edge_faces(state, i, j, out):
    # Faces holding both i and j, into out; returns how many.
    F, vf, deg = state.F, state.vf, state.deg
    n = 0
    for k in range(deg[i]):
        f = vf[i, k]
        if _contains(F, f, j):
            if n < out.shape[0]:
                out[n] = f
            n += 1
    return n


@jit
def _manifold_edge(state, i, j, out):
    # The faces of edge (i, j) into out and their number (1 or 2); 0 when i, j are not two
    # live vertices joined by a manifold edge.
    alive_v = state.alive_v
    if i == j or not alive_v[i] or not alive_v[j]:
        return 0
    n = _edge_faces(state, i, j, out)
    return n if 1 <= n <= 2 else 0


@jit
def _neighbours(state, v, out, seen):
    # Distinct vertices sharing an edge with v, into out; returns how many and whether v
    # lies on the boundary (some edge of v belongs to one face only). `seen` is scratch.
    F, vf, deg = state.F, state.vf, state.deg
    n = 0
    for k in range(deg[v]):
        f = vf[v, k]
        for c in range(3):
            u = F[f, c]
            if u == v:
                continue
            found = False
            for m in range(n):
                if out[m] == u:
                    seen[m] += 1
                    found = True
                    break
            if not found:
                out[n] = u
                seen[n] = 1
                n += 1
    boundary = False
    for m in range(n):
        if seen[m] == 1:
            boundary = True
    return n, boundary


@jit
def _opposite(F, f, i, j):
    # The corner of face f that is neither i nor j.
    for c in range(3):
        if F[f, c] != i and F[f, c] != j:
            return F[f, c]
    return -1


@jit
def _remove_face(vf, deg, v, f):
    for k in range(deg[v]):
        if vf[v, k] == f:
            deg[v] -= 1
            vf[v, k] = vf[v, deg[v]]
            vf[v, deg[v]] = -1
            return


@jit
def _add_face(vf, deg, v, f):
    vf[v, deg[v]] = f
    deg[v] += 1


# ------------------------------------------------------------------ geometry of candidates


@jit
def _point(V, v, h):
    # Vertex v's position, or h where v is H: one call per corner, since each call to a
    # kernel counts references to the arrays it takes (atomically: not free in a loop).
    if v == H:
        return h[0], h[1], h[2]
    return V[v, 0], V[v, 1], V[v, 2]


@jit
def _normal(V, h, a, b, c):
    # Unit normal of triangle (a, b, c), corners H meaning position h; zeros if degenerate.
    ax, ay, az = _point(V, a, h)
    bx, by, bz = _point(V, b, h)
    cx, cy, cz = _point(V, c, h)
    ux, uy, uz = bx - ax, by - ay, bz - az
    wx, wy, wz = cx - ax, cy - ay, cz - az
    nx, ny, nz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
    length = np.sqrt(nx * nx + ny * ny + nz * nz)
    scale = max(ux * ux + uy * uy + uz * uz, wx * wx + wy * wy + wz * wz)
    if length <= 1e-12 * scale or length == 0.0:
        return 0.0, 0.0, 0.0, False
    return nx / length, ny / length, nz / length, True


@jit
def _worst_fold(state, region, n_region, new_faces, n_new, h, min_cos):
    # Smallest cosine between the normals of two faces sharing an edge, over every edge of
    # the candidate faces `new_faces` (H = the new vertex at h), and how many of those are
    # below min_cos; `region` are the faces they replace. (-2, -1) if a candidate face is
    # degenerate.
    V, F, vf, deg = state.V, state.F, state.vf, state.deg
    worst = 1.0
    bad = 0
    for t in range(n_new):
        nx, ny, nz, ok = _normal(V, h, new_faces[t, 0], new_faces[t, 1], new_faces[t, 2])
        if not ok:
            return -2.0, -1
        for c in range(3):
            a, b = new_faces[t, c], new_faces[t, (c + 1) % 3]
            # The neighbour across (a, b): another candidate face, or a live face outside
            # the region.
            found = False
            for s in range(n_new):
                if s != t and _has(new_faces[s], 3, a) and _has(new_faces[s], 3, b):
                    mx, my, mz, _ = _normal(V, h, new_faces[s, 0], new_faces[s, 1], new_faces[s, 2])
                    cos = nx * mx + ny * my + nz * mz
                    worst = min(worst, cos)
                    bad += cos < min_cos
                    found = True
                    break
            if found or a == H or b == H:
                continue
            for k in range(deg[a]):
                g = vf[a, k]
                if _contains(F, g, b) and not _has(region, n_region, g):
                    mx, my, mz, _ = _normal(V, h, F[g, 0], F[g, 1], F[g, 2])
                    cos = nx * mx + ny * my + nz * mz
                    worst = min(worst, cos)
                    bad += cos < min_cos
    return worst, bad


@jit
def _region_fold(state, region, n_region, min_cos, faces, h):
    # The same as _worst_fold over the region faces themselves, before the move; `faces`
    # (at least n_region rows) and `h` are scratch.
    F = state.F
    for r in range(n_region):
        _copy(faces[r], F[region[r]])
    return _worst_fold(state, region, n_region, faces, n_region, h, min_cos)


@jit
def _gather_points(state, region, n_region, out):
    # The points assigned to the region faces, into out (scratch); returns the view of
    # out that holds them and the sum of their squared distances.
    pd, head, nxt, count = state.pd, state.head, state.nxt, state.count
    total = 0
    for r in range(n_region):
        total += count[region[r]]
    out = out[:total]
    n = 0
    energy = 0.0
    for r in range(n_region):
        p = head[region[r]]
        while p >= 0:
            out[n] = p
            energy += pd[p]
            n += 1
            p = nxt[p]
    return out, energy


@jit
def _project_local(state, scratch, pts, new_faces, n_new, near, h, best_face, best_bary, best_d2):
    # Project every point in pts onto the nearest candidate face; returns the energy (the
    # squared distances), or inf as soon as a point lies farther than its limit (the rest
    # then unprojected).
    # best_face holds a first guess per point (-1: none). A point with a guess g is
    # projected onto the faces t with near[g, t] only, g first, so that every other face
    # whose bounding sphere is no nearer is skipped. Fewer faces can only over-estimate
    # a distance.
    V, X, L2 = state.V, state.X, state.L2
    triangles, degenerate, sphere = scratch.triangles, scratch.degenerate, scratch.sphere
    for t in range(n_new):
        row = triangles[t]
        ax, ay, az = _point(V, new_faces[t, 0], h)
        bx, by, bz = _point(V, new_faces[t, 1], h)
        cx, cy, cz = _point(V, new_faces[t, 2], h)
        degenerate[t] = set_triangle(row, ax, ay, az, bx, by, bz, cx, cy, cz)
        for axis in range(3):
            sphere[t, axis] = (row[axis] + row[3 + axis] + row[6 + axis]) / 3.0
        radius2 = 0.0
        for c in range(3):
            r2 = 0.0
            for axis in range(3):
                r2 += (row[3 * c + axis] - sphere[t, axis]) ** 2
            radius2 = max(radius2, r2)
        sphere[t, 3] = np.sqrt(radius2)
    energy = 0.0
    for q in range(pts.shape[0]):
        p = pts[q]
        px, py, pz = X[p, 0], X[p, 1], X[p, 2]
        best = np.inf
        guess = best_face[q]
        if guess >= 0:
            best, u, v, w = closest_point_on_triangle(
                px, py, pz, triangles, guess, degenerate[guess]
            )
            best_bary[q, 0], best_bary[q, 1], best_bary[q, 2] = u, v, w
        for t in range(n_new):
            if t == guess or (guess >= 0 and not near[guess, t]):
                continue
            gap = (
                np.sqrt(
                    (px - sphere[t, 0]) ** 2 + (py - sphere[t, 1]) ** 2 + (pz - sphere[t, 2]) ** 2
                )
                - sphere[t, 3]
            )
            if gap > 0.0 and gap * gap >= best:
                continue
            d2, u, v, w = closest_point_on_triangle(px, py, pz, triangles, t, degenerate[t])
            if d2 < best:
                best = d2
                best_face[q] = t
                best_bary[q, 0], best_bary[q, 1], best_bary[q, 2] = u, v, w
        best_d2[q] = best
        energy += best
        if best > L2[p]:
            return np.inf
    return energy


@jit
def _adjacent(new_faces, n_new, near):
    # near[t, s] (into scratch): candidate faces t and s are one face or share an edge.
    for t in range(n_new):
        for s in range(n_new):
            shared = 0
            for c in range(3):
                shared += _has(new_faces[s], 3, new_faces[t, c])
            near[t, s] = shared >= 2


@jit
def _guesses(state, pts, global_face, n_new, face):
    # For each point, the candidate face that replaces the face it lies on now (-1: none),
    # into face.
    pf = state.pf
    for q in range(pts.shape[0]):
        face[q] = -1
        for t in range(n_new):
            if global_face[t] == pf[pts[q]]:
                face[q] = t
                break


@jit
def _spring(V, h, ring, n_ring):
    # Sum of squared lengths of the edges from h to the ring vertices.
    total = 0.0
    for m in range(n_ring):
        u = ring[m]
        total += (h[0] - V[u, 0]) ** 2 + (h[1] - V[u, 1]) ** 2 + (h[2] - V[u, 2]) ** 2
    return total


@jit
def _fit_vertex(
    state, scratch, pts, new_faces, n_new, near, ring, n_ring, kappa, target, face, bary, d2,
    iterations,
):  # fmt: skip
    # Optimise the new vertex from scratch.position: alternate, at most `iterations` times,
    # projecting the points onto the candidate faces and the least-squares position of the
    # one free vertex (Hoppe 1993, §4.3):
    # min_h sum_p |x_p - sum_c b_pc v_c|^2 + kappa sum_ring |h - v_u|^2.
    # Stops early once the energy is so far above `target` (what the move must beat) that
    # more alternations, each gaining less than the last, cannot reach it. `face` holds a
    # guess per point on entry, and face, bary, d2 the projection on return.
    # Returns the local energy (distances plus springs; inf where a point lies past its limit
    # from the start); the position is in scratch.position.
    V, X = state.V, state.X
    h, trial = scratch.position, scratch.trial_position
    n = pts.shape[0]
    trial_face, trial_bary = scratch.trial_face[:n], scratch.trial_bary[:n]
    trial_d2 = scratch.trial_d2[:n]
    energy = _project_local(state, scratch, pts, new_faces, n_new, near, h, face, bary, d2)
    if energy == np.inf:
        return energy  # a point past its limit: the others are not projected to solve with
    energy += kappa * _spring(V, h, ring, n_ring)
    for _ in range(iterations):
        weight = kappa * n_ring
        rx = ry = rz = 0.0
        for m in range(n_ring):
            rx += kappa * V[ring[m], 0]
            ry += kappa * V[ring[m], 1]
            rz += kappa * V[ring[m], 2]
        for q in range(n):
            t = face[q]
            bh = 0.0
            ox, oy, oz = X[pts[q], 0], X[pts[q], 1], X[pts[q], 2]
            for c in range(3):
                v = new_faces[t, c]
                if v == H:
                    bh = bary[q, c]
                else:
                    ox -= bary[q, c] * V[v, 0]
                    oy -= bary[q, c] * V[v, 1]
                    oz -= bary[q, c] * V[v, 2]
            weight += bh * bh
            rx += bh * ox
            ry += bh * oy
            rz += bh * oz
        if weight <= 1e-300:
            break
        trial[0], trial[1], trial[2] = rx / weight, ry / weight, rz / weight
        _copy(trial_face, face)  # the guesses; every bary and d2 is written anew
        trial_energy = _project_local(
            state, scratch, pts, new_faces, n_new, near, trial, trial_face, trial_bary, trial_d2
        )
        trial_energy += kappa * _spring(V, trial, ring, n_ring)
        if trial_energy >= energy:
            break
        gain = energy - trial_energy
        _copy(h, trial)
        energy = trial_energy
        _copy(face, trial_face)
        _copy_rows(bary, trial_bary, bary.shape[0])
        _copy(d2, trial_d2)
        if energy - target > 2.0 * gain:
            break
    return energy


@jit
def _reassign(state, region, n_region, pts, global_face, face, bary, d2):
    # Move each point to its new face with its new projection: `pts` are every point of
    # the faces `region[:n_region]` (`_gather_points`), whose lists are emptied first and
    # filled again.
    pf, pb, pd, head, nxt, prv = state.pf, state.pb, state.pd, state.head, state.nxt, state.prv
    count = state.count
    for r in range(n_region):
        head[region[r]] = -1
        count[region[r]] = 0
    for q in range(pts.shape[0]):
        p = pts[q]
        pf[p] = global_face[face[q]]
        pb[p, 0], pb[p, 1], pb[p, 2] = bary[q, 0], bary[q, 1], bary[q, 2]
        pd[p] = d2[q]
    _link(head, nxt, prv, count, pf, pts)


@jit
def _fold_ok(state, scratch, region, n_region, new_faces, n_new, h, min_cos):
    # No candidate face is degenerate, and no fold between neighbouring faces is sharper
    # than `min_cos`; where the region was folded before, the move may not add folds nor
    # sharpen the sharpest one.
    after, bad_after = _worst_fold(state, region, n_region, new_faces, n_new, h, min_cos)
    if bad_after < 0:
        return False
    if bad_after == 0:
        return True
    before, bad_before = _region_fold(
        state, region, n_region, min_cos, scratch.fold_faces, scratch.trial_position
    )
    return bad_after <= bad_before and after >= before - 1e-12


# ------------------------------------------------------------------ the three moves


@jit
def _collapse_region(state, scratch, i, j):
    # Whether edge (i, j) may collapse (Hoppe 1993, §4.1), and what it changes. Fills
    # scratch.edge (the faces on the edge), ring_i, ring_j, region (the faces around i or
    # j), new_faces and global_face (the region's faces that stay, i and j -> H) and ring
    # (the neighbours of the new vertex). Returns n_edge (0: illegal), n_i, n_j, n_region,
    # n_new, n_ring, boundary_i, boundary_j.
    F, vf, deg = state.F, state.vf, state.deg
    width = vf.shape[1]
    edge = scratch.edge
    n_edge = _manifold_edge(state, i, j, edge)
    ring_i, ring_j = scratch.ring_i, scratch.ring_j
    # Counters start as np.int64: from a literal 0, Numba would first compile every callee
    # for Literal[int](0), then again for int64.
    zero = np.int64(0)
    if n_edge == 0:
        return zero, zero, zero, zero, zero, zero, False, False
    n_i, boundary_i = _neighbours(state, i, ring_i, scratch.seen)
    n_j, boundary_j = _neighbours(state, j, ring_j, scratch.seen)
    illegal = (zero, n_i, n_j, zero, zero, zero, boundary_i, boundary_j)
    # An edge joining two boundary vertices must be a boundary edge.
    if boundary_i and boundary_j and n_edge == 2:
        return illegal
    # Link condition: the common neighbours of i and j are the corners opposite the edge.
    common = 0
    for m in range(n_i):
        if _has(ring_j, n_j, ring_i[m]):
            common += 1
    if common != n_edge:
        return illegal
    # The same with the boundary closed by a virtual vertex joined to it: a boundary face
    # whose other two edges are boundary edges too (an ear) may not collapse.
    if n_edge == 1:
        k = _opposite(F, edge[0], i, j)
        probe = scratch.probe
        if _edge_faces(state, i, k, probe) == 1 and _edge_faces(state, j, k, probe) == 1:
            return illegal
    # The mesh keeps more than a tetrahedron (or a triangle, at a boundary).
    if state.sizes[2] <= (3 if boundary_i or boundary_j else 4):
        return illegal
    if deg[i] + deg[j] - 2 * n_edge > width:
        return illegal
    region = scratch.region
    n_region = zero
    for k in range(deg[i]):
        region[n_region] = vf[i, k]
        n_region += 1
    for k in range(deg[j]):
        if not _contains(F, vf[j, k], i):
            region[n_region] = vf[j, k]
            n_region += 1
    new_faces, global_face = scratch.new_faces, scratch.global_face
    n_new = zero
    for r in range(n_region):
        f = region[r]
        if _contains(F, f, i) and _contains(F, f, j):
            continue
        for c in range(3):
            v = F[f, c]
            new_faces[n_new, c] = H if (v == i or v == j) else v
        global_face[n_new] = f
        n_new += 1
    ring = scratch.ring
    n_ring = zero
    for m in range(n_i):
        if ring_i[m] != j:
            ring[n_ring] = ring_i[m]
            n_ring += 1
    for m in range(n_j):
        if ring_j[m] != i and not _has(ring, n_ring, ring_j[m]):
            ring[n_ring] = ring_j[m]
            n_ring += 1
    return n_edge, n_i, n_j, n_region, n_new, n_ring, boundary_i, boundary_j


@jit
def _apply_collapse(state, i, j, h, edge, n_edge):
    # Vertex i survives at h; j and the faces on the edge, `edge[:n_edge]`, go.
    V, F, vf, deg = state.V, state.F, state.vf, state.deg
    _copy(V[i], h)
    for e in range(n_edge):
        f = edge[e]
        state.alive_f[f] = False
        for c in range(3):
            _remove_face(vf, deg, F[f, c], f)
    for k in range(deg[j]):
        f = vf[j, k]
        for c in range(3):
            if F[f, c] == j:
                F[f, c] = i
        _add_face(vf, deg, i, f)
    deg[j] = 0
    state.alive_v[j] = False
    state.sizes[2] -= 1


@jit
def try_collapse(state, scratch, i, j, kappa, c_rep, min_cos, force, hold, result):
    """Collapse edge (i, j) into one vertex if that is legal and lowers the energy.

    `result` (2,) float64 gets the energy change and the number of the surviving vertex.
    Returns an outcome code. With `force`, any legal move is made. With `hold`, the
    boundary stays where it is: no boundary edge collapses, and an edge with one end on
    the boundary collapses onto that end.
    """
    V = state.V
    n_edge, n_i, n_j, n_region, n_new, n_ring, boundary_i, boundary_j = _collapse_region(
        state, scratch, i, j
    )
    if n_edge == 0 or (hold and boundary_i and boundary_j):
        return ILLEGAL_TOPOLOGY
    ring_i, ring_j, region = scratch.ring_i, scratch.ring_j, scratch.region
    pts, old = _gather_points(state, region, n_region, scratch.pts)
    for m in range(n_i):
        u = ring_i[m]
        old += kappa * (
            (V[i, 0] - V[u, 0]) ** 2 + (V[i, 1] - V[u, 1]) ** 2 + (V[i, 2] - V[u, 2]) ** 2
        )
    for m in range(n_j):
        u = ring_j[m]
        if u != i:
            old += kappa * (
                (V[j, 0] - V[u, 0]) ** 2 + (V[j, 1] - V[u, 1]) ** 2 + (V[j, 2] - V[u, 2]) ** 2
            )
    # One start: the midpoint, or the boundary end point when only one end is on the
    # boundary, so that the boundary keeps its place (Hoppe 1993 tries all three; the local
    # solve moves the vertex from there).
    h = scratch.position
    if boundary_i and not boundary_j:
        _copy(h, V[i])
    elif boundary_j and not boundary_i:
        _copy(h, V[j])
    else:
        h[:] = 0.5 * (V[i] + V[j])
    n = pts.shape[0]
    face, bary, d2 = scratch.face[:n], scratch.bary[:n], scratch.d2[:n]
    _guesses(state, pts, scratch.global_face, n_new, face)
    _adjacent(scratch.new_faces, n_new, scratch.near)
    iterations = _HELD if hold and (boundary_i or boundary_j) else _LOCAL_ITERATIONS
    new = _fit_vertex(
        state, scratch, pts, scratch.new_faces, n_new, scratch.near, scratch.ring, n_ring,
        kappa, old + c_rep, face, bary, d2, iterations,
    )  # fmt: skip
    delta = new - old - c_rep
    result[0] = delta
    result[1] = i
    if not force and delta >= 0.0:
        return ENERGY_INCREASE
    if not _fold_ok(state, scratch, region, n_region, scratch.new_faces, n_new, h, min_cos):
        return BAD_DIHEDRAL
    _apply_collapse(state, i, j, h, scratch.edge, n_edge)
    _reassign(state, region, n_region, pts, scratch.global_face, face, bary, d2)
    return ACCEPTED


@jit
def _facing(state, scratch, normals, pts, face, n_new, h, min_cos):
    # Whether every point of pts lies on a candidate face (face, into scratch.new_faces)
    # whose normal is within arccos(min_cos) of the point's own (normals (N, 3), unit).
    new_faces, face_normals = scratch.new_faces, scratch.sphere  # the spheres are spent
    for t in range(n_new):
        nx, ny, nz, _ = _normal(state.V, h, new_faces[t, 0], new_faces[t, 1], new_faces[t, 2])
        face_normals[t, 0], face_normals[t, 1], face_normals[t, 2] = nx, ny, nz
    for q in range(pts.shape[0]):
        t, p = face[q], pts[q]
        cos = (
            face_normals[t, 0] * normals[p, 0]
            + face_normals[t, 1] * normals[p, 1]
            + face_normals[t, 2] * normals[p, 2]
        )
        if cos < min_cos:
            return False
    return True


@jit
def try_collapse_within(state, scratch, normals, i, j, min_cos):
    """Collapse edge (i, j) onto one of its ends if that is legal and every point on the
    faces it changes stays within its limit (``state.L2``) of the new faces, on a face whose
    normal is within arccos(`min_cos`) of the point's own (`normals` (N, 3), unit).

    The vertex that stays keeps its place (a half-edge collapse), so every vertex stays a
    vertex of the starting mesh: i if that keeps the points within, else j; a boundary
    vertex always stays, and no boundary edge collapses, so that the boundary keeps its
    place. Returns an outcome code: ENERGY_INCREASE when a point would lie too far.
    """
    V = state.V
    n_edge, _, _, n_region, n_new, _, boundary_i, boundary_j = _collapse_region(
        state, scratch, i, j
    )
    if n_edge == 0 or (boundary_i and boundary_j):
        return ILLEGAL_TOPOLOGY  # the boundary keeps every vertex
    region = scratch.region
    pts, _ = _gather_points(state, region, n_region, scratch.pts)
    n = pts.shape[0]
    face, bary, d2 = scratch.face[:n], scratch.bary[:n], scratch.d2[:n]
    _adjacent(scratch.new_faces, n_new, scratch.near)
    h = scratch.position
    within = False
    for end in (i, j):
        if (boundary_i and end == j) or (boundary_j and end == i):
            continue
        _copy(h, V[end])
        _guesses(state, pts, scratch.global_face, n_new, face)
        within = np.isfinite(
            _project_local(
                state,
                scratch,
                pts,
                scratch.new_faces,
                n_new,
                scratch.near,
                h,
                face,
                bary,
                d2,
            )  # fmt: skip
        )
        if within:
            break
    if not within:
        return ENERGY_INCREASE
    if not _fold_ok(state, scratch, region, n_region, scratch.new_faces, n_new, h, min_cos):
        return BAD_DIHEDRAL
    if not _facing(state, scratch, normals, pts, face, n_new, h, min_cos):
        return BAD_DIHEDRAL
    _apply_collapse(state, i, j, h, scratch.edge, n_edge)
    _reassign(state, region, n_region, pts, scratch.global_face, face, bary, d2)
    return ACCEPTED


@jit
def try_split(state, scratch, i, j, kappa, c_rep, min_cos, force, hold, result):
    """Split edge (i, j) at a new vertex if that lowers the energy (always legal, but for
    a boundary edge with `hold`, which keeps the boundary as it is).

    `result` gets the energy change and the new vertex. Returns an outcome code.
    """
    V, F, vf, deg = state.V, state.F, state.vf, state.deg
    alive_v, alive_f = state.alive_v, state.alive_f
    sizes = state.sizes
    width = vf.shape[1]
    edge = scratch.edge
    n_edge = _manifold_edge(state, i, j, edge)
    if n_edge == 0 or (hold and n_edge == 1):
        return ILLEGAL_TOPOLOGY
    if sizes[0] >= sizes[3] or sizes[1] + n_edge > sizes[4]:
        return ILLEGAL_TOPOLOGY  # no room left; not a property of the mesh
    n_new = 2 * n_edge
    new_faces, global_face, ring = scratch.new_faces, scratch.global_face, scratch.ring
    ring[0], ring[1] = i, j
    for e in range(n_edge):
        f = edge[e]
        k = _opposite(F, f, i, j)
        if deg[k] + 1 > width:
            return ILLEGAL_TOPOLOGY
        ring[2 + e] = k
        # Rotate so that the face reads (x, y, k) with {x, y} = {i, j}.
        c = 0
        while F[f, (c + 2) % 3] != k:
            c += 1
        x, y = F[f, c], F[f, (c + 1) % 3]
        new_faces[2 * e, 0], new_faces[2 * e, 1], new_faces[2 * e, 2] = x, H, k
        new_faces[2 * e + 1, 0], new_faces[2 * e + 1, 1], new_faces[2 * e + 1, 2] = H, y, k
        global_face[2 * e] = f
        global_face[2 * e + 1] = sizes[1] + e
    pts, old = _gather_points(state, edge, n_edge, scratch.pts)
    old += kappa * ((V[i, 0] - V[j, 0]) ** 2 + (V[i, 1] - V[j, 1]) ** 2 + (V[i, 2] - V[j, 2]) ** 2)
    if not force and old <= c_rep:
        # The new energy is at least 0: the split cannot pay for its vertex.
        result[0] = c_rep - old
        result[1] = sizes[0]
        return ENERGY_INCREASE
    h = scratch.position
    h[:] = 0.5 * (V[i] + V[j])
    n = pts.shape[0]
    face, bary, d2 = scratch.face[:n], scratch.bary[:n], scratch.d2[:n]
    _guesses(state, pts, global_face, n_new, face)
    near = scratch.near
    near[:n_new, :n_new] = True
    new = _fit_vertex(
        state, scratch, pts, new_faces, n_new, near, ring, 2 + n_edge, kappa, old - c_rep,
        face, bary, d2, _LOCAL_ITERATIONS,
    )  # fmt: skip
    delta = new - old + c_rep
    result[0] = delta
    result[1] = sizes[0]
    if not force and delta >= 0.0:
        return ENERGY_INCREASE
    if not _fold_ok(state, scratch, edge, n_edge, new_faces, n_new, h, min_cos):
        return BAD_DIHEDRAL
    # Apply: vertex s at h; face f becomes (x, s, k), a new face g is (s, y, k).
    s = sizes[0]
    sizes[0] += 1
    sizes[2] += 1
    _copy(V[s], h)
    alive_v[s] = True
    deg[s] = 0
    for e in range(n_edge):
        f, g = global_face[2 * e], global_face[2 * e + 1]
        x, y, k = new_faces[2 * e, 0], new_faces[2 * e + 1, 1], new_faces[2 * e, 2]
        F[f, 0], F[f, 1], F[f, 2] = x, s, k
        _remove_face(vf, deg, y, f)
        _add_face(vf, deg, s, f)
        F[g, 0], F[g, 1], F[g, 2] = s, y, k
        alive_f[g] = True
        _add_face(vf, deg, s, g)
        _add_face(vf, deg, y, g)
        _add_face(vf, deg, k, g)
    sizes[1] += n_edge
    _reassign(state, edge, n_edge, pts, global_face, face, bary, d2)
    return ACCEPTED


@jit
def _swap_region(state, scratch, i, j):
    # Whether interior edge (i, j) may be swapped for the other diagonal (k, m), and what
    # it changes: scratch.edge holds f1 (running i -> j) and f2, new_faces the faces
    # (i, m, k) and (m, j, k), global_face f1 and f2. Returns f1, f2, k, m; f1 -1: illegal.
    F, vf, deg, alive_v = state.F, state.vf, state.deg, state.alive_v
    width = vf.shape[1]
    no = np.int64(-1)
    if i == j or not alive_v[i] or not alive_v[j]:
        return no, no, no, no
    edge = scratch.edge
    if _edge_faces(state, i, j, edge) != 2:
        return no, no, no, no  # boundary edges are never swapped
    # Name the faces so that f1 runs i -> j and f2 runs j -> i.
    f1, f2 = edge[0], edge[1]
    c = 0
    while F[f1, c] != i:
        c += 1
    if F[f1, (c + 1) % 3] != j:
        f1, f2 = f2, f1
    edge[0], edge[1] = f1, f2
    k, m = _opposite(F, f1, i, j), _opposite(F, f2, i, j)
    if k == m or deg[k] + 1 > width or deg[m] + 1 > width:
        return no, no, no, no
    if _edge_faces(state, k, m, scratch.probe) > 0:
        return no, no, no, no  # (k, m) is an edge already
    ring_i = scratch.ring_i
    _, boundary_i = _neighbours(state, i, ring_i, scratch.seen)
    _, boundary_j = _neighbours(state, j, ring_i, scratch.seen)
    # i and j each lose a face: keep an interior vertex with three faces at least.
    if deg[i] - 1 < (1 if boundary_i else 3) or deg[j] - 1 < (1 if boundary_j else 3):
        return no, no, no, no
    new_faces, global_face = scratch.new_faces, scratch.global_face
    new_faces[0, 0], new_faces[0, 1], new_faces[0, 2] = i, m, k
    new_faces[1, 0], new_faces[1, 1], new_faces[1, 2] = m, j, k
    global_face[0], global_face[1] = f1, f2
    return f1, f2, k, m


@jit
def _apply_swap(state, i, j, f1, f2, k, m):
    F, vf, deg = state.F, state.vf, state.deg
    F[f1, 0], F[f1, 1], F[f1, 2] = i, m, k
    F[f2, 0], F[f2, 1], F[f2, 2] = m, j, k
    _remove_face(vf, deg, j, f1)
    _add_face(vf, deg, m, f1)
    _remove_face(vf, deg, i, f2)
    _add_face(vf, deg, k, f2)


@jit
def _swap_projection(state, scratch):
    # The points on the two faces of a swap (`_swap_region`) projected onto its two new
    # faces: pts, their energies before and after (inf once one lies farther than its
    # limit), and face, bary, d2 of the new projection.
    two = np.int64(2)  # a literal 2 would compile each callee once more, for Literal[int](2)
    pts, old = _gather_points(state, scratch.edge, two, scratch.pts)
    n = pts.shape[0]
    face, bary, d2 = scratch.face[:n], scratch.bary[:n], scratch.d2[:n]
    _guesses(state, pts, scratch.global_face, two, face)
    scratch.near[:2, :2] = True
    h = scratch.position  # no corner is the new vertex; unused
    new = _project_local(
        state, scratch, pts, scratch.new_faces, two, scratch.near, h, face, bary, d2
    )
    return pts, old, new, face, bary, d2


@jit
def try_swap(state, scratch, i, j, kappa, c_rep, min_cos, force, hold, result):
    """Swap interior edge (i, j) for the other diagonal (k, m) if legal and lowering energy.

    `result` gets the energy change. Returns an outcome code. `hold` changes nothing: a
    swap never moves the boundary.
    """
    V = state.V
    f1, f2, k, m = _swap_region(state, scratch, i, j)
    if f1 < 0:
        return ILLEGAL_TOPOLOGY
    pts, old, new, face, bary, d2 = _swap_projection(state, scratch)
    old += kappa * ((V[i, 0] - V[j, 0]) ** 2 + (V[i, 1] - V[j, 1]) ** 2 + (V[i, 2] - V[j, 2]) ** 2)
    new += kappa * ((V[k, 0] - V[m, 0]) ** 2 + (V[k, 1] - V[m, 1]) ** 2 + (V[k, 2] - V[m, 2]) ** 2)
    delta = new - old
    result[0] = delta
    result[1] = -1
    if not force and delta >= 0.0:
        return ENERGY_INCREASE
    two = np.int64(2)  # a literal 2 would compile each callee once more, for Literal[int](2)
    edge, h = scratch.edge, scratch.position  # no corner is the new vertex: h unused
    if not _fold_ok(state, scratch, edge, two, scratch.new_faces, two, h, min_cos):
        return BAD_DIHEDRAL
    _apply_swap(state, i, j, f1, f2, k, m)
    _reassign(state, edge, two, pts, scratch.global_face, face, bary, d2)
    return ACCEPTED


@jit
def try_swap_within(state, scratch, normals, i, j, min_cos):
    """Swap interior edge (i, j) for the other diagonal if that is legal, brings the points
    on its two faces nearer (their squared distances summed) and keeps each within
    its limit of a face within arccos(`min_cos`) of its normal (as `try_collapse_within`).
    Returns an outcome code."""
    f1, f2, k, m = _swap_region(state, scratch, i, j)
    if f1 < 0:
        return ILLEGAL_TOPOLOGY
    pts, old, new, face, bary, d2 = _swap_projection(state, scratch)
    if new >= old:
        return ENERGY_INCREASE
    two = np.int64(2)
    edge, h, global_face = scratch.edge, scratch.position, scratch.global_face
    if not _fold_ok(state, scratch, edge, two, scratch.new_faces, two, h, min_cos):
        return BAD_DIHEDRAL
    if not _facing(state, scratch, normals, pts, face, two, h, min_cos):
        return BAD_DIHEDRAL
    _apply_swap(state, i, j, f1, f2, k, m)
    _reassign(state, edge, two, pts, global_face, face, bary, d2)
    return ACCEPTED


# ------------------------------------------------------------------ one pass over the edges


@jit
def _push_star(state, v, queue, tail, capacity, head, probe):
    # Queue every edge of the faces around v once, each at a random place among those
    # waiting: of a face (v, a, b), the edges (v, a) and (a, b), and (b, v) only where it
    # is a boundary edge (inside, the next face around v holds it as its (v, b)). `probe`
    # is scratch for `_edge_faces`.
    F, vf, deg = state.F, state.vf, state.deg
    for k in range(deg[v]):
        f = vf[v, k]
        c = 0
        while F[f, c] != v:
            c += 1
        a, b = F[f, (c + 1) % 3], F[f, (c + 2) % 3]
        for e in range(3):
            if e == 2 and _edge_faces(state, v, b, probe) > 1:
                break
            if tail - head >= capacity:
                return tail
            slot = tail % capacity
            queue[slot, 0], queue[slot, 1] = (v, a) if e == 0 else (a, b) if e == 1 else (b, v)
            other = head + np.random.randint(0, tail - head + 1)  # noqa: NPY002 (Numba's own)
            if other != tail:
                o = other % capacity
                for m in range(2):
                    queue[slot, m], queue[o, m] = queue[o, m], queue[slot, m]
            tail += 1
    return tail


@jit
def _owned(state, owner, label, i, j):
    # Whether every corner of the faces around i and j is labelled `label`. Moves so
    # labelled run at once without touching each other's data: a move writes only the
    # faces around its edge, the positions and face lists of their corners and the points
    # on them, all of one label; what else it reads (the faces around those corners and
    # their positions) touches a vertex of its label, which no move of another label
    # writes or moves.
    F, vf, deg = state.F, state.vf, state.deg
    if owner[i] != label or owner[j] != label:
        return False
    for v in (i, j):
        for k in range(deg[v]):
            f = vf[v, k]
            for c in range(3):
                if owner[F[f, c]] != label:
                    return False
    return True


@jit
def run_pass(
    state, scratch, owner, label, edges, kappa, c_rep, min_cos, hold, seed, max_attempts,
    tally, deferred,
):  # fmt: skip
    """Try the moves on every edge of `edges` (E, 2), in that order, until none is left.

    For each candidate edge, collapse, then swap, then split are tried (Hoppe 1993, §4.2);
    after an accepted move the edges around its vertices join the queue at random places.
    `tally` (3, 4) int64 counts the outcome of each kind of move. With `hold`, no move
    moves the boundary (see `try_collapse`, `try_split`).

    With `label` >= 0, an edge is tried only if every face around its ends has all its
    corners labelled `label` in `owner` (Vc,) int64 (see `_owned`); the others
    go to `deferred` (Q, 2) int64, as many as fit, and a split's new vertex takes the
    label. Moves on different labels then touch disjoint parts of the state, so passes over
    them may run at once. With `label` -1 every edge is tried.

    Returns the energy change of the accepted moves and the number of deferred edges.
    """
    np.random.seed(seed)  # noqa: NPY002 (seeds Numba's generator from the caller's Generator)
    capacity = max(8 * edges.shape[0], 1024)
    queue = np.zeros((capacity, 2), dtype=np.int64)
    n = min(edges.shape[0], capacity)
    _copy_rows(queue, edges, n)
    head, tail = 0, n
    result = np.zeros(2)
    # A typed False: a literal one would compile each move once more, for Literal[bool],
    # beside the bool signature that `zeroset.optimization.moves.MoveState` calls.
    unforced = np.bool_(False)
    alive_v = state.alive_v
    total = 0.0
    attempts = 0
    n_deferred = 0
    while head < tail and attempts < max_attempts:
        slot = head % capacity
        i, j = queue[slot, 0], queue[slot, 1]
        head += 1
        if label >= 0 and not _owned(state, owner, label, i, j):
            if n_deferred < deferred.shape[0]:
                deferred[n_deferred, 0], deferred[n_deferred, 1] = i, j
                n_deferred += 1
            continue
        if not alive_v[i] or not alive_v[j] or _edge_faces(state, i, j, scratch.probe) == 0:
            continue  # the edge went with an earlier move
        attempts += 1
        outcome = try_collapse(state, scratch, i, j, kappa, c_rep, min_cos, unforced, hold, result)
        tally[COLLAPSE, outcome] += 1
        if outcome == ACCEPTED:
            total += result[0]
            tail = _push_star(state, i, queue, tail, capacity, head, scratch.probe)
            continue
        outcome = try_swap(state, scratch, i, j, kappa, c_rep, min_cos, unforced, hold, result)
        tally[SWAP, outcome] += 1
        if outcome == ACCEPTED:
            total += result[0]
            tail = _push_star(state, i, queue, tail, capacity, head, scratch.probe)
            tail = _push_star(state, j, queue, tail, capacity, head, scratch.probe)
            continue
        outcome = try_split(state, scratch, i, j, kappa, c_rep, min_cos, unforced, hold, result)
        tally[SPLIT, outcome] += 1
        if outcome == ACCEPTED:
            total += result[0]
            s = int(result[1])
            if label >= 0:
                owner[s] = label
            tail = _push_star(state, s, queue, tail, capacity, head, scratch.probe)
    return total, n_deferred


@jit
def run_within_pass(state, scratch, normals, owner, label, edges, min_cos, tally, deferred):
    """Try `try_collapse_within` on every edge of `edges` (E, 2), in that order; after a
    collapse, the edges around its vertex join the end of the queue; where no collapse is
    made, `try_swap_within` is tried, and after a swap the edges around the new diagonal's
    ends join the queue. `tally` (3, 4) int64 counts the outcomes (rows as in `run_pass`).

    With `label` >= 0, an edge is tried only if every face around its ends has all its
    corners labelled `label` in `owner` (Vc,) int64 (see `_owned`); the others go to
    `deferred` (Q, 2) int64, as many as fit, so that passes over different labels may run
    at once. With `label` -1 every edge is tried.

    Returns the number of collapses and of deferred edges.
    """
    F, alive_v = state.F, state.alive_v
    capacity = max(4 * edges.shape[0], 1024)
    queue = np.zeros((capacity, 2), dtype=np.int64)
    n = min(edges.shape[0], capacity)
    _copy_rows(queue, edges, n)
    head, tail = 0, n
    done = 0
    n_deferred = 0
    while head < tail:
        slot = head % capacity
        i, j = queue[slot, 0], queue[slot, 1]
        head += 1
        if not alive_v[i] or not alive_v[j] or _edge_faces(state, i, j, scratch.probe) == 0:
            continue  # the edge went with an earlier collapse
        if label >= 0 and not _owned(state, owner, label, i, j):
            if n_deferred < deferred.shape[0]:
                deferred[n_deferred, 0], deferred[n_deferred, 1] = i, j
                n_deferred += 1
            continue
        outcome = try_collapse_within(state, scratch, normals, i, j, min_cos)
        tally[COLLAPSE, outcome] += 1
        if outcome == ACCEPTED:
            done += 1
            tail = _push_edges(state, i, queue, tail, head)
            continue
        outcome = try_swap_within(state, scratch, normals, i, j, min_cos)
        tally[SWAP, outcome] += 1
        if outcome == ACCEPTED:
            # The new diagonal's ends, corners 1 and 2 of the first face (i, m, k): their
            # edges may collapse now.
            f1 = scratch.edge[0]
            tail = _push_edges(state, F[f1, 1], queue, tail, head)
            tail = _push_edges(state, F[f1, 2], queue, tail, head)
    return done, n_deferred


@jit
def _push_edges(state, v, queue, tail, head):
    # Queue the edges from v, one per face around it; returns the new tail.
    F, vf, deg = state.F, state.vf, state.deg
    capacity = queue.shape[0]
    for k in range(deg[v]):
        f = vf[v, k]
        for c in range(3):
            if tail - head < capacity and F[f, c] == v:
                slot = tail % capacity
                queue[slot, 0], queue[slot, 1] = v, F[f, (c + 1) % 3]
                tail += 1
    return tail

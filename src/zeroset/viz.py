"""Off-screen pictures of meshes and points, rendered with OpenGL (ModernGL, headless).

No display is needed: the context is a standalone one, through EGL where there is no window
system (Mesa's software rasteriser renders a million triangles in well under a second).
"""

from __future__ import annotations

import os
from functools import cache
from pathlib import Path

import numpy as np

from ._extras import require
from ._validate import as_points
from .errors import InputError, ZerosetError
from .io import atomic_target
from .topology import boundary_edges, vertex_normals
from .types import Mesh

__all__ = [
    "RenderError",
    "colour_map",
    "distance_colours",
    "intensity_colours",
    "picture_modules",
    "preview",
    "render",
    "vertex_distances",
]

#: (elevation, azimuth) in degrees of the two views side by side.
VIEWS = ((25.0, -60.0), (70.0, 30.0))
#: At most this many points are drawn; more are drawn from a seeded random subset.
MAX_POINTS = 500_000
_SUPERSAMPLE = 2
_BACKGROUND = (1.0, 1.0, 1.0)
_FRONT, _BACK = (0.35, 0.55, 0.85), (0.85, 0.55, 0.35)  # outside blue, inside orange
_POINT, _BOUNDARY, _NORMAL = (0.15, 0.15, 0.15), (0.85, 0.05, 0.05), (0.1, 0.6, 0.2)

_SURFACE_SHADERS = (
    """
    #version 330
    uniform mat4 mvp;
    in vec3 position;
    in vec3 normal;
    in vec3 colour;
    out vec3 v_normal;
    out vec3 v_colour;
    void main() {
        gl_Position = mvp * vec4(position, 1.0);
        v_normal = normal;
        v_colour = colour;
    }
    """,
    """
    #version 330
    uniform vec3 light;
    uniform vec3 back;
    uniform bool tint_back;
    in vec3 v_normal;
    in vec3 v_colour;
    out vec4 colour;
    void main() {
        vec3 n = normalize(v_normal);
        vec3 base = v_colour;
        if (!gl_FrontFacing) {
            n = -n;
            if (tint_back) base = back;
        }
        float diffuse = max(dot(n, light), 0.0);
        colour = vec4(base * (0.3 + 0.7 * diffuse), 1.0);
    }
    """,
)
_FLAT_SHADERS = (
    """
    #version 330
    uniform mat4 mvp;
    uniform float size;
    in vec3 position;
    in vec3 colour;
    out vec3 v_colour;
    void main() {
        gl_Position = mvp * vec4(position, 1.0);
        gl_PointSize = size;
        v_colour = colour;
    }
    """,
    """
    #version 330
    in vec3 v_colour;
    out vec4 colour;
    void main() { colour = vec4(v_colour, 1.0); }
    """,
)


class RenderError(ZerosetError, RuntimeError):
    """No OpenGL context could be created on this machine."""


def render(
    mesh: Mesh,
    *,
    points=None,
    point_colours=None,
    normals=None,
    boundaries: bool = True,
    colours=None,
    width: int = 1200,
    height: int = 600,
    views=VIEWS,
    rng=0,
) -> np.ndarray:
    """Render a mesh, shaded, from several views side by side.

    Faces seen from outside (counter-clockwise) are blue and faces seen from inside orange,
    so a wrongly oriented patch shows at a glance; `colours` replaces the outside colour.

    Parameters
    ----------
    mesh : Mesh
    points : (N, 3) array_like of float, optional
        Drawn as dots (at most `MAX_POINTS`, a seeded random subset beyond).
    point_colours : (N, 3) array_like of float in [0, 1], optional
        A colour per point, e.g. ``intensity_colours(cloud.intensity)``; dark grey if None.
    normals : tuple of two (K, 3) array_like of float, optional
        Origins and unit directions, drawn as short green lines.
    boundaries : bool
        Draw the boundary edges in red.
    colours : (M, 3) array_like of float in [0, 1], optional
        Per-vertex colour, e.g. ``distance_colours(vertex_distances(mesh, points))``.
    width, height : int
        Picture size in pixels.
    views : sequence of (elevation, azimuth) in degrees
        One panel per view, left to right.
    rng : numpy.random.Generator or int or None
        Chooses the points drawn when there are too many.

    Returns
    -------
    (height, width, 3) uint8
        The picture, top row first.

    Raises
    ------
    InputError
        If the mesh has no faces.
    RenderError
        When no OpenGL context can be created (on Linux without a display, Mesa's EGL
        libraries are needed: ``apt-get install libegl1 libgl1-mesa-dri``).
    """
    moderngl = picture_modules()[0]

    if mesh.n_faces == 0:
        raise InputError("nothing to render: the mesh has no faces")
    ctx = _context()
    centre, radius = _bounding_sphere(mesh.vertices)
    scale = 1.0 / radius  # draw in a unit frame: float32 keeps full precision far from 0
    vertices = ((mesh.vertices - centre) * scale).astype(np.float32)
    base = np.broadcast_to(np.asarray(_FRONT, np.float32), vertices.shape)
    if colours is not None:
        base = np.asarray(colours, dtype=np.float32).reshape(vertices.shape)
    layers = []  # (mode, (K, 3) positions in the unit frame, colour(s)) drawn over the surface
    if points is not None:
        points = as_points(points)
        tint = _POINT
        if point_colours is not None:
            tint = np.asarray(point_colours, dtype=np.float64).reshape(points.shape)
        if points.shape[0] > MAX_POINTS:
            keep = np.random.default_rng(rng).choice(points.shape[0], MAX_POINTS, replace=False)
            points = points[keep]
            tint = tint if point_colours is None else tint[keep]
        layers.append((moderngl.POINTS, (points - centre) * scale, tint))
    if boundaries:
        ends = mesh.vertices[boundary_edges(mesh.faces)].reshape(-1, 3)
        layers.append((moderngl.LINES, (ends - centre) * scale, _BOUNDARY))
    if normals is not None:
        origins, directions = as_points(normals[0], "origins"), as_points(normals[1], "normals")
        tips = origins + directions * (0.03 * radius)
        ends = np.stack([origins, tips], axis=1).reshape(-1, 3)
        layers.append((moderngl.LINES, (ends - centre) * scale, _NORMAL))

    ss = _SUPERSAMPLE
    size = (width * ss, height * ss)
    made = []  # every GL object of this call, released at the end: the context lives on

    def keep(resource):
        made.append(resource)
        return resource

    try:
        surface = keep(
            ctx.program(vertex_shader=_SURFACE_SHADERS[0], fragment_shader=_SURFACE_SHADERS[1])
        )
        flat = keep(ctx.program(vertex_shader=_FLAT_SHADERS[0], fragment_shader=_FLAT_SHADERS[1]))
        data = np.hstack([vertices, vertex_normals(mesh).astype(np.float32), base])
        surface_vao = keep(
            ctx.vertex_array(
                surface,
                [(keep(ctx.buffer(data.tobytes())), "3f 3f 3f", "position", "normal", "colour")],
                index_buffer=keep(ctx.buffer(mesh.faces.astype(np.uint32).tobytes())),
            )
        )
        overlays = [
            (mode, keep(ctx.vertex_array(flat, [(keep(ctx.buffer(_coloured(p, tint))), "3f 3f",
                                                 "position", "colour")])))  # fmt: skip
            for mode, p, tint in layers
            if p.shape[0]
        ]
        fbo = keep(ctx.simple_framebuffer(size))
        fbo.use()
        fbo.clear(*_BACKGROUND, 1.0, depth=1.0)
        ctx.enable(moderngl.DEPTH_TEST | moderngl.PROGRAM_POINT_SIZE)
        panel = size[0] // len(views)
        for index, (elevation, azimuth) in enumerate(views):
            ctx.viewport = (index * panel, 0, panel, size[1])
            mvp, eye = _camera(elevation, azimuth, panel / size[1])
            surface["mvp"].write(mvp.T.astype(np.float32).tobytes())
            surface["light"].value = tuple(eye)
            surface["back"].value = _BACK
            surface["tint_back"].value = colours is None
            ctx.polygon_offset = 1.0, 1.0  # lines and points drawn on the surface stay visible
            surface_vao.render(moderngl.TRIANGLES)
            ctx.polygon_offset = 0.0, 0.0
            flat["mvp"].write(mvp.T.astype(np.float32).tobytes())
            flat["size"].value = float(ss)
            for mode, vao in overlays:
                vao.render(mode)
        picture = np.frombuffer(fbo.read(components=3), dtype=np.uint8)
    finally:
        for resource in reversed(made):
            resource.release()
    picture = picture.reshape(size[1], size[0], 3)
    picture = picture[::-1].reshape(height, ss, width, ss, 3).mean(axis=(1, 3))
    return np.round(picture).astype(np.uint8)


def _coloured(positions: np.ndarray, tint) -> bytes:
    """Interleaved float32 (position, colour) rows; `tint` one colour or one per row."""
    colours = np.broadcast_to(np.asarray(tint, dtype=np.float64), positions.shape)
    return np.hstack([positions, colours]).astype(np.float32).tobytes()


def preview(mesh: Mesh, path: str | os.PathLike, *, title: str | None = None, **options) -> Path:
    """Render `mesh` (see :func:`render`, which takes the same options) and write a PNG.

    Parameters
    ----------
    mesh : Mesh
    path : str or os.PathLike
        The picture to write, atomically.
    title : str, optional
        A line of text at the top; by default the vertex and triangle counts.

    Returns
    -------
    pathlib.Path
    """
    _, image, draw = picture_modules()

    target = Path(path)
    picture = image.fromarray(render(mesh, **options))
    text = title or f"{mesh.n_vertices:,} vertices, {mesh.n_faces:,} triangles"
    draw.Draw(picture).text((10, 8), text, fill=(0, 0, 0))
    with atomic_target(target) as temporary:
        picture.save(temporary, format="PNG")
    return target


def vertex_distances(mesh: Mesh, points) -> np.ndarray:
    """Return how far the data lie from the mesh around each vertex.

    Every point is projected onto the mesh exactly (see
    :func:`zeroset.evaluate.closest_points_on_mesh`); a face gets the mean distance of the
    points that land on it, a vertex the mean over its faces that got any. A vertex with no
    point on any of its faces gets NaN.

    Parameters
    ----------
    mesh : Mesh
    points : (N, 3) array_like of float

    Returns
    -------
    (M,) float64, in data units
    """
    from .evaluate import closest_points_on_mesh

    _, face, distance = closest_points_on_mesh(points, mesh)
    hits = np.bincount(face, minlength=mesh.n_faces)
    face_mean = np.bincount(face, distance, mesh.n_faces) / np.maximum(hits, 1)
    corners = mesh.faces.reshape(-1)
    covered = np.repeat(hits > 0, 3)
    total = np.bincount(corners[covered], np.repeat(face_mean, 3)[covered], mesh.n_vertices)
    count = np.bincount(corners[covered], minlength=mesh.n_vertices)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / count, np.nan)


def distance_colours(distances, *, limit: float | None = None) -> np.ndarray:
    """Map distances to colours (viridis: dark near, yellow far; grey where NaN).

    Parameters
    ----------
    distances : (M,) array_like of float
        E.g. from :func:`vertex_distances`.
    limit : float, optional
        Distance shown in the brightest colour; by default the 95th percentile.

    Returns
    -------
    (M, 3) float64 in [0, 1]
    """
    viridis = colour_map("viridis")

    distances = np.asarray(distances, dtype=np.float64)
    known = np.isfinite(distances)
    if limit is None:
        limit = float(np.percentile(distances[known], 95)) if known.any() else 1.0
    colours = viridis(np.clip(np.nan_to_num(distances) / max(limit, 1e-300), 0, 1))
    colours[~known] = 0.6
    return colours[:, :3]


def intensity_colours(intensity) -> np.ndarray:
    """Map return intensities to colours (plasma: weak dark blue, strong yellow).

    The 2nd to 98th percentiles span the colour map, so a few saturated returns do not
    wash out the rest.

    Parameters
    ----------
    intensity : (N,) array_like of float
        E.g. ``zeroset.io.read_points(path).intensity``.

    Returns
    -------
    (N, 3) float64 in [0, 1]
    """
    plasma = colour_map("plasma")

    intensity = np.asarray(intensity, dtype=np.float64)
    low, high = np.percentile(intensity, [2, 98]) if intensity.size else (0.0, 1.0)
    scaled = np.clip((intensity - low) / max(high - low, 1e-300), 0.0, 1.0)
    return plasma(scaled)[:, :3]


def colour_map(name: str):
    """matplotlib's colour map `name` (the ``render`` extra): values in [0, 1] to RGBA."""
    return require("matplotlib", "colour maps").colormaps[name]


def picture_modules() -> tuple:
    """moderngl, PIL.Image and PIL.ImageDraw: what drawing a picture imports (the
    ``render`` extra)."""
    return tuple(
        require(name, "drawing pictures") for name in ("moderngl", "PIL.Image", "PIL.ImageDraw")
    )


@cache
def _context():
    """One standalone OpenGL context per process: the platform's own, else EGL."""
    moderngl = picture_modules()[0]

    errors = []
    for backend in (None, "egl"):
        try:
            options = {} if backend is None else {"backend": backend}
            return moderngl.create_standalone_context(require=330, **options)
        except Exception as error:  # each backend fails in its own way
            errors.append(f"{backend or 'default'}: {error}")
    raise RenderError(
        "no OpenGL context for rendering (" + "; ".join(errors) + "); on Linux without a "
        "display install Mesa's EGL: apt-get install libegl1 libgl1-mesa-dri"
    )


def _bounding_sphere(vertices: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre and radius of the bounding box's sphere."""
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    return (lo + hi) / 2.0, max(float(np.linalg.norm(hi - lo)) / 2.0, 1e-12)


def _camera(elevation: float, azimuth: float, aspect: float) -> tuple[np.ndarray, np.ndarray]:
    """(4, 4) projection x view matrix looking at the unit sphere, and the unit eye direction."""
    e, a = np.radians(elevation), np.radians(azimuth)
    eye = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    up = np.array([0.0, 0.0, 1.0]) if abs(eye[2]) < 0.99 else np.array([0.0, 1.0, 0.0])
    forward = -eye
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    true_up = np.cross(right, forward)
    distance = 1.0 / np.sin(np.radians(15.0))  # a 30 degree field of view fits the sphere
    view = np.eye(4)
    view[:3, :3] = np.stack([right, true_up, -forward])
    view[:3, 3] = -view[:3, :3] @ (eye * distance)
    near, far = distance - 1.5, distance + 1.5
    f = 1.0 / np.tan(np.radians(15.0))
    projection = np.zeros((4, 4))
    projection[0, 0] = f / max(aspect, 1.0)
    projection[1, 1] = f * min(aspect, 1.0)
    projection[2, 2] = (far + near) / (near - far)
    projection[2, 3] = 2.0 * far * near / (near - far)
    projection[3, 2] = -1.0
    return projection @ view, eye

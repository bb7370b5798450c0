"""Pictures of an inspection: the unrolled deviation map, ovality along the pipe, and the mesh
coloured by deviation. Each is returned as PNG bytes; matplotlib is imported when drawing."""

from __future__ import annotations

import io

import numpy as np

from .._extras import require
from ..types import Mesh
from ._inspection import Inspection

__all__ = ["clock_label", "deviation_colours", "deviation_map", "mesh_picture", "ovality_plot"]

#: Diverging colour map: blue inward, white on the nominal wall, red outward.
COLOURS = "RdBu_r"


def picture_modules() -> tuple:
    """What the inspection's pictures import (the ``render`` extra): matplotlib's figures,
    and what `zeroset.viz.picture_modules` names for the picture of the mesh."""
    from .. import viz

    return (require("matplotlib.figure", "inspection plots"), *viz.picture_modules())


def clock_label(clock: float) -> str:
    """A clock angle in degrees as the time on a clock face: 0 is 12:00, 90 is 3:00."""
    minutes = int(round((clock % 360.0) * 2.0)) % 720  # 360 degrees are 720 minutes
    hours = minutes // 60 or 12
    return f"{hours}:{minutes % 60:02d}"


def colour_limit(inspection: Inspection) -> float:
    """Deviation (m) shown in the deepest colours: the 99th percentile of the map's
    |deviation|, at least twice the defect threshold."""
    known = np.abs(inspection.wall.deviation[np.isfinite(inspection.wall.deviation)])
    limit = float(np.percentile(known, 99)) if known.size else 0.0
    return max(limit, 2.0 * inspection.defects.threshold, 1e-6)


def deviation_colours(deviation, limit: float) -> np.ndarray:
    """(M, 3) colours in [0, 1] of signed deviations (m): blue inward, red outward, at
    `limit` the deepest; grey where NaN."""
    from ..viz import colour_map

    deviation = np.asarray(deviation, dtype=np.float64)
    scaled = 0.5 + 0.5 * np.clip(np.nan_to_num(deviation) / limit, -1.0, 1.0)
    colours = colour_map(COLOURS)(scaled)[:, :3]
    colours[~np.isfinite(deviation)] = 0.6
    return colours


def deviation_map(inspection: Inspection, *, title: str | None = None) -> bytes:
    """PNG of the unrolled wall: axial position against clock angle, coloured by deviation
    in mm, with the defects outlined and numbered and the branches marked."""
    figure, axes = _figure(11.0, 4.2)
    wall, limit = inspection.wall, 1000.0 * colour_limit(inspection)
    extent = (wall.axial_edges[0], wall.axial_edges[-1], 360.0, 0.0)
    image = axes.imshow(
        1000.0 * wall.deviation.T,
        cmap=COLOURS,
        vmin=-limit,
        vmax=limit,
        extent=extent,
        aspect="auto",
        interpolation="nearest",
    )
    colour_bar = figure.colorbar(image, ax=axes, pad=0.01)
    colour_bar.set_label("deviation, mm (- inward, + outward)")
    labels = inspection.defects.labels
    if (labels >= 0).any():
        middle_axial = 0.5 * (wall.axial_edges[:-1] + wall.axial_edges[1:])
        middle_clock = 0.5 * (wall.clock_edges[:-1] + wall.clock_edges[1:])
        axes.contour(
            middle_axial, middle_clock, (labels >= 0).T.astype(float), levels=[0.5],
            colors="black", linewidths=0.8,
        )  # fmt: skip
    for number, defect in enumerate(inspection.defects.defects, start=1):
        axes.annotate(
            f"{number}",
            (defect.axial, defect.clock),
            xytext=(4, -4),
            textcoords="offset points",
            fontsize=8,
            fontweight="bold",
        )
    for branch in inspection.defects.branches:
        axes.annotate("branch", (branch.axial, branch.clock), ha="center", fontsize=8)
    axes.set_xlim(0.0, inspection.pipe.length)
    axes.set_yticks(np.arange(0.0, 361.0, 90.0), ["12:00", "3:00", "6:00", "9:00", "12:00"])
    axes.set_xlabel("axial position along the centreline, m")
    axes.set_ylabel("clock position")
    axes.set_title(title or _headline(inspection))
    return _png(figure)


def ovality_plot(inspection: Inspection) -> bytes:
    """PNG of the ovality per station along the pipe, in percent."""
    figure, axes = _figure(11.0, 3.0)
    found = inspection.ovality
    axes.plot(found.axial, 100.0 * found.ovality, lw=1.2, color="#1f4e99")
    axes.set_xlim(0.0, inspection.pipe.length)
    axes.set_ylim(bottom=0.0)
    axes.set_xlabel("axial position along the centreline, m")
    axes.set_ylabel("ovality, %")
    axes.set_title("ovality (D_max - D_min) / D_nominal per station")
    axes.grid(alpha=0.3)
    return _png(figure)


def mesh_picture(mesh: Mesh, inspection: Inspection, *, width=1200, height=600) -> bytes:
    """PNG of the mesh coloured by each vertex's deviation (needs OpenGL; see
    `zeroset.viz.render`)."""
    image = require("PIL.Image", "writing pictures")

    from ..viz import render

    colours = deviation_colours(inspection.vertex_deviation, colour_limit(inspection))
    pixels = render(mesh, colours=colours, width=width, height=height)
    buffer = io.BytesIO()
    image.fromarray(pixels).save(buffer, format="PNG")
    return buffer.getvalue()


def _headline(inspection: Inspection) -> str:
    pipe, count = inspection.pipe, len(inspection.defects.defects)
    return (
        f"deviation from the nominal pipe (D = {2000.0 * pipe.radius:.1f} mm, "
        f"{pipe.length:.2f} m): {count} defect{'s' if count != 1 else ''}"
    )


def _figure(width: float, height: float):
    figures = require("matplotlib.figure", "inspection plots")

    figure = figures.Figure(figsize=(width, height), dpi=110, layout="constrained")
    return figure, figure.add_subplot()


def _png(figure) -> bytes:
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png")
    return buffer.getvalue()

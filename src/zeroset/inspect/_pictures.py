"""Pictures of an inspection: the unrolled deviation map, ovality along the pipe, and the mesh
coloured by deviation. Each is returned as PNG bytes; matplotlib is imported when drawing."""

from __future__ import annotations

import io

import numpy as np

from .._extras import require
from ..types import Mesh
from ._inspection import Inspection

__all__ = [
    "clock_label",
    "colour_range",
    "colour_ticks",
    "deviation_colours",
    "deviation_map",
    "deviation_norm",
    "mesh_picture",
    "ovality_plot",
    "place_labels",
    "stretch",
]

#: Diverging colour map: blue inward, white on the nominal wall, red outward.
COLOURS = "RdBu_r"
#: Share of each half of the colour map given to the noise, within +-threshold: its pale
#: middle. Beyond, the colours deepen logarithmically out to the deepest defect.
NOISE_BAND = 0.3
#: Least distance, as a share of the colour bar, between two of its ticks.
TICK_GAP = 0.07
#: Font size of the map's labels, and their least clearance from what they must not cover,
#: points.
LABEL_SIZE = 7.5
LABEL_GAP = 3.0
#: A label's area outside the picture costs this many times its area over what it must
#: not cover.
OUTSIDE = 10.0


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


def colour_range(inspection: Inspection) -> tuple[float, float]:
    """The noise band and the deepest colours of the deviations, metres.

    Returns
    -------
    threshold : float
        The defect threshold (`Defects.threshold`; at least a thousandth of `limit`).
    limit : float
        The deviation shown in the deepest colours: the deepest defect's depth, at least the
        99th percentile of the map's |deviation| and twice the threshold.
    """
    deviation = inspection.wall.deviation
    known = np.abs(deviation[np.isfinite(deviation)])
    deepest = max((abs(d.depth) for d in inspection.defects.defects), default=0.0)
    threshold = inspection.defects.threshold
    limit = max(
        deepest, float(np.percentile(known, 99)) if known.size else 0.0, 2.0 * threshold, 1e-6
    )
    return max(threshold, 1e-3 * limit), limit


def stretch(values, threshold: float, limit: float) -> np.ndarray:
    """Signed deviations as places on the diverging colour map, 0 to 1.

    Within +-`threshold` (the noise) linearly onto the map's pale middle, ``0.5 +-
    NOISE_BAND / 2``; beyond, logarithmically in |deviation|, out to 0 at ``-limit`` and 1 at
    `limit` (and past them beyond). `threshold` and `limit` are in the values' units, with
    ``0 < threshold < limit``. Masked arrays stay masked.
    """
    values = np.asanyarray(values, dtype=np.float64)
    size = np.abs(values)
    inner = NOISE_BAND * np.minimum(size, threshold) / threshold
    outer = (1.0 - NOISE_BAND) * np.log(np.maximum(size, threshold) / threshold)
    return 0.5 + 0.5 * np.sign(values) * (inner + outer / np.log(limit / threshold))


def _unstretch(places, threshold: float, limit: float) -> np.ndarray:
    """The deviations at `places` on the colour map: the inverse of `stretch`."""
    places = np.asanyarray(places, dtype=np.float64)
    half = np.abs(2.0 * places - 1.0)
    inner = threshold * np.minimum(half, NOISE_BAND) / NOISE_BAND
    outer = np.exp(
        np.maximum(half - NOISE_BAND, 0.0) / (1.0 - NOISE_BAND) * np.log(limit / threshold)
    )
    return np.sign(places - 0.5) * inner * outer


def deviation_norm(threshold: float, limit: float):
    """The matplotlib norm of `stretch`, from ``-limit`` to `limit`: a colour bar drawn with
    it gives the noise band and each decade beyond their share of its length."""
    colors = require("matplotlib.colors", "inspection plots")

    return colors.FuncNorm(
        (lambda v: stretch(v, threshold, limit), lambda p: _unstretch(p, threshold, limit)),
        vmin=-limit,
        vmax=limit,
    )


def colour_ticks(threshold: float, limit: float) -> np.ndarray:
    """Ticks of the colour bar, ascending, in the arguments' units: 0, +-`threshold`,
    +-`limit`, and between those the values 1, 2 and 5 times a power of ten that lie at
    least `TICK_GAP` of the bar from their neighbours."""
    decades = 10.0 ** np.arange(np.floor(np.log10(threshold)), np.ceil(np.log10(limit)) + 1)
    nice = np.outer(decades, (1.0, 2.0, 5.0)).ravel()
    top = stretch(limit, threshold, limit)
    ticks = [threshold]
    for value in nice[(nice > threshold) & (nice < limit)]:
        place = stretch(value, threshold, limit)
        if min(place - stretch(ticks[-1], threshold, limit), top - place) >= TICK_GAP:
            ticks.append(float(value))
    positive = np.array([*ticks, limit])
    return np.concatenate([-positive[::-1], [0.0], positive])


def deviation_colours(deviation, threshold: float, limit: float) -> np.ndarray:
    """(M, 3) colours in [0, 1] of signed deviations (m), on the scale of `stretch`: blue
    inward, red outward, pale within +-`threshold`, the deepest at `limit`; grey where
    NaN."""
    from ..viz import colour_map

    deviation = np.asarray(deviation, dtype=np.float64)
    places = np.clip(stretch(np.nan_to_num(deviation), threshold, limit), 0.0, 1.0)
    colours = colour_map(COLOURS)(places)[:, :3]
    colours[~np.isfinite(deviation)] = 0.6
    return colours


def place_labels(anchors, sizes, obstacles, bounds, *, gap: float = 0.0) -> np.ndarray:
    """Place labels beside their anchors, clear of obstacles and of each other.

    Greedy, in the labels' order (the most important first): each label takes the first
    place, on rings round its anchor from the nearest out, and in each ring trying right,
    left, up, down and then the directions between, where its box, grown by `gap`, covers
    no obstacle and no label placed before it, and lies inside `bounds`. Where there is no
    such place it takes the one covering least, its area outside `bounds` counted
    `OUTSIDE` times.

    Parameters
    ----------
    anchors : (n, 2) array_like of float
        The point each label names (e.g. a defect's deepest point), in any one unit of
        length on the picture (e.g. pixels).
    sizes : (n, 2) array_like of float
        Each label's width and height.
    obstacles : (m, 4) array_like of float
        Boxes ``(x0, y0, x1, y1)`` no label may cover, e.g. the regions labelled (which
        hold their anchors: their labels go beside them).
    bounds : (4,) array_like of float
        The box ``(x0, y0, x1, y1)`` the labels lie in.
    gap : float
        Least clearance between a label and an obstacle or another label.

    Returns
    -------
    (n, 2) ndarray of float64
        The labels' centres.

    Examples
    --------
    >>> place_labels([[5.0, 5.0]], [[4.0, 2.0]], [[3.0, 3.0, 7.0, 7.0]], [0, 0, 20, 20])
    array([[9., 5.]])
    """
    anchors = np.asarray(anchors, dtype=np.float64).reshape(-1, 2)
    sizes = np.asarray(sizes, dtype=np.float64).reshape(-1, 2)
    blocked = np.asarray(obstacles, dtype=np.float64).reshape(-1, 4)
    bounds = np.asarray(bounds, dtype=np.float64)
    angles = np.radians([0, 180, 90, 270, 45, 135, 225, 315, 22.5, 157.5, 202.5, 337.5,
                         67.5, 112.5, 247.5, 292.5])  # fmt: skip
    directions = np.column_stack([np.cos(angles), np.sin(angles)])
    step = 0.5 * max(float(sizes[:, 1].min(initial=np.inf)), 1e-9)
    reach = float(np.hypot(*(bounds[2:] - bounds[:2])))
    radii = gap + step * np.arange(int(np.ceil(reach / step)) + 1)
    offsets = (radii[:, None, None] * directions[None]).reshape(-1, 2)
    unit = np.repeat(directions[None], radii.size, axis=0).reshape(-1, 2)
    centres = np.empty_like(anchors)
    for i, (anchor, size) in enumerate(zip(anchors, sizes, strict=True)):
        # the box's edge, not its centre, on the ring: the label starts `radius` from the anchor
        candidates = anchor + offsets + 0.5 * size * unit
        boxes = np.hstack([candidates - 0.5 * size, candidates + 0.5 * size])
        grown = boxes + [-gap, -gap, gap, gap]
        cost = _overlap(grown, blocked).sum(axis=1)
        cost += OUTSIDE * (np.prod(size) - _overlap(boxes, bounds[None])[:, 0])
        free = cost <= 1e-9 * np.prod(size)
        centres[i] = candidates[np.argmax(free) if free.any() else np.argmin(cost)]
        blocked = np.vstack(
            [blocked, np.hstack([centres[i] - 0.5 * size, centres[i] + 0.5 * size])]
        )
    return centres


def _overlap(boxes: np.ndarray, others: np.ndarray) -> np.ndarray:
    """(K, M) areas shared by each of the (K, 4) `boxes` with each of the (M, 4) `others`."""
    low = np.maximum(boxes[:, None, :2], others[None, :, :2])
    high = np.minimum(boxes[:, None, 2:], others[None, :, 2:])
    return np.prod(np.clip(high - low, 0.0, None), axis=2)


def deviation_map(inspection: Inspection, *, title: str | None = None) -> bytes:
    """PNG of the unrolled wall: axial position (m) against clock position (hours),
    coloured by deviation (mm).

    The colours (`stretch`) are pale within the defect threshold, where the noise lies,
    and deepen logarithmically beyond it out to the deepest defect; the colour bar's ticks,
    in mm, include the threshold. The defects are outlined and labelled beside their
    regions (number, depth in mm and in % of the diameter, and "assess" where B31.8 would),
    with a leader line to their deepest point; joints are thin vertical lines labelled with
    their kind and size, branches are labelled, and stretches where the fit is unreliable
    are hatched grey. The labels are placed by `place_labels`.
    """
    backend = require("matplotlib.backends.backend_agg", "inspection plots")
    figure, axes = _figure(11.0, 4.6)
    canvas = backend.FigureCanvasAgg(figure)
    wall = inspection.wall
    threshold, limit = (1000.0 * value for value in colour_range(inspection))
    image = axes.imshow(
        1000.0 * wall.deviation.T,
        cmap=COLOURS,
        norm=deviation_norm(threshold, limit),
        extent=(wall.axial_edges[0], wall.axial_edges[-1], 360.0, 0.0),
        aspect="auto",
        interpolation="nearest",
    )
    _colour_bar(figure, axes, image, threshold, limit)
    labels = inspection.defects.labels
    if (labels >= 0).any():
        middle_axial = 0.5 * (wall.axial_edges[:-1] + wall.axial_edges[1:])
        middle_clock = 0.5 * (wall.clock_edges[:-1] + wall.clock_edges[1:])
        axes.contour(
            middle_axial, middle_clock, (labels >= 0).T.astype(float), levels=[0.5],
            colors="black", linewidths=0.8,
        )  # fmt: skip
    legend = _marks(axes, inspection)
    axes.set_xlim(0.0, inspection.pipe.length)
    axes.set_yticks(np.arange(0.0, 361.0, 90.0), ["12", "3", "6", "9", "12"])
    axes.set_yticks(np.arange(0.0, 361.0, 30.0), minor=True)
    axes.set_xlabel("axial position along the centreline, m")
    axes.set_ylabel("clock position, hours")
    axes.set_title(title or _headline(inspection), loc="left")
    if legend:
        axes.legend(
            handles=legend, loc="lower right", bbox_to_anchor=(1.0, 1.0), ncols=len(legend),
            frameon=False, fontsize=LABEL_SIZE, borderaxespad=0.2,
        )  # fmt: skip
    canvas.draw()  # lays the figure out; the labels are placed in that layout, kept
    figure.set_layout_engine("none")
    _label(axes, canvas.get_renderer(), inspection)
    return _png(figure)


def _colour_bar(figure, axes, image, threshold: float, limit: float) -> None:
    """The colour bar of the map, ticked in mm (`colour_ticks`), the threshold marked."""
    bar = figure.colorbar(image, ax=axes, pad=0.01)
    ticks = colour_ticks(threshold, limit)
    bar.set_ticks(ticks, labels=[_signed(t, ".3g") if t else "0" for t in ticks])
    bar.ax.minorticks_off()
    for edge in (-threshold, threshold):
        bar.ax.axhline(edge, color="0.15", lw=0.8)
    bar.set_label(f"deviation, mm (\u2212 inward, + outward); pale within \u00b1{threshold:.2f}")


def _marks(axes, inspection: Inspection) -> list:
    """Draw the joints' lines and hatch the unreliable stretches; return their legend
    entries."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    shade = dict(facecolor="0.55", edgecolor="0.25", alpha=0.45, hatch="////", linewidth=0)
    line = dict(color="0.1", linewidth=0.8)
    for stretch_ in inspection.pipe.unreliable:
        axes.axvspan(stretch_.axial_start, stretch_.axial_end, **shade)
    for joint in inspection.joints:
        axes.axvline(joint.axial, **line)
    legend = []
    if inspection.joints:
        legend.append(Line2D([], [], label="joint (kind, size)", **line))
    if inspection.pipe.unreliable:
        legend.append(Patch(label="data short of the circle: not judged", **shade))
    return legend


def _label(axes, renderer, inspection: Inspection) -> None:
    """Label the defects, joints and branches beside what they name, in this order of
    precedence, clear of the defects' regions and of each other (`place_labels`)."""
    from matplotlib.font_manager import FontProperties

    defects, joints = inspection.defects.defects, inspection.joints
    items = [
        *(
            (_defect_label(number, d), (d.axial, d.clock), "#8b0000" if d.assess else "black")
            for number, d in enumerate(defects, start=1)
        ),
        *((f"{j.kind} {1000 * j.size:.1f} mm", (j.axial, 0.0), "0.1") for j in joints),
        *(("branch", (b.axial, b.clock), "black") for b in inspection.defects.branches),
    ]
    if not items:
        return
    texts, places, colours = zip(*items, strict=True)
    font, points = FontProperties(size=LABEL_SIZE), axes.figure.dpi / 72.0  # pixels a point
    sizes = np.array(
        [renderer.get_text_width_height_descent(text, font, ismath=False)[:2] for text in texts]
    )
    sizes += 2 * 0.15 * LABEL_SIZE * points  # the box round the text
    gap, bounds = LABEL_GAP * points, np.array(axes.bbox.extents)
    anchors = axes.transData.transform(np.array(places, dtype=np.float64))
    tops = slice(len(defects), len(defects) + len(joints))  # joints: at the top of their lines
    anchors[tops, 1] = bounds[3] - gap - 0.5 * sizes[tops, 1]
    regions = _pixel_boxes(axes, _region_boxes(inspection))
    centres = place_labels(anchors, sizes, regions, bounds, gap=gap)
    to_data = axes.transData.inverted().transform
    for text, colour, anchor, centre in zip(
        texts, colours, to_data(anchors), to_data(centres), strict=True
    ):
        axes.annotate(
            text,
            anchor,
            xytext=centre,
            ha="center",
            va="center",
            fontsize=LABEL_SIZE,
            color=colour,
            bbox=dict(boxstyle="square,pad=0.15", facecolor="white", edgecolor="none", alpha=0.85),
            arrowprops=dict(arrowstyle="-", color="0.15", linewidth=0.6, shrinkA=0, shrinkB=0),
        )


def _defect_label(number: int, defect) -> str:
    """A defect's label on the map: its number, depth (mm, % D) and whether to assess it."""
    percent = f", {defect.depth_percent:.1f} % D" if np.isfinite(defect.depth_percent) else ""
    assess = ", assess" if defect.assess else ""
    return f"{number}: {_signed(1000 * defect.depth, '.1f')} mm{percent}{assess}"


def _signed(value: float, form: str) -> str:
    """`value` in the format `form`, always signed, with a true minus sign."""
    return format(value, "+" + form).replace("-", "\u2212")


def _pixel_boxes(axes, boxes: np.ndarray) -> np.ndarray:
    """(R, 4) boxes in data units as (x0, y0, x1, y1) boxes of the axes' pixels."""
    corners = axes.transData.transform(boxes.reshape(-1, 2)).reshape(-1, 2, 2)
    return np.hstack([corners.min(axis=1), corners.max(axis=1)])


def _region_boxes(inspection: Inspection) -> np.ndarray:
    """(R, 4) boxes (axial_start, clock_start, axial_end, clock_end) of the defects'
    regions, a region across 12 o'clock as two."""
    boxes = []
    for d in inspection.defects.defects:
        if d.clock_start <= d.clock_end:
            boxes.append((d.axial_start, d.clock_start, d.axial_end, d.clock_end))
        else:
            boxes += [(d.axial_start, d.clock_start, d.axial_end, 360.0),
                      (d.axial_start, 0.0, d.axial_end, d.clock_end)]  # fmt: skip
    return np.array(boxes, dtype=np.float64).reshape(-1, 4)


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
    """PNG of the mesh coloured by each vertex's deviation, on the map's colour scale
    (needs OpenGL; see `zeroset.viz.render`)."""
    image = require("PIL.Image", "writing pictures")

    from ..viz import render

    colours = deviation_colours(inspection.vertex_deviation, *colour_range(inspection))
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

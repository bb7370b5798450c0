"""An inspection's numbers as a JSON-able summary, CSV tables and printed lines."""

from __future__ import annotations

import csv
import math
import os
from dataclasses import asdict
from pathlib import Path

import numpy as np

from ..io import atomic_target, check_output
from ._centreline import Pipe
from ._defects import ASSESSED_DENT
from ._inspection import Inspection
from ._measure import Ovality
from ._pictures import clock_label

__all__ = [
    "ASSESS_NOTE",
    "branch_table",
    "DEFECT_COLUMNS",
    "JOINT_COLUMNS",
    "OVALITY_COLUMNS",
    "defect_rows",
    "defect_table",
    "inspection_lines",
    "inspection_summary",
    "joint_rows",
    "joint_table",
    "length_agrees",
    "ovality_table",
    "station_summary",
    "write_csv",
    "write_defects_csv",
    "write_joints_csv",
    "write_ovality_csv",
]

#: Columns of the defects table, with their units.
DEFECT_COLUMNS = (
    "number",
    "kind",
    "axial_m",
    "clock_deg",
    "clock",
    "depth_mm",
    "depth_percent",
    "assess",
    "uncertainty_mm",
    "axial_start_m",
    "axial_end_m",
    "clock_start_deg",
    "clock_end_deg",
    "width_mm",
    "area_cm2",
)
#: Columns of the joints table, with their units.
JOINT_COLUMNS = (
    "number",
    "kind",
    "axial_m",
    "size_mm",
    "uncertainty_mm",
    "clock_deg",
    "clock",
    "depth_mm",
)
#: Columns of the ovality table, with their units.
OVALITY_COLUMNS = (
    "axial_m",
    "ovality_percent",
    "d_max_mm",
    "d_mean_mm",
    "d_min_mm",
    "major_clock_deg",
    "unreliable",
)
#: What a defect with `Defect.assess` is marked with.
ASSESS_NOTE = f"B31.8: > {ASSESSED_DENT:g} % D, assess"
#: What a joint's size measures, by kind (see `Joint`).
JOINT_SIZES = {"gap": "wide", "offset": "step", "bead": "into the bore"}
#: The fitted centreline's length should agree with the data's extent within this share of
#: the extent and within one diameter.
LENGTH_TOLERANCE = 0.02


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def defect_rows(inspection: Inspection) -> list[dict]:
    """One dict per defect, deepest first, with the `DEFECT_COLUMNS` (mm, %, cm^2, m, deg);
    ``assess`` is ``"yes"`` or empty, a depth percent not measured None."""
    return defect_table(inspection.defects.defects)


def defect_table(defects) -> list[dict]:
    """`defect_rows` of a sequence of `Defect`, numbered from 1 in its order."""
    return [
        {
            "number": number,
            "kind": d.kind,
            "axial_m": round(d.axial, 4),
            "clock_deg": round(d.clock, 1),
            "clock": clock_label(d.clock),
            "depth_mm": round(1000.0 * d.depth, 2),
            "depth_percent": _finite(round(d.depth_percent, 2)),
            "assess": "yes" if d.assess else "",
            "uncertainty_mm": _finite(round(1000.0 * d.uncertainty, 2)),
            "axial_start_m": round(d.axial_start, 4),
            "axial_end_m": round(d.axial_end, 4),
            "clock_start_deg": round(d.clock_start, 1),
            "clock_end_deg": round(d.clock_end, 1),
            "width_mm": round(1000.0 * d.width, 1),
            "area_cm2": round(1e4 * d.area, 2),
        }
        for number, d in enumerate(defects, start=1)
    ]


def joint_rows(inspection: Inspection) -> list[dict]:
    """One dict per joint, by axial position, with the `JOINT_COLUMNS` (m, mm, deg): the
    clock (degrees and ``"h:mm"``) of an offset and the depth of a gap, None otherwise."""
    return joint_table(inspection.joints)


def joint_table(joints) -> list[dict]:
    """`joint_rows` of a sequence of `Joint`, numbered from 1 in its order."""
    return [
        {
            "number": number,
            "kind": j.kind,
            "axial_m": round(j.axial, 4),
            "size_mm": _finite(round(1000.0 * j.size, 2)),
            "uncertainty_mm": _finite(round(1000.0 * j.uncertainty, 2)),
            "clock_deg": _finite(round(j.clock, 1)),
            "clock": clock_label(j.clock) if math.isfinite(j.clock) else None,
            "depth_mm": _finite(round(1000.0 * j.depth, 2)),
        }
        for number, j in enumerate(joints, start=1)
    ]


def station_summary(ovality: Ovality) -> dict:
    """The stations that measured a section: their ``count``, and the ``min``, ``median``
    and ``max`` over them of ``d_min_mm``, ``d_mean_mm``, ``d_max_mm`` and
    ``ovality_percent`` (each None when no station did)."""
    fitted = np.isfinite(ovality.ovality)
    figures = {
        "d_min_mm": 1000.0 * ovality.d_min,
        "d_mean_mm": 1000.0 * ovality.d_mean,
        "d_max_mm": 1000.0 * ovality.d_max,
        "ovality_percent": 100.0 * ovality.ovality,
    }
    spread = {
        name: {
            "min": float(values[fitted].min()),
            "median": float(np.median(values[fitted])),
            "max": float(values[fitted].max()),
        }
        if fitted.any()
        else None
        for name, values in figures.items()
    }
    return {"count": int(np.count_nonzero(fitted)), **spread}


def length_agrees(pipe: Pipe) -> bool | None:
    """Whether the fitted centreline's length agrees with the data's extent, measured
    without it: within `LENGTH_TOLERANCE` of the extent and within one diameter; None when
    the extent is not known."""
    if not math.isfinite(pipe.extent):
        return None
    allowed = min(LENGTH_TOLERANCE * pipe.extent, 2.0 * pipe.radius)
    return bool(abs(pipe.length - pipe.extent) <= allowed)


def inspection_summary(inspection: Inspection) -> dict:
    """Return the numbers of a pipe inspection, ready for JSON.

    Returns
    -------
    dict
        ``nominal_diameter``, ``measured_diameter`` and ``length`` (along the fitted
        centreline), metres; ``extent``, the run's length measured without the centreline
        (None when not measured), and ``length_agrees`` (`length_agrees`); ``unreliable``,
        one dict per `Unreliable` stretch; ``threshold``, the smallest depth judged a defect
        (metres), also as ``threshold_mm``, and ``threshold_basis``, what it came from, in
        words; ``significance``, the standard errors a cell's residual needed to count;
        ``texture``, the wall's texture they were taken times (`Defects.texture`);
        ``stations``, the diameters and ovality ``(D_max - D_min) / D_nominal`` over the
        stations (`station_summary`, mm and %); ``defects``, one dict per `Defect`, deepest
        first, with its fields (metres, degrees, square metres, percent), its ``number``
        from 1, ``depth_mm`` and ``clock_time`` (the clock angle as ``"h:mm"``: 0 degrees
        is ``"12:00"``, 90 ``"3:00"``); ``joints``, one dict per `Joint` (`joint_rows`, in
        mm); ``branches``, one dict per `Branch` with its fields and ``clock_time``;
        ``timings``, seconds per stage. NaN values (an uncertainty not measured) are None.
    """
    pipe, found = inspection.pipe, inspection.defects
    return {
        "nominal_diameter": 2.0 * pipe.radius,
        "measured_diameter": 2.0 * pipe.measured_radius,
        "length": pipe.length,
        "extent": _finite(pipe.extent),
        "length_agrees": length_agrees(pipe),
        "unreliable": [asdict(stretch) for stretch in pipe.unreliable],
        "threshold": found.threshold,
        "threshold_mm": 1000.0 * found.threshold,
        "threshold_basis": found.basis,
        "significance": found.significance,
        "texture": found.texture,
        "stations": station_summary(inspection.ovality),
        "defects": [
            {
                "number": number,
                **_fields(defect),
                "depth_mm": 1000.0 * defect.depth,
                "clock_time": clock_label(defect.clock),
            }
            for number, defect in enumerate(found.defects, start=1)
        ],
        "joints": joint_rows(inspection),
        "branches": branch_table(found.branches),
        "timings": dict(inspection.timings),
    }


def branch_table(branches) -> list[dict]:
    """One dict per `Branch`, with its fields and ``clock_time`` (``"h:mm"``)."""
    return [{**_fields(b), "clock_time": clock_label(b.clock)} for b in branches]


def _fields(record) -> dict:
    """A dataclass's fields as a dict, with NaN and infinite floats as None."""
    return {
        name: None if isinstance(value, float) and not math.isfinite(value) else value
        for name, value in asdict(record).items()
    }


def write_defects_csv(path: str | os.PathLike, inspection: Inspection) -> Path:
    """Write the defects table (`DEFECT_COLUMNS`, deepest first) as CSV, atomically."""
    return write_csv(path, DEFECT_COLUMNS, defect_rows(inspection))


def write_joints_csv(path: str | os.PathLike, inspection: Inspection) -> Path:
    """Write the joints table (`JOINT_COLUMNS`, by axial position) as CSV, atomically."""
    return write_csv(path, JOINT_COLUMNS, joint_rows(inspection))


def write_ovality_csv(path: str | os.PathLike, inspection: Inspection) -> Path:
    """Write the ovality per station as CSV, atomically (`OVALITY_COLUMNS`).

    Per station: its axial position (m), ovality (%), largest, mean and smallest diameter
    (mm), the largest's clock angle (degrees), and ``unreliable``, the reason of the
    `Pipe.unreliable` stretches it lies in (empty in none). Stations whose data do not go
    round the pipe are left out.
    """
    rows = ovality_table(inspection.ovality, inspection.pipe.unreliable)
    return write_csv(path, OVALITY_COLUMNS, rows)


def ovality_table(found: Ovality, stretches) -> list[dict]:
    """The rows of `write_ovality_csv` for the stations of `found` and the `Unreliable`
    `stretches`."""
    return [
        {
            "axial_m": round(float(a), 4),
            "ovality_percent": round(100.0 * float(o), 4),
            "d_max_mm": round(1000.0 * float(hi), 3),
            "d_mean_mm": round(1000.0 * float(mean), 3),
            "d_min_mm": round(1000.0 * float(lo), 3),
            "major_clock_deg": round(float(c), 1),
            "unreliable": "; ".join(
                s.reason for s in stretches if s.axial_start <= a <= s.axial_end
            ),
        }
        for a, o, hi, mean, lo, c in zip(
            found.axial,
            found.ovality,
            found.d_max,
            found.d_mean,
            found.d_min,
            found.major_clock,
            strict=True,
        )
        if math.isfinite(o)
    ]


def inspection_lines(inspection: Inspection) -> list[str]:
    """The inspection as printed lines: the pipe, the stretches not judged, the
    centreline and stations, then one line per defect, joint and branch."""
    facts = inspection_summary(inspection)
    lines = [
        f"pipe        diameter {1000 * facts['nominal_diameter']:.1f} mm nominal, "
        f"{1000 * facts['measured_diameter']:.1f} mm measured"
    ]
    if facts["unreliable"]:  # up front: what the report does not speak for
        count, length = len(facts["unreliable"]), facts["length"]
        unjudged = sum(s["axial_end"] - s["axial_start"] for s in facts["unreliable"])
        lines.append(
            f"not judged  {unjudged:.2f} m of {length:.2f} m ({100 * unjudged / length:.0f} %) "
            f"in {count} stretch{'es' if count != 1 else ''} the data leave short; nothing "
            "there is reported as a defect"
        )
    lines.extend(
        f"  {s['axial_start']:.3f}-{s['axial_end']:.3f} m: {s['reason']}"
        for s in facts["unreliable"]
    )
    lines += ["centreline  " + _length_line(facts), *_station_lines(facts["stations"])]
    lines.append(
        f"defects     {len(facts['defects'])} beyond {facts['threshold_mm']:.2f} mm "
        f"({facts['significance']:.1f} standard errors)"
    )
    if facts["threshold_basis"]:
        lines.append(f"            threshold: {facts['threshold_basis']}")
    lines.extend(_defect_line(row) for row in defect_rows(inspection))
    if facts["joints"]:
        lines.append(f"joints      {len(facts['joints'])}")
    lines.extend(_joint_line(row) for row in facts["joints"])
    lines.extend(
        f"  branch    at {branch['axial']:.3f} m, {branch['clock_time']} "
        f"({branch['clock']:.0f} deg), opening {1e4 * branch['area']:.0f} cm2"
        for branch in facts["branches"]
    )
    return lines


def _length_line(facts: dict) -> str:
    """The fitted length beside the data's extent, with a warning mark where they differ."""
    fitted = f"fitted {facts['length']:.2f} m"
    if facts["extent"] is None:
        return f"{fitted}; the data's extent not measured"
    line = f"{fitted}; the data extend {facts['extent']:.2f} m"
    if not facts["length_agrees"]:
        line += (
            f"  (!) they differ by {abs(facts['length'] - facts['extent']):.2f} m, more than "
            f"{100 * LENGTH_TOLERANCE:.0f} % or one diameter: check the centreline"
        )
    return line


def _station_lines(stations: dict) -> list[str]:
    """Ovality and diameters over the stations, min / median / max, in two lines."""
    if not stations["count"]:
        return ["ovality     not measured: the data do not go round the pipe"]

    def spread(name: str, digits: int) -> str:
        s = stations[name]
        return f"{s['min']:.{digits}f} / {s['median']:.{digits}f} / {s['max']:.{digits}f}"

    return [
        f"ovality     {spread('ovality_percent', 2)} % (D_max - D_min) / D_nominal, "
        f"min / median / max over {stations['count']} stations",
        f"diameters   D_min {spread('d_min_mm', 1)}, D_mean {spread('d_mean_mm', 1)}, "
        f"D_max {spread('d_max_mm', 1)} mm",
    ]


def _defect_line(row: dict) -> str:
    """A row of `defect_rows` as a printed line."""
    error, percent = row["uncertainty_mm"], row["depth_percent"]
    return (
        f"  {row['number']:>3} {row['kind']:<5} at {row['axial_m']:.3f} m, "
        f"{row['clock']} ({row['clock_deg']:.0f} deg): depth {row['depth_mm']:+.1f}"
        + (f" +- {error:.1f}" if error is not None else "")
        + " mm"
        + (f" ({percent:.1f} % D)" if percent is not None else "")
        + f", {row['axial_end_m'] - row['axial_start_m']:.3f} m long, "
        f"{row['width_mm']:.0f} mm wide, {row['area_cm2']:.1f} cm2"
        + (f"  {ASSESS_NOTE}" if row["assess"] else "")
    )


def _joint_line(row: dict) -> str:
    """A row of `joint_rows` as a printed line."""
    error = row["uncertainty_mm"]
    size = "?" if row["size_mm"] is None else f"{row['size_mm']:.1f}"
    line = (
        f"  {row['number']:>3} {row['kind']:<6} at {row['axial_m']:.3f} m: {size}"
        + (f" +- {error:.1f}" if error is not None else "")
        + f" mm {JOINT_SIZES.get(row['kind'], '')}".rstrip()
    )
    if row["clock"] is not None:
        line += f" towards {row['clock']} ({row['clock_deg']:.0f} deg)"
    if row["depth_mm"] is not None:
        line += f", {row['depth_mm']:.1f} mm deep"
    return line


def write_csv(path, columns, rows) -> Path:
    """Write `rows` (dicts) under `columns` as CSV, atomically."""
    target = check_output(path)
    with atomic_target(target) as temporary:
        with open(temporary, "w", newline="", encoding="utf-8") as handle:
            writer = csv.DictWriter(handle, fieldnames=list(columns))
            writer.writeheader()
            writer.writerows(rows)
    return target

"""An inspection's numbers as a JSON-able summary, CSV tables and printed lines."""

from __future__ import annotations

import csv
import math
import os
from dataclasses import asdict
from pathlib import Path

import numpy as np

from ..io import atomic_target, check_output
from ._inspection import Inspection
from ._pictures import clock_label

__all__ = [
    "defect_rows",
    "inspection_lines",
    "inspection_summary",
    "write_defects_csv",
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
    "uncertainty_mm",
    "axial_start_m",
    "axial_end_m",
    "clock_start_deg",
    "clock_end_deg",
    "width_mm",
    "area_cm2",
)


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def defect_rows(inspection: Inspection) -> list[dict]:
    """One dict per defect, deepest first, with the `DEFECT_COLUMNS` (mm, cm^2, m, deg)."""
    return [
        {
            "number": number,
            "kind": d.kind,
            "axial_m": round(d.axial, 4),
            "clock_deg": round(d.clock, 1),
            "clock": clock_label(d.clock),
            "depth_mm": round(1000.0 * d.depth, 2),
            "uncertainty_mm": _finite(round(1000.0 * d.uncertainty, 2)),
            "axial_start_m": round(d.axial_start, 4),
            "axial_end_m": round(d.axial_end, 4),
            "clock_start_deg": round(d.clock_start, 1),
            "clock_end_deg": round(d.clock_end, 1),
            "width_mm": round(1000.0 * d.width, 1),
            "area_cm2": round(1e4 * d.area, 2),
        }
        for number, d in enumerate(inspection.defects.defects, start=1)
    ]


def inspection_summary(inspection: Inspection) -> dict:
    """Return the numbers of a pipe inspection, ready for JSON.

    Returns
    -------
    dict
        ``nominal_diameter``, ``measured_diameter``, ``length`` and ``threshold`` (the
        smallest depth judged a defect), metres; ``significance``, the standard errors a
        cell's residual needed to count; ``max_ovality`` and ``median_ovality``,
        ``(D_max - D_min) / D_nominal`` over the stations that measured one (None when
        none did), and ``ovality_stations``, their count; ``defects``, one dict per
        `Defect`, deepest first, with its fields (metres, degrees, square metres), its
        ``number`` from 1 and ``clock_time`` (the clock angle as ``"h:mm"``: 0 degrees is
        ``"12:00"``, 90 ``"3:00"``); ``branches``, one dict per `Branch` with its fields
        and ``clock_time``; ``timings``, seconds per stage. NaN values (an uncertainty not
        measured) are None.
    """
    pipe, found = inspection.pipe, inspection.defects
    ovality = inspection.ovality.ovality
    fitted = ovality[np.isfinite(ovality)]
    return {
        "nominal_diameter": 2.0 * pipe.radius,
        "measured_diameter": 2.0 * pipe.measured_radius,
        "length": pipe.length,
        "threshold": found.threshold,
        "significance": found.significance,
        "max_ovality": float(fitted.max()) if fitted.size else None,
        "median_ovality": float(np.median(fitted)) if fitted.size else None,
        "ovality_stations": int(fitted.size),
        "defects": [
            {"number": number, **_fields(defect), "clock_time": clock_label(defect.clock)}
            for number, defect in enumerate(found.defects, start=1)
        ],
        "branches": [
            {**_fields(branch), "clock_time": clock_label(branch.clock)}
            for branch in found.branches
        ],
        "timings": dict(inspection.timings),
    }


def _fields(record) -> dict:
    """A dataclass's fields as a dict, with NaN and infinite floats as None."""
    return {
        name: None if isinstance(value, float) and not math.isfinite(value) else value
        for name, value in asdict(record).items()
    }


def write_defects_csv(path: str | os.PathLike, inspection: Inspection) -> Path:
    """Write the defects table (`DEFECT_COLUMNS`, deepest first) as CSV, atomically."""
    return _write_csv(path, DEFECT_COLUMNS, defect_rows(inspection))


def write_ovality_csv(path: str | os.PathLike, inspection: Inspection) -> Path:
    """Write the ovality per station as CSV, atomically: axial position (m), ovality (%),
    largest and smallest diameter (mm) and the largest's clock angle (degrees); stations
    whose data do not go round the pipe are left out."""
    found = inspection.ovality
    rows = [
        {
            "axial_m": round(float(a), 4),
            "ovality_percent": round(100.0 * float(o), 4),
            "d_max_mm": round(1000.0 * float(hi), 3),
            "d_min_mm": round(1000.0 * float(lo), 3),
            "major_clock_deg": round(float(c), 1),
        }
        for a, o, hi, lo, c in zip(
            found.axial, found.ovality, found.d_max, found.d_min, found.major_clock, strict=True
        )
        if math.isfinite(o)
    ]
    columns = ("axial_m", "ovality_percent", "d_max_mm", "d_min_mm", "major_clock_deg")
    return _write_csv(path, columns, rows)


def inspection_lines(inspection: Inspection) -> list[str]:
    """The inspection as printed lines, one per defect and branch."""
    facts = inspection_summary(inspection)
    lines = [
        f"pipe        diameter {1000 * facts['nominal_diameter']:.1f} mm nominal, "
        f"{1000 * facts['measured_diameter']:.1f} mm measured; {facts['length']:.2f} m "
        "along the centreline",
        "ovality     "
        + (
            f"max {100 * facts['max_ovality']:.2f} %, median {100 * facts['median_ovality']:.2f}"
            f" % over {facts['ovality_stations']} stations"
            if facts["max_ovality"] is not None
            else "not measured: the data do not go round the pipe"
        ),
        f"defects     {len(facts['defects'])} beyond {1000 * facts['threshold']:.2f} mm "
        f"({facts['significance']:.1f} standard errors)",
    ]
    for row in defect_rows(inspection):
        error = row["uncertainty_mm"]
        lines.append(
            f"  {row['number']:>3} {row['kind']:<5} at {row['axial_m']:.3f} m, "
            f"{row['clock']} ({row['clock_deg']:.0f} deg): depth {row['depth_mm']:+.1f}"
            + (f" +- {error:.1f}" if error is not None else "")
            + f" mm, {row['axial_end_m'] - row['axial_start_m']:.3f} m long, "
            f"{row['width_mm']:.0f} mm wide, {row['area_cm2']:.1f} cm2"
        )
    for branch in facts["branches"]:
        lines.append(
            f"  branch    at {branch['axial']:.3f} m, {branch['clock_time']} "
            f"({branch['clock']:.0f} deg), opening {1e4 * branch['area']:.0f} cm2"
        )
    return lines


def _write_csv(path, columns, rows) -> Path:
    target = check_output(path)
    with atomic_target(target) as temporary:
        with open(temporary, "w", newline="", encoding="utf-8") as handle:
            writer = csv.DictWriter(handle, fieldnames=list(columns))
            writer.writeheader()
            writer.writerows(rows)
    return target

"""Delimited text points (XYZ, TXT, CSV, PTS) in and out through numpy."""

from __future__ import annotations

import re
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import InputError
from ._sniff import check_content

__all__ = ["read_3dtk_points", "read_points", "write_points"]

_ENCODING = "utf-8-sig"
_DELIMITERS = {";": "semicolons", ",": "commas", None: "whitespace"}
_ANY_DELIMITER = re.compile(r"[\s,;]+")

@dataclass(frozen=True)
class _Layout:
    """How a text file's data is laid out, found from its first lines."""

    delimiter: str | None  # "," or None for runs of whitespace
    skiprows: int  # file lines before the data, header and comments included
    columns: int  # fields on the first data line
    normals: bool  # columns 4-6 hold nx, ny, nz
    first_line: int  # 1-based line number of the first data line

    @property
    def used(self) -> int:
        """Number of leading columns read."""
        return 6 if self.normals else 3


def read_points(path: Path, *, normals: bool = True) -> dict[str, np.ndarray | None]:
    """Read ``x y z [nx ny nz]`` rows from a whitespace- or comma-separated text file.

    The delimiter of every line is a semicolon or else a comma if the first data line has
    one, else whitespace. ``#`` starts a comment. One leading line that is not all numbers
    is a header; one leading line with a single number is a point count (PTS) and is skipped
    too. Only the first three columns are read, unless the first data line has exactly six:
    then columns 4-6 are normals, except when a header names them otherwise
    (``x,y,z,r,g,b``) or `normals` is false.

    Parameters
    ----------
    path : pathlib.Path
        A UTF-8 text file.
    normals : bool
        Whether six columns may hold normals.

    Returns
    -------
    dict
        ``points`` : (N, 3) float64 (N may be 0); ``normals`` : (N, 3) float64 or None.

    Raises
    ------
    InputError
        If the file is another format (PLY, NumPy) or not UTF-8 text, a data line has fewer
        than three fields (six in a file with normals), separates them differently from the
        first data line, or a field is not a number. Messages carry no path prefix and name
        the 1-based file line.
    """
    check_content(path, ("text", "empty", "binary"), "text file")
    try:
        layout = _sniff(path)
        if layout is not None and not normals:
            layout = replace(layout, normals=False)
        if layout is None:
            return {"points": np.zeros((0, 3)), "normals": None}
        if layout.columns < 3:
            raise InputError(
                f"line {layout.first_line} has {_columns(layout.columns)}; expected at least 3"
            )
        try:
            table = np.loadtxt(
                path,
                dtype=np.float64,
                comments="#",
                delimiter=layout.delimiter,
                skiprows=layout.skiprows,
                usecols=range(layout.used),
                ndmin=2,
                encoding=_ENCODING,
            )
        except ValueError as exc:
            raise InputError(_diagnose(path, layout) or f"cannot parse ({exc})") from exc
    except UnicodeDecodeError as exc:
        raise InputError(f"not a UTF-8 text file ({exc.reason} at byte {exc.start})") from exc
    return {"points": table[:, :3], "normals": table[:, 3:6] if layout.normals else None}


def read_3dtk_points(path: Path) -> dict[str, np.ndarray | None]:
    """Read a 3DTK scan (``.3d``, the "uos" formats): ``x y z`` and maybe reflectance or colour.

    The coordinates are kept as they are: 3DTK writes centimetres in a left-handed frame
    with y up. Columns after the third are never normals.
    """
    return read_points(path, normals=False)


def _sniff(path: Path) -> _Layout | None:
    """Find the delimiter, header and column count from the first lines; None if no data."""
    skiprows = 0
    header: list[str] | None = None
    with open(path, encoding=_ENCODING) as stream:
        for number, line in enumerate(stream, start=1):  # stops at the first data line
            text = line.split("#", 1)[0].strip()
            if not text:
                continue
            delimiter = _delimiter(text)
            fields = _split(text, delimiter)
            if skiprows == 0 and (not _numeric(fields) or len(fields) == 1):
                skiprows, header = number, fields if not _numeric(fields) else None
                continue
            normals = len(fields) == 6 and (
                header is None or all(name.lower().startswith("n") for name in header[3:6])
            )
            return _Layout(delimiter, number - 1, len(fields), normals, number)
    return None


def _diagnose(path: Path, layout: _Layout) -> str | None:
    """Describe the first malformed data line (runs only after numpy has failed)."""
    with open(path, encoding=_ENCODING) as stream:
        for number, line in enumerate(stream, start=1):
            text = line.split("#", 1)[0].strip()
            if number <= layout.skiprows or not text:
                continue
            fields = _split(text, layout.delimiter)
            bad = [field for field in fields[: layout.used] if not _numeric([field])]
            if len(fields) >= layout.used and not bad:
                continue
            mixed = _delimiter(text) != layout.delimiter or any(len(f.split()) > 1 for f in fields)
            parts = _ANY_DELIMITER.split(text)
            if mixed and len(parts) >= layout.used and _numeric(parts[: layout.used]):
                return (
                    f"line {number} does not separate fields with "
                    f"{_DELIMITERS[layout.delimiter]} as line {layout.first_line} does; "
                    "use one delimiter throughout"
                )
            if len(fields) < layout.used:
                return f"line {number} has {_columns(len(fields))}; expected at least {layout.used}"
            return f"line {number}: cannot read {bad[0]!r} as a number"
    return None


def _delimiter(text: str) -> str | None:
    """Return the delimiter a data line uses: ";" or "," if it holds one, else None."""
    return next((mark for mark in (";", ",") if mark in text), None)


def _columns(count: int) -> str:
    """Return "1 column" or "n columns"."""
    return f"{count} column{'' if count == 1 else 's'}"


def _split(text: str, delimiter: str | None) -> list[str]:
    """Split one line into stripped fields, ignoring a trailing comma."""
    if delimiter is not None:
        text = text.rstrip(delimiter)
    return [field.strip() for field in text.split(delimiter)]


def _numeric(fields: list[str]) -> bool:
    """Return whether every field parses as a float."""
    try:
        [float(field) for field in fields]
    except ValueError:
        return False
    return True


def write_points(path: Path, points: np.ndarray, normals: np.ndarray | None) -> None:
    """Write ``x y z [nx ny nz]`` rows, space separated, with round-trip precision.

    Parameters
    ----------
    path : pathlib.Path
        Destination, overwritten.
    points : (N, 3) float64
    normals : (N, 3) float64 or None
    """
    table = points if normals is None else np.hstack([points, normals])
    np.savetxt(path, table, fmt="%.17g", delimiter=" ", encoding="utf-8")

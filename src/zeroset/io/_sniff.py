"""What a point file holds, told from its first bytes, whatever its suffix says."""

from __future__ import annotations

import codecs
from pathlib import Path

from ..errors import InputError

__all__ = ["check_content"]

#: Bytes read to tell what a file holds.
_HEAD_BYTES = 4096
#: Leading bytes of the binary formats read_points knows, with the kind they show.
_SIGNATURES = {
    b"ply\n": ".ply",
    b"ply\r": ".ply",
    b"\x93NUMPY": ".npy",
    b"PK\x03\x04": ".npz",
    b"PK\x05\x06": ".npz",
    b"LASF": ".las",
    b"ASTM-E57": ".e57",
    b"# .PCD": ".pcd",
    b"VERSION .7": ".pcd",
    b"VERSION 0.": ".pcd",
    b"\xff\xfe": "utf-16",
    b"\xfe\xff": "utf-16",
}
#: What each kind of content is, and what to do when it has the wrong suffix.
_KINDS = {
    ".ply": ("a PLY file", "rename it to .ply"),
    ".npy": ("a NumPy .npy file", "rename it to .npy"),
    ".npz": ("a zip archive such as NumPy's .npz", "rename it to .npz"),
    ".las": ("a LAS or LAZ file", "rename it to .las or .laz"),
    ".e57": ("an E57 file", "rename it to .e57"),
    ".pcd": ("a PCD file", "rename it to .pcd"),
    "text": ("text", "rename it to .xyz if it holds x y z rows"),
    "utf-16": ("UTF-16 text", "save it as UTF-8"),
}


def check_content(path: Path, accepted: tuple[str, ...], name: str) -> str:
    """Return the kind of content the first bytes of `path` show, if it is one of `accepted`.

    Parameters
    ----------
    path : pathlib.Path
    accepted : tuple of str
        Kinds the caller reads: ".ply", ".npy", ".npz", "utf-16", "text", "empty" or
        "binary" (none of the others).
    name : str
        What the caller reads, for messages ("PLY file").

    Raises
    ------
    InputError
        If the file is empty, or holds content of a kind not in `accepted`; the message
        names the kind and what to do. Messages carry no path prefix.
    """
    with open(path, "rb") as stream:
        head = stream.read(_HEAD_BYTES)
    kind = _kind(head)
    if kind in accepted:
        return kind
    if kind == "empty":
        raise InputError("is empty (0 bytes)")
    if kind == "binary":
        raise InputError(f"not a valid {name} (unrecognised leading bytes)")
    what, advice = _KINDS[kind]
    raise InputError(f"not a valid {name}: it is {what}; {advice}")


def _kind(head: bytes) -> str:
    """Name what a file's first bytes show: a `_SIGNATURES` kind, "empty", "text" or "binary"."""
    if not head:
        return "empty"
    for signature, kind in _SIGNATURES.items():
        if head.startswith(signature):
            return kind
    try:
        codecs.getincrementaldecoder("utf-8")().decode(head)  # a cut last character is fine
    except UnicodeDecodeError:
        return "binary"
    return "binary" if b"\0" in head else "text"

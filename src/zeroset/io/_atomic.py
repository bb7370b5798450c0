"""Atomic file replacement shared by every writer."""

from __future__ import annotations

import os
import stat
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["atomic_target"]


@contextmanager
def atomic_target(target: Path) -> Iterator[Path]:
    """Yield a temporary path beside `target`, then move it onto `target`.

    The caller writes the whole file to the yielded path. When the block ends normally the
    temporary file takes the permissions `target` has (or would get from the umask), is
    flushed to disk (``fsync``) and renamed onto `target` with `os.replace`, and the rename is
    flushed too, so readers, and the disk after a crash or power cut, hold either the old
    file or the new one, never half of it. When the block raises, the temporary file is
    removed, `target` is left untouched and the exception propagates. A process killed
    while writing leaves `target` untouched and a hidden ``.<name>.*`` file beside it.

    Parameters
    ----------
    target : pathlib.Path
        The file to create or replace. Its parent directory must exist.

    Yields
    ------
    pathlib.Path
        A closed, empty file in ``target.parent`` with the same suffix as `target`.

    Raises
    ------
    OSError
        If the temporary file cannot be created, written or renamed.
    """
    with tempfile.NamedTemporaryFile(
        delete=False, dir=target.parent, prefix=f".{target.name}.", suffix=target.suffix
    ) as handle:
        temp = Path(handle.name)
    try:
        yield temp
        os.chmod(temp, _final_mode(target))
        _fsync(temp)
        os.replace(temp, target)
    except BaseException:
        temp.unlink(missing_ok=True)
        raise
    _fsync(target.parent)


def _fsync(path: Path) -> None:
    """Flush a file's data, or a directory's entries, to disk."""
    descriptor = os.open(path, os.O_RDONLY)
    try:
        os.fsync(descriptor)
    finally:
        os.close(descriptor)


def _final_mode(target: Path) -> int:
    """Return the permission bits of `target`, or those a new file gets under the umask."""
    try:
        return stat.S_IMODE(target.stat().st_mode)
    except FileNotFoundError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask

"""A run's record: wall-clock seconds and counts per stage, with an optional progress bar."""

from __future__ import annotations

import sys
import time
from contextlib import contextmanager

from tqdm.auto import tqdm

from .stats import add_counts

try:  # POSIX only
    import resource
except ImportError:  # pragma: no cover - Windows
    resource = None

__all__ = ["Stages", "peak_mib"]


class Stages:
    """Time named stages; show a bar on stderr when `show` is true and stderr is a terminal.

    `run` also gathers what each stage counted: ``counts`` holds their sum
    (`zeroset.stats.add_counts`).
    As a context manager it closes the bar on exit.
    """

    def __init__(self, names: tuple[str, ...], *, show: bool) -> None:
        self.timings: dict[str, float] = {}
        self.counts: dict = {}
        self._bar = tqdm(
            total=len(names),
            disable=not (show and sys.stderr.isatty()),
            unit="stage",
            bar_format="{desc:<24}{bar}| {n_fmt}/{total_fmt} stages [{elapsed}]",
            leave=False,
        )

    @contextmanager
    def stage(self, name: str):
        """Time the block as stage `name` and advance the bar."""
        self._bar.set_description_str(name)
        start = time.perf_counter()
        try:
            yield
        finally:
            self.timings[name] = time.perf_counter() - start
            self._bar.update()

    def run(self, name: str, stage, *args, **kwargs):
        """Call ``stage(*args, **kwargs)``, which returns ``(result, counts)``, as stage
        `name`; add its counts to ``counts`` and return its result."""
        with self.stage(name):
            result, counts = stage(*args, **kwargs)
        add_counts(self.counts, counts)
        return result

    def close(self) -> None:
        self._bar.close()

    def __enter__(self) -> Stages:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def peak_mib() -> float | None:
    """The process' peak resident memory so far, MiB; None where the platform does not
    say (Windows)."""
    if resource is None:
        return None
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (1024 * 1024) if sys.platform == "darwin" else peak / 1024  # bytes on macOS

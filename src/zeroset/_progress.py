"""Per-stage wall-clock timing with an optional progress bar on a terminal."""

from __future__ import annotations

import sys
import time
from contextlib import contextmanager

from tqdm.auto import tqdm

__all__ = ["Stages"]


class Stages:
    """Time named stages; show a bar on stderr when `show` is true and stderr is a terminal."""

    def __init__(self, names: tuple[str, ...], *, show: bool) -> None:
        self.timings: dict[str, float] = {}
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

    def close(self) -> None:
        self._bar.close()

"""Compiled loops. The stage modules import from here, and the CLI `_ahead`, which compiles
the later stages' kernels ahead on a fresh install."""

"""Compiled loops. Only the stage modules import from here."""

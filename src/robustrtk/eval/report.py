"""Plain-text tables for the command line: :func:`robustrtk.io.tables.format_table`."""

from __future__ import annotations

from robustrtk.io.tables import format_table

__all__ = ["format_table"]

"""The change log of :mod:`robustrtk.sim.inject`: one record per changed observation value,
written as CSV."""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from dataclasses import dataclass
from os import PathLike

from robustrtk.io.atomic import atomic_path
from robustrtk.sim.fault_spec import Kind

__all__ = ["LOG_COLUMNS", "Change", "write_changes_csv", "write_log"]

#: Columns of the CSV log, in order.
LOG_COLUMNS = (
    "epoch_index", "time", "sat", "obs_code", "kind", "size_m", "size_native",
    "original", "new", "lli_original", "lli_new",
)  # fmt: skip


@dataclass(frozen=True)
class Change:
    """One changed observation value (one row of the log).

    ``new - original == size_native`` exactly (as decimals; ``original`` and ``new`` are
    the field texts, stripped). ``size_m`` is the requested size for phase and code and
    ``cycles * wavelength`` for slips (NaN when the wavelength is unknown). ``line`` is
    the 1-based line of the plain RINEX text.
    """

    epoch_index: int
    time: str
    sat: str
    obs_code: str
    kind: Kind
    size_m: float
    size_native: str
    original: str
    new: str
    lli_original: str
    lli_new: str
    line: int

    def row(self) -> list[str]:
        """The CSV row (columns :data:`LOG_COLUMNS`)."""
        size_m = "" if math.isnan(self.size_m) else f"{self.size_m:.6f}"
        return [
            str(self.epoch_index), self.time, self.sat, self.obs_code, self.kind, size_m,
            self.size_native, self.original, self.new, self.lli_original, self.lli_new,
        ]  # fmt: skip


def write_changes_csv(changes: Sequence[Change], path: str) -> None:
    """Write the CSV log to ``path`` directly (not atomically; see :func:`write_log`).

    Parameters
    ----------
    changes : sequence of Change
        Rows, in order.
    path : str
        Output file (overwritten).
    """
    with open(path, "w", newline="", encoding="ascii") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(LOG_COLUMNS)
        for c in changes:
            w.writerow(c.row())


def write_log(changes: Sequence[Change], path: str | PathLike[str]) -> None:
    """Write the CSV log (header :data:`LOG_COLUMNS`, one row per change), atomically."""
    with atomic_path(path) as tmp:
        write_changes_csv(changes, tmp)

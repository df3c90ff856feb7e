"""The number of satellites (transmitters) behind an epoch's double differences.

RTKLIB's ``ns`` column counts satellites, not measurement rows: an RTK epoch with 20
satellites on two frequencies has about 2 × (20 − 2) phase DDs plus as many code DDs. A DD
row ``"<tx>-<ref>"`` uses two transmitters; the epoch's count is the number of distinct
satellites over the rows the update kept (finite robust factor), references included. A
multi-frequency receiver's rows are ids ``"<sat>:<band>"`` (``"G05:L1"``, ``"G05:L2"``): the
satellite is the part before ``":"``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import replace

from robustrtk.pipeline.results import DiagRow, EpochResult

__all__ = ["satellites_used", "with_satellites"]

#: Row kinds that are measurements (other rows record events: integrity, adaptive, reinit).
_MEASUREMENT_KINDS = ("code", "phase")


def _pair(label: str, ids: frozenset[str]) -> tuple[str, str] | None:
    """``(tx, ref)`` of a DD label ``"<tx>-<ref>"`` whose two parts are known ids (an id may
    itself hold a ``-``: every split is tried)."""
    start = 0
    while True:
        i = label.find("-", start)
        if i < 0:
            return None
        a, b = label[:i], label[i + 1 :]
        if a in ids and b in ids:
            return a, b
        start = i + 1


def satellites_used(rows: Iterable[DiagRow], tx_ids: Sequence[str]) -> int:
    """Distinct transmitters of the measurement rows with a finite robust factor.

    Parameters
    ----------
    rows : iterable of DiagRow
        The epoch's diagnostics rows (DD labels ``"<tx>-<ref>"``).
    tx_ids : sequence of str
        The epoch's transmitter ids (the rover's rows).

    Returns
    -------
    int
        ``|{sat(tx)} ∪ {sat(ref)}|`` over the kept rows (0 when none).
    """
    ids = frozenset(tx_ids)
    used: set[str] = set()
    for row in rows:
        if row.kind not in _MEASUREMENT_KINDS or not math.isfinite(row.factor):
            continue
        pair = _pair(row.dd, ids)
        if pair is not None:
            used.update(p.partition(":")[0] for p in pair)
    return len(used)


def with_satellites(res: EpochResult, tx_ids: Sequence[str]) -> EpochResult:
    """The result with ``solution.n_sat`` set from its diagnostics rows."""
    n = satellites_used(res.diagnostics, tx_ids)
    return replace(res, solution=replace(res.solution, n_sat=n))

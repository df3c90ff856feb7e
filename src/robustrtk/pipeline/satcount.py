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
from functools import lru_cache

from robustrtk.core import replaced
from robustrtk.pipeline.results import DiagRow, EpochResult

__all__ = ["satellites_used", "with_satellites"]

#: Row kinds that are measurements (other rows record events: integrity, adaptive, reinit).
_MEASUREMENT_KINDS = ("code", "phase")


@lru_cache(maxsize=4096)
def _splits(label: str) -> tuple[tuple[str, str, str, str], ...]:
    """Every ``(tx, ref, sat(tx), sat(ref))`` a DD label ``"<tx>-<ref>"`` may stand for (an
    id may itself hold a ``-``), remembered: an epoch's labels recur in the next."""
    out = []
    i = label.find("-")
    while i >= 0:
        a, b = label[:i], label[i + 1 :]
        out.append((a, b, a.partition(":")[0], b.partition(":")[0]))
        i = label.find("-", i + 1)
    return tuple(out)


def _pair(label: str, ids: frozenset[str]) -> tuple[str, str] | None:
    """Satellites ``(sat(tx), sat(ref))`` of a DD label ``"<tx>-<ref>"`` whose two parts
    are known ids (the first split that is)."""
    for a, b, sa, sb in _splits(label):
        if a in ids and b in ids:
            return sa, sb
    return None


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
            used.update(pair)
    return len(used)


def with_satellites(res: EpochResult, tx_ids: Sequence[str]) -> EpochResult:
    """The result with ``solution.n_sat`` set from its diagnostics rows."""
    n = satellites_used(res.diagnostics, tx_ids)
    return replaced(res, solution=replaced(res.solution, n_sat=n))

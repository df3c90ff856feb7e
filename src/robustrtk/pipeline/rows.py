"""Rows of epochs: matching epochs by tag, reordering rows to another epoch's transmitters."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import replace
from functools import lru_cache
from typing import TYPE_CHECKING, Any

import numpy as np

from robustrtk.core import BoolArray, FloatArray, IntArray, ObsBatch, ObsEpoch

if TYPE_CHECKING:
    from robustrtk.pipeline.results import EpochInputs


def align_epochs(rover: ObsBatch, base: ObsBatch, tol_s: float = 0.005) -> Iterator[tuple[int, int]]:
    """Pairs ``(i_rover, i_base)`` of epochs whose times agree within ``tol_s``."""
    tb = base.t_s
    if tb.size == 0:
        return
    j = np.searchsorted(tb, rover.t_s)
    for i, jj in enumerate(j):
        best = None
        for c in (jj - 1, jj):
            if 0 <= c < tb.size and abs(tb[c] - rover.t_s[i]) <= tol_s:
                if best is None or abs(tb[c] - rover.t_s[i]) < abs(tb[best] - rover.t_s[i]):
                    best = c
        if best is not None:
            yield i, int(best)


@lru_cache(maxsize=16)
def row_map(
    src_ids: tuple[str, ...], dst_ids: tuple[str, ...]
) -> tuple[tuple[int, ...], BoolArray, IntArray]:
    """Where the rows ``dst_ids`` are in ``src_ids`` (the first row of each name).

    Returns
    -------
    idx : tuple of int, length len(dst_ids)
        Source row of each destination row, −1 when absent.
    have : ndarray of bool, shape (len(dst_ids),)
        ``idx >= 0``.
    src_rows : ndarray of int, shape (have.sum(),)
        ``idx[have]``.

    Remembered for the last few pairs (a batch's epochs share their transmitter tuples).
    """
    first: dict[str, int] = {}
    for i, t in enumerate(src_ids):
        first.setdefault(t, i)
    idx = tuple(first.get(t, -1) for t in dst_ids)
    idx_a = np.array(idx, dtype=np.int64)
    have = idx_a >= 0
    src_rows = idx_a[have]
    have.flags.writeable = False
    src_rows.flags.writeable = False
    return idx, have, src_rows


@lru_cache(maxsize=16)
def row_groups_of(system: tuple[str, ...], tx_ids: tuple[str, ...]) -> tuple[str, ...]:
    """DD group ``"<system>:<slot>"`` of each signal row ``"<tx>:<slot>"`` (remembered for
    the last few row tuples: a batch's epochs share theirs)."""
    return tuple(f"{s}:{t.split(':', 1)[1]}" for s, t in zip(system, tx_ids, strict=True))


def take_rows(a: np.ndarray, have: BoolArray, src_rows: IntArray, fill: float) -> np.ndarray:
    """``a``'s rows ``src_rows`` placed at the rows ``have`` of a new array, ``fill`` elsewhere
    (see :func:`row_map`)."""
    out = np.full((have.shape[0],) + a.shape[1:], fill, dtype=a.dtype)
    out[have] = a[src_rows]
    return out


def reindex(epoch: ObsEpoch, tx_ids: tuple[str, ...]) -> ObsEpoch:
    """The epoch's rows reordered to ``tx_ids`` (NaN rows for transmitters it lacks)."""
    if epoch.tx_ids == tx_ids:
        return epoch
    idx, have, rows = row_map(tuple(epoch.tx_ids), tuple(tx_ids))

    def take(a: np.ndarray | None, fill: float) -> np.ndarray | None:
        return None if a is None else take_rows(a, have, rows, fill)

    system = epoch.system
    kw: dict[str, Any] = dict(
        tx_ids=tx_ids,
        system=tuple(system[i] if i >= 0 else "P" for i in idx),
        code_m=take(epoch.code_m, np.nan),
        phase_cyc=take(epoch.phase_cyc, np.nan),
        doppler_hz=take(epoch.doppler_hz, np.nan),
        cn0_dbhz=take(epoch.cn0_dbhz, np.nan),
        lli=take(epoch.lli, 0),
        wavelength_m=take(epoch.wavelength_m, np.nan),
        code_sigma_m=take(epoch.code_sigma_m, np.nan),
        phase_sigma_cyc=take(epoch.phase_sigma_cyc, np.nan),
    )
    if type(epoch) is ObsEpoch:  # the constructor directly: replace() costs more than the copies
        return ObsEpoch(t_s=epoch.t_s, signals=epoch.signals, **kw)
    return replace(epoch, **kw)


def has_dd(groups: Sequence[str], avail: np.ndarray) -> bool:
    """Whether some group has two available rows (a reference and a DD)."""
    seen: set[str] = set()
    for g, ok in zip(groups, np.asarray(avail, bool).tolist(), strict=True):
        if ok:
            if g in seen:
                return True
            seen.add(g)
    return False


def position_queries(
    inputs: Sequence[EpochInputs], signal: int, ecef: bool, rates: bool
) -> list[tuple[float, tuple[str, ...], FloatArray]]:
    """The satellite-position queries a DD engine makes for these epochs, for a source's
    ``prefetch``: the rover's (and its ±:data:`~robustrtk.measurement.doppler_velocity.RATE_STEP_S`
    neighbours when ``rates``, the DGNSS Doppler rows' satellite rates) and, in ECEF, the
    base's at its own tag with its pseudoranges reindexed to the rover's rows."""
    from robustrtk.measurement.doppler_velocity import RATE_STEP_S

    k = signal
    queries: list[tuple[float, tuple[str, ...], FloatArray]] = []
    for inp in inputs:
        rover = inp.rover
        queries.append((rover.t_s, rover.tx_ids, rover.code_m[:, k]))
        if rates and np.isfinite(rover.doppler_hz[:, k]).any():
            # the satellite rates' central difference (doppler_velocity.satellite_rates)
            for h in (RATE_STEP_S, -RATE_STEP_S):
                queries.append((rover.t_s + h, rover.tx_ids, rover.code_m[:, k]))
        if ecef:
            # the base's column of pseudoranges reindexed as in step (reindex's numbers)
            base = inp.base
            code_b = base.code_m[:, k]
            if base.tx_ids != rover.tx_ids:
                _, have, rows = row_map(tuple(base.tx_ids), tuple(rover.tx_ids))
                code_b = take_rows(code_b, have, rows, np.nan)
            queries.append((base.t_s, rover.tx_ids, code_b))
    return queries


__all__ = ["align_epochs", "has_dd", "position_queries", "reindex", "row_groups_of", "row_map", "take_rows"]

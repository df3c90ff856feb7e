"""Signal selection for multi-frequency processing: one row per (satellite, frequency slot).

A receiver file has ``(T, N, K)`` arrays over satellites × RINEX signals (``1C``, ``2W``,
``5Q``, ...). Multi-frequency DD processing wants one observable per satellite and
frequency, with the same tracking mode for all satellites of a system (so that phase
offsets between tracking modes, e.g. the quarter cycle between L2C and L2P, cancel
between satellites). :func:`signal_rows` picks, per system and frequency slot, the
receiver's tracking mode with the most phase data and lays the result out as a
``(T, N·B, 1)`` batch whose rows are named ``"<sat>:<slot>"`` (``"G05:L1"``).

Frequency slots (RINEX band digits, RTKLIB's ordering of frequencies)::

    slot  GPS  GLONASS  Galileo     BeiDou      QZSS
    L1    1    1        1 (E1)      2 (B1I)     1
    L2    2    2        7 (E5b)     7 (B2I)     2
    L5    5    3        5 (E5a)     6 (B3I)     5

Galileo and BeiDou fall back to their other bands when the preferred one is absent
(E5a for L2, B2a/B3I).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from functools import lru_cache

import numpy as np

from robustrtk.core import FloatArray, InputError, IntArray, ObsBatch

#: Band digits tried per system and slot, in order of preference.
SLOT_BANDS: dict[str, dict[str, tuple[str, ...]]] = {
    "L1": {"G": ("1",), "R": ("1",), "E": ("1",), "C": ("2", "1"), "J": ("1",), "I": ("5",)},
    "L2": {"G": ("2",), "R": ("2",), "E": ("7", "5"), "C": ("7", "5"), "J": ("2",), "I": ("9",)},
    "L5": {"G": ("5",), "R": ("3",), "E": ("5", "6"), "C": ("6", "5"), "J": ("5",)},
}

#: Tracking-mode preference within a band when the amounts of data tie.
ATTRIBUTE_PREFERENCE = "CLXSWPQIDBZAYMN"

SLOTS: tuple[str, ...] = tuple(SLOT_BANDS)


def parse_slots(text: str) -> tuple[str, ...]:
    """``"L1+L2"``, ``"1+2+5"`` or ``"L1,L2"`` → ``("L1", "L2")`` (validated)."""
    out: list[str] = []
    for tok in text.replace(",", "+").split("+"):
        tok = tok.strip().upper()
        if not tok:
            continue
        if not tok.startswith("L"):
            tok = "L" + tok
        if tok not in SLOT_BANDS:
            raise InputError(f"freqs: frequency {tok!r}: expected L1, L2 or L5 joined by '+'")
        if tok in out:
            raise InputError(
                f"freqs: frequency {tok!r} given twice in {text!r}; expected distinct frequencies"
            )
        out.append(tok)
    if not out:
        raise InputError(f"freqs: expected frequencies such as L1+L2, got {text!r}")
    return tuple(out)


def choose_signals(
    batch: ObsBatch, slots: Sequence[str], systems: str | None = None
) -> dict[tuple[str, str], int]:
    """Signal column per (system, slot) with the most phase (else code) observations.

    Returns
    -------
    dict
        ``(system, slot) -> column index`` into ``batch.signals``; pairs without data absent.
    """
    sys_arr = np.array(batch.system)
    out: dict[tuple[str, str], int] = {}
    for s in dict.fromkeys(batch.system):
        if systems is not None and s not in systems:
            continue
        rows = np.flatnonzero(sys_arr == s)
        for slot in slots:
            best: tuple[int, int, int] | None = None  # (-n_phase, -n_code, pref) ordering
            col_best = -1
            for band in SLOT_BANDS[slot].get(s, ()):
                for k, sig in enumerate(batch.signals):
                    if sig[:1] != band:
                        continue
                    n_ph = int(np.isfinite(batch.phase_cyc[:, rows, k]).sum())
                    n_c = int(np.isfinite(batch.code_m[:, rows, k]).sum())
                    if n_ph + n_c == 0:
                        continue
                    attr = sig[1:2]
                    pref = ATTRIBUTE_PREFERENCE.find(attr) if attr in ATTRIBUTE_PREFERENCE else 99
                    key = (-n_ph, -n_c, pref)
                    if best is None or key < best:
                        best, col_best = key, k
                if col_best >= 0:
                    break  # a preferred band with data wins over the fallbacks
            if col_best >= 0:
                out[(s, slot)] = col_best
    return out


def signal_rows(
    batch: ObsBatch,
    slots: Sequence[str] = ("L1", "L2"),
    systems: str | None = None,
    columns: dict[tuple[str, str], int] | None = None,
) -> ObsBatch:
    """One row per (satellite, slot): a ``(T, N·B, 1)`` batch for multi-frequency DDs.

    Parameters
    ----------
    batch : ObsBatch
        A receiver's observations, ``(T, N, K)``.
    slots : sequence of str
        Frequency slots (``"L1"``, ``"L2"``, ``"L5"``).
    systems : str, optional
        System letters to keep (all when None).
    columns : dict, optional
        ``(system, slot) -> column`` (default :func:`choose_signals`).

    Returns
    -------
    ObsBatch
        Rows ``"<sat>:<slot>"`` ordered by slot then satellite, ``signals = ("f",)``,
        ``meta["signal_by_slot"] = {"G:L1": "1C", ...}`` and ``meta["row_sat"]`` (the
        satellite of each row).
    """
    cols = choose_signals(batch, slots, systems) if columns is None else columns
    r_idx: list[int] = []
    c_idx: list[int] = []
    ids: list[str] = []
    sysl: list[str] = []
    for slot in slots:
        for n, (sat, s) in enumerate(zip(batch.tx_ids, batch.system, strict=True)):
            k = cols.get((s, slot))
            if k is None:
                continue
            r_idx.append(n)
            c_idx.append(k)
            ids.append(f"{sat}:{slot}")
            sysl.append(s)
    r = np.asarray(r_idx, dtype=np.int64)
    c = np.asarray(c_idx, dtype=np.int64)

    def take(a: np.ndarray) -> np.ndarray:
        return a[:, r, c][:, :, None]

    meta = dict(batch.meta)
    meta["signal_by_slot"] = {f"{s}:{slot}": batch.signals[k] for (s, slot), k in cols.items()}
    meta["row_sat"] = tuple(batch.tx_ids[i] for i in r)
    return replace(
        batch,
        tx_ids=tuple(ids),
        system=tuple(sysl),
        signals=("f",),
        code_m=take(batch.code_m),
        phase_cyc=take(batch.phase_cyc),
        doppler_hz=take(batch.doppler_hz),
        cn0_dbhz=take(batch.cn0_dbhz),
        lli=take(batch.lli),
        wavelength_m=batch.wavelength_m[r, c][:, None] if r.size else np.zeros((0, 1)),
        meta=meta,
        code_sigma_m=None if batch.code_sigma_m is None else take(batch.code_sigma_m),
        phase_sigma_cyc=None if batch.phase_sigma_cyc is None else take(batch.phase_sigma_cyc),
    )


def row_satellite(row_id: str) -> str:
    """``"G05:L1"`` → ``"G05"``."""
    return row_id.split(":", 1)[0]


@lru_cache(maxsize=16)
def _row_satellites(tx_ids: tuple[str, ...]) -> tuple[tuple[str, ...], IntArray]:
    """Distinct satellites of signal rows (order of appearance) and each row's satellite
    index, remembered for the last few row tuples (a batch's epochs share theirs)."""
    where: dict[str, int] = {}
    inv = np.array([where.setdefault(row_satellite(t), len(where)) for t in tx_ids], dtype=np.int64)
    inv.flags.writeable = False
    return tuple(where), inv


class RowSource:
    """Satellite positions for ``"<sat>:<slot>"`` rows from a per-satellite source.

    Each satellite is evaluated once per call, with the first finite pseudorange among
    its rows (the frequencies differ by the ionosphere, metres, i.e. nanoseconds of
    transmission time).

    :meth:`prefetch` evaluates the queries of many epochs in a few vectorised calls of the
    source's ``positions_at`` (when it has one); :meth:`positions` then hands out those
    results for the same ``(t, rows, pseudoranges)``, which are row for row the numbers a
    call of its own would give, and computes anything else as before.
    """

    #: Epochs per vectorised call of :meth:`prefetch` (bounds the selection's work arrays).
    CHUNK_EPOCHS = 64

    def __init__(self, source: object) -> None:
        self.source = source
        self._ready: dict[tuple[float, tuple[str, ...], bytes], tuple[FloatArray, FloatArray]] = {}

    @staticmethod
    def _satellites(
        tx_ids: Sequence[str], code_m: FloatArray | None
    ) -> tuple[list[str], IntArray, FloatArray | None]:
        """Distinct satellites of the rows, the row → satellite index, and each satellite's
        pseudorange (its first finite row's)."""
        uniq_t, inv = _row_satellites(tuple(tx_ids))
        uniq = list(uniq_t)
        code_u: FloatArray | None = None
        if code_m is not None:
            code = np.asarray(code_m, float)
            code_u = np.full(len(uniq), np.nan)
            rows = np.flatnonzero(np.isfinite(code[: inv.shape[0]]))
            # the first finite row of each satellite wins (a stable sort keeps row order)
            sat, first = np.unique(inv[rows], return_index=True)
            code_u[sat] = code[rows[first]]
        return uniq, inv.copy(), code_u

    @staticmethod
    def _key(
        t_s: float, tx_ids: Sequence[str], code_m: FloatArray | None
    ) -> tuple[float, tuple[str, ...], bytes]:
        code = b"" if code_m is None else np.ascontiguousarray(code_m, dtype=np.float64).tobytes()
        return float(t_s), tuple(tx_ids), code

    def prefetch(self, queries: Sequence[tuple[float, Sequence[str], FloatArray | None]]) -> None:
        """Evaluate ``(t_s, tx_ids, code_m)`` queries (e.g. every epoch of a run) ahead.

        Does nothing when the source has no ``positions_at``; queries without pseudoranges
        are left to :meth:`positions`. Results are kept until :meth:`positions` asks for
        them (each once).
        """
        self._ready.clear()  # what an earlier prefetch left (epochs a step skipped)
        batch = getattr(self.source, "positions_at", None)
        if batch is None:
            return
        with_code = [(float(t), list(ids), np.asarray(c, float)) for t, ids, c in queries if c is not None]
        for c0 in range(0, len(with_code), self.CHUNK_EPOCHS):
            chunk = with_code[c0 : c0 + self.CHUNK_EPOCHS]
            parts = [self._satellites(ids, code) for _, ids, code in chunk]
            t_all = np.concatenate(
                [np.full(len(u), t) for (t, _, _), (u, _, _) in zip(chunk, parts, strict=True)]
            )
            ids_all = [s for u, _, _ in parts for s in u]
            if not ids_all:
                continue
            code_all = np.concatenate([c for _, _, c in parts if c is not None])
            pos_all, clk_all = batch(t_all, ids_all, code_all)
            pos_all = np.asarray(pos_all, float)
            clk_all = np.asarray(clk_all, float)
            i0 = 0
            for (t, ids, code), (u, inv, _) in zip(chunk, parts, strict=True):
                i1 = i0 + len(u)
                self._ready[self._key(t, ids, code)] = (pos_all[i0:i1][inv], clk_all[i0:i1][inv])
                i0 = i1

    def positions(
        self, t_s: float, tx_ids: tuple[str, ...] | list[str], code_m: FloatArray | None = None
    ) -> tuple[FloatArray, FloatArray]:
        if self._ready:
            hit = self._ready.pop(self._key(t_s, tx_ids, code_m), None)
            if hit is not None:
                return hit
        uniq, inv, code_u = self._satellites(tx_ids, code_m)
        pos, clk = self.source.positions(t_s, uniq, code_u)  # type: ignore[attr-defined]
        return np.asarray(pos, float)[inv], np.asarray(clk, float)[inv]


__all__ = [
    "RowSource",
    "SLOTS",
    "SLOT_BANDS",
    "choose_signals",
    "parse_slots",
    "row_satellite",
    "signal_rows",
]

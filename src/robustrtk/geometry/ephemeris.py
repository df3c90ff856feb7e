"""Satellite positions and clocks from broadcast ephemerides (a ``TransmitterSource``).

Ephemeris selection, per query ``(t, satellite)``: records of the same satellite that are
healthy (health word 0; for QZSS bit 0, the L6 signal health, is ignored) and whose
reference time is within the system's validity window ``|t - toe| <= max_age_s``
(defaults: GPS/QZSS 2 h, Galileo 3 h, BeiDou 1 h, GLONASS 30 min); the nearest ``toe``
wins. For Galileo the I/NAV records (data source bits 0/2,
clock for E5b/E1, the E1 user's message) are preferred over F/NAV ones, which are used only
when no I/NAV record is valid.

Group-delay convention (single-frequency L1/E1/B1I user; the broadcast clock refers to the
ionosphere-free combination, or B3I for BeiDou)::

    dt_L1 = dt_broadcast - T_GD
    GPS, QZSS : T_GD = TGD (L1 C/A)
    Galileo   : T_GD = BGD(E1, E5b) for I/NAV records, BGD(E1, E5a) for F/NAV records
    BeiDou    : T_GD = TGD1 (B1I)
    GLONASS   : 0 (tau_n refers to the G1 signal; the G1-G2 delay difference dTauN
                of RINEX 3.05 / 4 records concerns G2 users and is not applied)

``dt_broadcast`` includes the relativistic correction ``F e sqrt(A) sin E`` for the
Keplerian systems.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from robustrtk.core import CLIGHT, BoolArray, FloatArray, IntArray
from robustrtk.geometry.navdata import KEPLER_SYSTEMS, NavData
from robustrtk.geometry.orbits import (
    glonass_states,
    kepler_clock,
    kepler_ecc_anomaly,
    kepler_position,
    kepler_states,
)

#: Default validity window |t - toe| (s) per system.
DEFAULT_MAX_AGE_S: dict[str, float] = {
    "G": 7200.0,
    "J": 7200.0,
    "E": 10800.0,
    "C": 3600.0,
    "R": 1800.0,
}

#: Nominal signal travel time (s) used when no pseudorange is given.
NOMINAL_TRAVEL_TIME_S = 0.075

_GAL_INAV_BITS = 0b101  # bits 0 (E1-B) and 2 (E5b-I)
_FALLBACK_PENALTY_S = 1.0e7
#: Queries × records above which a selection first cuts the record table to the queries'
#: time window (:func:`_records_near`); below, the cut costs more than it saves.
_COMPACT_ABOVE = 50_000
#: Lists of satellite ids whose codes :meth:`EphemerisSource.select` remembers (then it
#: starts afresh: memory bounded on any length of run).
_CODED_MEMO = 4096
#: Longest list of ids remembered (one epoch's satellites; not a block of many epochs).
_CODED_LONGEST = 1024
# (f_L1 / f_band)^2 for scaling the GPS/QZSS TGD (IS-GPS-200 20.3.3.3.3.2, IS-GPS-705).
_GPS_BAND_GAMMA = {"1": 1.0, "2": (77.0 / 60.0) ** 2, "5": (154.0 / 115.0) ** 2}


class EphemerisSource:
    """Broadcast-ephemeris :class:`~robustrtk.core.TransmitterSource`.

    Parameters
    ----------
    nav : NavData
        Navigation data from :func:`robustrtk.io.rinex_nav.read_rinex_nav`.
    max_age_s : dict, optional
        Validity window per system letter, overriding :data:`DEFAULT_MAX_AGE_S`.
    allow_unhealthy : bool
        Use records whose health word is non-zero (default False).
    """

    def __init__(
        self,
        nav: NavData,
        max_age_s: dict[str, float] | None = None,
        allow_unhealthy: bool = False,
    ) -> None:
        self.nav = nav
        self.max_age_s = dict(DEFAULT_MAX_AGE_S)
        if max_age_s:
            self.max_age_s.update(max_age_s)
        self.allow_unhealthy = allow_unhealthy
        self._glo_channels = nav.glo_channels()
        self._words: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self._records: dict[str, tuple[dict[str, int], IntArray]] = {}
        #: :meth:`_codes` per list of satellite ids
        self._coded: dict[tuple[str, ...], tuple[np.ndarray, IntArray]] = {}

    def _select_words(self, system: str) -> tuple[np.ndarray, np.ndarray]:
        """Per-record usability (health) and Galileo source penalty, computed once."""
        if system not in self._words:
            if system == "R":
                health = self.nav.glonass.health
                penalty = np.zeros(len(self.nav.glonass.sat_id))
            else:
                kep = self.nav.kepler[system]
                health = kep.health
                penalty = np.zeros(len(kep.sat_id))
                if system == "E":
                    src = np.nan_to_num(kep.code_or_source).astype(np.int64)
                    penalty = np.where(src & _GAL_INAV_BITS, 0.0, _FALLBACK_PENALTY_S)
            h = np.nan_to_num(health, nan=1.0).astype(np.int64)
            if system == "J":
                h = h & ~1  # QZSS: bit 0 is the L6 (LEX) signal health, not L1
            usable = np.ones(h.shape, dtype=bool) if self.allow_unhealthy else h == 0
            self._words[system] = (usable, penalty)
        return self._words[system]

    def _records_of(self, system: str) -> tuple[dict[str, int], IntArray]:
        """Each satellite's records in its system's table, computed once: ``(code, cols)``
        with ``code[sat]`` a row of ``cols`` (K,) holding the satellite's record indices in
        ascending order, padded with -1."""
        if system not in self._records:
            tab_ids = self.nav.glonass.sat_id if system == "R" else self.nav.kepler[system].sat_id
            cols_of: dict[str, list[int]] = {}
            for j, sid in enumerate(np.asarray(tab_ids).tolist()):
                cols_of.setdefault(str(sid), []).append(j)
            width = max((len(v) for v in cols_of.values()), default=0)
            cols = np.full((len(cols_of), width), -1, dtype=np.int64)
            code: dict[str, int] = {}
            for c, (sid, js) in enumerate(cols_of.items()):
                code[sid] = c
                cols[c, : len(js)] = js
            self._records[system] = (code, cols)
        return self._records[system]

    # ------------------------------------------------------------------ selection
    def select(self, t_s: FloatArray, sat_ids: Sequence[str]) -> IntArray:
        """Row index (within its system's table) of the ephemeris for each query.

        Parameters
        ----------
        t_s : ndarray, shape (N,)
            Query times (GPST s).
        sat_ids : sequence of str, length N

        Returns
        -------
        row : ndarray of int, shape (N,)
            Index into ``nav.kepler[sys]`` or ``nav.glonass``; -1 where no valid record.
        """
        t = np.broadcast_to(np.asarray(t_s, dtype=float), (len(sat_ids),))
        return self.select_coded(t, *self._codes(sat_ids))

    def _codes(self, sat_ids: Sequence[str]) -> tuple[np.ndarray, IntArray]:
        """:meth:`query_codes` of each query (N,), remembered per list of ids: an
        epoch-by-epoch solve asks for the same satellites several times per epoch, and
        epoch after epoch."""
        ids = tuple(str(s)[:3] for s in sat_ids)  # names as three-character ids
        coded = self._coded.get(ids)
        if coded is None:
            cols: dict[str, int] = {}
            col_of_row = np.array([cols.setdefault(s, len(cols)) for s in ids], dtype=np.int64)
            letter, code = self.query_codes(list(cols))
            coded = (letter[col_of_row], code[col_of_row])
            if len(ids) <= _CODED_LONGEST:
                if len(self._coded) >= _CODED_MEMO:
                    self._coded.clear()
                self._coded[ids] = coded
        return coded

    def query_codes(self, sat_ids: Sequence[str]) -> tuple[np.ndarray, IntArray]:
        """System letters and record-table codes of satellites, for :meth:`select_coded`.

        Parameters
        ----------
        sat_ids : sequence of str, length S

        Returns
        -------
        letter : ndarray of str (U1), shape (S,)
        code : ndarray of int, shape (S,)
            The satellite's row in its system's record table; -1 when it has no record.
        """
        ids = [str(s)[:3] for s in sat_ids]
        letter = np.array([s[:1] for s in ids], dtype="U1")
        code = np.full(len(ids), -1, dtype=np.int64)
        for j, s in enumerate(ids):
            system = s[:1]
            if system not in KEPLER_SYSTEMS and system != "R":
                continue
            if system != "R" and system not in self.nav.kepler:
                continue
            code[j] = self._records_of(system)[0].get(s, -1)
        return letter, code

    def select_coded(self, t_s: FloatArray, letter: np.ndarray, code: IntArray) -> IntArray:
        """:meth:`select` with the satellites given by :meth:`query_codes` (row by row the
        same choice, without a Python loop over the queries).

        Parameters
        ----------
        t_s : ndarray, shape (N,)
            Query times (GPST s).
        letter, code : ndarray, shape (N,)
            System letter and record-table code of each query.

        Returns
        -------
        row : ndarray of int, shape (N,)
            Index into ``nav.kepler[sys]`` or ``nav.glonass``; -1 where no valid record.
        """
        t = np.asarray(t_s, dtype=float)
        row = np.full(t.shape[0], -1, dtype=np.int64)
        for system in (*KEPLER_SYSTEMS, "R"):
            if system != "R" and system not in self.nav.kepler:
                continue
            toe = self.nav.glonass.toe_s if system == "R" else self.nav.kepler[system].toe_s
            if len(toe) == 0:
                continue
            q = np.flatnonzero((letter == system) & (code >= 0))
            if q.size == 0:
                continue
            _, cols = self._records_of(system)
            tq = t[q]
            fin = tq[np.isfinite(tq)]
            if fin.size * cols.shape[1] > _COMPACT_ABOVE:  # pays on large calls only
                cols = _records_near(cols, toe, float(fin.min()), float(fin.max()), self.max_age_s[system])
            # each query against its own satellite's records only (the others score ∞):
            # the same choice as over the whole table, ties to the first record
            cand = cols[code[q]]  # (nq, K), -1 padded
            valid = cand >= 0
            c0 = np.where(valid, cand, 0)
            usable, penalty = self._select_words(system)
            dt = np.abs(tq[:, None] - toe[c0])
            ok = valid & (dt <= self.max_age_s[system]) & usable[c0]
            score = np.where(ok, dt + penalty[c0], np.inf)
            best = np.argmin(score, axis=1)
            ar = np.arange(q.size)
            found = np.isfinite(score[ar, best])
            row[q] = np.where(found, cand[ar, best], -1)
        return row

    # ------------------------------------------------------------------ states
    def sat_states(
        self, t_tx_s: FloatArray, sat_ids: Sequence[str]
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, BoolArray]:
        """Satellite states at transmission time, in ECEF at that same time.

        Parameters
        ----------
        t_tx_s : ndarray, shape (N,)
            Signal transmission time in GPST (s) (the satellite clock already removed).
        sat_ids : sequence of str, length N

        Returns
        -------
        pos_ecef_m : ndarray, shape (N, 3)
        vel_ecef_m_s : ndarray, shape (N, 3)
            Velocity in the rotating ECEF frame.
        clk_s : ndarray, shape (N,)
            Broadcast clock offset including the relativistic term, without group delay
            (see :meth:`group_delay_s`).
        clk_drift_s_s : ndarray, shape (N,)
        ok : ndarray of bool, shape (N,)
            False where no valid ephemeris exists (those rows are NaN).
        """
        ids = list(sat_ids)
        n = len(ids)
        t = np.broadcast_to(np.asarray(t_tx_s, dtype=float), (n,)).copy()
        pos = np.full((n, 3), np.nan)
        vel = np.full((n, 3), np.nan)
        clk = np.full(n, np.nan)
        drift = np.full(n, np.nan)
        row = self.select(t, ids)
        sys_letter = np.array([s[:1] for s in ids], dtype="U1")
        for system in (*KEPLER_SYSTEMS, "R"):
            q = np.nonzero((sys_letter == system) & (row >= 0))[0]
            if q.size == 0:
                continue
            if system == "R":
                p, v, c, d = glonass_states(self.nav.glonass.take(row[q]), t[q])
            else:
                p, v, c, d = kepler_states(self.nav.kepler[system].take(row[q]), t[q], system)
            pos[q], vel[q], clk[q], drift[q] = p, v, c, d
        ok = (row >= 0) & np.isfinite(clk) & np.all(np.isfinite(pos), axis=1)
        return pos, vel, clk, drift, ok

    def group_delay_s(self, t_s: FloatArray, sat_ids: Sequence[str], band: str = "1") -> FloatArray:
        """Group delay ``T_GD`` (s) of the selected records for a single-frequency user.

        ``dt_band = clk_s - T_GD(band)``. Band ``"1"`` follows the module docstring; other
        bands: GPS/QZSS ``"2"``, ``"5"`` scale TGD by ``(f1/f)^2``; Galileo ``"5"`` (E5a)
        ``BGD(E1,E5a) (f1/f5a)^2``, ``"7"`` (E5b) ``BGD(E1,E5b) (f1/f5b)^2``; BeiDou ``"2"``
        (B1I, same as ``"1"``) TGD1, ``"7"`` (B2I) TGD2, ``"6"`` (B3I) 0; GLONASS 0.

        Returns
        -------
        tgd_s : ndarray, shape (N,)
            NaN where no valid record or the band is not covered.
        """
        ids = list(sat_ids)
        t = np.broadcast_to(np.asarray(t_s, dtype=float), (len(ids),))
        return self._group_delay_rows(_letters(ids), self.select(t, ids), band)

    def _group_delay_rows(self, sys_letter: np.ndarray, row: IntArray, band: str) -> FloatArray:
        """``T_GD`` (s) of the records ``row`` for ``band`` (vectorised per system)."""
        out = np.full(len(sys_letter), np.nan)
        for system in (*KEPLER_SYSTEMS, "R"):
            q = np.nonzero((sys_letter == system) & (row >= 0))[0]
            if q.size == 0:
                continue
            if system == "R":
                out[q] = 0.0
                continue
            kep = self.nav.kepler[system]
            r = row[q]
            if system in ("G", "J"):
                out[q] = kep.tgd1_s[r] * _GPS_BAND_GAMMA.get(band, np.nan)
            elif system == "E":
                inav = (np.nan_to_num(kep.code_or_source[r]).astype(np.int64) & _GAL_INAV_BITS) != 0
                if band == "1":
                    out[q] = np.where(inav, kep.tgd2_s[r], kep.tgd1_s[r])
                elif band == "5":
                    out[q] = kep.tgd1_s[r] * (1575.42 / 1176.45) ** 2
                elif band == "7":
                    out[q] = kep.tgd2_s[r] * (1575.42 / 1207.14) ** 2
            elif system == "C":
                if band in ("1", "2"):
                    out[q] = kep.tgd1_s[r]
                elif band == "7":
                    out[q] = kep.tgd2_s[r]
                elif band == "6":
                    out[q] = 0.0
        return out

    def glo_channel(self, sat_id: str) -> int | None:
        """GLONASS frequency channel of ``sat_id`` (None when unknown)."""
        return self._glo_channels.get(sat_id)

    # ------------------------------------------------------------------ protocol
    def transmission_time(
        self, t_rx_s: float, tx_ids: Sequence[str], code_m: FloatArray | None = None
    ) -> FloatArray:
        """Signal transmission time (GPST s) from the receiver time tag and pseudorange.

        ``t_tx = t_rx - P / c - dt_sat(t_tx)``, iterated three times (the satellite clock
        changes by < 1e-11 s per iteration); ``dt_sat`` includes the L1 group delay.
        Without pseudoranges a nominal travel time of 75 ms is used.
        """
        ids = list(tx_ids)
        return self.transmission_times(np.full(len(ids), float(t_rx_s)), ids, code_m)

    def transmission_times(
        self, t_rx_s: FloatArray, tx_ids: Sequence[str], code_m: FloatArray | None = None
    ) -> FloatArray:
        """:meth:`transmission_time` of queries with their own receiver times (the rows of
        many epochs in one call; row by row the same numbers): ``t_rx_s``, ``tx_ids`` and
        ``code_m`` as in :meth:`positions_at` (without pseudoranges a nominal travel time of
        75 ms); returns the transmission times ``t_tx_s``, shape (N,), GPST s."""
        ids = list(tx_ids)
        if code_m is None:
            travel = np.full(len(ids), NOMINAL_TRAVEL_TIME_S)
        else:
            travel = np.asarray(code_m, dtype=float) / CLIGHT
        return self._iterate_tx(np.asarray(t_rx_s, dtype=float) - travel, *self._codes(ids))

    def _iterate_tx(self, t_sv: FloatArray, letter: np.ndarray, code: IntArray) -> FloatArray:
        """``t_tx = t_sv - (dt(t_tx) - T_GD)`` from ``t_sv = t_rx - P/c``, three iterations."""
        t = t_sv.copy()
        row = self.select_coded(t_sv, letter, code)  # also the first iteration's records
        tgd = self._group_delay_rows(letter, row, "1")
        for k in range(3):
            # the clocks of sat_states(t, ids) without the orbits it would also compute
            clk = self._clock(t, letter, row if k == 0 else self.select_coded(t, letter, code))
            t = t_sv - (clk - tgd)
        return t

    def positions(
        self, t_s: float, tx_ids: tuple[str, ...] | list[str], code_m: FloatArray | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """Satellite positions and L1 clock offsets for one receiver epoch.

        Parameters as :meth:`robustrtk.core.TransmitterSource.positions`, with ``t_s`` in
        GPST seconds; NaN rows of ``code_m`` give NaN outputs.

        Returns
        -------
        pos_m : ndarray, shape (N, 3)
            ECEF at transmission time (not rotated for the Earth's rotation during the
            signal travel: see :func:`robustrtk.geometry.los.geometric_range`).
        clock_m : ndarray, shape (N,)
            ``c (dt_broadcast - T_GD)`` (m), relativistic term included; NaN where no
            valid ephemeris.
        """
        ids = list(tx_ids)
        return self.positions_at(np.full(len(ids), float(t_s)), ids, code_m)

    def positions_at(
        self, t_rx_s: FloatArray, tx_ids: Sequence[str], code_m: FloatArray | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """:meth:`positions` for queries with their own receiver times (vectorised over
        satellites and epochs: the rows of many epochs in one call).

        Parameters
        ----------
        t_rx_s : ndarray, shape (N,)
            Receiver time tag of each query (GPST s).
        tx_ids : sequence of str, length N
        code_m : ndarray, shape (N,), optional
            Pseudoranges (m); NaN rows give NaN outputs.

        Returns
        -------
        pos_m : ndarray, shape (N, 3)
        clock_m : ndarray, shape (N,)
            As :meth:`positions`, row by row the same numbers.

        Notes
        -----
        ``t_sv = t_rx − P/c``; one ephemeris selection at ``t_sv``; the clock at ``t_sv`` gives
        the transmission time ``t_tx = t_sv − (dt(t_sv) − T_GD)`` (the clock changes by
        < 1e-13 s over the travel-time difference); then position and clock at ``t_tx``.
        """
        ids = list(tx_ids)
        if code_m is None:
            travel = np.full(len(ids), NOMINAL_TRAVEL_TIME_S)
        else:
            travel = np.asarray(code_m, dtype=float) / CLIGHT
        t_sv = np.asarray(t_rx_s, dtype=float) - travel
        row = self.select(t_sv, ids)
        letter = _letters(ids)
        tgd = self._group_delay_rows(letter, row, "1")
        clk0 = self._clock(t_sv, letter, row)
        t_tx = t_sv - (clk0 - tgd)
        pos, clk = self._pos_clock(t_tx, letter, row)
        clock_m = (clk - tgd) * CLIGHT
        bad = (row < 0) | ~np.isfinite(clock_m) | ~np.all(np.isfinite(pos), axis=1)
        pos[bad] = np.nan
        clock_m[bad] = np.nan
        return pos, clock_m

    def code_states(
        self, t_rx_s: FloatArray, letter: np.ndarray, code: IntArray, code_m: FloatArray
    ) -> tuple[FloatArray, FloatArray, BoolArray]:
        """Positions and L1 clocks of many queries, each with its own receiver time and
        pseudorange, the satellites given by :meth:`query_codes`: row by row the numbers of
        :meth:`transmission_time` followed by :meth:`sat_states` and :meth:`group_delay_s`
        at the transmission time (the single-point geometry of one epoch), for the rows of
        many epochs at once.

        Parameters
        ----------
        t_rx_s : ndarray, shape (N,)
            Receiver time tag of each query (GPST s).
        letter, code : ndarray, shape (N,)
            System letter and record-table code of each query (:meth:`query_codes`).
        code_m : ndarray, shape (N,)
            Pseudoranges (m).

        Returns
        -------
        pos_ecef_m : ndarray, shape (N, 3)
            At the transmission time (NaN where no valid ephemeris).
        clock_m : ndarray, shape (N,)
            ``c (dt_broadcast - T_GD)`` (m).
        ok : ndarray of bool, shape (N,)
            A valid record, finite position and clock.
        """
        t_sv = np.asarray(t_rx_s, dtype=float) - np.asarray(code_m, dtype=float) / CLIGHT
        t = self._iterate_tx(t_sv, letter, code)
        row = self.select_coded(t, letter, code)
        pos, clk = self._pos_clock(t, letter, row)
        clock_m = (clk - self._group_delay_rows(letter, row, "1")) * CLIGHT
        ok = (row >= 0) & np.isfinite(clk) & np.all(np.isfinite(pos), axis=1) & np.isfinite(clock_m)
        return pos, clock_m, ok

    def _clock(self, t: FloatArray, sys_letter: np.ndarray, row: IntArray) -> FloatArray:
        """Clocks (N,) with the records ``row``: the clock of :meth:`_pos_clock` without the
        positions (the eccentric anomaly alone for the relativistic term)."""
        clk = np.full(len(sys_letter), np.nan)
        for system in (*KEPLER_SYSTEMS, "R"):
            q = np.nonzero((sys_letter == system) & (row >= 0) & np.isfinite(t))[0]
            if q.size == 0:
                continue
            if system == "R":  # the clock of glonass_states, without the orbit integration
                glo = self.nav.glonass.take(row[q])
                clk[q] = glo.minus_tau_n_s + glo.gamma_n * (t[q] - glo.toe_s)
            else:
                eph = self.nav.kepler[system].take(row[q])
                clk[q] = kepler_clock(eph, t[q], system, kepler_ecc_anomaly(eph, t[q], system))
        return clk

    def _pos_clock(
        self, t: FloatArray, sys_letter: np.ndarray, row: IntArray
    ) -> tuple[FloatArray, FloatArray]:
        """Positions (N, 3) and clocks (N,) with the records ``row`` (no velocities)."""
        n = len(sys_letter)
        pos = np.full((n, 3), np.nan)
        clk = np.full(n, np.nan)
        for system in (*KEPLER_SYSTEMS, "R"):
            q = np.nonzero((sys_letter == system) & (row >= 0) & np.isfinite(t))[0]
            if q.size == 0:
                continue
            if system == "R":
                p, _, c, _ = glonass_states(self.nav.glonass.take(row[q]), t[q])
            else:
                eph = self.nav.kepler[system].take(row[q])
                p, big_e = kepler_position(eph, t[q], system)
                c = kepler_clock(eph, t[q], system, big_e)
            pos[q], clk[q] = p, c
        return pos, clk


def _letters(ids: Sequence[str]) -> np.ndarray:
    """System letters (U1 array) of satellite ids."""
    return np.array([str(s)[:1] for s in ids], dtype="U1")


def _records_near(cols: IntArray, toe: FloatArray, t_lo: float, t_hi: float, max_age_s: float) -> IntArray:
    """The record table ``cols`` (satellites × records, ascending, -1 padded) cut to the
    records that can be valid for a query in ``[t_lo, t_hi]`` (``|t − toe| ≤ max_age_s``),
    in the same order: a query scores every other record ∞, so its choice is unchanged."""
    if cols.shape[1] <= 4 or not (np.isfinite(t_lo) and np.isfinite(t_hi)):
        return cols
    c0 = np.where(cols >= 0, cols, 0)
    near = (cols >= 0) & (toe[c0] >= t_lo - max_age_s) & (toe[c0] <= t_hi + max_age_s)
    width = int(near.sum(axis=1).max(initial=0))
    if width >= cols.shape[1]:
        return cols
    order = np.argsort(~near, axis=1, kind="stable")[:, : max(width, 1)]
    out = np.take_along_axis(cols, order, axis=1)
    keep = np.take_along_axis(near, order, axis=1)
    return np.where(keep, out, -1)

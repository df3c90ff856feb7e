"""Signals of the Kalman and batch SPP: the two bands per transmitter, the satellite states of an
epoch and its least-squares geometry."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from robustrtk.core import CLIGHT, FloatArray, ObsBatch
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.io.rinex_nav import NavData
from robustrtk.measurement.undifferenced import (
    EpochGeometry,
    carrier_frequency,
)
from robustrtk.pipeline.spp_common import (
    BAND1_PREFERENCE,
)

#: Second band per system, in order of preference (L5/E5a first: ten times the chip rate
#: of L1 C/A, so far less code multipath on phones).
BAND2_PREFERENCE: dict[str, tuple[str, ...]] = {
    "G": ("5", "2"),
    "J": ("5", "2"),
    "E": ("5", "7"),
    "C": ("7", "6"),
    "R": ("2",),
    "S": ("5",),
    "I": (),
}
#: Carrier phases with ``|phi|`` below this (cycles) are treated as absent: Android
#: converters write 0 where the accumulated delta range is invalid.
PHASE_ZERO_CYC = 1e-3
#: Prior variance of the phase clock when the filter starts (m^2); its common mode with
#: the carrier-phase biases is not observable, so any finite value serves.
PHASE_CLOCK_VAR0_M2 = 1.0e2

AmbKey = tuple[str, int, int]  # (transmitter, band index 0/1, arc number)


# ---------------------------------------------------------------------- signals
@dataclass(frozen=True)
class Signals:
    """Columns of the two bands per transmitter, pulled out of a batch.

    Attributes
    ----------
    systems : tuple of str
        Systems with ephemerides and at least one chosen column, sorted.
    rows : ndarray of int, shape (N',)
        Batch transmitter indices kept.
    ids, sys : tuple of str, length N'
    band : tuple of (str, str)
        Band digit of columns 0 and 1 of each kept transmitter (``""`` when absent).
    code_m, phase_cyc, doppler_hz, cn0_dbhz, lli : ndarray, shape (T, N', 2)
    wavelength_m : ndarray, shape (N', 2)
    """

    systems: tuple[str, ...]
    rows: np.ndarray
    ids: tuple[str, ...]
    sys: tuple[str, ...]
    band: tuple[tuple[str, str], ...]
    code_m: FloatArray
    phase_cyc: FloatArray
    doppler_hz: FloatArray
    cn0_dbhz: FloatArray
    lli: FloatArray
    wavelength_m: FloatArray


def spp_columns(
    batch: ObsBatch,
    nav: NavData,
    dual_frequency: bool,
    systems: str | None = None,
    fixed: Mapping[tuple[str, int], str] | None = None,
) -> dict[str, tuple[int, int]]:
    """The batch columns :func:`spp_signals` takes per system: band 1 and band 2 (``-1``
    where none), systems with ephemerides (and in ``systems``) and a column only.

    ``fixed`` names the signal of a ``(system, band index)`` chosen before (a stream keeps
    its first choice): that column when the batch has it, none otherwise; the others are
    the first column of the preferred bands with any code.
    """
    sys_arr = np.array(batch.system)
    single = batch.signals == ("1",)
    given = fixed or {}

    def pick(s: str, b: int, rows: np.ndarray, bands: tuple[str, ...]) -> int:
        name = given.get((s, b))
        if name is not None:
            return batch.signals.index(name) if name in batch.signals else -1
        for band in bands:
            for k, sig in enumerate(batch.signals):
                if sig[:1] == band and np.isfinite(batch.code_m[:, rows, k]).any():
                    return k
        return -1

    out: dict[str, tuple[int, int]] = {}
    for s in dict.fromkeys(batch.system):
        if nav.n_records(s) == 0 or (systems is not None and s not in systems):
            continue
        rows = np.flatnonzero(sys_arr == s)
        k1 = 0 if single else pick(s, 0, rows, BAND1_PREFERENCE.get(s, ("1",)))
        k2 = -1 if (single or not dual_frequency) else pick(s, 1, rows, BAND2_PREFERENCE.get(s, ()))
        if k1 >= 0 or k2 >= 0:
            out[s] = (k1, k2)
    return out


def spp_signals(
    batch: ObsBatch,
    nav: NavData,
    dual_frequency: bool,
    systems: str | None = None,
    columns: Mapping[str, tuple[int, int]] | None = None,
) -> Signals:
    """Per system, the first band-1 column with code (:data:`BAND1_PREFERENCE`) and, when
    ``dual_frequency``, the first second-band column with code (:data:`BAND2_PREFERENCE`).

    A batch reduced by :func:`robustrtk.pipeline.spp_common.select_band1` (``signals == ("1",)``)
    gives band 1 only. Systems without ephemeris records, or not in ``systems`` (letters,
    all when None), are dropped. ``columns`` (:func:`spp_columns`' form) gives the columns
    chosen otherwise.
    """
    sys_arr = np.array(batch.system)
    T = len(batch)
    single = batch.signals == ("1",)
    cols_of = spp_columns(batch, nav, dual_frequency, systems) if columns is None else columns
    keep: list[int] = []
    cols: list[tuple[int, int]] = []
    used: list[str] = []
    for s, (k1, k2) in cols_of.items():
        rows = np.flatnonzero(sys_arr == s)
        used.append(s)
        keep.extend(rows.tolist())
        cols.extend([(k1, k2)] * rows.size)
    order = np.argsort(keep, kind="stable")
    r = np.asarray(keep, dtype=np.int64)[order]
    c = np.asarray(cols, dtype=np.int64).reshape(-1, 2)[order]
    n = r.size

    def take(a: np.ndarray) -> FloatArray:
        out = np.full((T, n, 2), np.nan)
        for b in range(2):
            ok = c[:, b] >= 0
            out[:, ok, b] = a[:, r[ok], c[ok, b]]
        return out

    wl = np.full((n, 2), np.nan)
    bands: list[tuple[str, str]] = []
    for q in range(n):
        pair = []
        for b in range(2):
            if c[q, b] >= 0:
                wl[q, b] = batch.wavelength_m[r[q], c[q, b]]
                pair.append("1" if single else batch.signals[c[q, b]][:1])
            else:
                pair.append("")
        bands.append((pair[0], pair[1]))
    phase = take(batch.phase_cyc)
    phase[np.abs(phase) < PHASE_ZERO_CYC] = np.nan
    return Signals(
        systems=tuple(sorted(used)),
        rows=r,
        ids=tuple(batch.tx_ids[i] for i in r),
        sys=tuple(batch.system[i] for i in r),
        band=tuple(bands),
        code_m=take(batch.code_m),
        phase_cyc=phase,
        doppler_hz=take(batch.doppler_hz),
        cn0_dbhz=take(batch.cn0_dbhz),
        lli=take(batch.lli),
        wavelength_m=wl,
    )


# ---------------------------------------------------------------------- epoch geometry
@dataclass
class SatStates:
    """Satellite states of one epoch (rows = transmitters with code and ephemeris)."""

    idx: np.ndarray  # indices into Signals
    t_tx_s: FloatArray
    pos_m: FloatArray
    vel_m_s: FloatArray
    clk_m: FloatArray  # c dt, no group delay
    drift_m_s: FloatArray
    tgd_m: FloatArray  # (n, 2) c T_GD of each band (NaN when not covered)


def sat_states(sig: Signals, i: int, t_s: float, eph: EphemerisSource) -> SatStates:
    code = sig.code_m[i]
    tt = np.where(np.isfinite(code[:, 0]), code[:, 0], code[:, 1])
    idx = np.flatnonzero(np.isfinite(tt))
    ids = [sig.ids[j] for j in idx]
    if idx.size == 0:
        z = np.zeros((0, 3))
        return SatStates(idx, np.zeros(0), z, z, np.zeros(0), np.zeros(0), np.zeros((0, 2)))
    t_tx = eph.transmission_time(t_s, ids, tt[idx])
    pos, vel, clk, drift, ok = eph.sat_states(t_tx, ids)
    tgd = np.full((idx.size, 2), np.nan)
    for b in range(2):
        for band in {sig.band[j][b] for j in idx} - {""}:
            sel = np.array([sig.band[j][b] == band for j in idx])
            tgd[sel, b] = eph.group_delay_s(t_tx[sel], [ids[q] for q in np.flatnonzero(sel)], band)
    ok &= np.isfinite(clk)
    return SatStates(
        idx[ok], t_tx[ok], pos[ok], vel[ok], clk[ok] * CLIGHT, drift[ok] * CLIGHT, tgd[ok] * CLIGHT
    )


#: Epochs whose satellite states :class:`SatStatesTable` computes in one call.
SAT_STATES_BLOCK = 256


class SatStatesTable:
    """:func:`sat_states` of every epoch of ``sig``, computed a block of epochs at a time
    (the ephemeris calls vectorised over the rows of :data:`SAT_STATES_BLOCK` epochs: row by
    row the same numbers, :meth:`robustrtk.geometry.ephemeris.EphemerisSource.transmission_times`).

    Parameters
    ----------
    sig : Signals
    t_s : ndarray, shape (T,)
        Receiver time tag of each epoch (GPST s).
    eph : EphemerisSource
    """

    def __init__(self, sig: Signals, t_s: FloatArray, eph: EphemerisSource) -> None:
        self.sig, self.eph = sig, eph
        self.t_s = np.asarray(t_s, dtype=float)
        self._lo, self._hi = 0, 0
        self._block: list[SatStates] = []

    def of(self, i: int) -> SatStates:
        """The satellite states of epoch ``i`` (:func:`sat_states`)."""
        if not self._lo <= i < self._hi:
            self._lo = i
            self._hi = min(i + SAT_STATES_BLOCK, len(self.t_s))
            self._block = self._compute(self._lo, self._hi)
        return self._block[i - self._lo]

    def _compute(self, lo: int, hi: int) -> list[SatStates]:
        sig, eph = self.sig, self.eph
        code = sig.code_m[lo:hi]
        tt = np.where(np.isfinite(code[:, :, 0]), code[:, :, 0], code[:, :, 1])
        ei, jj = np.nonzero(np.isfinite(tt))
        ids = [sig.ids[j] for j in jj.tolist()]
        t_tx = eph.transmission_times(self.t_s[lo:hi][ei], ids, tt[ei, jj])
        pos, vel, clk, drift, ok = eph.sat_states(t_tx, ids)
        tgd = np.full((jj.size, 2), np.nan)
        for b in range(2):
            band_of = np.array([sig.band[j][b] for j in jj.tolist()], dtype=object)
            for band in set(band_of.tolist()) - {""}:
                sel = band_of == band
                tgd[sel, b] = eph.group_delay_s(t_tx[sel], [ids[q] for q in np.flatnonzero(sel)], band)
        ok &= np.isfinite(clk)
        clk_m, drift_m_s, tgd_m = clk * CLIGHT, drift * CLIGHT, tgd * CLIGHT
        bounds = np.searchsorted(ei, np.arange(hi - lo + 1))
        out: list[SatStates] = []
        for k in range(hi - lo):
            a, z = int(bounds[k]), int(bounds[k + 1])
            if a == z:
                zero = np.zeros((0, 3))
                empty = np.flatnonzero(np.zeros(0, bool))
                out.append(
                    SatStates(empty, np.zeros(0), zero, zero, np.zeros(0), np.zeros(0), np.zeros((0, 2)))
                )
                continue
            r = a + np.flatnonzero(ok[a:z])
            out.append(SatStates(jj[r], t_tx[r], pos[r], vel[r], clk_m[r], drift_m_s[r], tgd_m[r]))
        return out


def lsq_geometry(sig: Signals, i: int, sats: SatStates) -> EpochGeometry:
    """Band-1 code of the epoch in the form the least-squares SPP takes."""
    code1 = sig.code_m[i, sats.idx, 0]
    sel = np.isfinite(code1) & np.isfinite(sats.tgd_m[:, 0])
    j = sats.idx[sel]
    wl = sig.wavelength_m[j, 0]
    return EpochGeometry(
        ids=tuple(sig.ids[q] for q in j),
        sys=tuple(sig.sys[q] for q in j),
        code_m=code1[sel],
        cn0_dbhz=sig.cn0_dbhz[i, j, 0],
        rate_m_s=-wl * sig.doppler_hz[i, j, 0],
        freq_hz=carrier_frequency(wl),
        sat_pos_m=sats.pos_m[sel],
        sat_vel_m_s=sats.vel_m_s[sel],
        sat_clk_m=sats.clk_m[sel] - sats.tgd_m[sel, 0],
        sat_drift_m_s=sats.drift_m_s[sel],
        ok=np.ones(int(sel.sum()), bool),
    )

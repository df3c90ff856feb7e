"""Observations and ephemerides decoded from binary streams, gathered into the project's
types (:class:`~robustrtk.core.ObsBatch`, :class:`~robustrtk.geometry.navdata.NavData`).

The UBX and RTCM 3 decoders (:mod:`robustrtk.io.ubx`, :mod:`robustrtk.io.rtcm3`) produce one
cell at a time -- (epoch, satellite, signal) with code, phase, Doppler, C/N0 and LLI -- and
one ephemeris at a time. :class:`ObsCollector` stacks the cells into ``(T, N, K)`` arrays with
the same conventions as the RINEX reader (:mod:`robustrtk.io.rinex_obs`): satellites sorted by
system (``G R E C J S I``) then number, signals sorted, NaN where absent, ``lli`` bit 0 loss of
lock and bit 1 half-cycle ambiguity, wavelengths from :func:`robustrtk.gnss.wavelength_m`
(GLONASS with the decoded frequency channel). :class:`NavCollector` keeps each distinct
ephemeris once (by satellite, reference time and issue of data).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from robustrtk.core import ObsBatch
from robustrtk.geometry.navdata import KEPLER_SYSTEMS, GloNav, IonoModel, KeplerNav, NavData
from robustrtk.gnss import wavelength_m

__all__ = [
    "GLO_FIELDS",
    "KEPLER_FIELDS",
    "SYSTEM_ORDER",
    "NavCollector",
    "ObsCollector",
    "count",
    "merge_nav",
]

SYSTEM_ORDER = "GRECJSI"

#: Field names of a Keplerian record (those of :class:`KeplerNav`).
KEPLER_FIELDS = tuple(KeplerNav.__dataclass_fields__)
#: Field names of a GLONASS record (those of :class:`GloNav`).
GLO_FIELDS = tuple(GloNav.__dataclass_fields__)


def count(counter: dict[str, int], key: str, n: int = 1) -> None:
    """Add ``n`` to ``counter[key]``."""
    counter[key] = counter.get(key, 0) + n


def _tx_key(tx: str) -> tuple[int, int]:
    return SYSTEM_ORDER.index(tx[0]) if tx[0] in SYSTEM_ORDER else 99, int(tx[1:])


class ObsCollector:
    """Observation cells of one receiver, stacked into an :class:`ObsBatch` at the end."""

    def __init__(self) -> None:
        self._t: list[int] = []
        self._tx: list[str] = []
        self._sig: list[str] = []
        self._val: list[tuple[float, float, float, float]] = []
        self._lli: list[int] = []
        #: GLONASS frequency channel per satellite id (``"R07"`` -> 5).
        self.glo_channels: dict[str, int] = {}

    def __len__(self) -> int:
        return len(self._t)

    def add(
        self,
        t_ns: int,
        tx: str,
        signal: str,
        code_m: float,
        phase_cyc: float,
        doppler_hz: float,
        cn0_dbhz: float,
        lli: int,
    ) -> None:
        """One cell: epoch ``t_ns`` (GPST ns, exact integer), satellite ``tx`` (``"G05"``),
        signal (``"1C"``); NaN for absent values."""
        self._t.append(t_ns)
        self._tx.append(tx)
        self._sig.append(signal)
        self._val.append((code_m, phase_cyc, doppler_hz, cn0_dbhz))
        self._lli.append(lli)

    def keep_epochs(self, t_keep: set[int]) -> int:
        """Drop the cells whose epoch (GPST ns) is not in ``t_keep``; returns the epochs
        dropped."""
        keep = [k for k, t in enumerate(self._t) if t in t_keep]
        dropped = len(set(self._t)) - len({self._t[k] for k in keep})
        self._t = [self._t[k] for k in keep]
        self._tx = [self._tx[k] for k in keep]
        self._sig = [self._sig[k] for k in keep]
        self._val = [self._val[k] for k in keep]
        self._lli = [self._lli[k] for k in keep]
        return dropped

    def epoch_tags_ns(self) -> list[int]:
        """Distinct epoch tags (GPST ns) held, increasing."""
        return sorted(set(self._t))

    def pop_epochs(self, tags_ns: set[int]) -> ObsCollector:
        """Move the cells of the epochs ``tags_ns`` into a new collector (a stream hands
        each completed epoch on and keeps only the one being received)."""
        out = ObsCollector()
        out.glo_channels = dict(self.glo_channels)
        keep: list[int] = []
        for k, t in enumerate(self._t):
            if t in tags_ns:
                out.add(t, self._tx[k], self._sig[k], *self._val[k], self._lli[k])
            else:
                keep.append(k)
        self._t = [self._t[k] for k in keep]
        self._tx = [self._tx[k] for k in keep]
        self._sig = [self._sig[k] for k in keep]
        self._val = [self._val[k] for k in keep]
        self._lli = [self._lli[k] for k in keep]
        return out

    def batch(
        self, receiver: str = "", approx_pos_m: np.ndarray | None = None, meta: dict[str, Any] | None = None
    ) -> ObsBatch:
        """The cells as an :class:`ObsBatch` (epochs = the distinct time tags, increasing;
        the exact tags in ``meta["t_ns"]``)."""
        t_all = np.asarray(self._t, dtype=np.int64)
        t_u_ns, ep = np.unique(t_all, return_inverse=True)
        t_u = t_u_ns // 1_000_000_000 + (t_u_ns % 1_000_000_000) * 1e-9
        txs = sorted(set(self._tx), key=_tx_key)
        sigs = sorted(set(self._sig))
        tx_i = {t: i for i, t in enumerate(txs)}
        sig_i = {s: i for i, s in enumerate(sigs)}
        T, N, K = t_u.size, len(txs), len(sigs)
        out = np.full((4, T, N, K), np.nan)
        lli = np.zeros((T, N, K), np.int8)
        if self._t:
            n_idx = np.fromiter((tx_i[t] for t in self._tx), np.int64, len(self._tx))
            k_idx = np.fromiter((sig_i[s] for s in self._sig), np.int64, len(self._sig))
            vals = np.asarray(self._val, dtype=float).T  # (4, R)
            for f in range(4):
                out[f, ep, n_idx, k_idx] = vals[f]
            lli[ep, n_idx, k_idx] = np.asarray(self._lli, dtype=np.int64).astype(np.int8)
        used = np.zeros((N, K), bool)
        if self._t:
            used[n_idx, k_idx] = True
        wl = np.full((N, K), np.nan)
        for n, tx in enumerate(txs):
            ch = self.glo_channels.get(tx) if tx[0] == "R" else None
            for k, sig in enumerate(sigs):
                if used[n, k]:
                    wl[n, k] = wavelength_m(tx[0], sig, ch)
        m: dict[str, object] = dict(meta or {})
        m["glonass_channels"] = dict(sorted(self.glo_channels.items()))
        m["t_ns"] = t_u_ns
        m["t_ns_exact"] = True
        m.setdefault("time_system", "GPS")
        return ObsBatch.from_stacked(t_u, tuple(txs), tuple(sigs), out, lli, wl, receiver, approx_pos_m, m)


@dataclass
class NavCollector:
    """Ephemerides decoded from a stream, each distinct one kept once.

    Attributes
    ----------
    kepler : dict str -> list of dict
        Per system letter (``G E C J``), records with the :class:`KeplerNav` field names.
    glonass : list of dict
        Records with the :class:`GloNav` field names.
    ion_gps : ndarray, shape (8,), or None
        Klobuchar ``alpha0..3, beta0..3`` (latest decoded).
    leap_s : int or None
        GPST - UTC broadcast (latest decoded).
    counts : dict str -> int
        Ephemerides kept per kind (``"EPH G LNAV"``).
    """

    kepler: dict[str, list[dict[str, Any]]] = field(default_factory=lambda: {s: [] for s in KEPLER_SYSTEMS})
    glonass: list[dict[str, Any]] = field(default_factory=list)
    ion_gps: np.ndarray | None = None
    ion_gal: np.ndarray | None = None
    leap_s: int | None = None
    counts: dict[str, int] = field(default_factory=dict)
    _seen: set[tuple[object, ...]] = field(default_factory=set)

    @property
    def n_records(self) -> int:
        """Ephemerides kept so far (a stream sends navigation events when it grows)."""
        return len(self._seen)

    def add_kepler(self, system: str, rec: dict[str, Any], message: str) -> bool:
        """Keep ``rec`` unless the same (satellite, toe, toc, iode) was kept before."""
        key = (rec["sat_id"], round(float(rec["toe_s"])), round(float(rec["toc_s"])), rec["iode"], message)
        if key in self._seen:
            return False
        self._seen.add(key)
        self.kepler[system].append(rec)
        count(self.counts, f"EPH {system} {message}")
        return True

    def add_glonass(self, rec: dict[str, Any]) -> bool:
        """Keep ``rec`` unless the same (satellite, tb) was kept before."""
        key = (rec["sat_id"], round(float(rec["toe_s"])), "R")
        if key in self._seen:
            return False
        self._seen.add(key)
        self.glonass.append(rec)
        count(self.counts, "EPH R FDMA")
        return True

    def marks(self) -> dict[str, int]:
        """Where the records kept so far end (per system letter, and ``counts`` keys): the
        ``since`` of a later :meth:`nav_data` that wants only the records kept after now."""
        out = {s: len(self.kepler[s]) for s in KEPLER_SYSTEMS}
        out["R"] = len(self.glonass)
        out.update({f"#{k}": v for k, v in self.counts.items()})
        return out

    def nav_data(self, files: tuple[str, ...] = (), since: Mapping[str, int] | None = None) -> NavData:
        """The ephemerides as a :class:`NavData` (records in decoding order); with ``since``
        (a :meth:`marks`) only the records kept after it, and their counts (ionosphere and
        leap seconds: the latest decoded, whatever ``since``)."""
        at = since or {}
        kep = {}
        for s in KEPLER_SYSTEMS:
            recs = self.kepler[s][at.get(s, 0) :]
            cols: dict[str, Any] = {}
            for f in KEPLER_FIELDS:
                if f == "sat_id":
                    cols[f] = np.asarray([r[f] for r in recs], dtype="U3")
                else:
                    cols[f] = np.asarray([r.get(f, math.nan) for r in recs], dtype=float)
            kep[s] = KeplerNav(**cols)
        g = self.glonass[at.get("R", 0) :]
        gcols: dict[str, Any] = {}
        for f in GLO_FIELDS:
            if f == "sat_id":
                gcols[f] = np.asarray([r[f] for r in g], dtype="U3")
            elif f in ("pos_m", "vel_m_s", "acc_m_s2"):
                gcols[f] = np.asarray([r[f] for r in g], dtype=float).reshape(-1, 3)
            elif f == "freq_channel":
                gcols[f] = np.asarray([r[f] for r in g], dtype=np.int64)
            else:
                gcols[f] = np.asarray([r[f] for r in g], dtype=float)
        new = {k: n - at.get(f"#{k}", 0) for k, n in self.counts.items()}
        iono: list[IonoModel] = []
        if self.ion_gps is not None:
            iono.append(IonoModel("G", "LNAV", "klobuchar", math.nan, self.ion_gps))
        return NavData(
            kepler=kep,
            glonass=GloNav(**gcols),
            ion_gps_alpha=None if self.ion_gps is None else self.ion_gps[:4].copy(),
            ion_gps_beta=None if self.ion_gps is None else self.ion_gps[4:].copy(),
            ion_gal=self.ion_gal,
            leap_s=self.leap_s,
            files=files,
            iono_models=tuple(iono),
            record_counts={k: n for k, n in new.items() if n > 0},
        )


def merge_nav(navs: list[NavData]) -> NavData:
    """The records of several :class:`NavData` concatenated (ionosphere, leap seconds and
    other single values from the first that has them)."""
    if not navs:
        raise ValueError("no navigation data to merge")
    kep = {
        s: KeplerNav(**{f: np.concatenate([getattr(n.kepler[s], f) for n in navs]) for f in KEPLER_FIELDS})
        for s in KEPLER_SYSTEMS
    }
    glo = GloNav(**{f: np.concatenate([getattr(n.glonass, f) for n in navs]) for f in GLO_FIELDS})

    def first(attr: str) -> Any:
        return next((getattr(n, attr) for n in navs if getattr(n, attr) is not None), None)

    counts: dict[str, int] = {}
    skipped: dict[str, int] = {}
    for n in navs:
        for k, v in n.record_counts.items():
            count(counts, k, v)
        for k, v in n.skipped_records.items():
            count(skipped, k, v)
    return NavData(
        kepler=kep,
        glonass=glo,
        ion_gps_alpha=first("ion_gps_alpha"),
        ion_gps_beta=first("ion_gps_beta"),
        ion_gal=first("ion_gal"),
        leap_s=first("leap_s"),
        files=tuple(f for n in navs for f in n.files),
        ion_bds_alpha=first("ion_bds_alpha"),
        ion_bds_beta=first("ion_bds_beta"),
        iono_models=tuple(m for n in navs for m in n.iono_models),
        record_counts=counts,
        skipped_records=skipped,
        versions=tuple(v for n in navs for v in n.versions),
    )

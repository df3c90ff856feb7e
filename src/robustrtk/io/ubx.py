"""u-blox UBX binary logs: raw observations (RXM-RAWX) and navigation words (RXM-SFRBX).

Framing (u-blox M8 receiver description, "UBX frame structure"): sync ``0xB5 0x62``, class,
id, little-endian payload length, payload, two Fletcher checksum bytes. Bytes outside frames
(NMEA sentences, RTCM 3 frames, garbage), frames whose checksum fails, frames cut short at the
end of the input and message types not decoded here are skipped and counted in
:attr:`UbxDecoder.counts`; nothing in the input raises.

RXM-RAWX (class 0x02, id 0x15) gives one epoch: receiver time of week and week (GPST), then
per signal the pseudorange (m), carrier phase (cycles), Doppler (Hz), C/N0 (dB-Hz), lock time
(ms) and tracking status. The cells are converted as RINEX observation files have them:

* code is kept when ``trkStat`` bit 0 (pseudorange valid) is set; phase when bit 1 (carrier
  phase valid) is set, the phase is not the receiver's ``-0.5`` placeholder and its standard
  deviation index ``cpStdev`` is at most 5 (0.02 cycles; 14 once a generation-9 receiver is
  recognised by a signal id above 1);
* LLI bit 0 (loss of lock): the lock time decreased or restarted from 0 since the previous
  epoch of the signal, the half-cycle-subtracted bit (``subHalfCyc``) changed, or
  ``cpStdev`` reached 15; a loss seen while the phase is invalid is carried to the next valid
  phase of the signal;
* LLI bit 1 (half-cycle ambiguity): a valid phase whose half-cycle ambiguity is not resolved
  (``halfCyc`` clear; for SBAS, a lock time of 8 s or less);
* BeiDou GEO phases (PRN 1-5, 59-63) get +0.5 cycle, the convention of other RINEX converters
  for the B1I D2 navigation phase.

Signals: with message version 0 (M8 receivers) GPS, GLONASS, QZSS and SBAS are ``1C``, Galileo
``1X`` and BeiDou ``2I`` (B1I); version 1 maps the signal id to ``1C 2X 5X`` (GPS), ``1C 2C``
(GLONASS), ``1X 5X 7X`` (Galileo), ``1C 2X 5X`` (QZSS), ``2I 7I 5X`` (BeiDou).

RXM-SFRBX (class 0x02, id 0x13) gives navigation words: GPS and QZSS LNAV subframes and
GLONASS strings are decoded into ephemerides by :mod:`robustrtk.io.nav_words`, Galileo I/NAV
pages by :mod:`robustrtk.io.nav_inav` (ephemeris at word 5, words 1-4 with one IODnav); other
systems' words (BeiDou D1/D2, SBAS, GPS CNAV) are counted as skipped. LNAV subframes are
kept per satellite and an ephemeris is decoded when subframe 3 arrives and subframes 1-3
share their issue of data; GLONASS strings must pass their Hamming code and strings 1-4 must
carry the same superframe/frame number (the word the receiver appends) to make an ephemeris.
"""

from __future__ import annotations

import math
import os
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from robustrtk.core import ObsBatch
from robustrtk.geometry.navdata import NavData
from robustrtk.io.bits import fletcher8
from robustrtk.io.framing import ByteFramer
from robustrtk.io.nav_inav import decode_inav_ephemeris, inav_page_word
from robustrtk.io.nav_words import (
    decode_glonass_frame,
    decode_lnav_ephemeris,
    decode_lnav_iono_utc,
    glonass_string_number,
    glonass_string_ok,
    lnav_subframe_id,
)
from robustrtk.io.raw_collect import NavCollector, ObsCollector, count
from robustrtk.timeutil import WEEK_S, leap_seconds_at_gpst

__all__ = ["UbxDecoder", "UbxFramer", "count_ubx_frames", "decode_ubx", "read_ubx"]

SYNC = b"\xb5\x62"
_RAWX = (0x02, 0x15)
_SFRBX = (0x02, 0x13)
_NAV_SOL = (0x01, 0x06)
_NAV_TIMEGPS = (0x01, 0x20)
_MAX_PAYLOAD = 8192  # longer "frames" are false syncs (RAWX: 16 + 32*255 bytes at most)

_GNSS = {0: "G", 1: "S", 2: "E", 3: "C", 5: "J", 6: "R"}
_SIG_V1: dict[str, dict[int, str]] = {
    "G": {0: "1C", 3: "2X", 4: "2X", 6: "5X", 7: "5X"},
    "R": {0: "1C", 2: "2C"},
    "E": {0: "1X", 1: "1X", 3: "5X", 4: "5X", 5: "7X", 6: "7X"},
    "J": {0: "1C", 1: "1C", 4: "2X", 5: "2X", 8: "5X", 9: "5X"},
    "C": {0: "2I", 1: "2I", 2: "7I", 3: "7I", 7: "5X"},
    "S": {0: "1C"},
}
_SIG_V0 = {"G": "1C", "R": "1C", "E": "1X", "C": "2I", "J": "1C", "S": "1C"}
_MAX_PRN = {"G": 32, "R": 27, "E": 36, "C": 63, "J": 10, "S": 58}
_CPSTD_VALID_GEN8 = 5
_CPSTD_VALID_GEN9 = 14
_CPSTD_SLIP = 15
_RAWX_HEAD = struct.Struct("<dHbBBB2x")
_RAWX_MEAS = struct.Struct("<ddfBBBBHBBBBBx")


#: Largest GPS week taken from RXM-RAWX (year 2137); beyond it the field is corrupt.
_MAX_WEEK = 8191


class UbxFramer(ByteFramer[tuple[int, int, bytes]]):
    """Incremental UBX frame splitter: :meth:`feed` bytes, get ``(class, id, payload)``.

    Attributes
    ----------
    counts : dict str -> int
        ``frames``, ``bad_checksum``, ``skipped_bytes`` (outside any frame),
        ``truncated`` (an incomplete frame at :meth:`close`).
    """

    def feed(self, data: bytes) -> Iterator[tuple[int, int, bytes]]:
        """Frames completed by ``data`` (bytes may arrive in any pieces)."""
        self._buf += data
        buf = self._buf
        i = 0
        n = len(buf)
        while True:
            j = buf.find(SYNC, i)
            if j < 0:
                keep = 1 if n and buf[-1] == SYNC[0] else 0
                count(self.counts, "skipped_bytes", max(n - keep - i, 0))
                i = max(n - keep, i)
                break
            if j > i:
                count(self.counts, "skipped_bytes", j - i)
            if j + 6 > n:
                i = j
                break
            length = buf[j + 4] | (buf[j + 5] << 8)
            if length > _MAX_PAYLOAD:
                count(self.counts, "bad_length")
                count(self.counts, "skipped_bytes", 1)
                i = j + 1
                continue
            end = j + 8 + length
            if end > n:
                i = j
                break
            body = bytes(buf[j + 2 : j + 6 + length])
            if fletcher8(body) != (buf[end - 2], buf[end - 1]):
                count(self.counts, "bad_checksum")
                count(self.counts, "skipped_bytes", 1)
                i = j + 1
                continue
            count(self.counts, "frames")
            i = end
            yield body[0], body[1], body[4:]
        del buf[:i]

    def _may_start_frame(self) -> bool:
        return self._buf[:2] == SYNC


def count_ubx_frames(head: bytes) -> int:
    """Number of complete UBX frames with a valid checksum in ``head``."""
    f = UbxFramer()
    return sum(1 for _ in f.feed(head))


@dataclass
class _Track:
    lock_s: float = 0.0
    halfc: int = 0
    lockflag: int = 0


@dataclass
class UbxDecoder:
    """Decoder state of one UBX stream (observations, navigation words, counters).

    Feed bytes with :meth:`feed`; take the observations with :meth:`batch` and the
    ephemerides with :meth:`nav_data`.
    """

    obs: ObsCollector = field(default_factory=ObsCollector)
    nav: NavCollector = field(default_factory=NavCollector)
    framer: UbxFramer = field(default_factory=UbxFramer)
    messages: dict[str, int] = field(default_factory=dict)
    t_last_s: float | None = None
    n_epochs: int = 0
    _tracks: dict[tuple[str, str], _Track] = field(default_factory=dict)
    _gen9: bool = False
    _lnav: dict[str, dict[int, bytes]] = field(default_factory=dict)
    _inav: dict[str, dict[int, bytes]] = field(default_factory=dict)
    _glo: dict[str, dict[int, tuple[bytes, int]]] = field(default_factory=dict)

    @property
    def counts(self) -> dict[str, int]:
        """Framing counters and decoded/skipped messages by kind."""
        return {**self.framer.counts, **self.messages}

    def feed(self, data: bytes) -> int:
        """Decode the frames completed by ``data``; returns the number of new epochs."""
        before = self.n_epochs
        for cls, mid, payload in self.framer.feed(data):
            self._frame(cls, mid, payload)
        return self.n_epochs - before

    def _frame(self, cls: int, mid: int, payload: bytes) -> None:
        try:
            if (cls, mid) == _RAWX:
                self._rawx(payload)
            elif (cls, mid) == _SFRBX:
                self._sfrbx(payload)
            elif (cls, mid) in (_NAV_SOL, _NAV_TIMEGPS):
                self._nav_time(cls, mid, payload)
            else:
                count(self.messages, f"skipped UBX 0x{cls:02X} 0x{mid:02X}")
        except (IndexError, struct.error, ValueError, OverflowError):
            count(self.messages, f"bad UBX 0x{cls:02X} 0x{mid:02X}")

    def close(self) -> None:
        """End of input: decode the frames left behind an incomplete one."""
        for cls, mid, payload in self.framer.close():
            self._frame(cls, mid, payload)

    # ---------------------------------------------------------------- RXM-RAWX
    def _rawx(self, p: bytes) -> None:
        if len(p) < 16:
            count(self.messages, "bad RXM-RAWX")
            return
        tow, week, _leap, nmeas, _stat, ver = _RAWX_HEAD.unpack_from(p, 0)
        if len(p) < 16 + 32 * nmeas or not math.isfinite(tow) or not 0.0 <= tow < WEEK_S + 1.0:
            count(self.messages, "bad RXM-RAWX")
            return
        if week == 0:
            count(self.messages, "RXM-RAWX without week")
            return
        if week > _MAX_WEEK:  # a corrupt week (the epoch would not fit an int64 of ns)
            count(self.messages, "bad RXM-RAWX (week)")
            return
        t = week * WEEK_S + tow
        t_ns = week * 604_800_000_000_000 + round(tow * 1e9)
        self.t_last_s = t
        count(self.messages, "RXM-RAWX")
        n_cells = 0
        for m in range(nmeas):
            pr, cp, do, gnss, svid, sigid, frq, lockt, cn0, _prs, cps, _dos, trk = _RAWX_MEAS.unpack_from(
                p, 16 + 32 * m
            )
            cpstd = cps & 15
            if sigid > 1:
                self._gen9 = True
            sys_ = _GNSS.get(gnss)
            if sys_ is None:
                continue
            prn = svid - 100 if sys_ == "S" else svid
            if not 1 <= prn <= _MAX_PRN[sys_]:
                continue
            sig = _SIG_V1[sys_].get(sigid) if ver >= 1 else _SIG_V0[sys_]
            if sig is None:
                continue
            tx = f"{sys_}{prn:02d}"
            if sys_ == "R" and 0 <= frq <= 13:
                self.obs.glo_channels.setdefault(tx, frq - 7)
            code = pr if trk & 1 and math.isfinite(pr) else math.nan
            valid = _CPSTD_VALID_GEN9 if self._gen9 else _CPSTD_VALID_GEN8
            phase = cp if trk & 2 and cp != -0.5 and cpstd <= valid and math.isfinite(cp) else math.nan
            if sys_ == "C" and (prn <= 5 or prn >= 59) and phase == phase:
                phase += 0.5
            halfv = lockt > 8000 if sys_ == "S" else bool(trk & 4)
            halfc = 1 if trk & 8 else 0
            st = self._tracks.setdefault((tx, sig), _Track())
            slip = lockt == 0 or lockt * 1e-3 < st.lock_s or halfc != st.halfc or cpstd >= _CPSTD_SLIP
            if slip:
                st.lockflag = 1
            st.lock_s = lockt * 1e-3
            lli = 2 if not halfv and phase == phase else 0
            if halfc != st.halfc:
                lli |= 1
            st.halfc = halfc
            if phase == phase:
                if st.lockflag:
                    lli |= 1
                st.lockflag = 0
            self.obs.add(t_ns, tx, sig, code, phase, float(do), float(cn0), lli)
            n_cells += 1
        if n_cells:
            self.n_epochs += 1

    # -------------------------------------------------------- NAV-SOL, NAV-TIMEGPS
    def _nav_time(self, cls: int, mid: int, p: bytes) -> None:
        """Receiver time from a navigation solution (used to date navigation words when
        RXM-RAWX is sparse): iTOW (ms), fTOW (ns), week, valid when the week and time of
        week are set (NAV-SOL flags bits 2-3, NAV-TIMEGPS valid bits 0-1)."""
        if len(p) < 12:
            count(self.messages, "bad NAV time")
            return
        itow, ftow, week = struct.unpack_from("<IiH" if (cls, mid) == _NAV_SOL else "<Iih", p, 0)
        flags = p[11]
        ok = (flags & 0x0C) == 0x0C if (cls, mid) == _NAV_SOL else (flags & 0x03) == 0x03
        count(self.messages, "NAV-SOL" if (cls, mid) == _NAV_SOL else "NAV-TIMEGPS")
        if ok and week > 0:
            self.t_last_s = week * WEEK_S + itow * 1e-3 + ftow * 1e-9

    # --------------------------------------------------------------- RXM-SFRBX
    def _sfrbx(self, p: bytes) -> None:
        if len(p) < 8:
            count(self.messages, "bad RXM-SFRBX")
            return
        gnss, svid, _r, frq, nwords = p[0], p[1], p[2], p[3], p[4]
        if len(p) < 8 + 4 * nwords:
            count(self.messages, "bad RXM-SFRBX")
            return
        words = struct.unpack_from(f"<{nwords}I", p, 8)
        sys_ = _GNSS.get(gnss)
        if sys_ in ("G", "J") and nwords >= 10:
            self._lnav_subframe(f"{sys_}{svid:02d}", words)
        elif sys_ == "R" and nwords >= 4:
            self._glonass_string(svid, frq, words)
        elif sys_ == "E" and nwords >= 8:
            self._inav_page(svid, words)
        else:
            count(self.messages, f"skipped RXM-SFRBX {sys_ or gnss}")

    def _lnav_subframe(self, sat: str, words: tuple[int, ...]) -> None:
        sf = b"".join(((w >> 6) & 0xFFFFFF).to_bytes(3, "big") for w in words[:10])
        if sf[0] != 0x8B:  # TLM preamble (IS-GPS-200 20.3.3.1)
            count(self.messages, "skipped RXM-SFRBX LNAV (no preamble)")
            return
        sid = lnav_subframe_id(sf)
        if self.t_last_s is None or not 1 <= sid <= 5:
            count(self.messages, "skipped RXM-SFRBX LNAV (no time)" if sid else "bad RXM-SFRBX LNAV")
            return
        count(self.messages, "RXM-SFRBX LNAV")
        if sid == 4:
            iu = decode_lnav_iono_utc(sf)
            if iu is not None:
                self.nav.ion_gps = np.asarray(iu[0], dtype=float)
                self.nav.leap_s = iu[1]
            return
        if sid > 3:
            return
        subs = self._lnav.setdefault(sat, {})
        subs[sid] = sf
        if sid == 3 and len(subs) == 3:
            rec = decode_lnav_ephemeris(sat, subs[1], subs[2], subs[3], self.t_last_s)
            if rec is None:
                count(self.messages, "LNAV subframes with mixed issues of data")
            else:
                self.nav.add_kepler(sat[0], rec, "LNAV")

    def _inav_page(self, svid: int, words: tuple[int, ...]) -> None:
        page = b"".join(w.to_bytes(4, "big") for w in words[:8])
        got = inav_page_word(page)
        if got is None:
            count(self.messages, "skipped RXM-SFRBX I/NAV (alert, order or CRC)")
            return
        wtype, word = got
        count(self.messages, "RXM-SFRBX I/NAV")
        if not 1 <= wtype <= 5 or not 1 <= svid <= 36 or self.t_last_s is None:
            return
        sat = f"E{svid:02d}"
        store = self._inav.setdefault(sat, {})
        store[wtype] = word
        if wtype == 5:
            rec = decode_inav_ephemeris(sat, store, self.t_last_s)
            if rec is not None:
                self.nav.add_kepler("E", rec, "INAV")

    def _glonass_string(self, slot: int, frq: int, words: tuple[int, ...]) -> None:
        if not 1 <= slot <= 27 or not 0 <= frq <= 13 or self.t_last_s is None:
            count(self.messages, "skipped RXM-SFRBX GLONASS (unknown slot or no time)")
            return
        s = b"".join(w.to_bytes(4, "big") for w in words[:4])
        if not glonass_string_ok(s):
            count(self.messages, "bad RXM-SFRBX GLONASS (Hamming code)")
            return
        m = glonass_string_number(s)
        count(self.messages, "RXM-SFRBX GLONASS")
        if not 1 <= m <= 4:
            return
        sat = f"R{slot:02d}"
        fid = words[3] & 0xFFFFFFFF  # superframe and frame number the receiver appends
        frame = self._glo.setdefault(sat, {})
        if frame.get(0, (b"", fid))[1] != fid:
            frame.clear()
        frame[0] = (b"", fid)
        frame[m] = (s, fid)
        if m == 4 and all(k in frame for k in (1, 2, 3)):
            t0 = self.t_last_s
            leap = self.nav.leap_s if self.nav.leap_s is not None else float(leap_seconds_at_gpst(t0))
            strings = {k: frame[k][0] for k in (1, 2, 3, 4)}
            rec = decode_glonass_frame(sat, strings, frq - 7, t0, float(leap))
            if rec is not None:
                self.nav.add_glonass(rec)
            frame.clear()

    # ---------------------------------------------------------------- results
    def batch(self, meta: dict[str, Any] | None = None) -> ObsBatch:
        """Observations decoded so far."""
        m = {"format": "ubx", "receiver_type": "u-blox", "decode_counts": self.counts}
        m.update(meta or {})
        return self.obs.batch(meta=m)

    def nav_data(self, files: tuple[str, ...] = ()) -> NavData:
        """Ephemerides decoded so far."""
        return self.nav.nav_data(files)


def decode_ubx(data: bytes, chunk: int = 1 << 16) -> UbxDecoder:
    """Decode a whole UBX byte string (in chunks, as a stream would arrive)."""
    dec = UbxDecoder()
    for k in range(0, len(data), chunk):
        dec.feed(data[k : k + chunk])
    dec.close()
    return dec


def read_ubx(
    path: str | os.PathLike[str], data: bytes | None = None
) -> tuple[ObsBatch, NavData, dict[str, int]]:
    """Observations, ephemerides and decoding counters of a UBX log (plain or compressed
    content already expanded in ``data`` when given)."""
    from robustrtk.io.raw_file import read_binary_log

    p = os.fspath(path)
    raw, compression = read_binary_log(p) if data is None else (data, "none")
    dec = decode_ubx(raw)
    meta = {"file": os.path.basename(p), "path": p, "compression": compression}
    return dec.batch(meta), dec.nav_data((p,)), dec.counts

"""RTCM 3 streams: observations (MSM4-7, 1001-1004, 1009-1012), station and ephemerides.

Framing (RTCM 10403.3 section 4): preamble ``0xD3``, 6 reserved bits, 10-bit payload length,
payload, CRC-24Q over preamble, length and payload. Bytes outside frames, frames whose CRC
fails, frames cut short at the end of the input, message types not decoded here and messages
shorter than their fields are skipped and counted in :attr:`Rtcm3Decoder.counts`; nothing in
the input raises.

Time: RTCM 3 observation messages carry the time of week (GPS, Galileo, QZSS, SBAS; BeiDou
in BDT, +14 s) or the GLONASS time of day (UTC + 3 h), never the week. The decoder keeps the
time of the latest epoch (GPST, integer milliseconds) and places each new time of week within
half a week of it (half a day for GLONASS), so a stream crossing the end of a week or day
continues. A time field out of its range (a time of week of a week or more, a GLONASS time of
day of a day or more) skips its message and is counted (``bad time (...)``); a BeiDou time of
week written as GPST - 14 s without the week wrap (a 30-bit two's complement of -14..0 s, as
some encoders do in the first 14 s of a GPS week) is read as the end of the previous BDT week.
The first epoch needs a reference within half a week: :class:`Rtcm3Decoder` takes
it as ``t_ref_s``; :func:`read_rtcm3` finds one when none is given (see there).

Observations (:mod:`robustrtk.io.rtcm3_msm`, :mod:`robustrtk.io.rtcm3_legacy`): cells of the
same epoch time form one epoch, whatever their messages. Phase (cycles) is the phase range
divided by the wavelength; GLONASS wavelengths use the frequency channel from the MSM5/7
extended satellite information, else from 1020 ephemerides or 1010/1012 messages seen before
(no channel: no phase and no Doppler). LLI bit 0 (loss of lock) is set when the lock-time
indicator is 0 (lock acquired less than the indicator's first step ago), when it decreased,
or when the lock time it stands for (less than the next step's minimum) is shorter than the
previous epoch's minimum lock time plus the time since, by more than one step of the
indicator or 1 s (the lock restarted in between, e.g. during a gap of the signal: RTCM
10403.3 tables 3.4-2, 3.5-74, 3.5-75; the margin for encoders that update the indicator
late); a signal's first epoch with a non-zero
indicator has no flag. The indicators of each scale (MSM4/5 DF402, MSM6/7 DF407, legacy
DF013/DF019) are followed apart, so that a stream carrying a signal in two kinds of messages
does not compare one scale with the other. A change of the reference station ID (DF003)
restarts the lock tracking. A loss of lock in a cell without phase is reported on the
signal's next phase. LLI bit 1 is the half-cycle ambiguity indicator DF420 of a cell with phase. Legacy
L1/L2 phases are the pseudorange plus the phase-minus-code field, kept continuous across its
+-1500-cycle roll-overs. Legacy GPS messages carry SBAS satellites as DF009 40-58 (PRN
120-138).
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from robustrtk.core import InputError, ObsBatch
from robustrtk.geometry.navdata import NavData
from robustrtk.gnss import wavelength_m
from robustrtk.io.bits import crc24q, getbitu
from robustrtk.io.framing import ByteFramer
from robustrtk.io.raw_collect import NavCollector, ObsCollector, count
from robustrtk.io.rtcm3_eph import EPHEMERIS_MESSAGES, decode_ephemeris, field_offset
from robustrtk.io.rtcm3_legacy import decode_legacy_obs, decode_station, legacy_lock_time_s
from robustrtk.io.rtcm3_msm import MSM_SYSTEMS, MsmError, decode_msm, msm_lock_time_s, msm_sat_id
from robustrtk.timeutil import WEEK_S, gpst_from_calendar, leap_seconds_at_gpst

__all__ = ["Rtcm3Decoder", "Rtcm3Framer", "count_rtcm3_frames", "read_rtcm3", "reference_time_s"]

PREAMBLE = 0xD3
_WEEK_MS = 604_800_000
_GPS_EPOCH_UNIX_S = 315_964_800.0  # 1980-01-06 00:00:00 UTC in Unix seconds
_DAY_MS = 86_400_000


class Rtcm3Framer(ByteFramer[bytes]):
    """Incremental RTCM 3 frame splitter: :meth:`feed` bytes, get message payloads.

    Attributes
    ----------
    counts : dict str -> int
        ``frames``, ``bad_crc``, ``skipped_bytes``, ``truncated``.
    """

    def feed(self, data: bytes) -> Iterator[bytes]:
        """Payloads of the frames completed by ``data``."""
        self._buf += data
        buf = self._buf
        n = len(buf)
        i = 0
        while True:
            j = buf.find(PREAMBLE, i)
            if j < 0:
                count(self.counts, "skipped_bytes", n - i)
                i = n
                break
            if j > i:
                count(self.counts, "skipped_bytes", j - i)
            if j + 3 > n:
                i = j
                break
            if buf[j + 1] & 0xFC:  # reserved bits must be 0
                count(self.counts, "skipped_bytes", 1)
                i = j + 1
                continue
            length = ((buf[j + 1] & 0x03) << 8) | buf[j + 2]
            end = j + 3 + length + 3
            if end > n:
                i = j
                break
            frame = bytes(buf[j:end])
            if crc24q(frame[:-3]) != int.from_bytes(frame[-3:], "big"):
                count(self.counts, "bad_crc")
                count(self.counts, "skipped_bytes", 1)
                i = j + 1
                continue
            count(self.counts, "frames")
            i = end
            yield frame[3:-3]
        del buf[:i]


def count_rtcm3_frames(head: bytes) -> int:
    """Number of complete RTCM 3 frames with a valid CRC in ``head``."""
    return sum(1 for _ in Rtcm3Framer().feed(head))


@dataclass
class Rtcm3Decoder:
    """Decoder state of one RTCM 3 stream.

    Parameters
    ----------
    t_ref_s : float or None
        GPST (s) within half a week of the first epoch; without it observation messages
        are counted and skipped.
    keep_incomplete : bool
        Keep the cells of epochs whose last message (multiple-message bit DF393 / DF005 = 0)
        never arrived. By default such an epoch is dropped and counted (``incomplete epochs
        dropped``), as a real-time receiver that waits for the end of the epoch does.
    beidou_gpst : bool
        BeiDou MSM epoch times are GPST (as some encoders write them) instead of BDT
        (RTCM 10403.3 DF427). Default BDT; a stream whose BeiDou epochs fall 14 s before the
        other systems' is counted (``BeiDou epochs 14 s off``).
    """

    t_ref_s: float | None = None
    keep_incomplete: bool = False
    obs: ObsCollector = field(default_factory=ObsCollector)
    nav: NavCollector = field(default_factory=NavCollector)
    framer: Rtcm3Framer = field(default_factory=Rtcm3Framer)
    messages: dict[str, int] = field(default_factory=dict)
    station: dict[str, Any] = field(default_factory=dict)
    n_epochs: int = 0
    _t_ms: int | None = None
    _t_epoch_ms: int | None = None
    _stime_ms: int | None = None
    beidou_gpst: bool = False
    _station_id: int | None = None
    _other_ms: int | None = None
    _lock: dict[tuple[str, str], tuple[int, int, float]] = field(default_factory=dict)
    _complete: set[int] = field(default_factory=set)
    _slip: set[tuple[str, str]] = field(default_factory=set)
    _cp: dict[tuple[str, str], float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.t_ref_s is not None and math.isfinite(self.t_ref_s):
            self._t_ms = int(round(self.t_ref_s * 1000.0))

    @property
    def counts(self) -> dict[str, int]:
        """Framing counters and decoded/skipped messages by kind."""
        return {**self.framer.counts, **self.messages}

    def feed(self, data: bytes) -> int:
        """Decode the frames completed by ``data``; returns the number of new epochs."""
        before = self.n_epochs
        for msg in self.framer.feed(data):
            self._payload(msg)
        return self.n_epochs - before

    def close(self) -> None:
        """End of input: decode the frames left behind an incomplete one."""
        for msg in self.framer.close():
            self._payload(msg)

    def _payload(self, msg: bytes) -> None:
        if len(msg) < 2:
            count(self.messages, "bad message (empty)")
            return
        number = getbitu(msg, 0, 12)
        try:
            self._message(number, msg)
        except (IndexError, ValueError, KeyError, OverflowError) as exc:
            kind = "short" if isinstance(exc, IndexError) else "bad"
            count(self.messages, f"{kind} {number}")

    # ------------------------------------------------------------------ dispatch
    def _message(self, number: int, msg: bytes) -> None:
        base = number - number % 10
        if base in MSM_SYSTEMS and number % 10 in (4, 5, 6, 7):
            self._msm(msg)
        elif 1001 <= number <= 1004 or 1009 <= number <= 1012:
            self._legacy(number, msg)
        elif number in (1005, 1006, 1033):
            self.station.update(decode_station(msg))
            count(self.messages, str(number))
        elif number in EPHEMERIS_MESSAGES:
            self._ephemeris(number, msg)
        else:
            count(self.messages, f"skipped {number}")

    # ---------------------------------------------------------------------- time
    def _leap_s(self) -> float:
        if self.nav.leap_s is not None:
            return float(self.nav.leap_s)
        t = self._t_ms / 1000.0 if self._t_ms is not None else 0.0
        return float(leap_seconds_at_gpst(t))

    def _time_from_tow(self, tow_ms: int) -> int:
        assert self._t_ms is not None
        week0 = (self._t_ms // _WEEK_MS) * _WEEK_MS
        t = week0 + tow_ms
        if t < self._t_ms - _WEEK_MS // 2:
            t += _WEEK_MS
        elif t > self._t_ms + _WEEK_MS // 2:
            t -= _WEEK_MS
        return t

    def _time_from_glo_tod(self, tod_ms: int) -> int:
        assert self._t_ms is not None
        shift = 10_800_000 - int(round(self._leap_s() * 1000))  # GPST -> GLONASS time
        tg = self._t_ms + shift
        day0 = (tg // _DAY_MS) * _DAY_MS
        t = day0 + tod_ms
        if t < tg - _DAY_MS // 2:
            t += _DAY_MS
        elif t > tg + _DAY_MS // 2:
            t -= _DAY_MS
        return t - shift

    def _epoch(self, system: str, field_value: int, station: int | None = None) -> int | None:
        """Epoch (GPST ms) of an observation message's time field; None without a reference
        or when the field is out of its range (the message is then counted and skipped)."""
        if self._t_ms is None:
            count(self.messages, "observations before a time reference")
            return None
        if system == "R":
            tod = field_value & 0x7FFFFFF  # DF034 / DF416+DF034: the day of week is ignored
            if tod >= _DAY_MS:
                count(self.messages, "bad time (GLONASS time of day >= 1 day)")
                return None
            t = self._time_from_glo_tod(tod)
        else:
            tow = field_value
            if system == "C":
                if tow >= _WEEK_MS:
                    # a BDT written as GPST - 14 s without the week wrap: -14 s .. 0 as a
                    # 30-bit two's complement (seen from encoders in the first 14 s of a week)
                    tow -= 1 << 30
                    if not -14_000 <= tow < 0:
                        count(self.messages, "bad time (BeiDou time of week >= 1 week)")
                        return None
                    tow += _WEEK_MS
                tow = (tow + (0 if self.beidou_gpst else 14_000)) % _WEEK_MS
            elif tow >= _WEEK_MS:
                count(self.messages, "bad time (time of week >= 1 week)")
                return None
            t = self._time_from_tow(tow)
        if system != "C":
            self._other_ms = t
        elif self._other_ms is not None and abs(t - self._other_ms) == 14_000:
            count(self.messages, "BeiDou epochs 14 s off")
        if station is not None:
            if self._station_id is not None and station != self._station_id:
                # another reference station: its lock times and phase counters start anew
                count(self.messages, "station changes")
                self._lock.clear()
                self._cp.clear()
                self._slip.clear()
            self._station_id = station
        self._t_ms = t
        if self._stime_ms is None:
            self._stime_ms = t
        if t != self._t_epoch_ms:
            self._t_epoch_ms = t
            self.n_epochs += 1
        return t

    # ---------------------------------------------------------------- lock / LLI
    def _loss_of_lock(
        self, key: tuple[str, str], t_ms: int, lti: int, lock_min_s: float, lock_max_s: float
    ) -> int:
        """LLI bit 0 of a cell from its lock-time indicator ``lti``, which says the lock has
        lasted at least ``lock_min_s`` and less than ``lock_max_s``."""
        st = self._lock.get(key)
        self._lock[key] = (lti, t_ms, lock_min_s)
        if lti == 0:  # lock (re)started less than the indicator's first step ago
            return 1
        if st is None:  # first epoch of the signal: nothing to be continuous with
            return 0
        plti, tobs, pmin_s = st
        # a continuous lock has lasted at least the previous minimum plus the time since;
        # encoders update the indicator late, so the lock restarted in between only when it
        # falls short of that by more than one step of the indicator or 1 s
        tol_s = max(1.0, lock_max_s - lock_min_s) if math.isfinite(lock_max_s) else 0.0
        return 1 if lti < plti or lock_max_s + tol_s < pmin_s + (t_ms - tobs) / 1000.0 else 0

    def _carry_slip(self, key: tuple[str, str], lli: int, has_phase: bool) -> int:
        """A loss of lock seen in a cell without phase is reported on the signal's next
        phase (the RINEX LLI belongs to the phase)."""
        if not has_phase:
            if lli & 1:
                self._slip.add(key)
            return lli
        if key in self._slip:
            self._slip.discard(key)
            return lli | 1
        return lli

    # ---------------------------------------------------------------------- MSM
    def _msm(self, msg: bytes) -> None:
        try:
            m = decode_msm(msg)
        except MsmError:
            count(self.messages, f"bad {getbitu(msg, 0, 12)}")
            return
        t = self._epoch(m.system, m.epoch_field, m.station)
        if t is None:
            return
        count(self.messages, str(m.number))
        if not m.multiple:
            self._complete.add(t)
        for c in m.cells:
            tx = msm_sat_id(m.system, c.sat)
            if tx is None or not c.signal:
                count(self.messages, f"cells skipped in {m.number}")
                continue
            ch: int | None = None
            if m.system == "R":
                if c.ext_info <= 13 and m.msm in (5, 7):
                    ch = c.ext_info - 7
                    self.obs.glo_channels.setdefault(tx, ch)
                else:
                    ch = self.obs.glo_channels.get(tx)
            wl = wavelength_m(m.system, c.signal, ch)
            phase = c.phaserange_m / wl if math.isfinite(wl) else math.nan
            dop = -c.rate_m_s / wl if math.isfinite(wl) else math.nan
            has_phase = math.isfinite(phase)
            hi = m.msm in (6, 7)
            lo_s = msm_lock_time_s(c.lock_indicator, hi)
            up_s = (
                math.inf
                if c.lock_indicator >= (704 if hi else 15)
                else msm_lock_time_s(c.lock_indicator + 1, hi)
            )
            # indicators of different scales (DF402, DF407, DF013) are tracked apart
            lli = self._loss_of_lock((tx, f"{c.signal} msm{6 if hi else 4}"), t, c.lock_indicator, lo_s, up_s)
            lli = self._carry_slip((tx, c.signal), lli, has_phase)
            if has_phase and c.half_cycle:
                lli |= 2
            cn0 = c.cn0_dbhz if c.cn0_dbhz > 0 else math.nan
            self.obs.add(t * 1_000_000, tx, c.signal, c.pseudorange_m, phase, dop, cn0, lli)

    # ------------------------------------------------------------------- legacy
    def _legacy(self, number: int, msg: bytes) -> None:
        o = decode_legacy_obs(msg)
        system = "R" if number >= 1009 else "G"
        t = self._epoch(system, o.epoch_ms, o.station)
        if t is None:
            return
        count(self.messages, str(number))
        if not o.sync:
            self._complete.add(t)
        for c in o.cells:
            if system == "G":
                if 1 <= c.prn <= 32:
                    tx = f"G{c.prn:02d}"
                elif 40 <= c.prn <= 58:  # DF009: 40-58 are SBAS PRN 120-138
                    tx = f"S{c.prn - 20:02d}"
                else:
                    count(self.messages, f"cells skipped in {number}")
                    continue
            else:
                if not 1 <= c.prn <= 24:
                    continue
                tx = f"R{c.prn:02d}"
                if c.channel is not None and -7 <= c.channel <= 6:
                    self.obs.glo_channels.setdefault(tx, c.channel)
            ch = self.obs.glo_channels.get(tx) if system == "R" else None
            wl = wavelength_m(system, c.signal, ch)
            phase = math.nan
            if math.isfinite(c.phase_minus_code_m) and math.isfinite(wl) and math.isfinite(c.pseudorange_m):
                cp = c.phase_minus_code_m / wl
                key = (tx, c.signal)
                prev = self._cp.get(key)
                if prev is not None:
                    if cp < prev - 750.0:
                        cp += 1500.0
                    elif cp > prev + 750.0:
                        cp -= 1500.0
                self._cp[key] = cp
                phase = self._l1_code(o.cells, c) / wl + cp
            lo_s = legacy_lock_time_s(c.lock_indicator)
            # 126 is the last finite step (its successor 127 = 937 s or more): some encoders
            # stay at 126 for a lock that goes on
            up_s = math.inf if c.lock_indicator >= 126 else legacy_lock_time_s(c.lock_indicator + 1)
            lli = self._loss_of_lock((tx, f"{c.signal} legacy"), t, c.lock_indicator, lo_s, up_s)
            lli = self._carry_slip((tx, c.signal), lli, math.isfinite(phase))
            cn0 = c.cn0_dbhz if c.cn0_dbhz > 0 else math.nan
            self.obs.add(t * 1_000_000, tx, c.signal, c.pseudorange_m, phase, math.nan, cn0, lli)

    @staticmethod
    def _l1_code(cells: tuple[Any, ...], c: Any) -> float:
        """The L1 pseudorange the phase of ``c`` is referred to (DF012/DF018, DF042/DF048)."""
        for x in cells:
            if x.prn == c.prn and x.signal[0] == "1":
                return float(x.pseudorange_m)
        return math.nan

    # --------------------------------------------------------------- ephemeris
    def _ephemeris(self, number: int, msg: bytes) -> None:
        if self._t_ms is None:
            count(self.messages, f"skipped {number} (no time reference)")
            return
        out = decode_ephemeris(msg, self._t_ms / 1000.0, self._leap_s())
        if out is None:
            count(self.messages, f"skipped {number}")
            return
        system, rec, kind = out
        count(self.messages, str(number))
        if system == "R":
            self.obs.glo_channels.setdefault(rec["sat_id"], int(rec["freq_channel"]))
            self.nav.add_glonass(rec)
        else:
            self.nav.add_kepler(system, rec, kind)

    # ---------------------------------------------------------------- results
    def complete_epochs_ns(self) -> set[int]:
        """Tags (GPST ns) of the epochs whose last message has arrived (streams emit them)."""
        return {t * 1_000_000 for t in self._complete}

    def batch(self, meta: dict[str, Any] | None = None) -> ObsBatch:
        """Observations decoded so far (``approx_pos_m``: the 1005/1006 ARP)."""
        arp = self.station.get("arp_ecef_m")
        m: dict[str, Any] = {"format": "rtcm3", "decode_counts": self.counts, "station": dict(self.station)}
        for k in ("receiver", "antenna"):
            if self.station.get(k):
                m[f"{k}_type"] = self.station[k]
        m.update(meta or {})
        name = f"{self.station['station']:04d}" if "station" in self.station else ""
        if not self.keep_incomplete:
            n = self.obs.keep_epochs({t * 1_000_000 for t in self._complete})
            m["decode_counts"]["incomplete epochs dropped"] = n
        return self.obs.batch(
            receiver=name, approx_pos_m=None if arp is None else np.asarray(arp, float), meta=m
        )

    def nav_data(self, files: tuple[str, ...] = ()) -> NavData:
        """Ephemerides decoded so far."""
        return self.nav.nav_data(files)


_REF_SCAN_BYTES = 2 << 20  # ephemerides come every minute or so: 2 MiB is minutes of MSM7
_DATE_IN_NAME = re.compile(r"(?<!\d)(19[89]\d|20\d\d)[-_]?(0[1-9]|1[0-2])[-_]?(0[1-9]|[12]\d|3[01])(?!\d)")


def reference_time_s(path: str, data: bytes) -> float | None:
    """An approximate GPST (s) for an RTCM 3 file without one given.

    In this order: the full week of the first Galileo (1045/1046) or BeiDou (1042) ephemeris
    in the first 2 MiB of the stream; a date ``YYYYMMDD`` / ``YYYY-MM-DD`` in the file name
    (noon of that day); the week of a GPS or QZSS ephemeris (1019/1044, broadcast modulo 1024)
    taken as the latest such week not after the computer's clock. None when none is found.
    """
    gps_week: int | None = None
    gps_toe = 0.0
    f = Rtcm3Framer()
    for k in range(0, min(len(data), _REF_SCAN_BYTES), 1 << 16):
        for msg in f.feed(data[k : k + (1 << 16)]):
            try:
                n = getbitu(msg, 0, 12)
                if n in (1045, 1046, 1042):
                    # the time of ephemeris: GST weeks count from GPS week 1024 (rolling
                    # over after 4096 weeks, in 2078), BDT weeks from GPS week 1356
                    week = getbitu(msg, *field_offset(n, "week"))
                    pos, bits = field_offset(n, "toe_sow_s")
                    if n == 1042:
                        return (week + 1356) * WEEK_S + getbitu(msg, pos, bits) * 8.0 + 14.0
                    return (week + 1024) * WEEK_S + getbitu(msg, pos, bits) * 60.0
                if gps_week is None and n in (1019, 1044):
                    gps_week = getbitu(msg, *field_offset(n, "week"))
                    gps_toe = getbitu(msg, *field_offset(n, "toe_sow_s")) * 16.0
            except IndexError:
                continue
    m = _DATE_IN_NAME.search(os.path.basename(path))
    if m:
        y, mo, d = (int(g) for g in m.groups())
        try:
            return gpst_from_calendar(y, mo, d, 12)
        except ValueError:
            return None
    if gps_week is not None:
        import time

        now_week = int((time.time() - _GPS_EPOCH_UNIX_S) // WEEK_S)
        week = gps_week + 1024 * ((now_week - gps_week) // 1024)
        return week * WEEK_S + gps_toe
    return None


def _anchor_time(raw: bytes, t_ref_s: float, beidou_gpst: bool) -> float:
    """``t_ref_s`` moved to the epoch of the stream's first time-of-week observation message
    (GPS, Galileo, QZSS, SBAS, BeiDou), placed within half a week of it: the GLONASS time of
    day of the messages before it then falls on the right day even when ``t_ref_s`` is more
    than half a day off. ``t_ref_s`` itself when the stream has no such message."""
    probe = Rtcm3Decoder(t_ref_s=t_ref_s, beidou_gpst=beidou_gpst)
    f = Rtcm3Framer()
    for k in range(0, min(len(raw), _REF_SCAN_BYTES), 1 << 16):
        for msg in f.feed(raw[k : k + (1 << 16)]):
            try:
                n = getbitu(msg, 0, 12)
                if 1001 <= n <= 1004 or (
                    n - n % 10 in MSM_SYSTEMS and n - n % 10 != 1080 and n % 10 in (4, 5, 6, 7)
                ):
                    system = "G" if n < 1070 else MSM_SYSTEMS[n - n % 10]
                    t = probe._epoch(system, getbitu(msg, 24, 30))
                    if t is not None:
                        return t / 1000.0
            except IndexError:
                continue
    return t_ref_s


def read_rtcm3(
    path: str | os.PathLike[str],
    t_ref_s: float | None = None,
    data: bytes | None = None,
    beidou_gpst: bool = False,
) -> tuple[ObsBatch, NavData, dict[str, int]]:
    """Observations, ephemerides and decoding counters of an RTCM 3 file.

    Parameters
    ----------
    path : path-like
        Plain or compressed (gzip, bzip2...) RTCM 3 file.
    t_ref_s : float, optional
        GPST (s) within half a week of the first epoch; default from
        :func:`reference_time_s`.
    data : bytes, optional
        The decompressed content, when already read.
    beidou_gpst : bool
        BeiDou MSM epoch times are GPST, not BDT (see :class:`Rtcm3Decoder`).

    Raises
    ------
    InputError
        Unreadable file, or no time reference (none given, none found).
    """
    from robustrtk.io.raw_file import read_binary_log

    p = os.fspath(path)
    raw, compression = read_binary_log(p) if data is None else (data, "none")
    if t_ref_s is None:
        t_ref_s = reference_time_s(p, raw)
        if t_ref_s is None:
            raise InputError(
                "RTCM 3 carries no week number and this stream has no ephemeris that gives it; "
                "expected the approximate time (convert --time-ref 'YYYY/MM/DD HH:MM:SS') or "
                "a date YYYYMMDD in the file name",
                path=p,
            )
    t_ref_s = _anchor_time(raw, t_ref_s, beidou_gpst)
    dec = Rtcm3Decoder(t_ref_s=t_ref_s, beidou_gpst=beidou_gpst)
    for k in range(0, len(raw), 1 << 16):
        dec.feed(raw[k : k + (1 << 16)])
    dec.close()
    meta = {"file": os.path.basename(p), "path": p, "compression": compression, "t_ref_s": t_ref_s}
    return dec.batch(meta), dec.nav_data((p,)), dec.counts

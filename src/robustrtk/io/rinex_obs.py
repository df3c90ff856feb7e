"""RINEX observation files (2.10/2.11 and 3.02-3.05) into one :class:`~robustrtk.core.ObsBatch`.

Input may be plain text, gzip/bzip2/Unix-compress/zip, Hatanaka (Compact RINEX, ``.crx``,
``.??d``) or both (``.crx.gz``); the kind is detected from the file's first bytes, not its
name, and compressed files are expanded by :mod:`robustrtk.io.rinex_file` under a size cap.

Parsing is vectorised: the header and the epoch lines are read line by line (a few thousand
at most, :mod:`robustrtk.io.rinex_layout`), the observation records of all epochs are
gathered into one fixed-width byte array per system and every ``F14.3 I1 I1`` field is
converted column-wise (:mod:`robustrtk.io.rinex_decode`), so the cost per observation is a
handful of numpy operations. Files are opened by :mod:`robustrtk.io.rinex_file`.

Output conventions
------------------
* ``t_s``: GPS time (s since 1980-01-06T00:00:00 GPST) of the receiver time tag, **not
  rounded** (a tag 3 ms after the second stays 3 ms after it). The file's time system is
  read from ``TIME OF FIRST OBS`` (when it names none, the RINEX default of the file's
  system: GPS, GLO (UTC) for GLONASS-only, GAL, QZS, BDT, IRN files):
  GPS/GAL/QZS/IRN tags are used as they are, BDT tags get +14 s, GLO (RINEX's UTC) tags get
  the leap seconds (header ``LEAP SECONDS`` or the table). The offset applied is
  ``meta["time_offset_s"]``; the exact tags as int64 ns are in ``meta["t_ns"]``.
* ``tx_ids``: ``"G05"``, ``"R12"``, ... sorted by system (``G R E C J S I``) then number; a
  blank RINEX 2 system letter means GPS.
* ``signals``: RINEX 3 band + attribute (``"1C"``, ``"2W"``, ``"5Q"``), the sorted union over
  the systems kept. RINEX 3 observation code ``C1C`` fills ``code_m``, ``L1C`` ``phase_cyc``,
  ``D1C`` ``doppler_hz`` and ``S1C`` ``cn0_dbhz`` of signal ``"1C"``; other types (``X``
  channel numbers, ``I`` ionosphere) are ignored. In RINEX 3.00-3.02 BeiDou B1I is written
  with band 1 (``C1I``); it is renamed to the 3.03+ name ``"2I"`` so the carrier is right.
* ``lli``: the loss-of-lock digit of the **phase** observation of each cell (bit 0 loss of
  lock / possible slip, bit 1 half-cycle ambiguity, bit 2 anti-spoofing in RINEX 2 or BOC
  tracking in RINEX 3 -- slip detectors should test bit 0 only);
  0 where the phase is absent. The signal-strength digits of the phases are in
  ``meta["ssi"]`` (int8, 0 = blank).
* ``wavelength_m``: :func:`robustrtk.gnss.wavelength_m` per (transmitter, signal) for the
  signals the transmitter's system declares (NaN for the others); GLONASS FDMA bands use the
  channel from ``GLONASS SLOT / FRQ #`` (NaN without it, e.g. in RINEX 2).
* ``approx_pos_m``: ``APPROX POSITION XYZ`` (ECEF m), ``None`` when absent or all zero.
* Epoch flags: 0 and 1 are kept (``meta["power_failure_epochs"]`` lists the epoch indices
  with flag 1); 2-5 (events with header or comment records) are skipped and listed in
  ``meta["events"]``; 6 (cycle-slip records) is skipped and counted in
  ``meta["n_slip_records_skipped"]``.
* ``SYS / SCALE FACTOR`` (RINEX 3) divides the values of the named types.
* ``meta["read_notes"]``: one sentence per oddity tolerated (never silently): a default time
  system assumed, ``APPROX POSITION XYZ`` outside its columns, seconds with a stray blank,
  ``>`` lines without date or records skipped, satellites of a system the header's file type
  does not declare (read as in a mixed file).

RINEX 2 observation codes
-------------------------
=========  ======================  ===========================================================
system     code -> signal          notes
=========  ======================  ===========================================================
GPS, QZSS  C1 -> 1C, P1 -> 1W      ``L1 D1 S1`` -> ``1C``; both C1 and P1 are kept
           C2 -> 2L, P2 -> 2W      ``L2 D2 S2`` -> ``2W``
           C5 L5 D5 S5 -> 5X
GLONASS    C1 -> 1C, P1 -> 1P      ``L1 D1 S1`` -> ``1C``
           C2 -> 2C, P2 -> 2P      ``L2 D2 S2`` -> ``2P``
Galileo    C1 L1 D1 S1 -> 1X       band 5 -> ``5X``, 7 -> ``7X``, 8 -> ``8X``, 6 -> ``6X``
SBAS       C1 L1 D1 S1 -> 1C       band 5 -> ``5X``
=========  ======================  ===========================================================

Codes without an entry (e.g. ``T1``, BeiDou in RINEX 2.12 drafts) are ignored and listed in
``meta["ignored_obs_types"]``.

Malformed input raises :class:`~robustrtk.core.InputError` naming the file, the line and the
reason: bad ``RINEX VERSION / TYPE`` line, missing ``END OF HEADER``, bad epoch line,
satellite count that does not match the records, non-numeric field, time going backwards.
A mid-file change of observation types (event flag 4 with a new obs-type record) is reported
as unsupported.
"""

from __future__ import annotations

from collections.abc import Callable
from os import PathLike
from pathlib import Path

import numpy as np
import numpy.typing as npt

from robustrtk.core import InputError, ObsBatch
from robustrtk.gnss import wavelength_m
from robustrtk.io.obs_checks import mask_impossible
from robustrtk.io.rinex_decode import (
    check_digit_field,
    digit_field,
    f14_to_float,
    fix_odd_fields,
    gather_lines,
)
from robustrtk.io.rinex_file import read_rinex_bytes
from robustrtk.io.rinex_layout import (
    LLI_OFFSET,
    OBS_FIELD_WIDTH,
    OBS_VALUE_WIDTH,
    RINEX2_SIGNAL_MAP,
    SSI_OFFSET,
    SYSTEM_ORDER,
    V2_LINE_WIDTH,
    V2_OBS_PER_LINE,
    V3_SAT_ID_WIDTH,
    RinexObsHeader,
    U8Array,
    rinex3_signal,
    v2_lines_per_record,
)
from robustrtk.io.rinex_text import (
    RinexObsText,
    scan_obs_text,
)
from robustrtk.timeutil import BDT_GPST_OFFSET_S, leap_seconds_at_utc

__all__ = ["read_rinex_obs", "read_rinex_bytes", "RINEX2_SIGNAL_MAP", "SYSTEM_ORDER"]

# Observation type letter -> index into (code_m, phase_cyc, doppler_hz, cn0_dbhz).
_TYPE2FIELD = {"C": 0, "L": 1, "D": 2, "S": 3}
_PHASE = 1


# --------------------------------------------------------------------------------------------
# main reader


#: Two-letter time systems some writers put in ``TIME OF FIRST OBS`` (RTKLIB reads them as GPS
#: time when unknown; the letters name the system here).
_TWO_LETTER_TIME_SYSTEMS = {
    "GP": "GPS",
    "GL": "GLO",
    "GA": "GAL",
    "BD": "BDT",
    "QZ": "QZS",
    "IR": "IRN",
    "UT": "UTC",
}


#: The time system of a single-system file whose ``TIME OF FIRST OBS`` names none (RINEX
#: 2.11 and 3.0x: GPS for GPS files, GLO (UTC) for GLONASS, GAL, QZS, BDT, IRN for the others).
_DEFAULT_TIME_SYSTEM = {"R": "GLO", "E": "GAL", "J": "QZS", "C": "BDT", "I": "IRN"}


def _time_offset(h: RinexObsHeader, t0_s: float | None, path: str, notes: list[str]) -> tuple[str, float]:
    """(time system, seconds to add to the tags to get GPST); a default other than GPS is
    noted in ``notes``."""
    ts = h.time_system.upper()
    if h.first_obs != "date":
        what = "no TIME OF FIRST OBS record" if not h.first_obs else "TIME OF FIRST OBS all zeros or blank"
        notes.append(f"{what}: the first epoch gives the start")
    if not ts:
        ts = _DEFAULT_TIME_SYSTEM.get(h.file_system.upper(), "GPS")
        fs = h.file_system.upper()
        if ts != "GPS" or h.first_obs != "date":
            why = (
                f"the RINEX default for a file of system {fs!r}"
                if fs in _DEFAULT_TIME_SYSTEM or fs == "G"
                else "which a mixed file must name"
            )
            notes.append(f"TIME OF FIRST OBS names no time system: {ts} assumed, {why}")
    ts = _TWO_LETTER_TIME_SYSTEMS.get(ts, ts)
    if ts in ("GPS", "GAL", "QZS", "IRN"):
        return ts, 0.0
    if ts == "BDT":
        return ts, BDT_GPST_OFFSET_S
    if ts in ("GLO", "UTC"):
        if h.leap_s is not None:
            return ts, float(h.leap_s)
        return ts, float(leap_seconds_at_utc(t0_s)) if t0_s is not None else 0.0
    raise InputError(f"TIME OF FIRST OBS: unknown time system {ts!r}", path)


def _epoch_text(txt: RinexObsText, k: int) -> bytes:
    """The bytes of epoch ``k`` (its epoch line(s) and records), line ends excluded."""
    ep = txt.epochs
    per_sat = 1 if txt.v3 else v2_lines_per_record(len(txt.header.obs_types2))
    first, last = ep.line[k], ep.first_rec[k] + ep.nsat[k] * per_sat
    if last <= first:
        return b""
    return b"\n".join(txt.bufp[txt.starts[i] : txt.ends[i]].tobytes() for i in range(first, last))


def _drop_exact_duplicates(t_s: np.ndarray, txt: RinexObsText, path: str) -> np.ndarray:
    """Epochs to keep: an epoch written again byte for byte after itself (some loggers write
    the last epoch twice) is dropped; any other epoch whose time does not increase is
    refused, naming its line."""
    keep = np.ones(t_s.shape, bool)
    if t_s.size < 2:
        return keep
    d = np.diff(t_s)
    for k in (np.flatnonzero(d <= 0) + 1).tolist():
        if d[k - 1] == 0 and _epoch_text(txt, k) == _epoch_text(txt, k - 1):
            keep[k] = False
            continue
        raise InputError(
            "epoch time does not increase (earlier than the previous epoch, or the same time "
            "with different content)",
            path,
            txt.epochs.line[k] + 1,
        )
    return keep


def _sys_and_prn(
    bufp: U8Array,
    st: npt.NDArray[np.int64],
    sys_default: str,
    lines: npt.NDArray[np.int64],
    path: str,
) -> tuple[U8Array, npt.NDArray[np.int64]]:
    """System letter codes and PRN numbers of 3-character satellite ids at ``st``."""
    if st.size and int(st.max()) + 2 >= bufp.size:
        r = int(np.argmax(st))
        raise InputError("satellite record beyond the end of the file", path, int(lines[r]) + 1)
    sy = bufp[st].copy()
    sy[sy == 32] = ord(sys_default)
    d1 = bufp[st + 1]
    d2 = bufp[st + 2]
    ok1 = ((d1 >= 48) & (d1 <= 57)) | (d1 == 32)
    ok2 = (d2 >= 48) & (d2 <= 57)
    known = np.isin(sy, np.frombuffer(SYSTEM_ORDER.encode(), np.uint8))
    bad = ~(ok1 & ok2 & known)
    if bad.any():
        r = int(np.argmax(bad))
        sid = bufp[st[r] : st[r] + 3].tobytes().decode("ascii", "replace")
        raise InputError(
            f"bad satellite id {sid!r}: expected a system letter from {SYSTEM_ORDER} and a 2-digit number",
            path,
            int(lines[r]) + 1,
        )
    prn = np.where(d1 == 32, 0, d1.astype(np.int64) - 48) * 10 + (d2.astype(np.int64) - 48)
    return sy, prn


def _v2_types_carried(
    h: RinexObsHeader,
    bufp: U8Array,
    starts: npt.NDArray[np.int64],
    lens: npt.NDArray[np.int64],
    rec_line: npt.NDArray[np.int64],
    per_sat: int,
    notes: list[str],
) -> list[str]:
    """The RINEX 2 observation types the records carry when ``# / TYPES OF OBSERV`` lists
    more types than it declares (records of as many lines either way): all listed ones when
    some record holds a value in a field past the declared count, else the declared ones;
    either way a note."""
    codes, listed = h.obs_types2, h.obs_types2_listed
    if len(listed) <= len(codes):
        return codes
    n, m = len(codes), len(listed)
    head = f"# / TYPES OF OBSERV declares {n} observation types but lists {m}"
    used = False
    if rec_line.size:
        ln = rec_line[:, None] + np.arange(per_sat)[None, :]
        block = gather_lines(bufp, starts[ln.ravel()], lens[ln.ravel()], V2_LINE_WIDTH)
        fields = block.reshape(rec_line.size, per_sat * V2_OBS_PER_LINE, OBS_FIELD_WIDTH)
        used = bool(np.any(fields[:, n:m, :OBS_VALUE_WIDTH] != 32))
    if used:
        notes.append(f"{head}; the records carry values for all {m}: the listed types read")
        return list(listed)
    notes.append(f"{head}; the records carry {n}: the first {n} read")
    return codes


def _systems_present(sy: np.ndarray) -> set[str]:
    """The system letters among the bytes ``sy`` (uint8), as ``set(np.unique(sy)...)`` gives
    them, counted instead of sorted (``np.unique`` also loads ``numpy.ma`` on first use)."""
    return set(np.flatnonzero(np.bincount(sy, minlength=256)).astype(np.uint8).tobytes().decode())


def read_rinex_obs(
    path: str | PathLike[str],
    *,
    systems: str | None = None,
    t_start_s: float | None = None,
    t_end_s: float | None = None,
    epoch_mask: Callable[[np.ndarray], np.ndarray] | None = None,
    data: bytes | None = None,
) -> ObsBatch:
    """Read a RINEX 2.10/2.11 or 3.0x observation file.

    Parameters
    ----------
    path : str or path-like
        Plain, gzip or Hatanaka-compressed RINEX observation file (detected from content).
    systems : str, optional
        System letters to keep, e.g. ``"GE"``; all when ``None``.
    t_start_s, t_end_s : float, optional
        Keep epochs with ``t_start_s <= t_s <= t_end_s`` (GPS seconds, see module docstring).
    epoch_mask : callable, optional
        ``epoch_mask(t_s)`` → bool array, shape (T,), over the time tags of every epoch of
        the file (GPS seconds, increasing): also keep only the epochs it marks (a time
        window with an interval, say). It may raise :class:`InputError`. Only the kept
        epochs are decoded.
    data : bytes, optional
        Plain RINEX text to decode instead of the file's (a header and some of its epochs:
        :mod:`robustrtk.io.rinex_chunks`); ``path`` then only names it in messages.

    Returns
    -------
    ObsBatch
        ``(T, N, K)`` arrays: T epochs (flags 0 and 1), N transmitters (union over the
        file), K signals (union over the kept systems' observation types).

    Raises
    ------
    InputError
        Unreadable or malformed file (message names file, line and reason).
    """
    p = str(path)
    if systems is not None:
        unknown = sorted(set(systems) - set(SYSTEM_ORDER))
        if unknown:
            raise InputError(
                f"systems: unknown system letter(s) {''.join(unknown)!r}; expected letters "
                f"from {SYSTEM_ORDER}"
            )
    data, compression = read_rinex_bytes(p) if data is None else (data, "none")
    txt = scan_obs_text(data, p)
    h, ep, v3 = txt.header, txt.epochs, txt.v3
    bufp, starts, ends = txt.bufp, txt.starts, txt.ends
    lens = ends - starts

    t_all = np.asarray(ep.t_s, dtype=float)
    t0 = float(t_all[0]) if t_all.size else None
    if t0 is not None and not np.all(np.abs(t_all) < 1e11):  # GPS seconds up to year ~5100
        raise InputError("epoch time out of range (expected a calendar date)", p)
    notes = list(h.notes) + ep.notes()
    tsys, offset = _time_offset(h, t0, p, notes)
    t_all = t_all + offset
    t_ns_all = np.asarray(ep.t_ns, dtype=np.int64) + int(round(offset * 1e9))
    keep = _drop_exact_duplicates(t_all, txt, p)
    n_duplicates = int((~keep).sum())
    if t_start_s is not None:
        keep &= t_all >= t_start_s
    if t_end_s is not None:
        keep &= t_all <= t_end_s
    if epoch_mask is not None:
        keep &= np.asarray(epoch_mask(t_all), dtype=bool)
    kept = np.flatnonzero(keep)
    T = kept.size
    nsat = np.asarray(ep.nsat, dtype=np.int64)[kept]
    first_rec = np.asarray(ep.first_rec, dtype=np.int64)[kept]
    # one entry per satellite record: epoch index (0..T-1) and first line
    ep_of = np.repeat(np.arange(T, dtype=np.int64), nsat)
    offs = np.arange(nsat.sum(), dtype=np.int64) - np.repeat(np.cumsum(nsat) - nsat, nsat)

    ignored: dict[str, list[str]] = {}
    # a single-system file (type G, R, E, ...) holds that system (GPS files also SBAS)
    fs = h.file_system.upper()
    allowed = SYSTEM_ORDER if fs == "M" or fs not in SYSTEM_ORDER else fs + ("S" if fs == "G" else "")
    blank_sys = fs if fs in SYSTEM_ORDER else "G"  # RINEX 2: a blank letter is the file's system
    if v3:
        rec_line = np.repeat(first_rec, nsat) + offs
        sy, prn = _sys_and_prn(bufp, starts[rec_line], "G", rec_line, p)
        obs_types = dict(h.obs_types)
        sig_map: dict[str, list[tuple[int, int, str]]] = {}  # sys -> (col j, field, signal)
        for s, codes in obs_types.items():
            lst = []
            for j, c in enumerate(codes):
                if len(c) == 3 and c[0] in _TYPE2FIELD:
                    sig = rinex3_signal(s, c, h.version)
                    lst.append((j, _TYPE2FIELD[c[0]], sig))
                else:
                    ignored.setdefault(s, []).append(c)
            sig_map[s] = lst
        present = _systems_present(sy)
        missing = sorted(present - set(obs_types))
        if missing:
            r = int(np.argmax(sy == ord(missing[0])))
            raise InputError(
                f"satellite system {missing[0]!r} has no 'SYS / # / OBS TYPES' header record",
                p,
                int(rec_line[r]) + 1,
            )
    else:
        codes2 = h.obs_types2
        per_sat = v2_lines_per_record(len(codes2))
        rec_line = np.repeat(first_rec, nsat) + offs * per_sat
        codes2 = _v2_types_carried(h, bufp, starts, ends - starts, rec_line, per_sat, notes)
        sat_txt = "".join("".join(ep.sats[k]) for k in kept.tolist()).encode("ascii", "replace")
        sat_buf = np.frombuffer(sat_txt, np.uint8)
        sy, prn = _sys_and_prn(
            np.concatenate([sat_buf, np.full(3, 32, np.uint8)]),
            np.arange(nsat.sum(), dtype=np.int64) * 3,
            blank_sys,
            np.repeat(np.asarray(ep.line, np.int64)[kept], nsat),
            p,
        )
        present = _systems_present(sy)
        obs_types = {s: list(codes2) for s in sorted(present, key=SYSTEM_ORDER.index)}
        sig_map = {}
        for s in obs_types:
            table = RINEX2_SIGNAL_MAP.get(s, {})
            lst = []
            for j, c in enumerate(codes2):
                if c in table:
                    lst.append((j, _TYPE2FIELD.get(c[0], 0), table[c]))  # P1/P2: code
                else:
                    ignored.setdefault(s, []).append(c)
            sig_map[s] = lst

    foreign = sorted(_systems_present(sy) - set(allowed), key=SYSTEM_ORDER.index)
    if foreign:
        notes.append(
            f"the header declares system(s) {allowed!r} only (RINEX VERSION / TYPE, column 41) but "
            f"the records hold {''.join(foreign)!r} too: all read, as in a mixed ('M') file"
        )
    sys_keep = [s for s in SYSTEM_ORDER if s in obs_types and (systems is None or s in systems)]
    signals = tuple(sorted({sig for s in sys_keep for _, _, sig in sig_map[s]}))
    sig_index = {sig: k for k, sig in enumerate(signals)}

    sel = np.isin(sy, np.frombuffer("".join(sys_keep).encode(), np.uint8))
    rank = np.zeros(256, np.int64)
    for r, s in enumerate(SYSTEM_ORDER):
        rank[ord(s)] = r
    key = rank[sy] * 1000 + prn
    ukeys, tx_of = np.unique(key[sel], return_inverse=True)
    tx_ids = tuple(f"{SYSTEM_ORDER[k // 1000]}{k % 1000:02d}" for k in ukeys.tolist())
    N, K = len(tx_ids), len(signals)

    out = np.full((4, T, N, K), np.nan)
    lli = np.zeros((T, N, K), np.int8)
    ssi = np.zeros((T, N, K), np.int8)
    rec_sel = np.flatnonzero(sel)
    sys_sel = sy[rec_sel]
    for s in sys_keep:
        m = sys_sel == ord(s)
        if not m.any() or not sig_map[s]:
            continue
        rows = rec_sel[m]
        tx = tx_of[m]
        ee = ep_of[rows]
        cols = np.array([j for j, _, _ in sig_map[s]], dtype=np.int64)
        n_types = len(obs_types[s])
        if v3:
            width = V3_SAT_ID_WIDTH + OBS_FIELD_WIDTH * n_types
            block = gather_lines(bufp, starts[rec_line[rows]], lens[rec_line[rows]], width)
            f16 = block[:, V3_SAT_ID_WIDTH:].reshape(rows.size, n_types, OBS_FIELD_WIDTH)[:, cols]
            line_of = np.broadcast_to(rec_line[rows][:, None], f16.shape[:2])
            col_of = np.broadcast_to(V3_SAT_ID_WIDTH + OBS_FIELD_WIDTH * cols[None, :], f16.shape[:2])
        else:
            per_sat = v2_lines_per_record(n_types)
            ln = rec_line[rows][:, None] + np.arange(per_sat)[None, :]
            block = gather_lines(bufp, starts[ln.ravel()], lens[ln.ravel()], V2_LINE_WIDTH)
            f16 = block.reshape(rows.size, per_sat * V2_OBS_PER_LINE, OBS_FIELD_WIDTH)[:, cols]
            line_of = rec_line[rows][:, None] + (cols // V2_OBS_PER_LINE)[None, :]
            col_of = np.broadcast_to(OBS_FIELD_WIDTH * (cols % V2_OBS_PER_LINE)[None, :], f16.shape[:2])
        vals, odd = f14_to_float(f16[..., :OBS_VALUE_WIDTH])
        if odd.any():
            fix_odd_fields(
                vals,
                odd,
                f16[..., :OBS_VALUE_WIDTH],
                line_of,
                col_of,
                p,
                [obs_types[s][j] for j in cols.tolist()],
            )
        check_digit_field(f16[..., LLI_OFFSET], line_of, col_of + LLI_OFFSET, p, "LLI")
        check_digit_field(f16[..., SSI_OFFSET], line_of, col_of + SSI_OFFSET, p, "signal strength")
        d_lli = digit_field(f16[..., LLI_OFFSET])
        d_ssi = digit_field(f16[..., SSI_OFFSET])
        scale = h.scale.get(s, {})
        for q, (j, fld, sig) in enumerate(sig_map[s]):
            v = vals[:, q]
            fac = scale.get(obs_types[s][j], scale.get("*", 1.0))
            if fac != 1.0:
                v = v / fac
            k = sig_index[sig]
            out[fld, ee, tx, k] = v
            if fld == _PHASE:
                has = ~np.isnan(v)
                lli[ee[has], tx[has], k] = d_lli[has, q]
                ssi[ee[has], tx[has], k] = d_ssi[has, q]

    # wavelength of the signals each system declares (NaN elsewhere)
    declared = {s: {sig for _, _, sig in sig_map[s]} for s in sys_keep}
    wl = np.full((N, K), np.nan)
    for n, tid in enumerate(tx_ids):
        ch = h.glo_channel.get(tid) if tid[0] == "R" else None
        for k, sig in enumerate(signals):
            if sig in declared[tid[0]]:
                wl[n, k] = wavelength_m(tid[0], sig, ch)

    flags = np.asarray(ep.flag, dtype=np.int64)[kept]
    approx = h.approx_pos_m
    if approx is not None and not np.any(approx):
        approx = None
    meta: dict[str, object] = {
        "file": Path(p).name,
        "path": p,
        "compression": compression,
        "rinex_version": h.version,
        "file_system": h.file_system,
        "marker_name": h.marker,
        "receiver_type": h.receiver_type,
        "antenna_type": h.antenna_type,
        "interval_s": h.interval_s,
        "obs_types": {s: list(obs_types[s]) for s in sys_keep},
        "ignored_obs_types": {s: v for s, v in ignored.items() if s in sys_keep},
        "time_system": tsys,
        "time_offset_s": offset,
        "leap_seconds": h.leap_s,
        "glonass_channels": dict(h.glo_channel),
        "t_ns": t_ns_all[kept],
        "rcv_clock_offset_s": np.asarray(ep.clk_s, dtype=float)[kept],
        "power_failure_epochs": np.flatnonzero(flags == 1).tolist(),
        "events": ep.events,
        "n_slip_records_skipped": ep.n_slip,
        "duplicate_epochs_dropped": n_duplicates,
        "read_notes": notes,
        "ssi": ssi,
    }
    return mask_impossible(
        ObsBatch.from_stacked(t_all[kept], tx_ids, signals, out, lli, wl, h.marker, approx, meta)
    )

"""Files that are not observations of a format this package reads, named by what they are.

When :func:`robustrtk.io.readers.detect_format` recognises no format, the refusal should
say what the file is and what to do with it, not print its first bytes. Each test looks at
the first (decompressed) bytes only; the first that matches names the file.
"""

from __future__ import annotations

import re

__all__ = ["name_foreign"]

_NMEA = re.compile(rb"^\$(G[PLANBQ]|BD|GI)[A-Z]{3},")
_POS_TIME = re.compile(rb"^\s*(\d{4}/\d\d/\d\d\s+\d\d:\d\d:\d\d(\.\d+)?|\d{3,4}\s+\d+(\.\d+)?)\s+-?\d")
_TRUTH_COLS = (b"latitudedegrees", b"longitudedegrees")
#: First line of an SP3 file: ``#`` version letter (a-d), position/velocity flag, year.
_SP3 = re.compile(rb"^#[a-d][PV ]\s*\d{4}\s")


def _lines(head: bytes, n: int = 40) -> list[bytes]:
    return [ln.rstrip() for ln in head.replace(b"\r", b"").split(b"\n")[:n] if ln.strip()]


def _rinex_kind(first: bytes) -> str | None:
    if first[60:80].strip() != b"RINEX VERSION / TYPE":
        # RINEX clock 3.04 moved the labels to column 66 and the type to column 22
        if first.rstrip().endswith(b"RINEX VERSION / TYPE") and first[21:22] == b"C":
            return "a RINEX clock file"
        return None
    kind = first[20:21].upper()
    names = {b"M": "a RINEX meteorological file", b"C": "a RINEX clock file"}
    return names.get(kind, f"a RINEX file of type {kind.decode('ascii', 'replace')!r}")


def name_foreign(head: bytes) -> str | None:
    """What a file that no reader recognised is, with the next step, or None.

    Parameters
    ----------
    head : bytes
        The first bytes of the (decompressed) content, ``\\r`` kept.

    Returns
    -------
    str or None
        E.g. ``"Septentrio SBF binary data (sync '$@'); convert it to RINEX first
        (sbf2rin, or RTKLIB convbin -r sbf)"``.
    """
    if not head:
        return None
    sbf = head.count(b"$@")
    if head.startswith(b"$@") or sbf >= 3:
        return (
            "Septentrio SBF binary data (blocks with sync '$@'); "
            "convert it to RINEX first (Septentrio sbf2rin, or RTKLIB convbin -r sbf)"
        )
    if head.startswith((b"\x89HDF\r\n\x1a\n", b"CDF\x01", b"CDF\x02")):
        return (
            "a netCDF/HDF5 data file (e.g. RINEX already converted to arrays), not RINEX or a "
            "receiver log; give the RINEX file it came from"
        )
    if head.startswith(b"\xb5\x62"):
        return (
            "u-blox UBX binary data without raw measurement frames (RXM-RAWX) that check; "
            "log RXM-RAWX and RXM-SFRBX, or convert with RTKLIB convbin"
        )
    if head.startswith(b"\xd3") and len(head) > 3 and head[1] & 0xFC == 0:
        return "RTCM 3 data without two frames whose CRC checks; record more of the stream"
    lines = _lines(head)
    if not lines:
        return None
    first = lines[0]
    if _SP3.match(first):
        return (
            f"an SP3-{chr(first[1])} precise orbit file (satellite orbits and clocks, not "
            "observations); orbits are read from broadcast RINEX navigation files (--nav)"
        )
    rinex = _rinex_kind(first)
    if rinex is not None:
        return f"{rinex}; expected RINEX observation data"
    if sum(1 for ln in lines if _NMEA.match(ln.lstrip())) >= max(1, len(lines) // 2):
        return (
            "NMEA sentences (positions, not raw observations); "
            "use them as --truth of compare, report or evaluate"
        )
    comments = [ln for ln in lines if ln.startswith(b"%")]
    if (
        comments
        and any(_POS_TIME.match(ln) for ln in lines if not ln.startswith(b"%"))
        or any(b"GPST" in ln and (b"latitude" in ln or b"x-ecef" in ln) for ln in comments)
    ):
        return (
            "an RTKLIB .pos solution file (positions, not observations); "
            "use it as --truth or compare it with robustrtk compare"
        )
    low = first.lower().replace(b" ", b"")
    if low.startswith(b"time,x,y,z"):
        return "a robustrtk CSV solution (positions, not observations); compare it with robustrtk compare"
    if all(c in low for c in _TRUTH_COLS):
        return (
            "a ground-truth CSV (positions, not observations); "
            "use it as --truth of compare, report or evaluate"
        )
    if first.startswith(b"#") and b"Fix," in head[:4096]:
        return (
            "an Android GnssLogger log without 'Raw' measurement rows; enable raw measurements in the logger"
        )
    return None

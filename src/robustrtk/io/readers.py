"""Input files recognised by their content, and a registry of observation readers.

:func:`detect_format` looks at the first bytes of a file (after gzip/bzip2/Unix-compress
decompression and Hatanaka expansion where those apply), never at its name:

==================  ========================================================================
format              recognised by
==================  ========================================================================
``rinex_obs``       ``RINEX VERSION / TYPE`` in columns 61-80 of line 1, type ``O`` (col 21)
``rinex_nav``       the same line with a navigation type (``N``, ``G``, ``H``, and the
                    Galileo ``E``/``L`` of RINEX 2.12, in RINEX 2)
``obs_table_csv``   a CSV header with the pseudolite table columns ``time``, ``receiver``,
                    ``transmitter`` and ``code_m`` or ``phase_cyc``
``obs_table_parquet``  the Parquet magic ``PAR1`` (columns checked when read)
``site_toml``       TOML text with a ``[transmitters]`` table (pseudolite site file)
``gnsslogger``      an Android GnssLogger log: a ``# Raw,...`` comment line naming the
                    ``GnssMeasurement`` columns (``ReceivedSvTimeNanos``...) before any row
``gsdc_device_gnss``  a CSV header with ``utcTimeMillis``, ``Svid``, ``ConstellationType``
                    and ``RawPseudorangeMeters`` (GSDC ``device_gnss.csv``)
``ubx``             binary: at least two UBX frames (sync ``0xB5 0x62``) with valid checksums
                    in the first 64 KiB, and more of them than RTCM 3 frames
``rtcm3``           binary: at least two RTCM 3 frames (preamble ``0xD3``) with valid CRC-24Q
                    in the first 64 KiB, and more of them than UBX frames
==================  ========================================================================

Binary formats are tested on the decompressed bytes as they are (text formats with ``\r``
removed) and after every text format, so a text file never reaches them.

Compact RINEX (``CRINEX VERS``) and compressed files are expanded before the test, so a
Hatanaka-compressed, gzip'd observation file is ``rinex_obs``.

:func:`read_observations` dispatches through a registry of ``(name, sniff, read)`` entries
tried in registration order; a new input kind (e.g. an Android GnssLogger log) is added with
one :func:`register_reader` call.
"""

from __future__ import annotations

import csv
import io
import os
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from robustrtk.core import InputError, ObsBatch
from robustrtk.geometry.navdata import NavData
from robustrtk.io.foreign import name_foreign
from robustrtk.io.rinex_file import (
    check_regular_file,
    compression_kind,
    decompress_capped,
    first_text_line,
    is_hatanaka,
    read_errors_as_input,
    uncompress_capped,
    unzip_capped,
)
from robustrtk.io.rinex_obs import read_rinex_obs

__all__ = [
    "HEAD_BYTES",
    "Reader",
    "detect_format",
    "read_head",
    "read_navigation",
    "read_observations",
    "register_reader",
    "registered_readers",
]

#: Bytes of (decompressed) content that format detection looks at.
HEAD_BYTES = 64 * 1024

Sniff = Callable[[bytes], bool]
Read = Callable[..., ObsBatch]


@dataclass(frozen=True)
class Reader:
    """One registered input kind.

    Attributes
    ----------
    name : str
        Format name returned by :func:`detect_format`.
    sniff : callable bytes -> bool
        True when the decompressed head of a file (up to :data:`HEAD_BYTES` bytes) is this
        format.
    read : callable or None
        ``read(path, **kw) -> ObsBatch``; None for recognised inputs that are not
        observations (navigation data, site files).
    binary : bool
        ``sniff`` is given the bytes as they are (``\r`` kept), not the text head.
    """

    name: str
    sniff: Sniff
    read: Read | None
    binary: bool = False


_REGISTRY: list[Reader] = []


def register_reader(name: str, sniff: Sniff, read: Read | None, *, binary: bool = False) -> None:
    """Register (or replace, by name) an input kind.

    Parameters
    ----------
    name : str
        Format name.
    sniff : callable bytes -> bool
        Content test on the decompressed first bytes (at most :data:`HEAD_BYTES`).
    read : callable or None
        ``read(path, **kw) -> ObsBatch``, or None when the format is recognised but holds no
        observations.
    binary : bool
        Give ``sniff`` the bytes with ``\r`` kept (binary formats).

    Notes
    -----
    Entries are tried in registration order; a replaced entry keeps its place.
    """
    entry = Reader(name, sniff, read, binary)
    for i, r in enumerate(_REGISTRY):
        if r.name == name:
            _REGISTRY[i] = entry
            return
    _REGISTRY.append(entry)


def registered_readers() -> tuple[Reader, ...]:
    """The registered input kinds, in the order they are tried."""
    return tuple(_REGISTRY)


# --------------------------------------------------------------------------------------------
# content


def _decompress_head(raw: bytes, kind: str, path: str) -> bytes:
    try:
        if kind == "gzip":
            d = zlib.decompressobj(wbits=31)
            return d.decompress(raw, HEAD_BYTES)
        if kind == "bzip2":
            import bz2  # here: bzip2 input is rare, and the module costs every start

            return bz2.BZ2Decompressor().decompress(raw, HEAD_BYTES)
        if kind == "zip":
            return unzip_capped(raw, path)[:HEAD_BYTES]
        return uncompress_capped(raw, path)[:HEAD_BYTES]
    except InputError:
        raise
    except Exception as exc:  # corrupt archive: one-line message
        raise InputError(f"cannot decompress {kind} data: {exc}", path=path) from None


def read_head(path: str | os.PathLike[str], n: int = HEAD_BYTES, *, keep_cr: bool = False) -> bytes:
    """The first ``n`` bytes of the plain content of a file.

    gzip, bzip2, Unix compress and zip are undone, then Compact RINEX (Hatanaka) is expanded;
    ``\\r`` is removed.

    Parameters
    ----------
    path : path-like
    n : int
        Bytes wanted (fewer when the content is shorter).
    keep_cr : bool
        Keep ``\r`` bytes (binary content).

    Returns
    -------
    bytes

    Raises
    ------
    InputError
        Missing or unreadable file, corrupt compressed data.
    """
    p = os.fspath(path)
    check_regular_file(p)
    with read_errors_as_input(p), open(p, "rb") as fh:
        raw = fh.read(4)
        kind = compression_kind(raw)
        if kind in ("compress", "zip", "bzip2"):
            raw += fh.read()  # these decoders want the whole stream
        else:
            raw += fh.read(max(n, HEAD_BYTES) - 4)
    data = _decompress_head(raw, kind, p) if kind else raw
    if is_hatanaka(data):
        with open(p, "rb") as fh:
            whole = fh.read()
        if kind in ("gzip", "bzip2"):
            whole = decompress_capped(whole, kind, p)
        elif kind == "zip":
            whole = unzip_capped(whole, p)
        elif kind:
            whole = _decompress_head(whole, kind, p)
        from robustrtk.io.crx import crx_decompress

        data = crx_decompress(whole, p, head=max(n, HEAD_BYTES))
    data = data[:n]
    return data if keep_cr else data.replace(b"\r", b"")


def _first_line(head: bytes) -> str:
    return first_text_line(head).decode("ascii", "replace")


def _rinex_type(head: bytes) -> str | None:
    """File type letter (column 21) of a RINEX header line, None when not RINEX."""
    line = _first_line(head)
    if line[60:].strip() != "RINEX VERSION / TYPE":
        return None
    try:
        float(line[:9])
    except ValueError:
        return None
    return line[20:21].upper()


def _sniff_rinex_obs(head: bytes) -> bool:
    return _rinex_type(head) == "O"


def _sniff_rinex_nav(head: bytes) -> bool:
    t = _rinex_type(head)
    if t is None:
        return False
    version = float(_first_line(head)[:9])
    return t == "N" if version >= 3.0 else t in ("N", "G", "H", "E", "L")


def _sniff_obs_table_csv(head: bytes) -> bool:
    # the header row alone decides; a bad byte further down is the reader's to report by line
    first = head.split(b"\n", 1)[0].decode("utf-8", "replace")
    if "," not in first:
        return False
    header = [c.strip() for c in next(csv.reader(io.StringIO(first)), [])]
    from robustrtk.io.obstable import REQUIRED_COLUMNS

    return all(c in header for c in REQUIRED_COLUMNS) and ("code_m" in header or "phase_cyc" in header)


def _sniff_parquet(head: bytes) -> bool:
    return head[:4] == b"PAR1"


def _sniff_site_toml(head: bytes) -> bool:
    if len(head) >= HEAD_BYTES:
        return False  # site files are small
    import tomllib

    try:
        doc = tomllib.loads(head.decode("utf-8"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError):
        return False
    return isinstance(doc.get("transmitters"), dict)


# --------------------------------------------------------------------------------------------
# readers


def _pick_receiver(batches: dict[str, ObsBatch], receiver: str | None, path: str) -> ObsBatch:
    if receiver is None:
        if len(batches) == 1:
            return next(iter(batches.values()))
        raise InputError(
            f"the table holds receivers {', '.join(batches)}; expected receiver=NAME to choose one",
            path=path,
        )
    if receiver not in batches:
        raise InputError(f"receiver {receiver!r} not in the table (has {', '.join(batches)})", path=path)
    return batches[receiver]


# The readers of the less common formats are imported when a file of theirs is met (a
# RINEX solve does not pay for them at start-up).
def _read_obs_table_csv(path: str, *, receiver: str | None = None, **kw: Any) -> ObsBatch:
    from robustrtk.io.obstable import read_obs_table

    return _pick_receiver(read_obs_table(path, fmt="csv", **kw), receiver, path)


def _read_obs_table_parquet(path: str, *, receiver: str | None = None, **kw: Any) -> ObsBatch:
    from robustrtk.io.obstable import read_obs_table

    return _pick_receiver(read_obs_table(path, fmt="parquet", **kw), receiver, path)


def _sniff_gnsslogger(head: bytes) -> bool:
    from robustrtk.io.gnsslogger import is_gnsslogger

    return is_gnsslogger(head)


def _read_gnsslogger(path: str, **kw: Any) -> ObsBatch:
    from robustrtk.io.gnsslogger import read_gnsslogger

    return read_gnsslogger(path, **kw)


def _sniff_device_gnss(head: bytes) -> bool:
    from robustrtk.io.gsdc import is_device_gnss

    return is_device_gnss(head)


def _read_device_gnss(path: str, **kw: Any) -> ObsBatch:
    from robustrtk.io.gsdc import read_device_gnss

    return read_device_gnss(path, **kw)


def _read_rinex(path: str, **kw: Any) -> ObsBatch:
    return read_rinex_obs(path, **kw)


register_reader("rinex_obs", _sniff_rinex_obs, _read_rinex)
register_reader("rinex_nav", _sniff_rinex_nav, None)
register_reader("obs_table_parquet", _sniff_parquet, _read_obs_table_parquet)
register_reader("obs_table_csv", _sniff_obs_table_csv, _read_obs_table_csv)
register_reader("site_toml", _sniff_site_toml, None)
register_reader("gnsslogger", _sniff_gnsslogger, _read_gnsslogger)
register_reader("gsdc_device_gnss", _sniff_device_gnss, _read_device_gnss)


def _binary_counts(head: bytes) -> tuple[int, int]:
    from robustrtk.io.rtcm3 import count_rtcm3_frames
    from robustrtk.io.ubx import count_ubx_frames

    return count_ubx_frames(head), count_rtcm3_frames(head)


def _sniff_ubx(head: bytes) -> bool:
    if b"\xb5\x62" not in head:
        return False
    n_ubx, n_rtcm = _binary_counts(head)
    return n_ubx >= 2 and n_ubx >= n_rtcm


def _sniff_rtcm3(head: bytes) -> bool:
    if b"\xd3" not in head:
        return False
    n_ubx, n_rtcm = _binary_counts(head)
    return n_rtcm >= 2 and n_rtcm > n_ubx


def _window(batch: ObsBatch, systems: str | None, t_start_s: float | None, t_end_s: float | None) -> ObsBatch:
    if systems:
        batch = batch.select_systems(systems.upper())
    if t_start_s is not None or t_end_s is not None:
        t = batch.t_s
        keep = np.ones(t.shape, bool)
        if t_start_s is not None:
            keep &= t >= t_start_s
        if t_end_s is not None:
            keep &= t <= t_end_s
        batch = batch.select_epochs(keep)
    return batch


def _read_ubx(
    path: str,
    *,
    systems: str | None = None,
    t_start_s: float | None = None,
    t_end_s: float | None = None,
    **_: Any,
) -> ObsBatch:
    from robustrtk.io.ubx import read_ubx

    return _window(read_ubx(path)[0], systems, t_start_s, t_end_s)


def _read_rtcm3(
    path: str,
    *,
    systems: str | None = None,
    t_start_s: float | None = None,
    t_end_s: float | None = None,
    t_ref_s: float | None = None,
    **_: Any,
) -> ObsBatch:
    from robustrtk.io.rtcm3 import read_rtcm3

    return _window(read_rtcm3(path, t_ref_s=t_ref_s)[0], systems, t_start_s, t_end_s)


register_reader("ubx", _sniff_ubx, _read_ubx, binary=True)
register_reader("rtcm3", _sniff_rtcm3, _read_rtcm3, binary=True)


def _expected() -> str:
    return ", ".join(r.name for r in _REGISTRY)


def detect_format(path: str | os.PathLike[str]) -> str:
    """Name of the registered format whose content test ``path`` passes.

    Parameters
    ----------
    path : path-like

    Returns
    -------
    str
        ``"rinex_obs"``, ``"rinex_nav"``, ``"obs_table_csv"``, ``"obs_table_parquet"``,
        ``"site_toml"``, ``"gnsslogger"``, ``"gsdc_device_gnss"``, ``"ubx"``, ``"rtcm3"``
        or the name of a reader registered later.

    Raises
    ------
    InputError
        Unreadable file, or content of none of the registered formats (the message names
        the file and the formats expected).
    """
    p = os.fspath(path)
    raw = read_head(p, keep_cr=True)
    head = raw.replace(b"\r", b"")
    for r in _REGISTRY:
        if r.sniff(raw if r.binary else head):
            return r.name
    if not head:
        raise InputError(f"empty file; expected one of: {_expected()}", path=p)
    foreign = name_foreign(raw)
    if foreign is not None:
        raise InputError(foreign, path=p)
    raise InputError(f"unrecognised content {head[:40]!r}; expected one of: {_expected()}", path=p)


def read_observations(path: str | os.PathLike[str], **kw: Any) -> ObsBatch:
    """Read observations from a file of any registered format (detected from its content).

    Parameters
    ----------
    path : path-like
    **kw
        Passed to the format's reader: ``systems``, ``t_start_s``, ``t_end_s`` for RINEX;
        ``receiver`` (required with several receivers) and ``wavelength_m`` for pseudolite
        observation tables; ``systems``, ``t_start_s``, ``t_end_s`` (and ``clock``,
        ``max_sv_time_unc_ns``) for GnssLogger logs and ``device_gnss.csv``; ``systems``,
        ``t_start_s``, ``t_end_s`` for UBX and RTCM 3 logs (and ``t_ref_s``, the approximate
        GPST of an RTCM 3 stream, see :func:`robustrtk.io.rtcm3.read_rtcm3`).

    Returns
    -------
    ObsBatch

    Raises
    ------
    InputError
        Unrecognised content, a recognised file without observations (navigation data,
        site file), or the reader's own errors.
    """
    p = os.fspath(path)
    name = detect_format(p)
    reader = next(r for r in _REGISTRY if r.name == name)
    if reader.read is None:
        readable = ", ".join(r.name for r in _REGISTRY if r.read is not None)
        raise InputError(f"{name} holds no observations; expected one of: {readable}", path=p)
    return reader.read(p, **kw)


def read_navigation(paths: str | os.PathLike[str] | Sequence[str | os.PathLike[str]]) -> NavData:
    """Broadcast ephemerides of navigation files of any kind, recognised by content.

    UBX and RTCM 3 logs give the ephemerides decoded from their navigation messages; every
    other file goes to :func:`robustrtk.io.rinex_nav.read_rinex_nav` (RINEX 2, 3, 4), whose
    errors name what is wrong with it. The records of all files are concatenated.

    Raises
    ------
    InputError
        The readers' errors (missing file, not a navigation file, malformed record).
    """
    from robustrtk.io.rinex_nav import read_rinex_nav

    plist = [os.fspath(paths)] if isinstance(paths, (str, os.PathLike)) else [os.fspath(p) for p in paths]

    def kind(p: str) -> str:
        try:
            k = detect_format(p)
        except InputError:
            return "rinex_nav"  # the RINEX reader says what is wrong with it
        return k if k in ("ubx", "rtcm3") else "rinex_nav"

    kinds = [kind(p) for p in plist]
    rinex = [p for p, k in zip(plist, kinds, strict=True) if k == "rinex_nav"]
    navs = [read_rinex_nav(rinex)] if rinex else []
    for p, k in zip(plist, kinds, strict=True):
        if k == "ubx":
            from robustrtk.io.ubx import read_ubx

            navs.append(read_ubx(p)[1])
        elif k == "rtcm3":
            from robustrtk.io.rtcm3 import read_rtcm3

            navs.append(read_rtcm3(p)[1])
    if len(navs) == 1:
        return navs[0]
    from robustrtk.io.raw_collect import merge_nav  # here: RINEX alone reads as one

    return merge_nav(navs)

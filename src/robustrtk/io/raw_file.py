"""Bytes of binary receiver logs (UBX, RTCM 3), plain or compressed.

The compression is recognised from the content (:func:`robustrtk.io.rinex_file.compression_kind`):
gzip (several members allowed), bzip2, Unix compress or zip. Unlike RINEX text, nothing is
removed from the decompressed bytes. A gzip or bzip2 stream cut short gives the bytes
decompressed up to the cut (a log copied while it was being written), noted in the second
return value.
"""

from __future__ import annotations

import bz2
import os
import zlib
from pathlib import Path

from robustrtk.core import InputError
from robustrtk.io.rinex_file import compression_kind

__all__ = ["read_binary_log"]


def _gunzip(raw: bytes) -> tuple[bytes, bool]:
    out = []
    rest = raw
    complete = True
    while rest:
        d = zlib.decompressobj(wbits=31)
        out.append(d.decompress(rest))
        if not d.eof:
            complete = False
            break
        rest = d.unused_data.lstrip(b"\x00")
        if rest[:2] != b"\x1f\x8b":
            break
    return b"".join(out), complete


def read_binary_log(path: str | os.PathLike[str]) -> tuple[bytes, str]:
    """The decompressed bytes of a binary log and how it was stored.

    Parameters
    ----------
    path : path-like

    Returns
    -------
    data : bytes
    compression : str
        ``"none"``, ``"gzip"``, ``"bzip2"``, ``"compress"``, ``"zip"``; with ``" (truncated)"``
        appended when a gzip or bzip2 stream ends early.

    Raises
    ------
    InputError
        Missing or unreadable file, undecodable compressed data.
    """
    p = os.fspath(path)
    try:
        raw = Path(p).read_bytes()
    except FileNotFoundError:
        raise InputError("file not found", path=p) from None
    except IsADirectoryError:
        raise InputError("is a directory, expected a file", path=p) from None
    except OSError as exc:
        raise InputError(f"cannot read file ({exc.strerror})", path=p) from None
    kind = compression_kind(raw)
    if kind is None:
        return raw, "none"
    try:
        if kind == "gzip":
            data, complete = _gunzip(raw)
        elif kind == "bzip2":
            d = bz2.BZ2Decompressor()
            data = d.decompress(raw)
            complete = d.eof
        else:
            import hatanaka

            data, complete = bytes(hatanaka.decompress(raw)), True
    except Exception as exc:  # corrupt archive: one line, no traceback
        raise InputError(f"cannot decompress {kind} data: {exc}", path=p) from None
    return data, kind if complete else f"{kind} (truncated)"

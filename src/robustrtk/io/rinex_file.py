"""Opening RINEX files: plain text, gzip, bzip2, Unix compress, zip and Hatanaka.

The kind of compression is detected from the content (magic bytes and the Compact RINEX
header line), never from the file name. Decompression of ``.Z``, ``.zip`` and Compact
RINEX is done with :func:`hatanaka.decompress`.
"""

from __future__ import annotations

import bz2
import gzip
from os import PathLike
from pathlib import Path

from robustrtk.core import InputError

__all__ = ["COMPRESSION_MAGIC", "compression_kind", "decompress_rinex", "is_hatanaka", "read_rinex_bytes"]

#: Magic bytes of the outer compression formats recognised, in test order.
COMPRESSION_MAGIC: tuple[tuple[bytes, str], ...] = (
    (b"\x1f\x8b", "gzip"),
    (b"\x1f\x9d", "compress"),
    (b"BZh", "bzip2"),
    (b"PK\x03\x04", "zip"),
)


def compression_kind(raw: bytes) -> str | None:
    """Outer compression of ``raw`` from its magic bytes.

    Parameters
    ----------
    raw : bytes
        The first bytes of a file (at least 4 for a reliable answer).

    Returns
    -------
    str or None
        ``"gzip"``, ``"compress"``, ``"bzip2"``, ``"zip"``, or ``None`` for anything else.
    """
    for magic, kind in COMPRESSION_MAGIC:
        if raw[: len(magic)] == magic:
            return kind
    return None


def is_hatanaka(data: bytes) -> bool:
    """Whether ``data`` (after any outer decompression) starts with a Compact RINEX header."""
    return b"CRINEX VERS" in data[:200] or b"COMPACT RINEX" in data[:200]


def decompress_rinex(raw: bytes, path: str) -> tuple[bytes, str]:
    """Plain RINEX text of the bytes of a possibly compressed file.

    Parameters
    ----------
    raw : bytes
        Whole file content.
    path : str
        File name for messages.

    Returns
    -------
    data : bytes
        Plain RINEX, ``\\r`` removed.
    compression : str
        ``"none"``, ``"gzip"``, ``"hatanaka"``, ``"hatanaka+gzip"``, ... (detected from
        content).

    Raises
    ------
    InputError
        Corrupt archive or Compact RINEX data.
    """
    kinds = []
    outer = compression_kind(raw)
    if outer is not None:
        kinds.append(outer)
    data = raw
    if kinds:
        try:
            if kinds[0] == "gzip":
                data = gzip.decompress(raw)
            elif kinds[0] == "bzip2":
                data = bz2.decompress(raw)
            else:
                import hatanaka

                data = hatanaka.decompress(raw)
        except Exception as exc:  # corrupt archive: report, no traceback
            raise InputError(f"cannot decompress {kinds[0]} data: {exc}", path=path) from None
    if is_hatanaka(data):
        kinds.insert(0, "hatanaka")
        try:
            import hatanaka

            data = hatanaka.decompress(data)
        except Exception as exc:
            raise InputError(f"bad Hatanaka (Compact RINEX) data: {exc}", path=path) from None
    if b"\r" in data:
        data = data.replace(b"\r", b"")
    return data, "+".join(kinds) if kinds else "none"


def read_rinex_bytes(path: str | PathLike[str]) -> tuple[bytes, str]:
    """The plain RINEX text of ``path`` and how it was stored.

    Parameters
    ----------
    path : str or path-like
        Plain or compressed RINEX file.

    Returns
    -------
    data : bytes
        Plain RINEX, ``\\r`` removed.
    compression : str
        ``"none"``, ``"gzip"``, ``"hatanaka"``, ``"hatanaka+gzip"``, ... (detected from
        content).

    Raises
    ------
    InputError
        Missing or unreadable file, corrupt compressed data.
    """
    p = str(path)
    try:
        raw = Path(p).read_bytes()
    except FileNotFoundError:
        raise InputError("file not found", path=p) from None
    except OSError as exc:
        raise InputError(f"cannot read file ({exc.strerror})", path=p) from None
    return decompress_rinex(raw, p)

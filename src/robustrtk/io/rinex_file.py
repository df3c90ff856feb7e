"""Opening RINEX files: plain text, gzip, bzip2, Unix compress, zip and Hatanaka.

The kind of compression is detected from the content (magic bytes and the Compact RINEX
header line), never from the file name. gzip, bzip2, zip (one member) and Unix compress
(``.Z``, the LZW format RINEX archives still ship, decoded by the ``ncompress`` package) are
expanded here under a cap on the output; Compact RINEX by :mod:`robustrtk.io.crx` under its
own cap.
"""

from __future__ import annotations

import contextlib
import os
import stat
import zlib
from collections.abc import Iterator
from os import PathLike
from pathlib import Path
from typing import Any

from robustrtk.core import InputError

__all__ = [
    "COMPRESSION_MAGIC",
    "MAX_EXPANSION",
    "MAX_PLAIN_BYTES",
    "check_regular_file",
    "compression_kind",
    "decompress_capped",
    "unzip_capped",
    "uncompress_capped",
    "decompress_rinex",
    "first_text_line",
    "is_hatanaka",
    "read_errors_as_input",
    "read_rinex_bytes",
]

#: A compressed input may expand to at most this many times its size (RINEX and Compact
#: RINEX gzip 2.5-5x on the shared datasets; a "bomb" of zeros 1000x) ...
MAX_EXPANSION = 20
#: ... and never beyond this many bytes.
MAX_PLAIN_BYTES = 4 << 30
_CHUNK = 1 << 22
#: What the first line of plain or Compact RINEX holds.
RINEX_MARKERS = (b"RINEX VERSION", b"CRINEX VERS")


def check_regular_file(path: str) -> None:
    """:class:`InputError` unless ``path`` is a regular file (or a link to one): a FIFO, a
    socket or a device would block the reader or never end, so it is refused at once
    without being opened. A missing path is left to the caller's open()."""
    try:
        st = os.stat(path)
    except OSError:
        return
    if stat.S_ISDIR(st.st_mode):
        raise InputError("is a directory, expected a file", path=path)
    if not stat.S_ISREG(st.st_mode):
        kind = "a FIFO (named pipe)" if stat.S_ISFIFO(st.st_mode) else "a device or socket"
        raise InputError(f"is {kind}, expected a regular file (save the stream to a file first)", path=path)


@contextlib.contextmanager
def read_errors_as_input(path: str) -> Iterator[None]:
    """Within the block, a failed read of ``path`` becomes an :class:`InputError` naming it:
    a missing file, a directory, or another OS error (with its message)."""
    try:
        yield
    except FileNotFoundError:
        raise InputError("file not found", path=path) from None
    except IsADirectoryError:
        raise InputError("is a directory, expected a file", path=path) from None
    except OSError as exc:
        raise InputError(f"cannot read file ({exc.strerror})", path=path) from None


def _bz2_decompressor() -> Any:
    """A bzip2 decoder (``bz2`` imported here: bzip2 input is rare, and the module, with
    its archive helpers, costs every start)."""
    import bz2

    return bz2.BZ2Decompressor()


def decompress_capped(raw: bytes, kind: str, path: str, expect: tuple[bytes, ...] = ()) -> bytes:
    """gzip (every member) or bzip2 data decoded in chunks, refused as soon as it grows past
    ``MAX_EXPANSION`` times the input (at most ``MAX_PLAIN_BYTES``), without decoding the
    rest: a decompression bomb costs a second, not minutes and gigabytes. With ``expect``,
    content whose first line holds none of those markers is refused after the first chunk."""
    limit = min(MAX_PLAIN_BYTES, max(64 << 20, MAX_EXPANSION * len(raw)))
    out = bytearray()
    data = raw
    while data:
        d: Any = zlib.decompressobj(wbits=31) if kind == "gzip" else _bz2_decompressor()
        buf = data
        while True:
            if kind == "gzip":
                piece = d.decompress(buf, _CHUNK)
                buf = d.unconsumed_tail
            else:
                piece = d.decompress(buf, _CHUNK)
                buf = b""
            out += piece
            if expect and len(out) == len(piece) and out and not any(m in out[:400] for m in expect):
                first = bytes(out[:40])
                raise InputError(f"{kind} content is not RINEX (starts {first!r})", path=path)
            if len(out) > limit:
                raise InputError(
                    f"{kind} data expands beyond {limit >> 20} MiB ({MAX_EXPANSION}x the file, at most "
                    f"{MAX_PLAIN_BYTES >> 30} GiB): refused as a likely decompression bomb",
                    path=path,
                )
            if d.eof:
                break
            if not piece and not buf and (kind == "gzip" or d.needs_input):
                raise InputError(f"cannot decompress {kind} data: truncated stream", path=path)
        data = d.unused_data
        if kind == "gzip" and data.strip(b"\x00") == b"":
            break  # trailing zero padding after the last member
    return bytes(out)


def unzip_capped(raw: bytes, path: str, expect: tuple[bytes, ...] = ()) -> bytes:
    """The one member of a zip archive, read in chunks under the same cap as
    :func:`decompress_capped` (the size the archive declares is not trusted). An archive of
    several files is refused: which one is meant cannot be told."""
    import io
    import zipfile

    limit = min(MAX_PLAIN_BYTES, max(64 << 20, MAX_EXPANSION * len(raw)))
    try:
        with zipfile.ZipFile(io.BytesIO(raw)) as zf:
            members = [m for m in zf.infolist() if not m.is_dir()]
            if len(members) != 1:
                names = ", ".join(m.filename for m in members[:4]) or "none"
                raise InputError(
                    f"zip archive holds {len(members)} files ({names}); expected exactly one", path=path
                )
            out = bytearray()
            with zf.open(members[0]) as fh:
                while piece := fh.read(_CHUNK):
                    out += piece
                    if expect and len(out) == len(piece) and not any(m in out[:400] for m in expect):
                        raise InputError(f"zip content is not RINEX (starts {bytes(out[:40])!r})", path=path)
                    if len(out) > limit:
                        raise InputError(
                            f"zip data expands beyond {limit >> 20} MiB ({MAX_EXPANSION}x the file, at "
                            f"most {MAX_PLAIN_BYTES >> 30} GiB): refused as a likely decompression bomb",
                            path=path,
                        )
    except (zipfile.BadZipFile, zipfile.LargeZipFile, NotImplementedError, EOFError, zlib.error) as exc:
        raise InputError(f"cannot decompress zip data: {exc}", path=path) from None
    return bytes(out)


class _CappedSink:
    """A binary sink that refuses to hold more than ``limit`` bytes."""

    def __init__(self, limit: int) -> None:
        self.buf = bytearray()
        self.limit = limit

    def write(self, b: bytes) -> int:
        self.buf += b
        if len(self.buf) > self.limit:
            raise OverflowError
        return len(b)


def uncompress_capped(raw: bytes, path: str, expect: tuple[bytes, ...] = ()) -> bytes:
    """Unix ``compress`` (LZW, ``.Z``) data decoded under the cap of
    :func:`decompress_capped`: decoding stops as soon as the output passes it. With
    ``expect``, content whose first line holds none of those markers is refused."""
    import ncompress

    limit = min(MAX_PLAIN_BYTES, max(64 << 20, MAX_EXPANSION * len(raw)))
    sink = _CappedSink(limit)
    try:
        ncompress.decompress(raw, sink)
    except OverflowError:
        raise InputError(
            f"compress data expands beyond {limit >> 20} MiB ({MAX_EXPANSION}x the file, at most "
            f"{MAX_PLAIN_BYTES >> 30} GiB): refused as a likely decompression bomb",
            path=path,
        ) from None
    except (ValueError, EOFError, OSError) as exc:
        raise InputError(f"cannot decompress compress (.Z) data: {exc}", path=path) from None
    out = bytes(sink.buf)
    if expect and out and not any(m in out[:400] for m in expect):
        raise InputError(f"compress content is not RINEX (starts {out[:40]!r})", path=path)
    return out


def first_text_line(data: bytes) -> bytes:
    """The first line of ``data`` that is not blank (RTKLIB skips blank lines before the
    ``RINEX VERSION / TYPE`` line; so do the readers here)."""
    for line in data.split(b"\n", 64):
        if line.strip():
            return line
    return b""


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
            if kinds[0] in ("gzip", "bzip2"):
                data = decompress_capped(raw, kinds[0], path, RINEX_MARKERS)
            elif kinds[0] == "zip":
                data = unzip_capped(raw, path, RINEX_MARKERS)
            else:
                data = uncompress_capped(raw, path, RINEX_MARKERS)
        except InputError:
            raise
        except Exception as exc:  # corrupt archive: report, no traceback
            raise InputError(f"cannot decompress {kinds[0]} data: {exc}", path=path) from None
    if is_hatanaka(data):
        kinds.insert(0, "hatanaka")
        from robustrtk.io.crx import crx_decompress

        data = crx_decompress(data, path)
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
    data, compression : bytes, str
        As :func:`decompress_rinex` returns them for the file's content.

    Raises
    ------
    InputError
        Missing or unreadable file, corrupt compressed data.
    """
    p = str(path)
    check_regular_file(p)
    with read_errors_as_input(p):
        raw = Path(p).read_bytes()
    return decompress_rinex(raw, p)

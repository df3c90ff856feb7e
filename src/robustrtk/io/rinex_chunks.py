"""RINEX observation files read a block of epochs at a time, in bounded memory.

:func:`iter_rinex_obs` yields :class:`~robustrtk.core.ObsBatch` blocks of at most
``epochs_per_chunk`` epochs, in file order. A plain RINEX 3/4 file is streamed: its header,
then its body cut at epoch lines (``>``), each piece decoded with the header by
:func:`robustrtk.io.rinex_obs.read_rinex_obs` (the same decoder, so each block holds exactly
the epochs the whole-file read gives, with the same values); memory is bounded by the block,
not the file. Messages name the line of the file. Compressed files (gzip, Hatanaka) and
RINEX 2 (whose epoch lines carry no marker) are read whole and handed out in blocks.

A block's transmitters and signals are those present in it (the union over its epochs),
so two blocks may have different columns.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from os import PathLike

import numpy as np

from robustrtk.core import ObsBatch
from robustrtk.errors import InputError
from robustrtk.io.rinex_file import check_regular_file, compression_kind, first_text_line, is_hatanaka
from robustrtk.io.rinex_obs import read_rinex_obs

#: Epochs per block by default (about 1 MB of RINEX 3 text for a phone or a survey receiver).
EPOCHS_PER_CHUNK = 4096
_READ_BYTES = 1 << 22
_EPOCH_START = re.compile(rb"\n>")
_HEADER_END = b"END OF HEADER"


def iter_rinex_obs(
    path: str | PathLike[str],
    *,
    systems: str | None = None,
    epochs_per_chunk: int = EPOCHS_PER_CHUNK,
) -> Iterator[ObsBatch]:
    """The epochs of a RINEX observation file, block by block.

    Parameters
    ----------
    path : str or path-like
    systems : str, optional
        System letters to keep (as :func:`read_rinex_obs`).
    epochs_per_chunk : int
        Largest number of epochs per block (≥ 1).

    Yields
    ------
    ObsBatch
        Consecutive blocks; together the epochs of ``read_rinex_obs(path, systems=...)``.

    Raises
    ------
    InputError
        As :func:`read_rinex_obs` (with the file's line numbers), and when an epoch of a
        block is not later than the last epoch of the previous block.
    """
    p = str(path)
    n = max(1, int(epochs_per_chunk))
    check_regular_file(p)
    with open(p, "rb") as fh:
        head = fh.read(4096)
    if compression_kind(head) is not None or not _is_plain_v3(head):
        whole = read_rinex_obs(p, systems=systems)
        for lo in range(0, len(whole), n):
            yield whole.select_epochs(np.arange(lo, min(len(whole), lo + n)))
        return
    last_t = -np.inf
    pending: list[str] = []  # notes of blocks without epochs, handed on with the next one
    for chunk, line0 in _text_chunks(p, n):
        batch = _decode(p, chunk, line0, systems)
        raw = batch.meta.get("read_notes")
        notes = [str(t) for t in raw] if isinstance(raw, list) else []
        if len(batch) == 0:
            pending += [t for t in notes if t not in pending]
            continue
        if pending:
            batch.meta["read_notes"] = pending + [t for t in notes if t not in pending]
            pending = []
        if not float(batch.t_s[0]) > last_t:
            raise InputError(
                "epoch time does not increase (duplicate or earlier than the previous epoch)", p, line0[1] + 1
            )
        last_t = float(batch.t_s[-1])
        yield batch


def is_streamed(path: str | PathLike[str]) -> bool:
    """Whether :func:`iter_rinex_obs` streams ``path`` (a plain RINEX 3/4 observation file)
    rather than reading it whole."""
    with open(path, "rb") as fh:
        head = fh.read(4096)
    return compression_kind(head) is None and _is_plain_v3(head)


def _is_plain_v3(head: bytes) -> bool:
    """A plain RINEX 3 or 4 observation header (version field of the first line)."""
    first = first_text_line(head)
    try:
        version = float(first[:9].decode("ascii", "replace").strip() or "0")
    except ValueError:
        return False
    return version >= 3.0 and not is_hatanaka(head)


def _text_chunks(path: str, n: int) -> Iterator[tuple[bytes, tuple[int, int]]]:
    """``(header + body piece, (header lines, file lines before the piece))`` of at most
    ``n`` epochs each, ``\\r`` removed.

    The body is read :data:`_READ_BYTES` at a time; each read block is searched once for
    epoch starts, and the blocks are joined only when a piece is cut (a file of at most ``n``
    epochs is copied once, into its one piece)."""
    with open(path, "rb") as fh:
        header_lines: list[bytes] = []
        for line in fh:
            header_lines.append(line.replace(b"\r", b""))
            if _HEADER_END in line[60:80] or _HEADER_END in line:
                break
        header = b"".join(header_lines)
        n_head = len(header_lines)
        before = n_head
        parts: list[bytes] = []  # the text since the last cut
        size = 0
        starts: list[int] = []  # epoch starts in that text
        while True:
            raw = fh.read(_READ_BYTES)
            block = raw.replace(b"\r", b"")
            if block:
                if block[:1] == b">" and (size == 0 or parts[-1][-1:] == b"\n"):
                    starts.append(size)
                starts += [m.start() + 1 + size for m in _EPOCH_START.finditer(block)]
                parts.append(block)
                size += len(block)
            if len(starts) > n:
                buf = b"".join(parts)
                k = n
                cut_at = 0
                while len(starts) > k:
                    cut = starts[k]
                    piece = buf[cut_at:cut]
                    yield header + piece, (n_head, before)
                    before += piece.count(b"\n")
                    cut_at = cut
                    k += n
                buf = buf[cut_at:]
                starts = [x - cut_at for x in starts if x >= cut_at]
                parts, size = [buf], len(buf)
            if not raw:
                rest = b"".join(parts)
                if rest.strip():
                    yield b"".join((header, rest)), (n_head, before)
                return


def _decode(path: str, data: bytes, line0: tuple[int, int], systems: str | None) -> ObsBatch:
    """One block decoded, errors and the lines of its read notes moved to the file's line
    numbers."""
    n_head, before = line0
    try:
        batch = read_rinex_obs(path, systems=systems, data=data)
    except InputError as exc:
        if exc.line is not None and exc.line > n_head:
            raise InputError(exc.message, exc.path, exc.line - n_head + before) from None
        raise
    notes = batch.meta.get("read_notes")
    if isinstance(notes, list) and notes:

        def file_line(m: re.Match[str]) -> str:
            k = int(m.group(1))
            return f"line {k - n_head + before if k > n_head else k}"

        batch.meta["read_notes"] = [re.sub(r"line (\d+)", file_line, str(t)) for t in notes]
    return batch


__all__ = ["EPOCHS_PER_CHUNK", "is_streamed", "iter_rinex_obs"]

"""Compact RINEX (Hatanaka) expanded with a cap on the output, like the gzip cap.

The expansion is done by the ``crx2rnx`` program of the :mod:`hatanaka` package, run as a
subprocess whose output is read in chunks: the run is stopped as soon as the output passes
the cap (``MAX_EXPANSION`` times the input, at least 64 MiB, at most ``MAX_PLAIN_BYTES``,
the limits of :func:`robustrtk.io.rinex_file.decompress_capped`), so a crafted file costs a
second, not gigabytes. ``head`` mode reads only the first bytes (format detection). The
program's warnings (exit status 2) are not Python warnings: the text is kept as it is.
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from importlib import resources
from typing import IO

from robustrtk.core import InputError

__all__ = ["CRX_MAX_EXPANSION", "crx_decompress"]

#: Compact RINEX expands about 3-8 times on real files (the shared KMS3 file: 4.6x); the cap
#: leaves room for sparse epochs.
CRX_MAX_EXPANSION = 40
_CHUNK = 1 << 20
#: Largest plain output in any case (the value of :data:`robustrtk.io.rinex_file.MAX_PLAIN_BYTES`,
#: which imports this module).
MAX_PLAIN_BYTES = 4 << 30


def _executable() -> str:
    name = "crx2rnx.exe" if sys.platform.startswith("win") else "crx2rnx"
    return str(resources.files("hatanaka.bin").joinpath(name))


def _feed(stream: IO[bytes], data: bytes) -> None:
    try:
        stream.write(data)
    except (BrokenPipeError, OSError):
        pass  # the reader stopped early (head, or over the cap)
    finally:
        try:
            stream.close()
        except OSError:
            pass


def crx_decompress(data: bytes, path: str, *, head: int | None = None, max_bytes: int | None = None) -> bytes:
    """Plain RINEX of Compact RINEX ``data``.

    Parameters
    ----------
    data : bytes
        Compact RINEX text (outer compression already undone).
    path : str
        File name for messages.
    head : int, optional
        Return only the first ``head`` bytes (the program is stopped there).
    max_bytes : int, optional
        Cap on the output (default ``CRX_MAX_EXPANSION`` times the input, at least 64 MiB,
        at most :data:`robustrtk.io.rinex_file.MAX_PLAIN_BYTES`).

    Raises
    ------
    InputError
        Output over the cap, or the program's error (its message, one line).
    """
    limit = (
        max_bytes
        if max_bytes is not None
        else min(MAX_PLAIN_BYTES, max(64 << 20, CRX_MAX_EXPANSION * len(data)))
    )
    try:
        proc = subprocess.Popen(
            [_executable(), "-"], stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE
        )
    except OSError as exc:
        raise InputError(f"cannot run crx2rnx to expand Compact RINEX ({exc.strerror})", path=path) from None
    assert proc.stdin is not None and proc.stdout is not None and proc.stderr is not None
    writer = threading.Thread(target=_feed, args=(proc.stdin, data), daemon=True)
    writer.start()
    out = bytearray()
    stopped = False
    try:
        while True:
            piece = os.read(proc.stdout.fileno(), _CHUNK)
            if not piece:
                break
            out += piece
            if head is not None and len(out) >= head:
                stopped = True
                break
            if len(out) > limit:
                raise InputError(
                    f"Compact RINEX (Hatanaka) data expands beyond {limit >> 20} MiB "
                    f"({CRX_MAX_EXPANSION}x the file): refused as a likely decompression bomb",
                    path=path,
                )
    finally:
        if proc.poll() is None and (stopped or len(out) > limit):
            proc.kill()
        err = b""
        try:
            err = proc.stderr.read() if not stopped and len(out) <= limit else b""
        finally:
            proc.stdout.close()
            proc.stderr.close()
            rc = proc.wait()
            writer.join(timeout=5)
    if stopped:
        return bytes(out[:head])
    if rc not in (0, 2):
        text = " ".join(err.decode("ascii", "replace").split())
        text = text.removeprefix("ERROR :").removeprefix("ERROR:").strip()
        raise InputError(
            f"bad Hatanaka (Compact RINEX) data: {text[:200] or f'crx2rnx exit status {rc}'}", path=path
        )
    return bytes(out)

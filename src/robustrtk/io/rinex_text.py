"""A plain RINEX 2/3 observation text located: its lines, its header and its epochs.

The whole-text scan that the reader (:mod:`robustrtk.io.rinex_obs`) and the fault injection
(:mod:`robustrtk.sim.inject`) share: the text split into lines, the header parsed
(:mod:`robustrtk.io.rinex_layout`) and the epoch lines scanned (:mod:`robustrtk.io.rinex_epochs`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robustrtk.core import InputError
from robustrtk.io.rinex_epochs import RinexEpochs, scan_epochs_v2, scan_epochs_v3
from robustrtk.io.rinex_layout import I64Array, RinexObsHeader, U8Array, parse_obs_header, v2_lines_per_record

__all__ = ["RinexObsText", "scan_obs_text", "split_lines"]


def split_lines(data: bytes) -> tuple[I64Array, I64Array, int]:
    """Line offsets of a text.

    Parameters
    ----------
    data : bytes
        Text with ``\n`` line ends (no ``\r``).

    Returns
    -------
    starts, ends : ndarray of int64
        Offset of the first character and one past the last (the newline excluded) of every
        line.
    n_lines : int
        Number of lines (the empty piece after a final newline not counted).
    """
    buf = np.frombuffer(data, dtype=np.uint8)
    nl = np.flatnonzero(buf == 10)
    starts = np.concatenate([[0], nl + 1]).astype(np.int64)
    ends = np.concatenate([nl, [buf.shape[0]]]).astype(np.int64)
    n_lines = int(starts.shape[0])
    if n_lines > 1 and starts[-1] == buf.shape[0]:
        n_lines -= 1  # the empty piece after the final newline
    return starts, ends, n_lines


@dataclass(frozen=True)
class RinexObsText:
    """A plain RINEX observation text located: lines, header and epochs.

    Attributes
    ----------
    data : bytes
        The plain text.
    bufp : ndarray of uint8
        ``data`` as bytes followed by 4 spaces (so fixed-column reads past a short last line
        stay in bounds).
    starts, ends : ndarray of int64
        Line offsets (see :func:`split_lines`).
    n_lines : int
        Lines of the body scanned (RINEX 3: trailing blank lines excluded).
    header : RinexObsHeader
    epochs : RinexEpochs
    v3 : bool
        RINEX 3 layout.
    per_sat : int
        Lines per satellite record (1 in RINEX 3).
    """

    data: bytes
    bufp: U8Array
    starts: I64Array
    ends: I64Array
    n_lines: int
    header: RinexObsHeader
    epochs: RinexEpochs
    v3: bool
    per_sat: int

    def text(self, k: int) -> str:
        """Line ``k`` (0-based) as text, without the newline."""
        return self.data[self.starts[k] : self.ends[k]].decode("ascii", "replace")


def scan_obs_text(data: bytes, path: str) -> RinexObsText:
    """Parse the header and scan the epoch lines of a plain RINEX 2/3 observation text.

    Parameters
    ----------
    data : bytes
        Plain RINEX observation text (``\n`` line ends), e.g. from
        :func:`robustrtk.io.rinex_file.read_rinex_bytes`.
    path : str
        File name for messages.

    Returns
    -------
    RinexObsText

    Raises
    ------
    InputError
        Malformed header or epoch line (see :func:`parse_obs_header`,
        :func:`scan_epochs_v3`, :func:`scan_epochs_v2`).
    """
    starts, ends, n_lines = split_lines(data)
    head: list[str] = []
    for k in range(n_lines):
        text = data[starts[k] : ends[k]].decode("ascii", "replace")
        head.append(text)
        label = text[60:].strip()
        first = len(head) == 1 or not any(x.strip() for x in head[:-1])
        if label == "END OF HEADER" or (first and text.strip() and label != "RINEX VERSION / TYPE"):
            break
    h = parse_obs_header(head, path)
    hb = h.n_lines  # first body line (0-based)
    v3 = h.version >= 3.0
    bufp = np.concatenate([np.frombuffer(data, dtype=np.uint8), np.full(4, 32, np.uint8)])
    if v3:
        # blank lines after the last record (never part of a RINEX 3 record)
        while n_lines > hb and not data[starts[n_lines - 1] : ends[n_lines - 1]].strip():
            n_lines -= 1
        ep = scan_epochs_v3(data, bufp, starts, ends, hb, n_lines, path)
        per_sat = 1
    else:
        if not h.obs_types2:
            raise InputError("missing '# / TYPES OF OBSERV' header record", path)
        ep = scan_epochs_v2(data, starts, ends, hb, n_lines, len(h.obs_types2), path)
        per_sat = v2_lines_per_record(len(h.obs_types2))
    return RinexObsText(data, bufp, starts, ends, n_lines, h, ep, v3, per_sat)

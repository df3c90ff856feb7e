"""Vectorised decoding of fixed-width RINEX observation fields into arrays.

The observation records of many epochs are gathered into one byte array and every
``F14.3 I1 I1`` field is converted column-wise (digits times powers of ten), so the cost per
observation is a handful of numpy operations. See :mod:`robustrtk.io.rinex_layout` for where
the fields are.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from numpy.lib.stride_tricks import sliding_window_view

from robustrtk.core import FloatArray, InputError
from robustrtk.io.rinex_layout import U8Array

__all__ = ["digit_field", "f14_to_float", "fix_odd_fields", "gather_lines"]

# Place value of each of the 14 characters of an F14.3 field (point at index 10), in 1e-3.
_W14 = tuple([10.0 ** (12 - i) for i in range(10)] + [0.0, 100.0, 10.0, 1.0])


#: Output bytes gathered per chunk by :func:`gather_lines` (its index array is 8× that).
GATHER_CHUNK_CELLS = 1 << 18


def gather_lines(
    bufp: U8Array, starts: npt.NDArray[np.int64], lens: npt.NDArray[np.int64], width: int
) -> U8Array:
    """Lines ``bufp[starts[i] : starts[i] + lens[i]]`` as rows of a space-padded byte array.

    Parameters
    ----------
    bufp : ndarray of uint8
        The text as bytes (at least one byte).
    starts, lens : ndarray of int64, shape (n,)
        Offset and length of each line.
    width : int
        Columns kept (longer lines are cut).

    Returns
    -------
    ndarray of uint8, shape (n, width)

    Notes
    -----
    A line whose ``width`` bytes all lie inside ``bufp`` is copied as one row of a strided
    view (``bufp[s : s + width]`` for every start ``s``); the few at the very end of the
    text are gathered by index, in chunks of about :data:`GATHER_CHUNK_CELLS` bytes so
    the int64 index array (8 bytes per output byte) stays small. The bytes past each line's
    length are then set to spaces.
    """
    n = starts.shape[0]
    cols = np.arange(width, dtype=np.int64)
    last = bufp.shape[0] - 1
    inside = starts <= bufp.shape[0] - width
    if n and width > 0 and inside.all():
        out = sliding_window_view(bufp, width)[starts]
    else:
        out = np.empty((n, width), np.uint8)
        if width > 0 and inside.any():
            out[inside] = sliding_window_view(bufp, width)[starts[inside]]
        rest = np.flatnonzero(~inside)
        step = max(1, GATHER_CHUNK_CELLS // max(width, 1))
        for a in range(0, rest.size, step):
            rows = rest[a : a + step]
            idx = starts[rows, None] + cols[None, :]
            np.minimum(idx, last, out=idx)
            out[rows] = np.take(bufp, idx)
    np.copyto(out, np.uint8(32), where=cols[None, :] >= lens[:, None])
    return out


def f14_to_float(f: U8Array) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    """Convert ``F14.3`` fields to float.

    Parameters
    ----------
    f : ndarray of uint8, shape (..., 14)
        ASCII characters of each field.

    Returns
    -------
    value : ndarray, shape (...)
        ``sign * sum_i digit_i * w_i / 1000`` with ``w`` the place values of the fixed
        layout (NaN for blank fields). Exactly ``float(text)``: the integer mantissa is below
        2**53 and one correctly rounded division by 1000 follows.
    odd : ndarray of bool, shape (...)
        Non-blank fields that do not follow the ``[-]ddd.ddd`` layout with the point in
        column 11; their ``value`` is meaningless and must be parsed another way.

    Notes
    -----
    The layout test uses counts over the integer part (columns 1-10): with ``s`` spaces,
    ``d`` digits and ``m`` minus signs, a valid field has ``s + d + m = 10``, the spaces
    leading (sum of their column indices ``= s(s-1)/2``), at most one minus, in column
    ``s``; then a point and three digits.
    """
    shape = f.shape[:-1]
    cols = np.ascontiguousarray(np.moveaxis(f, -1, 0)).reshape(14, -1)  # one row per column
    n = cols.shape[1]
    n_sp = np.zeros(n, np.int16)  # spaces in the integer part
    pos_sp = np.zeros(n, np.int16)  # sum of their column indices
    n_dig = np.zeros(n, np.int16)  # digits in the integer part
    n_dec = np.zeros(n, np.int16)  # digits among the decimals
    n_mi = np.zeros(n, np.int16)  # minus signs
    pos_mi = np.zeros(n, np.int16)
    n_blank = np.zeros(n, np.int16)  # spaces anywhere
    mant = np.zeros(n)
    point = cols[10] == 46
    for i in range(14):  # 14 column-wise passes, each vectorised over all fields
        c = cols[i]
        sp = c == 32
        n_blank += sp
        if i == 10:
            continue
        d = c - np.uint8(48)
        isd = d < 10
        d *= isd
        mant += d * _W14[i]
        if i < 10:
            n_dig += isd
            n_sp += sp
            pos_sp += sp * np.int16(i)
            mi = c == 45
            n_mi += mi
            pos_mi += mi * np.int16(i)
        else:
            n_dec += isd
    blank = n_blank == 14
    ok = (
        (n_sp + n_dig + n_mi == 10)
        & (2 * pos_sp == n_sp * (n_sp - 1))
        & ((n_mi == 0) | ((n_mi == 1) & (pos_mi == n_sp)))
        & point
        & (n_dec == 3)
    )
    mant[n_mi > 0] *= -1.0
    value = mant / 1000.0
    value[blank] = np.nan
    return value.reshape(shape), (~ok & ~blank).reshape(shape)


def digit_field(c: U8Array) -> npt.NDArray[np.int8]:
    """One-character integer fields (LLI, SSI): the digit, 0 for blank or anything else.

    Parameters
    ----------
    c : ndarray of uint8
        ASCII characters.

    Returns
    -------
    ndarray of int8, same shape
    """
    isd = (c >= 48) & (c <= 57)
    return np.where(isd, c.astype(np.int16) - 48, 0).astype(np.int8)


def check_digit_field(
    c: U8Array,
    line_of: npt.NDArray[np.int64],
    col_of: npt.NDArray[np.int64],
    path: str,
    what: str,
) -> None:
    """:class:`InputError` at the first character of ``c`` that is neither blank nor a digit.

    Parameters
    ----------
    c : ndarray of uint8, shape (n, m)
        ASCII characters of a one-character field.
    line_of, col_of : ndarray of int64, shape (n, m)
        0-based line and column of each character, for messages.
    path : str
        File name for messages.
    what : str
        Field name for messages (``"LLI"``).
    """
    bad = ~(((c >= 48) & (c <= 57)) | (c == 32) | (c == 0))
    if bad.any():
        r, j = (int(v[0]) for v in np.nonzero(bad))
        ch = bytes([int(c[r, j])]).decode("latin-1")
        raise InputError(
            f"{what} (column {int(col_of[r, j]) + 1}): expected a digit or blank, found {ch!r}",
            path,
            int(line_of[r, j]) + 1,
        )


def fix_odd_fields(
    values: FloatArray,
    odd: npt.NDArray[np.bool_],
    fields: U8Array,
    line_of: npt.NDArray[np.int64],
    col_of: npt.NDArray[np.int64],
    path: str,
    codes: list[str],
) -> None:
    """Parse the few non-standard fields with ``float`` or raise :class:`InputError`.

    Parameters
    ----------
    values : ndarray, shape (n, m)
        Values from :func:`f14_to_float`; the ``odd`` entries are replaced in place.
    odd : ndarray of bool, shape (n, m)
        Fields to parse.
    fields : ndarray of uint8, shape (n, m, 14)
        Characters of the fields.
    line_of, col_of : ndarray of int64, shape (n, m)
        0-based line and column of each field, for messages.
    path : str
        File name for messages.
    codes : list of str
        Observation code of each of the ``m`` columns, for messages.
    """
    for r, j in zip(*np.nonzero(odd), strict=True):
        text = fields[r, j].tobytes().decode("ascii", "replace")
        try:
            values[r, j] = float(text)
            if not math.isfinite(values[r, j]):
                raise ValueError(text)
        except ValueError:
            raise InputError(
                f"observation {codes[j]} (columns {col_of[r, j] + 1}-{col_of[r, j] + 14}): "
                f"expected a number in F14.3, found {text.strip()!r}",
                path,
                int(line_of[r, j]) + 1,
            ) from None

"""Per-epoch, per-double-difference diagnostics CSV (long format): table, writer, reader."""

from __future__ import annotations

import csv
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from robustrtk.core import FloatArray, InputError, IntArray
from robustrtk.io.solution_table import (
    PathLike,
    StrArray,
    float_field,
    fmt_float,
    int_field,
    open_atomic_text,
    read_text_lines,
)

__all__ = ["DIAG_COLUMNS", "DiagTable", "read_diagnostics_csv", "write_diagnostics_csv"]

#: Diagnostics CSV columns (one row per epoch and double difference).
DIAG_COLUMNS = ("time", "dd", "innovation", "residual", "std_residual", "dv", "factor",
                "situation")  # fmt: skip


@dataclass(frozen=True)
class DiagTable:
    """Per-epoch, per-DD diagnostics in long format (one row per epoch x DD).

    Attributes
    ----------
    t_s : ndarray, shape (R,)
    dd : ndarray of str, shape (R,)
        DD label such as ``"PL4-PL6"`` or ``"G05-G12/1C"``.
    innovation, residual, std_residual, dv, factor : ndarray, shape (R,)
        Pre-fit innovation, post-fit residual (same unit as the observation), standardised
        residual, discriminant statistic Δv̄ and robust factor (variance inflation).
    situation : ndarray of int, shape (R,)
        1 normal, 2 down-weighted, 3 rejected (0 unknown).
    """

    t_s: FloatArray
    dd: StrArray
    innovation: FloatArray
    residual: FloatArray
    std_residual: FloatArray
    dv: FloatArray
    factor: FloatArray
    situation: IntArray

    def __len__(self) -> int:
        return int(self.t_s.shape[0])

    def labels(self) -> list[str]:
        """DD labels in order of first appearance."""
        return list(dict.fromkeys(self.dd.tolist()))

    def pivot(self, field: str) -> tuple[FloatArray, list[str], FloatArray]:
        """Wide view of one column.

        Parameters
        ----------
        field : str
            Column name (``"residual"``, ``"dv"``, ``"situation"`` ...).

        Returns
        -------
        epoch_t_s : ndarray, shape (E,)
            Sorted distinct epoch times.
        labels : list of str, length L
        values : ndarray, shape (E, L)
            NaN where a DD is absent at an epoch.
        """
        vals = np.asarray(getattr(self, field), dtype=float)
        epochs, ei = np.unique(self.t_s, return_inverse=True)
        labels = self.labels()
        li = np.array([labels.index(x) for x in self.dd.tolist()], dtype=np.int64)
        out = np.full((epochs.size, len(labels)), np.nan)
        out[ei, li] = vals
        return epochs, labels, out


def _diag_row(row: Sequence[object] | Mapping[str, object]) -> list[object]:
    if isinstance(row, Mapping):
        missing = [k for k in ("time", "dd") if k not in row]
        if missing:
            raise InputError(f"diagnostics row lacks {missing}; expected keys {DIAG_COLUMNS}")
        return [row.get(k, 0 if k == "situation" else math.nan) for k in DIAG_COLUMNS]
    vals = list(row)
    if len(vals) != len(DIAG_COLUMNS):
        raise InputError(f"diagnostics row has {len(vals)} values; expected {DIAG_COLUMNS}")
    return vals


def write_diagnostics_csv(rows: Iterable[Sequence[object] | Mapping[str, object]], path: PathLike) -> None:
    """Write per-epoch, per-DD diagnostics (long format).

    Parameters
    ----------
    rows : iterable of tuple or dict
        Tuples in :data:`DIAG_COLUMNS` order or dicts with those keys (``time`` and ``dd``
        required; numbers default to NaN, ``situation`` to 0).
    path : path-like
    """
    with open_atomic_text(path, newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(DIAG_COLUMNS)
        for row in rows:
            v = _diag_row(row)
            dd = str(v[1])
            if "," in dd or "\n" in dd:
                raise InputError(f"DD label {dd!r} must not contain commas or newlines")
            w.writerow([fmt_float(float(v[0])), dd, *(fmt_float(float(x)) for x in v[2:7]),  # type: ignore[arg-type]
                        str(int(v[7]))])  # type: ignore[call-overload]  # fmt: skip


def read_diagnostics_csv(path: PathLike) -> DiagTable:
    """Read a file written by :func:`write_diagnostics_csv`.

    Raises
    ------
    InputError
        Wrong header, field count or unparsable value (file and line).
    """
    lines = read_text_lines(path)
    if not lines or tuple(h.strip() for h in lines[0].split(",")) != DIAG_COLUMNS:
        raise InputError("header: expected " + ",".join(DIAG_COLUMNS), str(path), 1)
    t, dd, situ = [], [], []
    num: list[list[float]] = []
    for ln, raw in enumerate(lines[1:], start=2):
        if not raw.strip():
            continue
        f = [c.strip() for c in raw.split(",")]
        if len(f) != len(DIAG_COLUMNS):
            raise InputError(f"expected {len(DIAG_COLUMNS)} fields, got {len(f)}", str(path), ln)
        t.append(float_field(f[0], "time", path, ln))
        dd.append(f[1])
        num.append([float_field(f[k], DIAG_COLUMNS[k], path, ln) for k in range(2, 7)])
        situ.append(int_field(f[7], "situation", path, ln))
    R = len(t)
    arr = np.array(num, dtype=float).reshape(R, 5)
    return DiagTable(
        t_s=np.array(t, dtype=float),
        dd=np.array(dd, dtype=str).reshape(R),
        innovation=arr[:, 0].copy(),
        residual=arr[:, 1].copy(),
        std_residual=arr[:, 2].copy(),
        dv=arr[:, 3].copy(),
        factor=arr[:, 4].copy(),
        situation=np.array(situ, dtype=np.int64),
    )

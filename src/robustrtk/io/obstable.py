"""Pseudolite observation table: one row per (time, receiver, transmitter), CSV or Parquet.

Columns (order free, extra columns ignored):

========== ======= ===================================================================
column     unit    meaning
========== ======= ===================================================================
time       s       epoch time tag (float), the table's own clock
receiver   --      receiver name (``base``, ``rover``, ...)
transmitter --     transmitter id (``PL1``, ``PL4``, ...)
code_m     m       pseudorange
phase_cyc  cycles  carrier phase
snr_dbhz   dB-Hz   signal-to-noise ratio
lli        --      integer loss-of-lock indicator; bit 0 = loss of lock / possible slip
========== ======= ===================================================================

``time``, ``receiver`` and ``transmitter`` are required, and at least one of ``code_m`` and
``phase_cyc``. Empty cells and NaN mean "absent" (``lli`` absent = 0). The reader returns one
:class:`~robustrtk.core.ObsBatch` per receiver, system ``"P"``, one signal ``"L1"``; its epochs
are the sorted union of that receiver's time tags and its transmitter axis is the union of all
transmitters of the file in natural order (``PL2`` before ``PL10``), identical for every
receiver so that batches can be differenced cell by cell.
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt

from robustrtk.core import FloatArray, InputError, ObsBatch
from robustrtk.io.atomic import atomic_path
from robustrtk.io.rinex_file import check_regular_file

#: Columns that must be present.
REQUIRED_COLUMNS = ("time", "receiver", "transmitter")
#: Observable columns; at least one of ``code_m`` / ``phase_cyc`` must be present.
VALUE_COLUMNS = ("code_m", "phase_cyc", "snr_dbhz")
#: Column order used by :func:`write_obs_table`.
WRITE_COLUMNS = ("time", "receiver", "transmitter", "code_m", "phase_cyc", "snr_dbhz", "lli")

SIGNAL = "L1"
SYSTEM = "P"

_DIGITS = re.compile(r"(\d+)")


def natural_key(name: str) -> tuple[tuple[int, int | str], ...]:
    """Sort key ordering embedded integers numerically (``PL2`` < ``PL10``)."""
    parts = _DIGITS.split(name)
    return tuple((1, int(p)) if p.isdigit() else (0, p) for p in parts if p != "")


def _fmt(x: float) -> str:
    """Shortest text that reads back to the same float; empty for NaN."""
    return "" if math.isnan(x) else repr(float(x))


# --------------------------------------------------------------------------------------
# reading
# --------------------------------------------------------------------------------------


def read_obs_table(
    path: str | os.PathLike[str], wavelength_m: float | None = None, *, fmt: str | None = None
) -> dict[str, ObsBatch]:
    """Read a pseudolite observation table (``.csv`` or ``.parquet``).

    Parameters
    ----------
    path : path-like
        ``*.csv`` (comma separated, header row) or ``*.parquet``/``*.pq``.
    wavelength_m : float, optional
        Carrier wavelength (m) written into every batch's ``wavelength_m`` (shape (N, 1));
        NaN when not given (the site file carries it).
    fmt : {"csv", "parquet"}, optional
        Table format; default from the extension (``.csv``, ``.parquet``/``.pq``).

    Returns
    -------
    dict of str to ObsBatch
        Keyed by receiver name, in order of first appearance in the file.

    Raises
    ------
    InputError
        Missing file or column, non-numeric value (naming the CSV line or the Parquet
        column), non-integer ``lli``, or a duplicated (time, receiver, transmitter) row.
    """
    p = Path(path)
    if not p.is_file():
        raise InputError("observation table not found", path=str(p))
    suffix = p.suffix.lower() if fmt is None else "." + fmt
    if suffix == ".csv":
        cols = _read_csv_columns(p)
    elif suffix in (".parquet", ".pq"):
        cols = _read_parquet_columns(p)
    elif fmt is not None:
        raise InputError(f"unknown observation table format {fmt!r}: expected csv or parquet", path=str(p))
    else:
        raise InputError(
            f"unknown observation table extension {p.suffix!r}: expected .csv or .parquet",
            path=str(p),
        )
    far = np.flatnonzero(np.abs(cols.time) > MAX_ABS_TIME_S)
    if far.size:
        i = int(far[0])
        raise InputError(
            f"column time: {cols.time[i]!r} at {cols.where(i)}; expected seconds within ±{MAX_ABS_TIME_S:g}",
            path=str(p),
            line=cols.line_of(i),
        )
    return _assemble(cols, p, wavelength_m, fmt=suffix.lstrip("."))


#: Largest accepted ``|time|`` (s) in a table: about 300 years, beyond any clock.
MAX_ABS_TIME_S = 1e10


class _Columns:
    """Parsed columns of a table (all arrays of equal length R)."""

    def __init__(
        self,
        time: FloatArray,
        receiver: list[str],
        transmitter: list[str],
        values: dict[str, FloatArray],
        lli: npt.NDArray[np.int64],
        where: Callable[[int], str],
        line_of: Callable[[int], int | None],
    ):
        self.time = time
        self.receiver = receiver
        self.transmitter = transmitter
        self.values = values
        self.lli = lli
        self.where = where  # row index -> "line N" / "row N"
        self.line_of = line_of  # row index -> 1-based file line (CSV) or None


def _check_header(header: Sequence[str], p: Path, line: int | None) -> None:
    missing = [c for c in REQUIRED_COLUMNS if c not in header]
    if missing:
        raise InputError(
            f"missing required column(s) {', '.join(missing)}; expected columns "
            f"{', '.join(WRITE_COLUMNS)} (header: {', '.join(header)})",
            path=str(p),
            line=line,
        )
    if "code_m" not in header and "phase_cyc" not in header:
        raise InputError(
            "missing observable columns: expected at least one of code_m, phase_cyc",
            path=str(p),
            line=line,
        )


def _decode_utf8(p: Path) -> str:
    """The text of ``p``; :class:`InputError` naming the line of the first non-UTF-8 byte."""
    check_regular_file(str(p))
    data = p.read_bytes()
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise InputError(f"not UTF-8 text (byte {data[exc.start]:#04x})", path=str(p), line=line) from None


def _read_csv_columns(p: Path) -> _Columns:
    with io.StringIO(_decode_utf8(p), newline="") as fh:
        reader = csv.reader(fh)
        try:
            header = next(reader)
        except StopIteration:
            raise InputError("empty file: expected a header row", path=str(p), line=1) from None
        header = [h.strip() for h in header]
        _check_header(header, p, 1)
        dup = {h for h in header if header.count(h) > 1 and h in WRITE_COLUMNS}
        if dup:
            raise InputError(f"duplicated column(s) {', '.join(sorted(dup))}", path=str(p), line=1)
        idx = {h: i for i, h in enumerate(header)}
        ncol = len(header)
        rows: list[list[str]] = []
        lines: list[int] = []
        try:
            for row in reader:
                if not row or (len(row) == 1 and not row[0].strip()):
                    continue  # blank line
                if len(row) != ncol:
                    raise InputError(
                        f"expected {ncol} fields as in the header, got {len(row)}",
                        path=str(p),
                        line=reader.line_num,
                    )
                rows.append(row)
                lines.append(reader.line_num)
        except csv.Error as exc:
            raise InputError(f"malformed CSV: {exc}", path=str(p), line=reader.line_num) from None
    line_arr = np.asarray(lines, dtype=np.int64)

    def where(i: int) -> str:
        return f"line {int(line_arr[i])}"

    def line_of(i: int) -> int | None:
        return int(line_arr[i])

    cols = list(zip(*rows, strict=True)) if rows else [()] * ncol

    def text_col(name: str) -> list[str]:
        return [s.strip() for s in cols[idx[name]]]

    def float_col(name: str, required: bool) -> FloatArray:
        if name not in idx:
            return np.full(len(rows), np.nan)
        raw = cols[idx[name]]
        try:
            arr = np.array([float(s) if s.strip() else math.nan for s in raw], dtype=float)
        except ValueError:
            for i, s in enumerate(raw):
                try:
                    float(s) if s.strip() else None
                except ValueError:
                    raise InputError(
                        f"column {name}: expected a number, got {s!r}",
                        path=str(p),
                        line=int(line_arr[i]),
                    ) from None
            raise  # pragma: no cover - unreachable
        inf = np.flatnonzero(np.isinf(arr))
        if inf.size:
            i = int(inf[0])
            raise InputError(
                f"column {name}: expected a finite number (or an empty field), got {raw[i]!r}",
                path=str(p),
                line=int(line_arr[i]),
            )
        if required:
            bad = np.flatnonzero(~np.isfinite(arr))
            if bad.size:
                i = int(bad[0])
                raise InputError(
                    f"column {name}: expected a finite number, got {raw[i]!r}",
                    path=str(p),
                    line=int(line_arr[i]),
                )
        return arr

    time = float_col("time", required=True)
    receiver = text_col("receiver")
    transmitter = text_col("transmitter")
    for name, col in (("receiver", receiver), ("transmitter", transmitter)):
        for i, s in enumerate(col):
            if not s:
                raise InputError(
                    f"column {name}: expected a non-empty name", path=str(p), line=int(line_arr[i])
                )
    values = {name: float_col(name, required=False) for name in VALUE_COLUMNS}
    lli = np.zeros(len(rows), dtype=np.int64)
    if "lli" in idx:
        raw = cols[idx["lli"]]
        for i, s in enumerate(raw):
            s = s.strip()
            if not s or s == "0":
                continue
            try:
                v = int(s)
            except ValueError:
                try:
                    f = float(s)
                except ValueError:
                    f = math.nan
                if math.isnan(f) and s.lower() == "nan":
                    continue
                if not (math.isfinite(f) and f == int(f)):
                    raise InputError(
                        f"column lli: expected an integer, got {s!r}",
                        path=str(p),
                        line=int(line_arr[i]),
                    ) from None
                v = int(f)
            if not 0 <= v <= 127:
                raise InputError(
                    f"column lli: expected an integer in 0..127, got {v}",
                    path=str(p),
                    line=int(line_arr[i]),
                )
            lli[i] = v
    return _Columns(time, receiver, transmitter, values, lli, where, line_of)


def _read_parquet_columns(p: Path) -> _Columns:
    import pyarrow as pa

    try:
        return _parquet_columns(p)
    except InputError:
        raise
    except (pa.ArrowException, UnicodeDecodeError, ValueError, TypeError, OSError) as exc:
        what = "; ".join(ln.strip() for ln in str(exc).splitlines() if ln.strip())
        raise InputError(f"cannot read Parquet file: {type(exc).__name__}: {what}", path=str(p)) from None


def _parquet_columns(p: Path) -> _Columns:
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.parquet as pq

    try:
        table = pq.read_table(p)
    except Exception as exc:  # pyarrow raises several types for corrupt files
        what = "; ".join(ln.strip() for ln in str(exc).splitlines() if ln.strip())
        raise InputError(f"cannot read Parquet file: {what}", path=str(p)) from None
    header = list(table.column_names)
    _check_header(header, p, None)
    n = table.num_rows

    def where(i: int) -> str:
        return f"row {i + 1}"

    def line_of(i: int) -> int | None:
        return None

    def float_col(name: str, required: bool) -> FloatArray:
        if name not in header:
            return np.full(n, np.nan)
        col = table.column(name)
        t = col.type
        if not (pa.types.is_integer(t) or pa.types.is_floating(t) or pa.types.is_null(t)):
            raise InputError(f"column {name}: expected a numeric column, got type {t}", path=str(p))
        if pa.types.is_null(t):
            arr = np.full(n, np.nan)
        else:
            arr = pc.cast(col, pa.float64()).to_numpy(zero_copy_only=False).astype(float)
            arr = np.where(pc.is_null(col).to_numpy(zero_copy_only=False), np.nan, arr)
        inf = np.flatnonzero(np.isinf(arr))
        if inf.size:
            raise InputError(
                f"column {name}: expected a finite number (or null), row {int(inf[0]) + 1} is infinite",
                path=str(p),
            )
        if required:
            bad = np.flatnonzero(~np.isfinite(arr))
            if bad.size:
                raise InputError(
                    f"column {name}: expected finite numbers, row {int(bad[0]) + 1} is missing or not finite",
                    path=str(p),
                )
        return arr

    def text_col(name: str) -> list[str]:
        col = table.column(name)
        if not (
            pa.types.is_string(col.type)
            or pa.types.is_large_string(col.type)
            or pa.types.is_dictionary(col.type)
            or pa.types.is_integer(col.type)
        ):
            raise InputError(f"column {name}: expected a string column, got type {col.type}", path=str(p))
        vals = pc.cast(col, pa.string()).to_pylist()
        out = []
        for i, v in enumerate(vals):
            if v is None or not str(v).strip():
                raise InputError(f"column {name}: expected a non-empty name at row {i + 1}", path=str(p))
            out.append(str(v).strip())
        return out

    time = float_col("time", required=True)
    receiver = text_col("receiver")
    transmitter = text_col("transmitter")
    values = {name: float_col(name, required=False) for name in VALUE_COLUMNS}
    lli = np.zeros(n, dtype=np.int64)
    if "lli" in header:
        f = float_col("lli", required=False)
        ok = np.isnan(f) | ((f == np.round(f)) & (f >= 0) & (f <= 127))
        if not ok.all():
            i = int(np.flatnonzero(~ok)[0])
            raise InputError(
                f"column lli: expected integers in 0..127, row {i + 1} has {f[i]!r}", path=str(p)
            )
        lli = np.where(np.isnan(f), 0, f).astype(np.int64)
    return _Columns(time, receiver, transmitter, values, lli, where, line_of)


def _assemble(c: _Columns, p: Path, wavelength_m: float | None, fmt: str) -> dict[str, ObsBatch]:
    """Scatter rows into per-receiver ``(T, N, 1)`` arrays."""
    n = c.time.shape[0]
    rx_names = list(dict.fromkeys(c.receiver))
    tx_names = sorted(set(c.transmitter), key=natural_key)
    rx_code = {r: i for i, r in enumerate(rx_names)}
    tx_code = {t: i for i, t in enumerate(tx_names)}
    rx_idx = np.fromiter((rx_code[r] for r in c.receiver), dtype=np.int64, count=n)
    tx_idx = np.fromiter((tx_code[t] for t in c.transmitter), dtype=np.int64, count=n)
    times, t_idx = np.unique(c.time, return_inverse=True)
    n_t, n_tx = times.shape[0], len(tx_names)

    # duplicated (time, receiver, transmitter)
    key = (rx_idx * max(n_t, 1) + t_idx) * max(n_tx, 1) + tx_idx
    order = np.argsort(key, kind="stable")
    sk = key[order]
    same = np.flatnonzero(sk[1:] == sk[:-1])
    if same.size:
        # the duplicate that appears earliest in the file (second occurrence)
        later = order[same + 1]
        first = order[same]
        j = int(np.argmin(later))
        i_dup, i_first = int(later[j]), int(first[j])
        raise InputError(
            f"duplicated row (time={c.time[i_dup]!r}, receiver={c.receiver[i_dup]!r}, "
            f"transmitter={c.transmitter[i_dup]!r}); first at {c.where(i_first)}: expected one "
            "row per (time, receiver, transmitter)",
            path=str(p),
            line=c.line_of(i_dup),
        )

    wl = np.full((n_tx, 1), np.nan if wavelength_m is None else float(wavelength_m))
    out: dict[str, ObsBatch] = {}
    for r, name in enumerate(rx_names):
        sel = np.flatnonzero(rx_idx == r)
        ep_global = np.unique(t_idx[sel])
        local = np.searchsorted(ep_global, t_idx[sel])
        T = ep_global.shape[0]
        arrays: dict[str, FloatArray] = {}
        for col in VALUE_COLUMNS:
            a = np.full((T, n_tx, 1), np.nan)
            a[local, tx_idx[sel], 0] = c.values[col][sel]
            arrays[col] = a
        lli = np.zeros((T, n_tx, 1), dtype=np.int8)
        lli[local, tx_idx[sel], 0] = c.lli[sel].astype(np.int8)
        out[name] = ObsBatch(
            t_s=times[ep_global].astype(float),
            tx_ids=tuple(tx_names),
            system=(SYSTEM,) * n_tx,
            signals=(SIGNAL,),
            code_m=arrays["code_m"],
            phase_cyc=arrays["phase_cyc"],
            doppler_hz=np.full((T, n_tx, 1), np.nan),
            cn0_dbhz=arrays["snr_dbhz"],
            lli=lli,
            wavelength_m=wl.copy(),
            receiver=name,
            approx_pos_m=None,
            meta={"path": str(p), "format": fmt},
        )
    return out


# --------------------------------------------------------------------------------------
# writing
# --------------------------------------------------------------------------------------


def _rows(batches: dict[str, ObsBatch]) -> dict[str, np.ndarray]:
    """Flatten batches into column arrays (rows where some observable is present)."""
    time, rx, tx, code, phase, snr, lli = [], [], [], [], [], [], []
    for name, b in batches.items():
        if len(b.signals) != 1:
            raise ValueError(f"receiver {name}: the observation table holds one signal, got {b.signals}")
        present = ~(np.isnan(b.code_m[..., 0]) & np.isnan(b.phase_cyc[..., 0]) & np.isnan(b.cn0_dbhz[..., 0]))
        ti, ni = np.nonzero(present)  # row-major: time, then transmitter
        time.append(b.t_s[ti])
        rx.append(np.full(ti.shape[0], name, dtype=object))
        tx.append(np.asarray(b.tx_ids, dtype=object)[ni])
        code.append(b.code_m[ti, ni, 0])
        phase.append(b.phase_cyc[ti, ni, 0])
        snr.append(b.cn0_dbhz[ti, ni, 0])
        lli.append(b.lli[ti, ni, 0].astype(np.int64))
    if not time:
        return {c: np.zeros(0) for c in WRITE_COLUMNS}
    return {
        "time": np.concatenate(time),
        "receiver": np.concatenate(rx),
        "transmitter": np.concatenate(tx),
        "code_m": np.concatenate(code),
        "phase_cyc": np.concatenate(phase),
        "snr_dbhz": np.concatenate(snr),
        "lli": np.concatenate(lli),
    }


def write_obs_table(batches: dict[str, ObsBatch], path: str | os.PathLike[str]) -> Path:
    """Write batches as an observation table, CSV or Parquet by the file extension.

    Rows are written receiver by receiver, epoch by epoch, transmitter by transmitter; cells
    where code, phase and SNR are all absent are skipped. Floats are written with the
    shortest text that reads back exactly. The file is written to a temporary file in the
    same directory and moved into place, so a reader never sees a half-written table.

    Parameters
    ----------
    batches : dict of str to ObsBatch
        One single-signal batch per receiver (the key is the receiver name).
    path : path-like
        Destination ``*.csv`` or ``*.parquet``.

    Returns
    -------
    Path
        The written path.
    """
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in (".csv", ".parquet", ".pq"):
        raise InputError(
            f"unknown observation table extension {p.suffix!r}: expected .csv or .parquet",
            path=str(p),
        )
    cols = _rows(batches)
    p.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(p) as tmp:
        if suffix == ".csv":
            with open(tmp, "w", newline="", encoding="utf-8") as fh:
                w = csv.writer(fh, lineterminator="\n")
                w.writerow(WRITE_COLUMNS)
                w.writerows(
                    zip(
                        map(_fmt, cols["time"].tolist()),
                        cols["receiver"].tolist(),
                        cols["transmitter"].tolist(),
                        map(_fmt, cols["code_m"].tolist()),
                        map(_fmt, cols["phase_cyc"].tolist()),
                        map(_fmt, cols["snr_dbhz"].tolist()),
                        map(str, cols["lli"].tolist()),
                        strict=True,
                    )
                )
        else:
            import pyarrow as pa
            import pyarrow.parquet as pq

            table = pa.table(
                {
                    "time": pa.array(cols["time"], pa.float64()),
                    "receiver": pa.array(cols["receiver"], pa.string()),
                    "transmitter": pa.array(cols["transmitter"], pa.string()),
                    "code_m": pa.array(cols["code_m"], pa.float64()),
                    "phase_cyc": pa.array(cols["phase_cyc"], pa.float64()),
                    "snr_dbhz": pa.array(cols["snr_dbhz"], pa.float64()),
                    "lli": pa.array(cols["lli"], pa.int8()),
                }
            )
            pq.write_table(table, tmp)
    return p

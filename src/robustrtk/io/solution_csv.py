"""Solution CSV (full float precision, any frame): writer and reader."""

from __future__ import annotations

import csv
from collections.abc import Iterable

import numpy as np

from robustrtk.core import STATUSES, InputError, Solution
from robustrtk.io.solution_table import (
    PathLike,
    SolutionTable,
    check_status,
    float_field,
    fmt_float,
    int_field,
    open_atomic_text,
    read_text_lines,
)

__all__ = ["CSV_COLUMNS", "CSV_VEL_COLUMNS", "read_solution_csv", "write_solution_csv"]

#: CSV solution columns (``vx,vy,vz`` appended when velocities are present).
CSV_COLUMNS = ("time", "x", "y", "z", "sx", "sy", "sz", "status", "n_used", "ratio",
               "n_fixed", "n_amb")  # fmt: skip
CSV_VEL_COLUMNS = ("vx", "vy", "vz")


def write_solution_csv(solutions: Iterable[Solution], path: PathLike) -> None:
    """Write solutions as CSV (all epochs, full float precision).

    Columns: ``time,x,y,z,sx,sy,sz,status,n_used,ratio,n_fixed,n_amb`` plus ``vx,vy,vz``
    when any solution has a velocity (``nan`` where one does not). ``sx, sy, sz`` are the
    square roots of the covariance diagonal (m).
    """
    table = SolutionTable.from_solutions(solutions)
    for s in table.status.tolist():
        check_status(s)
    cols = CSV_COLUMNS + (CSV_VEL_COLUMNS if table.vel_m_s is not None else ())
    with open_atomic_text(path, newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(cols)
        for i in range(len(table)):
            row = [fmt_float(table.t_s[i]), *map(fmt_float, table.pos_m[i]), *map(fmt_float, table.std_m[i]),
                   str(table.status[i]), str(int(table.n_used[i])), fmt_float(table.ratio[i]),
                   str(int(table.n_fixed[i])), str(int(table.n_amb[i]))]  # fmt: skip
            if table.vel_m_s is not None:
                row += [fmt_float(v) for v in table.vel_m_s[i]]
            w.writerow(row)


def read_solution_csv(path: PathLike) -> SolutionTable:
    """Read a CSV written by :func:`write_solution_csv`.

    Raises
    ------
    InputError
        Missing file, wrong header, wrong field count, unparsable number or unknown
        status (with file and line).
    """
    lines = read_text_lines(path)
    if not lines:
        raise InputError("empty file; expected a header line " + ",".join(CSV_COLUMNS), str(path))
    rows = list(csv.reader(lines))
    header = tuple(h.strip() for h in rows[0])
    if header == CSV_COLUMNS:
        has_vel = False
    elif header == CSV_COLUMNS + CSV_VEL_COLUMNS:
        has_vel = True
    else:
        raise InputError("header: expected " + ",".join(CSV_COLUMNS) + "[,vx,vy,vz]", str(path), 1)
    ncol = len(header)
    t, pos, std, status, n_used, ratio, n_fixed, n_amb, vel = ([] for _ in range(9))
    for ln, row in enumerate(rows[1:], start=2):
        if not row or all(not c.strip() for c in row):
            continue
        if len(row) != ncol:
            raise InputError(f"expected {ncol} fields, got {len(row)}", str(path), ln)
        f = [c.strip() for c in row]
        t.append(float_field(f[0], "time", path, ln))
        pos.append([float_field(f[k], CSV_COLUMNS[k], path, ln) for k in (1, 2, 3)])
        std.append([float_field(f[k], CSV_COLUMNS[k], path, ln) for k in (4, 5, 6)])
        if f[7] not in STATUSES:
            raise InputError(f"field 'status': expected one of {STATUSES}, got {f[7]!r}",
                             str(path), ln)  # fmt: skip
        status.append(f[7])
        n_used.append(int_field(f[8], "n_used", path, ln))
        ratio.append(float_field(f[9], "ratio", path, ln))
        n_fixed.append(int_field(f[10], "n_fixed", path, ln))
        n_amb.append(int_field(f[11], "n_amb", path, ln))
        if has_vel:
            vel.append([float_field(f[k], header[k], path, ln) for k in (12, 13, 14)])
    T = len(t)
    return SolutionTable(
        t_s=np.array(t, dtype=float),
        pos_m=np.array(pos, dtype=float).reshape(T, 3),
        std_m=np.array(std, dtype=float).reshape(T, 3),
        status=np.array(status, dtype=str).reshape(T),
        n_used=np.array(n_used, dtype=np.int64),
        ratio=np.array(ratio, dtype=float),
        n_fixed=np.array(n_fixed, dtype=np.int64),
        n_amb=np.array(n_amb, dtype=np.int64),
        vel_m_s=np.array(vel, dtype=float).reshape(T, 3) if has_vel else None,
    )

"""Solution files: CSV, RTKLIB ``.pos``, NMEA GGA, and the per-DD diagnostics CSV.

Writers take a sequence of :class:`robustrtk.core.Solution`; readers return a
:class:`SolutionTable` (arrays). Every writer writes a temporary file in the target's
directory and renames it over the target (:func:`os.replace`), so an error never leaves a
truncated or missing output. Readers raise :class:`robustrtk.core.InputError` naming the
file, the line and what was expected.

Times: ``t_s`` is GPS time in seconds since 1980-01-06 for GNSS solutions, the table's own
seconds for pseudolite solutions. RTKLIB ``.pos`` and NMEA carry geodetic coordinates and
calendar times, so only ECEF (GNSS) solutions can be written to them: a solution whose
position is not within 100 km of the WGS84 ellipsoid surface (a local pseudolite frame)
raises :class:`InputError` instead of producing a file that plots on the wrong continent.
Use the CSV writer for local frames.

Status mapping (RTKLIB ``Q`` / NMEA GGA quality):

=========  ===  ====
status     Q    GGA
=========  ===  ====
fixed      1    4
partial    1    4
float      2    5
dgnss      4    2
code       4    2
single     5    1
none       (epoch not written)
=========  ===  ====

Reading ``Q``: 1 fixed, 2 float, 3 (SBAS) dgnss, 4 dgnss, 5 single, 6 (PPP) float.
"""

from __future__ import annotations

import contextlib
import csv
import math
import os
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import IO

import numpy as np
import numpy.typing as npt

from robustrtk.core import STATUSES, FloatArray, InputError, IntArray, Solution
from robustrtk.geometry.frames import ecef2geodetic, geodetic2ecef
from robustrtk.io.atomic import atomic_path
from robustrtk.timeutil import calendar_from_gpst, gpst2utc, gpst_from_calendar, utc2gpst

PathLike = str | os.PathLike[str]
StrArray = npt.NDArray[np.str_]

#: CSV solution columns (``vx,vy,vz`` appended when velocities are present).
CSV_COLUMNS = ("time", "x", "y", "z", "sx", "sy", "sz", "status", "n_used", "ratio",
               "n_fixed", "n_amb")  # fmt: skip
CSV_VEL_COLUMNS = ("vx", "vy", "vz")
#: Diagnostics CSV columns (one row per epoch and double difference).
DIAG_COLUMNS = ("time", "dd", "innovation", "residual", "std_residual", "dv", "factor",
                "situation")  # fmt: skip

_Q_OF_STATUS = {"fixed": 1, "partial": 1, "float": 2, "dgnss": 4, "code": 4, "single": 5}
_STATUS_OF_Q = {1: "fixed", 2: "float", 3: "dgnss", 4: "dgnss", 5: "single", 6: "float"}
_GGA_OF_STATUS = {"fixed": 4, "partial": 4, "float": 5, "dgnss": 2, "code": 2, "single": 1}
_WGS84_A_M = 6_378_137.0
_WGS84_B_M = 6_356_752.314245
_SURFACE_TOL_M = 100_000.0


# --------------------------------------------------------------------------- tables
@dataclass(frozen=True)
class SolutionTable:
    """Solutions of T epochs as arrays.

    Attributes
    ----------
    t_s : ndarray, shape (T,)
        Epoch times (s).
    pos_m : ndarray, shape (T, 3)
        Positions (ECEF for GNSS, local for pseudolites), m.
    std_m : ndarray, shape (T, 3)
        Standard deviations of the position components in the same frame (m); NaN if
        unknown.
    status : ndarray of str, shape (T,)
        Values of :data:`robustrtk.core.STATUSES`.
    n_used : ndarray of int, shape (T,)
        Observations used (RTKLIB ``ns``: satellites).
    ratio : ndarray, shape (T,)
        Ratio test value (NaN or 0 where none).
    n_fixed, n_amb : ndarray of int, shape (T,)
        Fixed ambiguities and ambiguities in the state; -1 when the file does not say
        (RTKLIB ``.pos``).
    vel_m_s : ndarray, shape (T, 3), or None
        Velocities (NaN rows where absent).
    """

    t_s: FloatArray
    pos_m: FloatArray
    std_m: FloatArray
    status: StrArray
    n_used: IntArray
    ratio: FloatArray
    n_fixed: IntArray
    n_amb: IntArray
    vel_m_s: FloatArray | None = None

    def __len__(self) -> int:
        return int(self.t_s.shape[0])

    @classmethod
    def from_solutions(cls, solutions: Iterable[Solution]) -> SolutionTable:
        """Stack :class:`Solution` records (standard deviations from ``cov_m2``)."""
        sols = list(solutions)
        T = len(sols)
        t = np.array([s.t_s for s in sols], dtype=float)
        pos = np.array([np.asarray(s.pos_m, float) for s in sols]).reshape(T, 3)
        cov = np.array([np.asarray(s.cov_m2, float) for s in sols]).reshape(T, 3, 3)
        with np.errstate(invalid="ignore"):
            std = np.sqrt(np.diagonal(cov, axis1=1, axis2=2))
        vel = None
        if any(s.vel_m_s is not None for s in sols):
            vel = np.array(
                [
                    np.full(3, np.nan) if s.vel_m_s is None else np.asarray(s.vel_m_s, float) for s in sols
                ]  # fmt: skip
            ).reshape(T, 3)
        return cls(
            t_s=t,
            pos_m=pos,
            std_m=std,
            status=np.array([s.status for s in sols], dtype=str).reshape(T),
            n_used=np.array([s.n_used for s in sols], dtype=np.int64).reshape(T),
            ratio=np.array([s.ratio for s in sols], dtype=float).reshape(T),
            n_fixed=np.array([s.n_fixed for s in sols], dtype=np.int64).reshape(T),
            n_amb=np.array([s.n_amb for s in sols], dtype=np.int64).reshape(T),
            vel_m_s=vel,
        )


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


# ------------------------------------------------------------------- file helpers
@contextlib.contextmanager
def _atomic_open(path: PathLike, newline: str | None = None) -> Iterator[IO[str]]:
    """Open a temporary file beside ``path`` and rename it over ``path`` on success."""
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8", newline=newline) as fh:
        yield fh


def _read_lines(path: PathLike) -> list[str]:
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            return fh.read().splitlines()
    except OSError as exc:
        raise InputError(f"cannot read file ({exc.strerror})", path=str(path)) from exc


def _check_status(status: str) -> str:
    if status not in STATUSES:
        raise InputError(f"unknown solution status {status!r}; expected one of {STATUSES}")
    return status


def _looks_ecef(pos_m: FloatArray) -> bool:
    """True if every finite row lies within 100 km of the WGS84 surface."""
    r = np.linalg.norm(pos_m, axis=-1)
    ok = np.isfinite(r)
    return bool(np.all((r[ok] > _WGS84_B_M - _SURFACE_TOL_M) & (r[ok] < _WGS84_A_M + _SURFACE_TOL_M)))


def _enu_rotations(lat_rad: FloatArray, lon_rad: FloatArray) -> FloatArray:
    """Rotations ``R`` of shape (T, 3, 3) with ``enu = R @ d_ecef`` at each point."""
    sl, cl = np.sin(lat_rad), np.cos(lat_rad)
    so, co = np.sin(lon_rad), np.cos(lon_rad)
    z = np.zeros_like(sl)
    return np.stack(
        [
            np.stack([-so, co, z], axis=-1),
            np.stack([-sl * co, -sl * so, cl], axis=-1),
            np.stack([cl * co, cl * so, sl], axis=-1),
        ],
        axis=-2,
    )


def _signed_sqrt(v: FloatArray) -> FloatArray:
    """RTKLIB's convention for off-diagonal terms: ``sign(c) sqrt(|c|)``."""
    return np.sign(v) * np.sqrt(np.abs(v))


def _signed_square(v: FloatArray) -> FloatArray:
    return np.sign(v) * v * v


def _writable(solutions: Iterable[Solution]) -> list[Solution]:
    sols = [s for s in solutions if s.status != "none" and np.all(np.isfinite(s.pos_m))]
    for s in sols:
        _check_status(s.status)
    return sols


# ------------------------------------------------------------------------------ CSV
def _fmt(v: float) -> str:
    return repr(float(v))


def write_solution_csv(solutions: Iterable[Solution], path: PathLike) -> None:
    """Write solutions as CSV (all epochs, full float precision).

    Columns: ``time,x,y,z,sx,sy,sz,status,n_used,ratio,n_fixed,n_amb`` plus ``vx,vy,vz``
    when any solution has a velocity (``nan`` where one does not). ``sx, sy, sz`` are the
    square roots of the covariance diagonal (m).
    """
    table = SolutionTable.from_solutions(solutions)
    for s in table.status.tolist():
        _check_status(s)
    cols = CSV_COLUMNS + (CSV_VEL_COLUMNS if table.vel_m_s is not None else ())
    with _atomic_open(path, newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(cols)
        for i in range(len(table)):
            row = [_fmt(table.t_s[i]), *map(_fmt, table.pos_m[i]), *map(_fmt, table.std_m[i]),
                   str(table.status[i]), str(int(table.n_used[i])), _fmt(table.ratio[i]),
                   str(int(table.n_fixed[i])), str(int(table.n_amb[i]))]  # fmt: skip
            if table.vel_m_s is not None:
                row += [_fmt(v) for v in table.vel_m_s[i]]
            w.writerow(row)


def _float_field(text: str, name: str, path: PathLike, line: int) -> float:
    try:
        return float(text)
    except ValueError:
        raise InputError(f"field {name!r}: expected a number, got {text!r}", str(path), line) from None


def _int_field(text: str, name: str, path: PathLike, line: int) -> int:
    try:
        return int(text)
    except ValueError:
        raise InputError(f"field {name!r}: expected an integer, got {text!r}", str(path), line) from None


def read_solution_csv(path: PathLike) -> SolutionTable:
    """Read a CSV written by :func:`write_solution_csv`.

    Raises
    ------
    InputError
        Missing file, wrong header, wrong field count, unparsable number or unknown
        status (with file and line).
    """
    lines = _read_lines(path)
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
        t.append(_float_field(f[0], "time", path, ln))
        pos.append([_float_field(f[k], CSV_COLUMNS[k], path, ln) for k in (1, 2, 3)])
        std.append([_float_field(f[k], CSV_COLUMNS[k], path, ln) for k in (4, 5, 6)])
        if f[7] not in STATUSES:
            raise InputError(f"field 'status': expected one of {STATUSES}, got {f[7]!r}",
                             str(path), ln)  # fmt: skip
        status.append(f[7])
        n_used.append(_int_field(f[8], "n_used", path, ln))
        ratio.append(_float_field(f[9], "ratio", path, ln))
        n_fixed.append(_int_field(f[10], "n_fixed", path, ln))
        n_amb.append(_int_field(f[11], "n_amb", path, ln))
        if has_vel:
            vel.append([_float_field(f[k], header[k], path, ln) for k in (12, 13, 14)])
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


# ------------------------------------------------------------------------- RTKLIB .pos
def _gpst_text(t_s: float) -> str:
    """``yyyy/mm/dd hh:mm:ss.sss`` of GPST ``t_s`` (rounded to the millisecond)."""
    ms = int(round(t_s * 1000.0))
    sec, frac = divmod(ms, 1000)
    y, mo, d, h, mi, s = calendar_from_gpst(float(sec))
    return f"{y:04d}/{mo:02d}/{d:02d} {h:02d}:{mi:02d}:{int(round(s)):02d}.{frac:03d}"


_POS_LLH_HEAD = (
    "% (lat/lon/height=WGS84/ellipsoidal,Q=1:fix,2:float,3:sbas,4:dgps,5:single,6:ppp,ns=# of satellites)",
    "%  GPST                  latitude(deg) longitude(deg)  height(m)   Q  ns   sdn(m)   sde(m)"
    "   sdu(m)  sdne(m)  sdeu(m)  sdun(m) age(s)  ratio",
)
_POS_XYZ_HEAD = (
    "% (x/y/z-ecef=WGS84,Q=1:fix,2:float,3:sbas,4:dgps,5:single,6:ppp,ns=# of satellites)",
    "%  GPST                      x-ecef(m)      y-ecef(m)      z-ecef(m)   Q  ns   sdx(m)"
    "   sdy(m)   sdz(m)  sdxy(m)  sdyz(m)  sdzx(m) age(s)  ratio",
)


def write_pos(
    solutions: Iterable[Solution],
    path: PathLike,
    *,
    frame: str = "llh",
    header_lines: Sequence[str] = (),
) -> None:
    """Write an RTKLIB ``.pos`` solution file (readable by rtkplot and :func:`read_pos`).

    Parameters
    ----------
    solutions : iterable of Solution
        ECEF (GNSS) solutions; ``t_s`` in GPST seconds since 1980-01-06. Epochs with
        status ``"none"`` or a non-finite position are skipped (RTKLIB writes no line for
        them).
    path : path-like
    frame : {"llh", "ecef"}
        ``"llh"``: latitude/longitude (deg, 9 decimals), ellipsoidal height (m) and the
        covariance rotated to ENU (``sdn sde sdu sdne sdeu sdun``); ``"ecef"``: x/y/z (m,
        4 decimals) and ``sdx sdy sdz sdxy sdyz sdzx``. Off-diagonal terms are written as
        ``sign(c) sqrt(|c|)`` as RTKLIB does.
    header_lines : sequence of str
        Extra header lines (each written after ``"% "``).

    Notes
    -----
    ``ns`` carries ``n_used``; ``age`` is written as 0.00 (not tracked by
    :class:`Solution`); ``ratio`` is capped at 999.9 and NaN written as 0.0.

    Raises
    ------
    InputError
        Unknown ``frame`` or status, or positions not near the Earth's surface (local
        pseudolite frame; write CSV instead).
    """
    if frame not in ("llh", "ecef"):
        raise InputError(f"frame: expected 'llh' or 'ecef', got {frame!r}", str(path))
    sols = _writable(solutions)
    if sols:
        table = SolutionTable.from_solutions(sols)
        if not _looks_ecef(table.pos_m):
            raise InputError(
                "positions are not ECEF near the Earth's surface (local frame?); "
                ".pos needs geodetic positions, write CSV for local frames",
                str(path),
            )
        cov = np.array([np.asarray(s.cov_m2, float) for s in sols]).reshape(-1, 3, 3)
        lat, lon, h = ecef2geodetic(table.pos_m)
    with _atomic_open(path) as fh:
        fh.write("% program   : robustrtk\n")
        for hl in header_lines:
            fh.write(f"% {hl}\n".replace("\r", ""))
        fh.write("%\n")
        head = _POS_LLH_HEAD if frame == "llh" else _POS_XYZ_HEAD
        fh.write("\n".join(head) + "\n")
        if not sols:
            return
        if frame == "llh":
            rot = _enu_rotations(lat, lon)
            c = rot @ cov @ np.swapaxes(rot, 1, 2)  # ENU covariance
            sd = np.stack(
                [np.sqrt(np.abs(c[:, 1, 1])), np.sqrt(np.abs(c[:, 0, 0])),
                 np.sqrt(np.abs(c[:, 2, 2])), _signed_sqrt(c[:, 1, 0]),
                 _signed_sqrt(c[:, 0, 2]), _signed_sqrt(c[:, 2, 1])], axis=1
            )  # fmt: skip
            coords = [
                f"{np.degrees(lat[i]):14.9f} {np.degrees(lon[i]):14.9f} {h[i]:10.4f}"
                for i in range(len(sols))
            ]
        else:
            sd = np.stack(
                [np.sqrt(np.abs(cov[:, 0, 0])), np.sqrt(np.abs(cov[:, 1, 1])),
                 np.sqrt(np.abs(cov[:, 2, 2])), _signed_sqrt(cov[:, 0, 1]),
                 _signed_sqrt(cov[:, 1, 2]), _signed_sqrt(cov[:, 2, 0])], axis=1
            )  # fmt: skip
            p = table.pos_m
            coords = [f"{p[i, 0]:14.4f} {p[i, 1]:14.4f} {p[i, 2]:14.4f}" for i in range(len(sols))]
        sd = np.where(np.isfinite(sd), sd, 0.0)
        for i, s in enumerate(sols):
            ratio = s.ratio if math.isfinite(s.ratio) else 0.0
            sds = " ".join(f"{v:8.4f}" for v in sd[i])
            fh.write(
                f"{_gpst_text(s.t_s)} {coords[i]} {_Q_OF_STATUS[s.status]:3d} "
                f"{min(int(s.n_used), 999):3d} {sds} {0.0:6.2f} {min(ratio, 999.9):6.1f}\n"
            )


def _parse_pos_time(tokens: list[str], path: PathLike, line: int) -> float:
    """Seconds (in the file's scale) from ``yyyy/mm/dd hh:mm:ss.sss`` or ``week tow``."""
    try:
        if "/" in tokens[0]:
            y, mo, d = (int(v) for v in tokens[0].split("/"))
            hh, mm, ss = tokens[1].split(":")
            return gpst_from_calendar(y, mo, d, int(hh), int(mm), float(ss))
        return float(tokens[0]) * 604_800.0 + float(tokens[1])
    except (ValueError, IndexError):
        raise InputError(
            f"time: expected 'yyyy/mm/dd hh:mm:ss.sss' or 'week tow', got {' '.join(tokens[:2])!r}",
            str(path),
            line,
        ) from None


def read_pos(path: PathLike) -> SolutionTable:
    """Read an RTKLIB ``.pos`` file in llh (degrees) or xyz form.

    Geodetic positions are converted to ECEF and their ENU covariance
    (``sdn sde sdu sdne sdeu sdun`` with RTKLIB's signed-square-root off-diagonals) is
    rotated to ECEF for ``std_m``. Times may be GPST or UTC (converted to GPST with the
    leap-second table), as calendar dates or ``week tow``. ``n_used`` is ``ns``;
    ``n_fixed`` and ``n_amb`` are -1 (not in the format). Extra trailing columns (velocity
    output) are ignored.

    Raises
    ------
    InputError
        No column header, unsupported form (dms angles, ENU baselines, JST), or a data line
        with too few or unparsable fields.
    """
    lines = _read_lines(path)
    form: str | None = None
    timesys = "GPST"
    t, a, b, c, q, ns, sd, ratio = ([] for _ in range(8))
    for ln, raw in enumerate(lines, start=1):
        text = raw.strip()
        if not text:
            continue
        if text.startswith("%"):
            body = text[1:].split()
            if body and body[0] in ("GPST", "UTC", "JST"):
                timesys = body[0]
                if "latitude(deg)" in body:
                    form = "llh"
                elif "x-ecef(m)" in body:
                    form = "xyz"
                else:
                    raise InputError(
                        "column header: only latitude(deg)/longitude(deg)/height(m) or "
                        "x-ecef(m)/y-ecef(m)/z-ecef(m) forms are supported",
                        str(path),
                        ln,
                    )
                if timesys == "JST":
                    raise InputError("time system JST not supported; expected GPST or UTC",
                                     str(path), ln)  # fmt: skip
            continue
        if form is None:
            raise InputError("data before the '%  GPST ...' column header line", str(path), ln)
        tok = text.split()
        if len(tok) < 15:
            raise InputError(f"expected at least 15 fields, got {len(tok)}", str(path), ln)
        t.append(_parse_pos_time(tok, path, ln))
        try:
            vals = [float(v) for v in tok[2:15]]
        except ValueError:
            raise InputError("expected numbers after the time", str(path), ln) from None
        a.append(vals[0])
        b.append(vals[1])
        c.append(vals[2])
        q.append(int(vals[3]))
        ns.append(int(vals[4]))
        sd.append(vals[5:11])
        ratio.append(vals[12])
        if q[-1] not in _STATUS_OF_Q:
            raise InputError(f"Q: expected 1..6, got {tok[5]}", str(path), ln)
    if form is None:
        raise InputError("no '%  GPST ...' column header line found", str(path))
    T = len(t)
    t_arr = np.array(t, dtype=float)
    if timesys == "UTC":
        t_arr = utc2gpst(t_arr)
    sda = np.array(sd, dtype=float).reshape(T, 6)
    if form == "llh":
        lat = np.radians(np.array(a, dtype=float))
        lon = np.radians(np.array(b, dtype=float))
        pos = geodetic2ecef(lat, lon, np.array(c, dtype=float)).reshape(T, 3)
        sdn, sde, sdu, sne, seu, sun = sda.T
        cenu = np.zeros((T, 3, 3))
        cenu[:, 0, 0], cenu[:, 1, 1], cenu[:, 2, 2] = sde**2, sdn**2, sdu**2
        cenu[:, 0, 1] = cenu[:, 1, 0] = _signed_square(sne)
        cenu[:, 0, 2] = cenu[:, 2, 0] = _signed_square(seu)
        cenu[:, 1, 2] = cenu[:, 2, 1] = _signed_square(sun)
        rot = _enu_rotations(lat, lon)
        cov = np.swapaxes(rot, 1, 2) @ cenu @ rot
        std = np.sqrt(np.abs(np.diagonal(cov, axis1=1, axis2=2)))
    else:
        pos = np.stack([a, b, c], axis=1).astype(float).reshape(T, 3)
        std = sda[:, :3].copy()
    return SolutionTable(
        t_s=t_arr,
        pos_m=pos,
        std_m=std,
        status=np.array([_STATUS_OF_Q[v] for v in q], dtype=str).reshape(T),
        n_used=np.array(ns, dtype=np.int64),
        ratio=np.array(ratio, dtype=float),
        n_fixed=np.full(T, -1, dtype=np.int64),
        n_amb=np.full(T, -1, dtype=np.int64),
    )


# ------------------------------------------------------------------------------ NMEA
def nmea_checksum(sentence_body: str) -> str:
    """XOR of the characters between ``$`` and ``*`` as two upper-case hex digits."""
    cs = 0
    for ch in sentence_body:
        cs ^= ord(ch)
    return f"{cs:02X}"


def _angle_ddmm(value_deg: float, deg_digits: int) -> str:
    minutes = round(abs(value_deg) * 60.0, 7)
    deg = int(minutes // 60.0)
    mins = minutes - deg * 60.0
    return f"{deg:0{deg_digits}d}{mins:010.7f}"


def gga_sentence(t_s: float, pos_ecef_m: npt.ArrayLike, status: str, n_used: int) -> str:
    """One ``$GPGGA`` sentence (without line terminator).

    Time is UTC (GPST minus leap seconds) as ``hhmmss.ss``; latitude ``ddmm.mmmmmmm``,
    longitude ``dddmm.mmmmmmm``; quality from the status (see module table); satellites =
    ``n_used``; HDOP left empty; altitude = ellipsoidal height with geoid separation 0
    (no geoid model here), both in metres.
    """
    _check_status(status)
    if status == "none":
        raise InputError("status 'none' has no GGA quality")
    p = np.asarray(pos_ecef_m, dtype=float).reshape(3)
    if not _looks_ecef(p[None]):
        raise InputError("position is not ECEF near the Earth's surface (local frame?)")
    lat, lon, h = (float(v) for v in ecef2geodetic(p))
    cs = int(round(float(gpst2utc(t_s)) * 100.0))
    sod_cs = cs % (86_400 * 100)
    hh, rem = divmod(sod_cs, 360_000)
    mm, rem = divmod(rem, 6_000)
    ss, cc = divmod(rem, 100)
    lat_deg, lon_deg = math.degrees(lat), math.degrees(lon)
    body = (
        f"GPGGA,{hh:02d}{mm:02d}{ss:02d}.{cc:02d},"
        f"{_angle_ddmm(lat_deg, 2)},{'N' if lat_deg >= 0 else 'S'},"
        f"{_angle_ddmm(lon_deg, 3)},{'E' if lon_deg >= 0 else 'W'},"
        f"{_GGA_OF_STATUS[status]},{min(max(int(n_used), 0), 99):02d},,"
        f"{h:.4f},M,0.000,M,,"
    )
    return f"${body}*{nmea_checksum(body)}"


def write_nmea(solutions: Iterable[Solution], path: PathLike) -> None:
    """Write one GGA sentence per solution (``\\r\\n`` terminated); see :func:`gga_sentence`.

    Epochs with status ``"none"`` or a non-finite position are skipped.
    """
    sols = _writable(solutions)
    if sols and not _looks_ecef(np.array([s.pos_m for s in sols], dtype=float)):
        raise InputError(
            "positions are not ECEF near the Earth's surface (local frame?); NMEA needs geodetic positions",
            str(path),
        )
    with _atomic_open(path, newline="") as fh:
        for s in sols:
            fh.write(gga_sentence(s.t_s, s.pos_m, s.status, s.n_used) + "\r\n")


# ------------------------------------------------------------------- diagnostics CSV
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
    with _atomic_open(path, newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(DIAG_COLUMNS)
        for row in rows:
            v = _diag_row(row)
            dd = str(v[1])
            if "," in dd or "\n" in dd:
                raise InputError(f"DD label {dd!r} must not contain commas or newlines")
            w.writerow([_fmt(float(v[0])), dd, *(_fmt(float(x)) for x in v[2:7]),  # type: ignore[arg-type]
                        str(int(v[7]))])  # type: ignore[call-overload]  # fmt: skip


def read_diagnostics_csv(path: PathLike) -> DiagTable:
    """Read a file written by :func:`write_diagnostics_csv`.

    Raises
    ------
    InputError
        Wrong header, field count or unparsable value (file and line).
    """
    lines = _read_lines(path)
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
        t.append(_float_field(f[0], "time", path, ln))
        dd.append(f[1])
        num.append([_float_field(f[k], DIAG_COLUMNS[k], path, ln) for k in range(2, 7)])
        situ.append(_int_field(f[7], "situation", path, ln))
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

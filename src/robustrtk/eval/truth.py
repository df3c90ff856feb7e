"""Truth points and trajectories for solution comparison: reading, matching, time windows.

See :mod:`robustrtk.eval.compare` for the definitions (ENU errors at the truth, nearest
truth epoch within ``tol_s``, truth windows).
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robustrtk.core import FloatArray, InputError
from robustrtk.eval.metrics import position_errors
from robustrtk.eval.truth_formats import (
    is_gsdc_header,
    is_llh_csv_header,
    is_nmea_line,
    read_gsdc_truth,
    read_llh_csv,
    read_nmea_gga,
)
from robustrtk.geometry.frames import (
    WGS84_A_M,
    WGS84_B_M,
    ecef2enu_rotation,
    ecef2geodetic,
    geodetic2ecef_deg,
)
from robustrtk.io.solution import SolutionTable, read_pos, read_solution_csv
from robustrtk.timeutil import gpst2utc, gpst_from_week_tow, is_time_of_day, parse_gpst_instant, utc2gpst

__all__ = [
    "MATCH_TOL_S",
    "PathLike",
    "Truth",
    "is_number",
    "near_earth_surface",
    "parse_time_window",
    "parse_truth",
    "read_text_lines",
    "read_truth_file",
    "truth_from_llh",
    "truth_from_xyz",
]

PathLike = str | os.PathLike[str]

#: Default largest |t_solution - t_truth| for a trajectory match (s).
MATCH_TOL_S = 0.05

_SURFACE_TOL_M = 100_000.0
_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_NUM_RE = re.compile(rf"^{_NUM}$")


def is_number(text: str) -> bool:
    """Whether ``text`` is a plain decimal number (optional sign and exponent)."""
    return bool(_NUM_RE.match(text))


def near_earth_surface(pos_m: FloatArray) -> bool:
    """True if every finite row of ``pos_m`` (…, 3) lies within 100 km of the WGS84 surface
    (and there is at least one)."""
    with np.errstate(over="ignore", invalid="ignore"):  # 1e300 coordinates: inf, not a warning
        r = np.linalg.norm(np.asarray(pos_m, dtype=float).reshape(-1, 3), axis=1)
    r = r[np.isfinite(r)]
    return bool(r.size) and bool(np.all((r > WGS84_B_M - _SURFACE_TOL_M) & (r < WGS84_A_M + _SURFACE_TOL_M)))


# --------------------------------------------------------------------------- truth
@dataclass(frozen=True)
class Truth:
    """A truth point or trajectory.

    Attributes
    ----------
    pos_m : ndarray, shape (3,) for a point or (M, 3) for a trajectory
        ECEF (m) when ``ecef`` is true, otherwise a local frame with x, y, z taken as East,
        North, Up (m).
    t_s : ndarray, shape (M,), or None
        Trajectory epochs (s, the solutions' time scale: GPST for GNSS); None for a point.
    ecef : bool
    source : str
        Human-readable origin (``"point X,Y,Z"``, the file name ...).
    note : str or None
        A validity remark found in the truth file's comments (e.g. "valid only while
        static ..."), for the user.
    kind : str
        The file's form when it has a scoring convention of its own: ``"gsdc"`` for a GSDC
        ``ground_truth.csv`` (scored by the mean of the horizontal p50 and p95), ``"nmea"``
        for GGA fixes; empty otherwise.
    utc_time_of_day : bool
        ``t_s`` are UTC seconds of day with no date (an NMEA log without RMC/ZDA): they are
        anchored to the UTC day of the first compared solution epoch
        (:meth:`anchored_t_s`).
    """

    pos_m: FloatArray
    t_s: FloatArray | None
    ecef: bool
    source: str
    note: str | None = None
    kind: str = ""
    utc_time_of_day: bool = False

    @property
    def is_point(self) -> bool:
        return self.t_s is None

    def enu_errors(self, t_s: npt.ArrayLike, pos_m: npt.ArrayLike, tol_s: float = MATCH_TOL_S) -> FloatArray:
        """ENU errors of positions ``pos_m`` (T, 3) at times ``t_s`` (T,).

        Returns
        -------
        enu_m : ndarray, shape (T, 3)
            NaN rows where no truth epoch lies within ``tol_s`` (trajectories).
        """
        t = np.asarray(t_s, dtype=float).reshape(-1)
        p = np.asarray(pos_m, dtype=float).reshape(-1, 3)
        if self.is_point:
            err = p - self.pos_m.reshape(3)
        else:
            err = position_errors(_TimesPositions(t, p), self.anchored_t_s(t), self.pos_m, tol_s=tol_s)
        if not self.ecef:
            return err
        if self.is_point:
            lat, lon, _ = ecef2geodetic(self.pos_m.reshape(3))
            return err @ ecef2enu_rotation(float(lat), float(lon)).T
        out = np.full_like(err, np.nan)
        ok = np.all(np.isfinite(err), axis=1)
        if np.any(ok):
            lat_t, lon_t, _ = ecef2geodetic(p[ok] - err[ok])  # matched truth positions
            rot = ecef2enu_rotation(lat_t, lon_t)
            out[ok] = np.einsum("tij,tj->ti", rot, err[ok])
        return out

    def frame_errors(
        self, t_s: npt.ArrayLike, pos_m: npt.ArrayLike, tol_s: float = MATCH_TOL_S
    ) -> FloatArray:
        """Errors of positions ``pos_m`` (T, 3) at times ``t_s`` in the positions' own frame
        (ECEF for GNSS: the frame of a solution's ``std_m``), NaN rows where no truth epoch
        lies within ``tol_s``."""
        t = np.asarray(t_s, dtype=float).reshape(-1)
        p = np.asarray(pos_m, dtype=float).reshape(-1, 3)
        if self.is_point:
            return np.asarray(p - self.pos_m.reshape(3), float)
        return position_errors(_TimesPositions(t, p), self.anchored_t_s(t), self.pos_m, tol_s=tol_s)

    def anchored_t_s(self, solution_t_s: npt.ArrayLike) -> FloatArray:
        """Trajectory epochs in GPST seconds (M,); a dateless NMEA truth is placed on the UTC
        day of the first finite solution epoch (its first fix on that day, the day before or
        the day after, whichever lies nearest to that epoch)."""
        tt = self.t_s
        assert tt is not None
        if not self.utc_time_of_day:
            return tt
        t = np.asarray(solution_t_s, dtype=float).reshape(-1)
        t = t[np.isfinite(t)]
        if not t.size:
            return tt
        t0_utc = float(gpst2utc(t[0]))
        day0 = math.floor(t0_utc / 86_400.0) * 86_400.0
        first_tod = float(tt[0])
        day = min((day0 + k * 86_400.0 for k in (-1, 0, 1)), key=lambda d: abs(d + first_tod - t0_utc))
        return np.asarray(utc2gpst(tt + day), dtype=float)


@dataclass(frozen=True)
class _TimesPositions:
    t_s: FloatArray
    pos_m: FloatArray


def _three_numbers(text: str, what: str) -> FloatArray:
    parts = [p.strip() for p in text.split(",")]
    if len(parts) != 3 or not all(is_number(p) for p in parts):
        raise InputError(f"{what}: expected three comma-separated numbers, got {text!r}")
    v = np.array([float(p) for p in parts])
    if not np.all(np.isfinite(v)):
        raise InputError(f"{what}: expected finite numbers, got {text!r}")
    return v


def _check_llh(lat: float, lon: float, h: float, what: str, path: str | None = None,
               line: int | None = None) -> None:  # fmt: skip
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 360.0 and abs(h) < 100_000.0):
        raise InputError(
            f"{what}: expected latitude -90..90 deg, longitude -180..360 deg, height within "
            f"100 km, got {lat}, {lon}, {h}",
            path,
            line,
        )


def truth_from_xyz(text: str, what: str = "--truth") -> Truth:
    """Point truth from ``"X,Y,Z"`` (m): ECEF when near the Earth's surface, else a local frame."""
    v = _three_numbers(text, what)
    return Truth(pos_m=v, t_s=None, ecef=near_earth_surface(v), source=f"point {text.strip()}")


def truth_from_llh(text: str, what: str = "--truth-llh") -> Truth:
    """Point truth from ``"LAT,LON,H"`` (deg, deg, m ellipsoidal)."""
    lat, lon, h = (float(v) for v in _three_numbers(text, what))
    _check_llh(lat, lon, h, what)
    return Truth(pos_m=geodetic2ecef_deg(lat, lon, h).reshape(3), t_s=None, ecef=True,
                 source=f"point lat {lat} lon {lon} h {h}")  # fmt: skip


def read_text_lines(path: PathLike) -> list[str]:
    """Lines of a text file; :class:`InputError` for a directory or an unreadable file."""
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            return fh.read().splitlines()
    except IsADirectoryError:
        raise InputError("is a directory, expected a file", str(path)) from None
    except OSError as exc:
        raise InputError(f"cannot read file ({exc.strerror})", str(path)) from None


def _is_pos_column_header(text: str) -> bool:
    body = text.lstrip("%").split()
    return bool(body) and body[0] in ("GPST", "UTC", "JST") and len(body) > 3


def _truth_from_table(table: SolutionTable, path: PathLike, fixed_only: bool = False) -> Truth:
    ok = np.all(np.isfinite(table.pos_m), axis=1) & (table.status != "none")
    if fixed_only:
        ok &= table.status == "fixed"
    if not np.any(ok):
        what = "fixed truth epochs (Q = 1)" if fixed_only else "truth epochs with a position"
        raise InputError(f"no {what}", str(path))
    pos = table.pos_m[ok]
    return Truth(pos_m=pos, t_s=table.t_s[ok], ecef=near_earth_surface(pos), source=str(path))


def read_truth_file(path: PathLike, fixed_only: bool = False) -> Truth:
    """Read a truth point or trajectory file.

    With ``fixed_only`` only the epochs the file marks as fixed ambiguity solutions are
    kept (a ``.pos`` Q = 1, a solution CSV status ``fixed``, NMEA GGA quality 4); a form with
    no solution quality is then refused.

    Forms (``#`` and ``%`` start comment lines in the text forms):

    * RTKLIB ``.pos`` (llh or xyz) or our ``.pos`` → trajectory of every epoch in it;
    * GSDC ``ground_truth.csv`` (2021 ``millisSinceGpsEpoch`` or 2022/2023
      ``UnixTimeMillis`` layout) → trajectory, :attr:`Truth.kind` ``"gsdc"``;
    * NMEA 0183 GGA fixes (quality ≥ 1; dated by RMC/ZDA when present) → trajectory;
    * CSV with a header starting ``time,lat,lon,h`` (degrees, ellipsoidal metres) → trajectory;
    * CSV with a header starting ``time,x,y,z`` (our solution CSV, the simulator's
      ``truth.csv``) → trajectory (rows with status ``none`` skipped);
    * rows ``week tow x y z`` (GPS week, seconds of week, ECEF m) → trajectory;
    * rows ``t x y z`` (seconds in the solutions' time scale, m) → trajectory;
    * one point: ``X Y Z`` or ``LAT LON H`` on a line (told apart by magnitude: ECEF
      coordinates are millions of metres), optionally prefixed by a name and followed by a
      `` # comment``; names ending
      in ``xyz`` or ``ecef`` force ECEF, names ending in ``llh`` force degrees and metres.
      With several named points the one whose name starts with ``rover`` is used.

    A comment containing "valid only" is kept as :attr:`Truth.note`.

    Raises
    ------
    InputError
        Unreadable file or a line that fits none of these forms (file and line named).
    """
    p = str(path)
    lines = read_text_lines(path)
    first_text = next((ln for ln in lines if ln.strip()), "")
    if fixed_only and (is_gsdc_header(first_text) or is_llh_csv_header(first_text)):
        raise InputError(
            "--truth-fixed: this truth has no solution quality (expected .pos, NMEA GGA or solution CSV)", p
        )
    if is_gsdc_header(first_text):
        t_g, pos_g = read_gsdc_truth(path, lines[lines.index(first_text) :])
        return Truth(pos_m=pos_g, t_s=t_g, ecef=True, source=p, kind="gsdc")
    if is_llh_csv_header(first_text):
        t_l, pos_l = read_llh_csv(path, lines[lines.index(first_text) :])
        return Truth(pos_m=pos_l, t_s=t_l, ecef=True, source=p)
    if is_nmea_line(first_text):
        t_n, pos_n, tod = read_nmea_gga(path, lines, fixed_only=fixed_only)
        return Truth(pos_m=pos_n, t_s=t_n, ecef=True, source=p, kind="nmea", utc_time_of_day=tod)
    data: list[tuple[int, str]] = []
    note: str | None = None
    pos_header = False
    for ln, raw in enumerate(lines, start=1):
        text = raw.strip()
        if not text:
            continue
        if text.startswith(("#", "%")):
            if text.startswith("%") and _is_pos_column_header(text):
                pos_header = True
            if "valid only" in text.lower():
                note = text.lstrip("#% ").strip()
            continue
        if " #" in text:  # a trailing comment on a data line (named points)
            text = text.split(" #", 1)[0].strip()
        data.append((ln, text))
    if not data:
        raise InputError("no truth data lines; expected a point (X Y Z or LAT LON H) or a trajectory", p)
    first_ln, first = data[0]
    if first.lower().replace(" ", "").startswith("time,x,y,z"):
        return _read_truth_csv(path, lines, fixed_only)
    if pos_header and len(first.split()) >= 7:
        t = _truth_from_table(read_pos(path), path, fixed_only)
        return Truth(t.pos_m, t.t_s, t.ecef, t.source, note)
    if fixed_only:
        raise InputError(
            "--truth-fixed: this truth has no solution quality (expected .pos, NMEA GGA or solution CSV)", p
        )
    rows = [(ln, [tok for tok in re.split(r"[,\s]+", text) if tok]) for ln, text in data]
    n_num = len(rows[0][1])
    if all(is_number(tok) for tok in rows[0][1]) and n_num in (4, 5):
        return _read_truth_rows(rows, n_num, path, note)
    return _read_truth_point(rows, path, note)


def _read_truth_csv(path: PathLike, lines: list[str], fixed_only: bool = False) -> Truth:
    header = [h.strip().lower() for h in lines[0].split(",")] if lines else []
    if len(header) >= 12 and header[7] == "status":
        return _truth_from_table(read_solution_csv(path), path, fixed_only)
    if fixed_only:
        raise InputError(
            "--truth-fixed: this truth has no solution quality (expected .pos, NMEA GGA or solution CSV)",
            str(path),
        )
    t: list[float] = []
    xyz: list[list[float]] = []
    for ln, raw in enumerate(lines[1:], start=2):
        if not raw.strip():
            continue
        f = [c.strip() for c in raw.split(",")]
        if len(f) < 4 or not all(is_number(c) for c in f[:4]):
            raise InputError(f"expected numbers time,x,y,z, got {raw.strip()!r}", str(path), ln)
        t.append(float(f[0]))
        xyz.append([float(c) for c in f[1:4]])
        if not all(math.isfinite(v) and abs(v) < 1e12 for v in [t[-1], *xyz[-1]]):
            raise InputError("expected finite numbers time,x,y,z below 1e12 in magnitude", str(path), ln)
    if not t:
        raise InputError("no truth rows after the header", str(path))
    pos = np.array(xyz, dtype=float)
    return Truth(pos_m=pos, t_s=np.array(t), ecef=near_earth_surface(pos), source=str(path))


def _read_truth_rows(rows: list[tuple[int, list[str]]], n_num: int, path: PathLike,
                     note: str | None) -> Truth:  # fmt: skip
    form = "week tow x y z" if n_num == 5 else "t x y z"
    vals = []
    for ln, toks in rows:
        if len(toks) != n_num or not all(is_number(tok) for tok in toks):
            raise InputError(f"expected {n_num} numbers ({form}), got {' '.join(toks)!r}", str(path), ln)
        vals.append([float(tok) for tok in toks])
        if not all(abs(x) < 1e12 for x in vals[-1]):
            raise InputError(f"expected finite numbers ({form}) below 1e12 in magnitude", str(path), ln)
    a = np.array(vals, dtype=float)
    t = gpst_from_week_tow(a[:, 0], a[:, 1]) if n_num == 5 else a[:, 0]
    pos = a[:, -3:]
    return Truth(pos_m=pos, t_s=np.asarray(t, dtype=float), ecef=near_earth_surface(pos),
                 source=str(path), note=note)  # fmt: skip


def _read_truth_point(rows: list[tuple[int, list[str]]], path: PathLike, note: str | None) -> Truth:
    points: list[tuple[str, int, FloatArray, bool]] = []
    for ln, toks in rows:
        name = ""
        nums = toks
        if toks and not is_number(toks[0]):
            name, nums = toks[0], toks[1:]
        if len(nums) != 3 or not all(is_number(tok) for tok in nums):
            raise InputError(
                f"expected a point '[name] X Y Z' or '[name] LAT LON H', a 'week tow x y z' or "
                f"'t x y z' row, got {' '.join(toks)!r}",
                str(path),
                ln,
            )
        v = np.array([float(tok) for tok in nums])
        if not np.all(np.abs(v) < 1e12):
            raise InputError("expected finite coordinates below 1e12 in magnitude", str(path), ln)
        key = name.lower()
        if key.endswith(("xyz", "ecef")):
            is_llh = False
        elif key.endswith(("llh", "blh", "geodetic")):
            is_llh = True
        else:
            is_llh = bool(np.linalg.norm(v) < 1.0e6 and abs(v[0]) <= 90.0 and abs(v[1]) <= 360.0)
        if is_llh:
            _check_llh(float(v[0]), float(v[1]), float(v[2]), f"point {name or 'LAT LON H'}", str(path), ln)
            points.append((name, ln, geodetic2ecef_deg(v[0], v[1], v[2]).reshape(3), True))
        else:
            points.append((name, ln, v, near_earth_surface(v)))
    if len(points) > 1:
        rover = [pt for pt in points if pt[0].lower().startswith("rover")]
        if len(rover) != 1:
            names = ", ".join(pt[0] or f"line {pt[1]}" for pt in points)
            raise InputError(
                f"several points ({names}); expected one, or exactly one named rover*", str(path)
            )
        points = rover
    name, ln, pos, ecef = points[0]
    src = f"{path}" + (f" ({name})" if name else "")
    return Truth(pos_m=pos, t_s=None, ecef=ecef, source=src, note=note)


def parse_truth(text: str, fixed_only: bool = False) -> Truth:
    """``--truth`` value: ``"X,Y,Z"`` (m) or the path of a truth file (:func:`read_truth_file`;
    ``fixed_only``: its fixed epochs only)."""
    parts = [s.strip() for s in text.split(",")]
    if len(parts) == 3 and all(is_number(s) for s in parts):
        if fixed_only:
            raise InputError("--truth-fixed: a point has no solution quality; expected a trajectory file")
        return truth_from_xyz(text)
    if not os.path.exists(text):
        raise InputError(f"--truth: expected X,Y,Z (ECEF m) or an existing file, got {text!r}")
    return read_truth_file(text, fixed_only)


# --------------------------------------------------------------------------- windows
def parse_time_window(text: str, t_ref_s: float, what: str = "--truth-window") -> tuple[float, float]:
    """``"START,END"`` → ``(start_s, end_s)`` in GPST seconds.

    Each bound is a GPST calendar time ``yyyy/mm/dd hh:mm:ss[.s]`` (``-`` and ``T`` also
    accepted), a time of day ``hh:mm:ss`` on the GPST date of ``t_ref_s`` (the first
    solution epoch; an END before START moves to the next day), or a number of seconds in
    the solutions' own time scale.
    """
    parts = text.split(",")
    if len(parts) != 2:
        raise InputError(f"{what}: expected START,END, got {text!r}")
    a = parse_gpst_instant(parts[0], t_ref_s, what)
    b = parse_gpst_instant(parts[1], t_ref_s, what)
    if b < a and is_time_of_day(parts[1]):
        b += 86_400.0
    if b < a:
        raise InputError(f"{what}: END is before START in {text!r}")
    return a, b

r"""Compare solution files against a truth point or trajectory.

Reads RTKLIB ``.pos`` files (llh or xyz form, as written by ``rnx2rtkp``) and our own
``.pos`` and CSV solutions (:mod:`robustrtk.io.solution`), and reports per solution:

* ``epochs_solved`` — epochs with a position (RTKLIB ``Q`` 1..6; CSV rows whose status is
  not ``none``), the ``Q`` histogram (CSV statuses mapped as :func:`robustrtk.io.solution.write_pos`
  maps them: fixed and partial 1, float 2, dgnss and code 4, single 5) and, for CSV, the
  status histogram;
* fix rate — fixed (``Q = 1``) epochs in percent of the solved epochs and, when the
  number of rover epochs is known, of the rover epochs;
* time to first fix — seconds from the first solved epoch to the first fixed one;
* error statistics of the fixed (``Q = 1``), float (``Q = 2``) and all solved epochs that
  have a truth (and lie in the truth window when one is given).

Errors are East-North-Up at the truth: with an ECEF truth,
:math:`e_{enu} = R(\varphi_t, \lambda_t)\,(r - r_t)` where :math:`R` is
:func:`robustrtk.geometry.frames.ecef2enu_rotation` at the truth point (for a trajectory:
at the matched truth epoch's position). A truth in a local (pseudolite) frame is used as is,
``x, y, z`` taken as East, North, Up. For each group of :math:`n` epochs with
:math:`h_i = \sqrt{e_i^2 + n_i^2}` and :math:`v_i = |u_i|`:

* ``H_rms_m`` :math:`= \sqrt{\tfrac1n \sum h_i^2}`, ``V_rms_m`` likewise with :math:`v_i`;
* ``H_95_m``, ``V_95_m`` — 95th percentile with linear interpolation between order
  statistics (:func:`numpy.percentile`, ``method="linear"``): with the sorted values
  :math:`x_{(0)} \le \dots \le x_{(n-1)}`, :math:`p = 0.95 (n - 1)`, :math:`j = \lfloor p \rfloor`:
  :math:`x_{(j)} + (p - j)(x_{(j + 1)} - x_{(j)})`;
* ``mean_enu_m`` — mean of the ENU errors (signed);
* ``H_max_m``, ``V_max_m`` — largest :math:`h_i`, :math:`v_i`;
* ``n_3d_err_gt_0.10m`` — epochs with :math:`\|e_{enu}\| > 0.10` m.

These definitions reproduce the reference evaluations (``*.eval.json``) of the RTKLIB runs
in the shared datasets to their printed precision.

Truth trajectories are matched to solution epochs by the nearest truth epoch within
``tol_s`` (0.05 s); solution epochs without one are left out of the error statistics but
still count for the fix rate. A truth window ``[start, end]`` (GPST, inclusive within
1 ms) restricts the error statistics the same way — e.g. a kinematic rover whose truth
point is only valid while it stands still.
"""

from __future__ import annotations

import json
import math
import os
import re
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
from matplotlib.figure import Figure

from robustrtk.core import FloatArray, InputError, IntArray
from robustrtk.eval.metrics import position_errors
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic, geodetic2ecef_deg
from robustrtk.io.atomic import atomic_path
from robustrtk.io.solution import SolutionTable, read_pos, read_solution_csv
from robustrtk.timeutil import calendar_from_gpst, gpst_from_calendar, gpst_from_week_tow

PathLike = str | os.PathLike[str]

#: Default largest |t_solution - t_truth| for a trajectory match (s).
MATCH_TOL_S = 0.05
#: Threshold of the 3-D error count (m).
ERR_3D_THRESHOLD_M = 0.10
#: Tolerance of the truth-window bounds (s).
WINDOW_TOL_S = 1e-3
#: RTKLIB ``Q`` of each solution status (as :func:`robustrtk.io.solution.write_pos` writes them).
Q_OF_STATUS = {"fixed": 1, "partial": 1, "float": 2, "dgnss": 4, "code": 4, "single": 5}
#: Names of the RTKLIB ``Q`` values.
Q_NAMES = {1: "fixed", 2: "float", 3: "sbas", 4: "dgps", 5: "single", 6: "ppp"}
#: Error groups: name and the ``Q`` values it holds (None: every solved epoch).
GROUPS: tuple[tuple[str, tuple[int, ...] | None], ...] = (("fixed", (1,)), ("float", (2,)), ("all", None))

_WGS84_A_M = 6_378_137.0
_WGS84_B_M = 6_356_752.314245
_SURFACE_TOL_M = 100_000.0
_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_NUM_RE = re.compile(rf"^{_NUM}$")
_CAL_RE = re.compile(r"^(\d{4})[/-](\d{1,2})[/-](\d{1,2})[ T]+(\d{1,2}):(\d{2}):(\d{2}(?:\.\d*)?)$")
_TOD_RE = re.compile(r"^(\d{1,2}):(\d{2}):(\d{2}(?:\.\d*)?)$")


# --------------------------------------------------------------------------- helpers
def _is_number(text: str) -> bool:
    return bool(_NUM_RE.match(text))


def _near_earth_surface(pos_m: FloatArray) -> bool:
    """True if every finite row of ``pos_m`` (…, 3) lies within 100 km of the WGS84 surface."""
    r = np.linalg.norm(np.asarray(pos_m, dtype=float).reshape(-1, 3), axis=1)
    r = r[np.isfinite(r)]
    return bool(r.size) and bool(
        np.all((r > _WGS84_B_M - _SURFACE_TOL_M) & (r < _WGS84_A_M + _SURFACE_TOL_M))
    )


def _enu_rotations(pos_ecef_m: FloatArray) -> FloatArray:
    """Rotations ``R`` (T, 3, 3), ``enu = R @ d_ecef``, at each ECEF point of ``pos_ecef_m`` (T, 3)."""
    lat, lon, _ = ecef2geodetic(pos_ecef_m)
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    z = np.zeros_like(sl)
    return np.stack(
        [np.stack([-so, co, z], axis=-1),
         np.stack([-sl * co, -sl * so, cl], axis=-1),
         np.stack([cl * co, cl * so, sl], axis=-1)],
        axis=-2,
    )  # fmt: skip


def gpst_text(t_s: float) -> str:
    """``yyyy/mm/dd hh:mm:ss`` (GPST) of ``t_s``; fractional seconds kept when not whole."""
    ms = int(round(t_s * 1000.0))
    sec, frac = divmod(ms, 1000)
    y, mo, d, h, mi, s = calendar_from_gpst(float(sec))
    text = f"{y:04d}/{mo:02d}/{d:02d} {h:02d}:{mi:02d}:{int(round(s)):02d}"
    return text + (f".{frac:03d}" if frac else "")


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
    """

    pos_m: FloatArray
    t_s: FloatArray | None
    ecef: bool
    source: str
    note: str | None = None

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
            err = position_errors(_TimesPositions(t, p), self.t_s, self.pos_m, tol_s=tol_s)
        if not self.ecef:
            return err
        if self.is_point:
            lat, lon, _ = ecef2geodetic(self.pos_m.reshape(3))
            return err @ ecef2enu_rotation(float(lat), float(lon)).T
        out = np.full_like(err, np.nan)
        ok = np.all(np.isfinite(err), axis=1)
        if np.any(ok):
            rot = _enu_rotations(p[ok] - err[ok])  # matched truth positions
            out[ok] = np.einsum("tij,tj->ti", rot, err[ok])
        return out


@dataclass(frozen=True)
class _TimesPositions:
    t_s: FloatArray
    pos_m: FloatArray


def _three_numbers(text: str, what: str) -> FloatArray:
    parts = [p.strip() for p in text.split(",")]
    if len(parts) != 3 or not all(_is_number(p) for p in parts):
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
    return Truth(pos_m=v, t_s=None, ecef=_near_earth_surface(v), source=f"point {text.strip()}")


def truth_from_llh(text: str, what: str = "--truth-llh") -> Truth:
    """Point truth from ``"LAT,LON,H"`` (deg, deg, m ellipsoidal)."""
    lat, lon, h = (float(v) for v in _three_numbers(text, what))
    _check_llh(lat, lon, h, what)
    return Truth(pos_m=geodetic2ecef_deg(lat, lon, h).reshape(3), t_s=None, ecef=True,
                 source=f"point lat {lat} lon {lon} h {h}")  # fmt: skip


def _read_text(path: PathLike) -> list[str]:
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


def _truth_from_table(table: SolutionTable, path: PathLike) -> Truth:
    ok = np.all(np.isfinite(table.pos_m), axis=1) & (table.status != "none")
    if not np.any(ok):
        raise InputError("no truth epochs with a position", str(path))
    pos = table.pos_m[ok]
    return Truth(pos_m=pos, t_s=table.t_s[ok], ecef=_near_earth_surface(pos), source=str(path))


def read_truth_file(path: PathLike) -> Truth:
    """Read a truth point or trajectory file.

    Forms (``#`` and ``%`` start comment lines in the text forms):

    * RTKLIB ``.pos`` (llh or xyz) or our ``.pos`` → trajectory of every epoch in it;
    * CSV with a header starting ``time,x,y,z`` (our solution CSV, the simulator's
      ``truth.csv``) → trajectory (rows with status ``none`` skipped);
    * rows ``week tow x y z`` (GPS week, seconds of week, ECEF m) → trajectory;
    * rows ``t x y z`` (seconds in the solutions' time scale, m) → trajectory;
    * one point: ``X Y Z`` or ``LAT LON H`` on a line (told apart by magnitude: ECEF
      coordinates are millions of metres), optionally prefixed by a name; names ending
      in ``xyz`` or ``ecef`` force ECEF, names ending in ``llh`` force degrees and metres.
      With several named points the one whose name starts with ``rover`` is used.

    A comment containing "valid only" is kept as :attr:`Truth.note`.

    Raises
    ------
    InputError
        Unreadable file or a line that fits none of these forms (file and line named).
    """
    p = str(path)
    lines = _read_text(path)
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
        data.append((ln, text))
    if not data:
        raise InputError("no truth data lines; expected a point (X Y Z or LAT LON H) or a trajectory", p)
    first_ln, first = data[0]
    if first.lower().replace(" ", "").startswith("time,x,y,z"):
        return _read_truth_csv(path, lines)
    if pos_header and len(first.split()) >= 15:
        t = _truth_from_table(read_pos(path), path)
        return Truth(t.pos_m, t.t_s, t.ecef, t.source, note)
    rows = [(ln, [tok for tok in re.split(r"[,\s]+", text) if tok]) for ln, text in data]
    n_num = len(rows[0][1])
    if all(_is_number(tok) for tok in rows[0][1]) and n_num in (4, 5):
        return _read_truth_rows(rows, n_num, path, note)
    return _read_truth_point(rows, path, note)


def _read_truth_csv(path: PathLike, lines: list[str]) -> Truth:
    header = [h.strip().lower() for h in lines[0].split(",")] if lines else []
    if len(header) >= 12 and header[7] == "status":
        return _truth_from_table(read_solution_csv(path), path)
    t: list[float] = []
    xyz: list[list[float]] = []
    for ln, raw in enumerate(lines[1:], start=2):
        if not raw.strip():
            continue
        f = [c.strip() for c in raw.split(",")]
        if len(f) < 4 or not all(_is_number(c) for c in f[:4]):
            raise InputError(f"expected numbers time,x,y,z, got {raw.strip()!r}", str(path), ln)
        t.append(float(f[0]))
        xyz.append([float(c) for c in f[1:4]])
    if not t:
        raise InputError("no truth rows after the header", str(path))
    pos = np.array(xyz, dtype=float)
    return Truth(pos_m=pos, t_s=np.array(t), ecef=_near_earth_surface(pos), source=str(path))


def _read_truth_rows(rows: list[tuple[int, list[str]]], n_num: int, path: PathLike,
                     note: str | None) -> Truth:  # fmt: skip
    form = "week tow x y z" if n_num == 5 else "t x y z"
    vals = []
    for ln, toks in rows:
        if len(toks) != n_num or not all(_is_number(tok) for tok in toks):
            raise InputError(f"expected {n_num} numbers ({form}), got {' '.join(toks)!r}", str(path), ln)
        vals.append([float(tok) for tok in toks])
    a = np.array(vals, dtype=float)
    t = gpst_from_week_tow(a[:, 0], a[:, 1]) if n_num == 5 else a[:, 0]
    pos = a[:, -3:]
    return Truth(pos_m=pos, t_s=np.asarray(t, dtype=float), ecef=_near_earth_surface(pos),
                 source=str(path), note=note)  # fmt: skip


def _read_truth_point(rows: list[tuple[int, list[str]]], path: PathLike, note: str | None) -> Truth:
    points: list[tuple[str, int, FloatArray, bool]] = []
    for ln, toks in rows:
        name = ""
        nums = toks
        if toks and not _is_number(toks[0]):
            name, nums = toks[0], toks[1:]
        if len(nums) != 3 or not all(_is_number(tok) for tok in nums):
            raise InputError(
                f"expected a point '[name] X Y Z' or '[name] LAT LON H', a 'week tow x y z' or "
                f"'t x y z' row, got {' '.join(toks)!r}",
                str(path),
                ln,
            )
        v = np.array([float(tok) for tok in nums])
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
            points.append((name, ln, v, _near_earth_surface(v)))
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


def parse_truth(text: str) -> Truth:
    """``--truth`` value: ``"X,Y,Z"`` (m) or the path of a truth file (:func:`read_truth_file`)."""
    parts = [s.strip() for s in text.split(",")]
    if len(parts) == 3 and all(_is_number(s) for s in parts):
        return truth_from_xyz(text)
    if not os.path.exists(text):
        raise InputError(f"--truth: expected X,Y,Z (ECEF m) or an existing file, got {text!r}")
    return read_truth_file(text)


# --------------------------------------------------------------------------- windows
def _parse_instant(text: str, t_ref_s: float, what: str) -> float:
    s = text.strip()
    if _is_number(s):
        return float(s)
    m = _CAL_RE.match(s)
    if m:
        y, mo, d, hh, mi = (int(g) for g in m.groups()[:5])
        return gpst_from_calendar(y, mo, d, hh, mi, float(m.group(6)))
    m = _TOD_RE.match(s)
    if m:
        y, mo, d, _, _, _ = calendar_from_gpst(math.floor(t_ref_s))
        return gpst_from_calendar(y, mo, d, int(m.group(1)), int(m.group(2)), float(m.group(3)))
    raise InputError(
        f"{what}: expected 'yyyy/mm/dd hh:mm:ss', 'hh:mm:ss' (on the first epoch's date) or seconds, "
        f"got {s!r}"
    )


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
    a = _parse_instant(parts[0], t_ref_s, what)
    b = _parse_instant(parts[1], t_ref_s, what)
    if b < a and _TOD_RE.match(parts[1].strip()):
        b += 86_400.0
    if b < a:
        raise InputError(f"{what}: END is before START in {text!r}")
    return a, b


# --------------------------------------------------------------------------- solutions
def _pos_q_column(path: PathLike, n_expected: int) -> IntArray:
    """RTKLIB ``Q`` of each data line of a ``.pos`` file already read by :func:`read_pos`."""
    q: list[int] = []
    for ln, raw in enumerate(_read_text(path), start=1):
        tok = raw.split()
        if not tok or tok[0].startswith("%"):
            continue
        try:
            q.append(int(float(tok[5])))
        except (ValueError, IndexError):
            raise InputError("expected the Q value in field 6", str(path), ln) from None
    if len(q) != n_expected:
        raise InputError(f"read {n_expected} epochs but found {len(q)} data lines", str(path))
    return np.array(q, dtype=np.int64)


def load_solution(path: PathLike) -> tuple[SolutionTable, IntArray]:
    """Read a solution file and the RTKLIB ``Q`` of each of its epochs.

    RTKLIB-style ``.pos`` files (a ``%`` header) are read with
    :func:`robustrtk.io.solution.read_pos` and their ``Q`` column kept as written; CSV
    files (header ``time,x,y,z,...``) with :func:`robustrtk.io.solution.read_solution_csv`,
    ``Q`` from the status (:data:`Q_OF_STATUS`; 0 for ``none``).

    Returns
    -------
    table : SolutionTable
    q : ndarray of int, shape (T,)

    Raises
    ------
    InputError
        Unreadable file or one in neither format (file and line named).
    """
    lines = _read_text(path)
    first = next(((ln, s.strip()) for ln, s in enumerate(lines, start=1) if s.strip()), None)
    if first is None:
        raise InputError("empty file; expected an RTKLIB .pos or a robustrtk CSV solution", str(path))
    ln, text = first
    if text.lower().startswith("time,"):
        table = read_solution_csv(path)
        q = np.array([Q_OF_STATUS.get(str(s), 0) for s in table.status], dtype=np.int64)
        return table, q
    if text.startswith("%") or str(path).lower().endswith(".pos"):
        table = read_pos(path)
        return table, _pos_q_column(path, len(table))
    raise InputError(
        f"expected an RTKLIB .pos file ('%' header lines) or a robustrtk CSV (header 'time,x,y,z,...'), "
        f"got {text[:40]!r}",
        str(path),
        ln,
    )


def count_rover_epochs(obs_path: PathLike) -> int:
    """Number of epochs in a RINEX observation file (event records excluded)."""
    from robustrtk.io.rinex_obs import read_rinex_obs

    return int(read_rinex_obs(obs_path).t_s.shape[0])


def default_labels(paths: Sequence[PathLike]) -> list[str]:
    """File stems; ``parent/stem`` where stems repeat, then ``#k`` suffixes if still repeated."""
    stems = [Path(p).stem for p in paths]
    labels = [
        f"{Path(p).parent.name}/{s}" if stems.count(s) > 1 and Path(p).parent.name else s
        for p, s in zip(paths, stems, strict=True)
    ]
    seen: Counter[str] = Counter()
    out = []
    for lab in labels:
        seen[lab] += 1
        out.append(lab if labels.count(lab) == 1 else f"{lab}#{seen[lab]}")
    return out


# --------------------------------------------------------------------------- statistics
def error_group_stats(enu_m: npt.ArrayLike) -> dict[str, Any] | None:
    """Statistics of ENU errors (n, 3) (NaN rows dropped); None when no row remains.

    Returns
    -------
    dict or None
        ``n, H_rms_m, H_95_m, V_rms_m, V_95_m, mean_enu_m (list of 3), H_max_m, V_max_m,
        n_3d_err_gt_0.10m`` (definitions in the module docstring).
    """
    e = np.asarray(enu_m, dtype=float).reshape(-1, 3)
    e = e[np.all(np.isfinite(e), axis=1)]
    if e.shape[0] == 0:
        return None
    h = np.hypot(e[:, 0], e[:, 1])
    v = np.abs(e[:, 2])
    d3 = np.linalg.norm(e, axis=1)
    return {
        "n": int(e.shape[0]),
        "H_rms_m": float(np.sqrt(np.mean(h**2))),
        "H_95_m": float(np.percentile(h, 95.0, method="linear")),
        "V_rms_m": float(np.sqrt(np.mean(v**2))),
        "V_95_m": float(np.percentile(v, 95.0, method="linear")),
        "mean_enu_m": [float(x) for x in e.mean(axis=0)],
        "H_max_m": float(h.max()),
        "V_max_m": float(v.max()),
        "n_3d_err_gt_0.10m": int(np.sum(d3 > ERR_3D_THRESHOLD_M)),
    }


@dataclass(frozen=True)
class SolutionComparison:
    """One solution's comparison.

    Attributes
    ----------
    label, path : str
    t_s : ndarray, shape (T,)
        Times of the solved epochs (s).
    q : ndarray of int, shape (T,)
        RTKLIB ``Q`` of each solved epoch.
    status : ndarray of str, shape (T,)
    enu_err_m : ndarray, shape (T, 3)
        ENU error (m); NaN where the epoch has no truth or lies outside the truth window.
    rover_epochs : int or None
    groups : dict
        ``"fixed"``, ``"float"``, ``"all"`` → :func:`error_group_stats` (None when empty);
        empty without a truth.
    warnings : tuple of str
    """

    label: str
    path: str
    t_s: FloatArray
    q: IntArray
    status: npt.NDArray[np.str_]
    enu_err_m: FloatArray
    rover_epochs: int | None
    groups: dict[str, dict[str, Any] | None] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()

    @property
    def epochs_solved(self) -> int:
        return int(self.t_s.shape[0])

    @property
    def n_fixed(self) -> int:
        return int(np.sum(self.q == 1))

    @property
    def q_hist(self) -> dict[int, int]:
        vals, counts = np.unique(self.q, return_counts=True)
        return {int(v): int(c) for v, c in zip(vals, counts, strict=True)}

    @property
    def status_hist(self) -> dict[str, int]:
        return dict(sorted(Counter(str(s) for s in self.status).items()))

    @property
    def fix_rate_pct_of_solved(self) -> float:
        return 100.0 * self.n_fixed / self.epochs_solved if self.epochs_solved else math.nan

    @property
    def fix_rate_pct_of_rover_epochs(self) -> float | None:
        if self.rover_epochs is None:
            return None
        return 100.0 * self.n_fixed / self.rover_epochs if self.rover_epochs > 0 else math.nan

    @property
    def ttff_s(self) -> float | None:
        """Seconds from the first solved epoch to the first fixed one (None: never fixed)."""
        idx = np.flatnonzero(self.q == 1)
        return float(self.t_s[idx[0]] - self.t_s[0]) if idx.size else None

    @property
    def n_with_truth(self) -> int:
        return int(np.sum(np.all(np.isfinite(self.enu_err_m), axis=1)))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (keys as in the reference ``*.eval.json`` files, plus
        ``path``, ``status_hist``, ``ttff_s``, ``epochs_with_truth``)."""
        return {
            "label": self.label,
            "path": self.path,
            "epochs_solved": self.epochs_solved,
            "Q_hist": {str(k): v for k, v in self.q_hist.items()},
            "status_hist": self.status_hist,
            "fix_rate_pct_of_solved": _json_float(self.fix_rate_pct_of_solved),
            "rover_epochs": self.rover_epochs,
            "fix_rate_pct_of_rover_epochs": _json_float(self.fix_rate_pct_of_rover_epochs),
            "ttff_s": self.ttff_s,
            "epochs_with_truth": self.n_with_truth,
            **{name: self.groups.get(name) for name, _ in GROUPS},
            "warnings": list(self.warnings),
        }


def _json_float(v: float | None) -> float | None:
    return None if v is None or not math.isfinite(v) else float(v)


def compare_solution(
    table: SolutionTable,
    q: npt.ArrayLike,
    truth: Truth | None,
    *,
    label: str,
    path: str = "",
    rover_epochs: int | None = None,
    window_s: tuple[float, float] | None = None,
    tol_s: float = MATCH_TOL_S,
) -> SolutionComparison:
    """Compare one solution with the truth.

    Parameters
    ----------
    table : SolutionTable
        T epochs.
    q : array_like of int, shape (T,)
        RTKLIB ``Q`` per epoch (0 or ``status == "none"``: not solved).
    truth : Truth or None
        None: fix rate and time to first fix only.
    label, path : str
    rover_epochs : int, optional
        Rover epochs for the second fix-rate denominator.
    window_s : (start_s, end_s), optional
        Inclusive (±1 ms) time window of the error statistics.
    tol_s : float
        Trajectory match tolerance (s).

    Raises
    ------
    InputError
        ``q`` of the wrong length, fewer rover epochs than solved ones, or an ECEF truth
        with a local-frame solution (and vice versa).
    """
    qa = np.asarray(q, dtype=np.int64).reshape(-1)
    if qa.shape[0] != len(table):
        raise InputError(f"{len(table)} epochs but {qa.shape[0]} Q values", path or None)
    solved = (qa >= 1) & (table.status != "none") & np.all(np.isfinite(table.pos_m), axis=1)
    order = np.argsort(table.t_s[solved], kind="stable")
    t = table.t_s[solved][order]
    pos = table.pos_m[solved][order]
    qs = qa[solved][order]
    status = table.status[solved][order]
    if rover_epochs is not None and rover_epochs < t.shape[0]:
        raise InputError(
            f"{rover_epochs} rover epochs given but the solution has {t.shape[0]} solved epochs",
            path or None,
        )
    warnings: list[str] = []
    enu = np.full((t.shape[0], 3), np.nan)
    groups: dict[str, dict[str, Any] | None] = {}
    if truth is not None:
        if t.size and truth.ecef != _near_earth_surface(pos):
            frame = "ECEF" if truth.ecef else "a local frame"
            raise InputError(
                f"the truth is in {frame} but the solution's positions are not; "
                "expected solution and truth in the same frame",
                path or None,
            )
        enu = truth.enu_errors(t, pos, tol_s=tol_s)
        if window_s is not None:
            inside = (t >= window_s[0] - WINDOW_TOL_S) & (t <= window_s[1] + WINDOW_TOL_S)
            enu[~inside] = np.nan
        has = np.all(np.isfinite(enu), axis=1)
        for name, qset in GROUPS:
            sel = has if qset is None else has & np.isin(qs, qset)
            groups[name] = error_group_stats(enu[sel])
        if t.size and not np.any(has):
            warnings.append("no solved epoch has a truth (check the truth times or --truth-window)")
        elif np.any(has):
            med = float(np.median(np.linalg.norm(enu[has], axis=1)))
            if med > 1000.0:
                warnings.append(f"median 3-D error {med / 1000.0:.1f} km: is this the right truth?")
    return SolutionComparison(
        label=label, path=path, t_s=t, q=qs, status=status, enu_err_m=enu,
        rover_epochs=rover_epochs, groups=groups, warnings=tuple(warnings),
    )  # fmt: skip


def compare_files(
    paths: Sequence[PathLike],
    truth: Truth | None = None,
    *,
    labels: Sequence[str] | None = None,
    rover_epochs: int | None = None,
    window: str | tuple[float, float] | None = None,
    tol_s: float = MATCH_TOL_S,
) -> list[SolutionComparison]:
    """Read and compare several solution files.

    Parameters
    ----------
    paths : sequence of path-like
    truth : Truth, optional
    labels : sequence of str, optional
        One per path at most; the rest default to :func:`default_labels`.
    rover_epochs : int, optional
    window : str or (start_s, end_s), optional
        Truth window; a string is parsed by :func:`parse_time_window` with the earliest
        solved epoch as the reference date.
    tol_s : float
    """
    if not paths:
        raise InputError("no solution files given")
    labs = list(default_labels(paths))
    if labels:
        if len(labels) > len(paths):
            raise InputError(f"--label given {len(labels)} times for {len(paths)} solution files")
        labs[: len(labels)] = list(labels)
    loaded = [load_solution(p) for p in paths]
    win: tuple[float, float] | None
    if isinstance(window, str):
        firsts = [float(np.min(tb.t_s)) for tb, _ in loaded if len(tb)]
        win = parse_time_window(window, min(firsts) if firsts else 0.0)
    else:
        win = window
    return [
        compare_solution(
            tb, q, truth, label=lab, path=str(p), rover_epochs=rover_epochs, window_s=win, tol_s=tol_s
        )  # fmt: skip
        for (tb, q), lab, p in zip(loaded, labs, paths, strict=True)
    ]


# --------------------------------------------------------------------------- reports
def _cm(v: float | None) -> str:
    return "-" if v is None or not math.isfinite(v) else f"{100.0 * v:.2f}"


def _pct(v: float | None) -> str:
    return "-" if v is None or not math.isfinite(v) else f"{v:.2f}"


def _aligned(rows: Sequence[Sequence[str]], headers: Sequence[str]) -> str:
    width = [max(len(h), *(len(r[j]) for r in rows)) if rows else len(h) for j, h in enumerate(headers)]

    def line(cells: Sequence[str]) -> str:
        return "  ".join(c.ljust(w) if j == 0 else c.rjust(w)
                         for j, (c, w) in enumerate(zip(cells, width, strict=True))).rstrip()  # fmt: skip

    return "\n".join([line(headers), "  ".join("-" * w for w in width), *(line(r) for r in rows)])


_HV_KEYS = ("H_rms_m", "H_95_m", "V_rms_m", "V_95_m")


def _q_text(hist: Mapping[int, int]) -> str:
    return " ".join(f"{k}:{v}" for k, v in sorted(hist.items()))


SUMMARY_HEADERS = (
    "solution", "solved", "Q hist", "fix %", "fix % rover", "TTFF s",
    "fix n", "fix H rms", "fix H 95", "fix V rms", "fix V 95",
    "all n", "all H rms", "all H 95", "all V rms", "all V 95", "3D>10cm",
)  # fmt: skip


def summary_table(results: Sequence[SolutionComparison]) -> str:
    """One row per solution: epochs, Q histogram, fix rates (%), time to first fix (s),
    fixed-epoch and all-epoch H/V RMS and 95 % (cm), all-epoch count of 3-D errors > 10 cm."""
    rows = []
    for r in results:
        fx, al = r.groups.get("fixed"), r.groups.get("all")
        ttff = r.ttff_s
        rows.append([
            r.label, str(r.epochs_solved), _q_text(r.q_hist), _pct(r.fix_rate_pct_of_solved),
            _pct(r.fix_rate_pct_of_rover_epochs), "-" if ttff is None else f"{ttff:.0f}",
            str(fx["n"]) if fx else "0", *(_cm(fx[k] if fx else None) for k in _HV_KEYS),
            str(al["n"]) if al else "0", *(_cm(al[k] if al else None) for k in _HV_KEYS),
            str(al["n_3d_err_gt_0.10m"]) if al else "-",
        ])  # fmt: skip
    return _aligned(rows, SUMMARY_HEADERS) + "\n(errors in cm; fix % of solved and of rover epochs)"


DETAIL_HEADERS = ("solution", "epochs", "n", "H rms", "H 95", "V rms", "V 95", "mean E", "mean N",
                  "mean U", "H max", "V max", "3D>10cm")  # fmt: skip


def detail_table(results: Sequence[SolutionComparison]) -> str:
    """Rows per solution and group (fixed, float, all): n, H/V RMS and 95 %, mean ENU, H/V
    max (cm) and the count of 3-D errors above 10 cm."""
    rows = []
    for r in results:
        for name, _ in GROUPS:
            g = r.groups.get(name)
            if g is None:
                rows.append([r.label, name, "0", *("-" for _ in range(10))])
                continue
            rows.append([
                r.label, name, str(g["n"]),
                *(_cm(g[k]) for k in _HV_KEYS),
                *(_cm(v) for v in g["mean_enu_m"]), _cm(g["H_max_m"]), _cm(g["V_max_m"]),
                str(g["n_3d_err_gt_0.10m"]),
            ])  # fmt: skip
    return _aligned(rows, DETAIL_HEADERS) + "\n(cm)"


def comparison_report(
    results: Sequence[SolutionComparison],
    truth: Truth | None,
    window_s: tuple[float, float] | None = None,
    tol_s: float = MATCH_TOL_S,
) -> dict[str, Any]:
    """Machine-readable summary: truth description, window, tolerances and one entry per
    solution (:meth:`SolutionComparison.to_dict`; full precision, metres, NaN as null)."""
    truth_d: dict[str, Any] | None = None
    if truth is not None:
        truth_d = {"source": truth.source, "kind": "point" if truth.is_point else "trajectory",
                   "frame": "ecef" if truth.ecef else "local", "note": truth.note}  # fmt: skip
        if truth.is_point:
            truth_d["pos_m"] = [float(v) for v in truth.pos_m.reshape(3)]
        else:
            truth_d["epochs"] = int(truth.pos_m.shape[0])
    return {
        "truth": truth_d,
        "truth_window": None if window_s is None else [gpst_text(window_s[0]), gpst_text(window_s[1])],
        "truth_window_s": None if window_s is None else [float(window_s[0]), float(window_s[1])],
        "match_tol_s": tol_s,
        "err_3d_threshold_m": ERR_3D_THRESHOLD_M,
        "percentile_method": "linear",
        "solutions": [r.to_dict() for r in results],
    }


def write_json(report: Mapping[str, Any], path: PathLike) -> None:
    """Write ``report`` as indented JSON (temporary file, then rename)."""
    text = json.dumps(report, indent=1, allow_nan=False)
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as fh:
        fh.write(text + "\n")


# --------------------------------------------------------------------------- plots
#: Colour and legend name of each ``Q`` (RTKLIB's rtkplot colours).
Q_STYLE = {
    1: ("tab:green", "fixed (Q=1)"),
    2: ("orange", "float (Q=2)"),
    3: ("tab:purple", "SBAS (Q=3)"),
    4: ("tab:blue", "DGPS (Q=4)"),
    5: ("tab:red", "single (Q=5)"),
    6: ("tab:brown", "PPP (Q=6)"),
}
_FONT = 9


def plot_comparison(
    results: Sequence[SolutionComparison],
    *,
    title: str = "Position error against truth",
    range_m: float | None = None,
) -> Figure:
    """ENU error time series (three panels) and horizontal error scatter, one row per
    solution, points coloured by ``Q``.

    Parameters
    ----------
    results : sequence of SolutionComparison
        Only epochs with a truth (and in the window) are drawn.
    title : str
    range_m : float, optional
        Symmetric axis limit ±range_m (m) for all error axes; points beyond are not drawn
        (counted as "off-scale" in the panel title). Default: each panel's full range.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    if not results:
        raise InputError("plot_comparison needs at least one solution")
    t_all = [r.t_s[np.all(np.isfinite(r.enu_err_m), axis=1)] for r in results]
    starts = [float(t.min()) for t in t_all if t.size]
    t0 = min(starts) if starts else 0.0
    n = len(results)
    fig = Figure(figsize=(15.0, 2.7 * n + 0.9), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(n, 4, squeeze=False, gridspec_kw={"width_ratios": [1.0, 1.0, 1.0, 0.8]})
    comp = ("East", "North", "Up")
    for i, r in enumerate(results):
        has = np.all(np.isfinite(r.enu_err_m), axis=1)
        tt = r.t_s - t0
        for k in range(4):
            ax = axes[i, k]
            for qv in sorted(set(r.q[has].tolist())):
                sel = has & (r.q == qv)
                colour, name = Q_STYLE.get(qv, ("k", f"Q={qv}"))
                name = f"{name}: {int(sel.sum())}"
                if k < 3:
                    ax.plot(tt[sel], r.enu_err_m[sel, k], ".", ms=3, color=colour, label=name)
                else:
                    ax.plot(r.enu_err_m[sel, 0], r.enu_err_m[sel, 1], ".", ms=3, color=colour, label=name)
            outside = 0
            if range_m is not None:
                cols = [k] if k < 3 else [0, 1]
                outside = int(np.sum(np.any(np.abs(r.enu_err_m[has][:, cols]) > range_m, axis=1)))
                ax.set_ylim(-range_m, range_m)
                if k == 3:
                    ax.set_xlim(-range_m, range_m)
            extra = f" ({outside} off-scale)" if outside else ""
            if k < 3:
                ax.set_title(f"{r.label}: {comp[k]} error{extra}", fontsize=_FONT + 1)
                ax.set_ylabel(f"{comp[k]} error (m)", fontsize=_FONT)
                ax.set_xlabel(f"Time since {gpst_text(t0)} GPST (s)", fontsize=_FONT)
            else:
                ax.set_title(f"{r.label}: E-N error{extra}", fontsize=_FONT + 1)
                ax.set_xlabel("East error (m)", fontsize=_FONT)
                ax.set_ylabel("North error (m)", fontsize=_FONT)
                ax.axvline(0.0, color="k", lw=0.5)
                ax.set_aspect("equal", adjustable="datalim")
            ax.axhline(0.0, color="k", lw=0.5)
            ax.grid(True, alpha=0.3)
            if not np.any(has):
                ax.text(0.5, 0.5, "no epochs with truth", transform=ax.transAxes, ha="center", va="center")
            if k in (0, 3):
                ax.legend(fontsize=_FONT - 1, markerscale=2.5, loc="best")
    fig.suptitle(title, fontsize=_FONT + 3)
    return fig


__all__ = [
    "GROUPS",
    "MATCH_TOL_S",
    "Q_OF_STATUS",
    "SolutionComparison",
    "Truth",
    "compare_files",
    "compare_solution",
    "comparison_report",
    "count_rover_epochs",
    "default_labels",
    "detail_table",
    "error_group_stats",
    "load_solution",
    "parse_time_window",
    "parse_truth",
    "plot_comparison",
    "read_truth_file",
    "summary_table",
    "truth_from_llh",
    "truth_from_xyz",
    "write_json",
]

"""RTKLIB ``.pos`` solution files (llh or ECEF form): writer and reader.

See :mod:`robustrtk.io.solution` for the status mapping (``Q``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np

from robustrtk.core import STATUSES, FloatArray, InputError, Solution
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic, geodetic2ecef
from robustrtk.io.solution_table import (
    PathLike,
    SolutionTable,
    check_status,
    open_atomic_text,
    read_text_lines,
    require_ecef,
    writable_solutions,
)
from robustrtk.timeutil import gpst_from_calendar, gpst_text, utc2gpst

__all__ = [
    "pos_column_header",
    "pos_header",
    "pos_lines",
    "pos_table_lines",
    "read_pos",
    "satellites",
    "write_pos",
]

#: Largest magnitude of a number of a solution line (coordinates in m or deg, σ in m).
_MAX_FIELD = 1e12
_Q_OF_STATUS = {"fixed": 1, "partial": 1, "float": 2, "dgnss": 4, "code": 4, "single": 5}
_STATUS_OF_Q = {1: "fixed", 2: "float", 3: "dgnss", 4: "dgnss", 5: "single", 6: "float"}


def _signed_sqrt(v: FloatArray) -> FloatArray:
    """RTKLIB's convention for off-diagonal terms: ``sign(c) sqrt(|c|)``."""
    return np.sign(v) * np.sqrt(np.abs(v))


def _signed_square(v: FloatArray) -> FloatArray:
    return np.sign(v) * v * v


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
    inputs: Sequence[str] = (),
    ref_pos_ecef_m: Sequence[float] | FloatArray | None = None,
    header_lines: Sequence[str] = (),
    pos_frame: str = "ecef",
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
    inputs : sequence of str
        Input files, one ``% inp file  :`` line each (rover, base, navigation), as RTKLIB.
    ref_pos_ecef_m : array_like, shape (3,), optional
        The base (reference) position, ECEF (m): a ``% ref pos   :`` line in the frame of the
        file (llh: deg, deg, m; ecef: m), as RTKLIB writes it for a fixed base.
    header_lines : sequence of str
        Extra header lines (each written after ``"% "``), after the input files.
    pos_frame : {"ecef", "local"}
        Frame of the solutions' positions, as the solver reports it; ``"local"`` is refused
        (a ``.pos`` holds geodetic positions). Positions are not judged by their magnitude:
        an epoch far off the Earth is written as it is.

    Notes
    -----
    ``ns`` is the number of satellites used, references included (``n_sat``; ``n_used``
    for producers that count satellites as their rows, single-point solutions); ``age`` is
    the age of differential ``age_s`` (0.00 when unknown); ``ratio`` is capped at 999.9 and
    NaN written as 0.0.

    Raises
    ------
    InputError
        Unknown ``frame`` or status, or a local ``pos_frame`` (write CSV instead).
    """
    if frame not in ("llh", "ecef"):
        raise InputError(f"frame: expected 'llh' or 'ecef', got {frame!r}", str(path))
    require_ecef(pos_frame, "an RTKLIB .pos", path)
    head_lines = pos_header(inputs, ref_pos_ecef_m, frame, header_lines)
    lines = pos_lines(solutions, frame)
    with open_atomic_text(path) as fh:
        fh.write("".join(f"{hl}\n" for hl in head_lines))
        fh.write("\n".join(pos_column_header(frame)) + "\n")
        fh.write("".join(lines))


def pos_column_header(frame: str = "llh") -> tuple[str, ...]:
    """The column-name lines of a ``.pos`` file (after :func:`pos_header`)."""
    return tuple(_POS_LLH_HEAD if frame == "llh" else _POS_XYZ_HEAD)


def pos_lines(solutions: Iterable[Solution], frame: str = "llh") -> list[str]:
    """The solution lines of :func:`write_pos` (newline-terminated; unsolved epochs and
    non-finite positions have none)."""
    sols, pos = _writable(solutions)
    if not sols:
        return []
    ages = (float(getattr(s, "age_s", 0.0)) for s in sols)
    return pos_table_lines(
        [s.t_s for s in sols],
        pos,
        np.array([np.asarray(s.cov_m2, float) for s in sols]).reshape(-1, 3, 3),
        [s.status for s in sols],
        [int(s.n_sat) if s.n_sat > 0 else int(s.n_used) for s in sols],
        [min(a, 9999.99) if math.isfinite(a) and a > 0 else 0.0 for a in ages],
        [s.ratio for s in sols],
        frame,
    )


def pos_table_lines(
    t_s: Sequence[float],
    pos_ecef_m: FloatArray,
    cov_m2: FloatArray,
    status: Sequence[str],
    n_sat: Sequence[int],
    age_s: Sequence[float],
    ratio: Sequence[float],
    frame: str = "llh",
) -> list[str]:
    """The ``.pos`` lines of n writable solutions given as columns (what :func:`pos_lines`
    writes for the same solutions): times (GPST s), finite ECEF positions (n, 3) and their
    covariances (n, 3, 3) (m, m²), statuses (not ``"none"``), ``ns``, ages (s, 0 when
    unknown) and ratios (NaN written as 0).

    The numbers of all lines are computed as arrays and each line is formatted with one
    ``%`` operation (the ``f`` and ``d`` conversions write what the format specifications
    ``14.9f``, ``3d``... write)."""
    n = len(t_s)
    if n == 0:
        return []
    pos = np.asarray(pos_ecef_m, float).reshape(n, 3)
    cov = np.asarray(cov_m2, float).reshape(n, 3, 3)
    if frame == "llh":
        lat, lon, h = ecef2geodetic(pos)
        rot = ecef2enu_rotation(lat, lon)
        c = rot @ cov @ np.swapaxes(rot, 1, 2)  # ENU covariance
        sd = np.stack(
            [np.sqrt(np.abs(c[:, 1, 1])), np.sqrt(np.abs(c[:, 0, 0])),
             np.sqrt(np.abs(c[:, 2, 2])), _signed_sqrt(c[:, 1, 0]),
             _signed_sqrt(c[:, 0, 2]), _signed_sqrt(c[:, 2, 1])], axis=1
        )  # fmt: skip
        coords = np.stack([np.degrees(lat), np.degrees(lon), h], axis=1)
        body = " %14.9f %14.9f %10.4f %3d %3d %8.4f %8.4f %8.4f %8.4f %8.4f %8.4f %6.2f %6.1f\n"
    else:
        sd = np.stack(
            [np.sqrt(np.abs(cov[:, 0, 0])), np.sqrt(np.abs(cov[:, 1, 1])),
             np.sqrt(np.abs(cov[:, 2, 2])), _signed_sqrt(cov[:, 0, 1]),
             _signed_sqrt(cov[:, 1, 2]), _signed_sqrt(cov[:, 2, 0])], axis=1
        )  # fmt: skip
        coords = pos
        body = " %14.4f %14.4f %14.4f %3d %3d %8.4f %8.4f %8.4f %8.4f %8.4f %8.4f %6.2f %6.1f\n"
    sd = np.where(np.isfinite(sd), sd, 0.0)
    q = [_Q_OF_STATUS[st] for st in status]
    ns = [min(k, 999) for k in n_sat]
    rat = [min(r if math.isfinite(r) else 0.0, 999.9) for r in ratio]
    head, times = _time_columns(np.asarray(t_s, dtype=float))
    # Python floats and ints: the rows are formatted as f-strings would format them
    cols = zip(*times, *coords.T.tolist(), q, ns, *sd.T.tolist(), age_s, rat, strict=True)
    line = head + body
    return [line % row for row in cols]


def _writable(solutions: Iterable[Solution]) -> tuple[list[Solution], FloatArray]:
    """:func:`robustrtk.io.solution_table.writable_solutions` and their positions (n, 3),
    the finite positions tested as one array when every position has three coordinates."""
    cand = [s for s in solutions if s.status != "none"]
    try:
        pos = np.array([s.pos_m for s in cand], dtype=float)
    except (ValueError, TypeError):
        pos = None
    if pos is None or pos.shape != (len(cand), 3):
        sols = writable_solutions(cand)
        return sols, np.array([np.asarray(s.pos_m, float) for s in sols]).reshape(len(sols), 3)
    finite = np.isfinite(pos).all(axis=1)
    sols = [s for s, ok in zip(cand, finite.tolist(), strict=True) if ok]
    if not {s.status for s in sols} <= _KNOWN_STATUSES:
        for s in sols:
            check_status(s.status)  # the first unknown one, as writable_solutions
    return sols, pos[finite]


_KNOWN_STATUSES = frozenset(STATUSES)


def _time_columns(t_s: FloatArray) -> tuple[str, list[list[str] | list[int]]]:
    """The ``%`` format and the columns of :func:`robustrtk.timeutil.gpst_text` (3
    decimals, fraction always written) of every time: date text (once per day), hour,
    minute, second and millisecond of the integer milliseconds it rounds to."""
    if t_s.size == 0 or not np.all(np.abs(t_s) < 1e12):
        return "%s", [[gpst_text(float(t), trim_zero_fraction=False) for t in t_s]]
    ticks = np.rint(t_s * 1000.0).astype(np.int64)  # round(): half to even, as np.rint
    sec, frac = np.divmod(ticks, 1000)
    days, sod = np.divmod(sec, 86400)
    hour, rest = np.divmod(sod, 3600)
    minute, s = np.divmod(rest, 60)
    day_list = days.tolist()
    text = {d: gpst_text(d * 86400.0, 0).rsplit(" ", 1)[0] for d in set(day_list)}
    dates = [text[d] for d in day_list]
    return "%s %02d:%02d:%02d.%03d", [dates, hour.tolist(), minute.tolist(), s.tolist(), frac.tolist()]


def satellites(sol: Solution) -> int:
    """Satellites of a solution as RTKLIB's ``ns`` counts them: ``n_sat`` when the producer
    counted them (DD modes), else ``n_used`` (single-point rows are satellites)."""
    return int(sol.n_sat) if sol.n_sat > 0 else int(sol.n_used)


def pos_header(
    inputs: Sequence[str] = (),
    ref_pos_ecef_m: Sequence[float] | FloatArray | None = None,
    frame: str = "llh",
    extra: Sequence[str] = (),
) -> list[str]:
    """The ``%`` lines of a ``.pos`` header before the column names, in RTKLIB's layout.

    ``% program   :`` once, one ``% inp file  :`` per input, the ``extra`` lines, then
    ``% ref pos   :`` when a reference position is given, then a lone ``%``.

    Parameters
    ----------
    inputs : sequence of str
        Input file names.
    ref_pos_ecef_m : array_like, shape (3,), optional
        Reference (base) position, ECEF (m).
    frame : {"llh", "ecef"}
        How the reference position is written: latitude, longitude (deg, 9 decimals) and
        ellipsoidal height (m, 4 decimals), or x, y, z (m, 4 decimals).
    extra : sequence of str
        More lines, each written after ``"% "``.

    Returns
    -------
    list of str
        Lines without newline.

    Raises
    ------
    InputError
        A reference position that is not three finite numbers.
    """
    from robustrtk.version import __version__

    lines = [f"% program   : robustrtk ver.{__version__}"]
    lines += ["% inp file  : " + str(p).replace("\r", "").replace("\n", " ") for p in inputs]
    lines += [f"% {hl}".replace("\r", "").replace("\n", " ") for hl in extra]
    if ref_pos_ecef_m is not None:
        ref = np.asarray(ref_pos_ecef_m, float).reshape(-1)
        if ref.shape != (3,) or not np.all(np.isfinite(ref)):
            raise InputError(f"ref pos: expected three finite ECEF numbers (m), got {ref_pos_ecef_m!r}")
        if frame == "llh":
            lat, lon, h = (float(v) for v in ecef2geodetic(ref))
            lines.append(f"% ref pos   :{math.degrees(lat):14.9f} {math.degrees(lon):14.9f} {h:10.4f}")
        else:
            lines.append(f"% ref pos   :{ref[0]:14.4f} {ref[1]:14.4f} {ref[2]:14.4f}")
    lines.append("%")
    return lines


def _age(sol: Solution) -> float:
    """Age of differential (s) to write: ``age_s`` when finite, capped at 9999.99."""
    age = float(getattr(sol, "age_s", 0.0))
    return min(age, 9999.99) if math.isfinite(age) and age > 0 else 0.0


def _parse_pos_time(tokens: list[str], path: PathLike, line: int) -> float:
    """Seconds (in the file's scale) from ``yyyy/mm/dd hh:mm:ss.sss`` or ``week tow``."""
    try:
        if "/" in tokens[0]:
            y, mo, d = (int(v) for v in tokens[0].split("/"))
            hh, mm, ss = tokens[1].split(":")
            if not (1 <= mo <= 12 and 1 <= d <= 31 and 0 <= int(hh) <= 24 and 0 <= int(mm) <= 59):
                raise ValueError(tokens[0])
            t = gpst_from_calendar(y, mo, d, int(hh), int(mm), float(ss))
        else:
            t = float(tokens[0]) * 604_800.0 + float(tokens[1])
        if not abs(t) <= 1e11:  # finite, within a few thousand years
            raise ValueError(tokens[0])
        return t
    except (ValueError, IndexError, OverflowError):
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
    output) are ignored; a short line (time, three coordinates, ``Q``, ``ns`` and fewer than
    the eight columns after them) gives NaN for the missing σ, age and ratio.

    Raises
    ------
    InputError
        No column header, unsupported form (dms angles, ENU baselines, JST), or a data line
        with fewer than 7 fields or unparsable ones.
    """
    lines = read_text_lines(path)
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
        if len(tok) < 7:
            raise InputError(
                f"expected at least 7 fields (time, 3 coordinates, Q, ns), got {len(tok)}", str(path), ln
            )
        t.append(_parse_pos_time(tok, path, ln))
        try:
            vals = [float(v) for v in tok[2:15]] + [math.nan] * max(0, 15 - len(tok))
        except ValueError:
            raise InputError("expected numbers after the time", str(path), ln) from None
        if not all(math.isfinite(v) for v in vals[: min(len(tok), 15) - 2]):
            raise InputError("expected finite numbers after the time (found nan or inf)", str(path), ln)
        if not all(abs(v) < _MAX_FIELD for v in vals[: min(len(tok), 15) - 2]):
            raise InputError(
                f"expected numbers below {_MAX_FIELD:.0e} in magnitude after the time", str(path), ln
            )
        if vals[3] != int(vals[3]) or vals[4] != int(vals[4]) or not 0 <= vals[4] < 2**31:
            raise InputError(f"Q and ns: expected integers, got {tok[5]} {tok[6]}", str(path), ln)
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
        rot = ecef2enu_rotation(lat, lon)
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

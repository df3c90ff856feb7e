"""Comparison of solutions with a truth: loading, fix rate, time to first fix and error
statistics per group (fixed, float, all).

See :mod:`robustrtk.eval.compare` for the definitions.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from robustrtk.core import FloatArray, InputError, IntArray
from robustrtk.eval.metrics import hv_error_stats
from robustrtk.eval.truth import (
    MATCH_TOL_S,
    PathLike,
    Truth,
    near_earth_surface,
    parse_time_window,
    read_text_lines,
)
from robustrtk.io.solution import SolutionTable, read_pos, read_solution_csv

__all__ = [
    "ERR_3D_THRESHOLD_M",
    "GROUPS",
    "Q_NAMES",
    "Q_OF_STATUS",
    "WINDOW_TOL_S",
    "SolutionComparison",
    "compare_files",
    "compare_solution",
    "count_rover_epochs",
    "default_labels",
    "error_group_stats",
    "load_solution",
]

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


# --------------------------------------------------------------------------- solutions
def _pos_q_column(path: PathLike, n_expected: int) -> IntArray:
    """RTKLIB ``Q`` of each data line of a ``.pos`` file already read by :func:`read_pos`."""
    q: list[int] = []
    for ln, raw in enumerate(read_text_lines(path), start=1):
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
    lines = read_text_lines(path)
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
    hv = hv_error_stats(e)
    d3 = np.linalg.norm(e, axis=1)
    return {
        "n": int(e.shape[0]),
        **{k: hv[k] for k in ("H_rms_m", "H_95_m", "V_rms_m", "V_95_m")},
        "mean_enu_m": [float(x) for x in e.mean(axis=0)],
        "H_max_m": hv["H_max_m"],
        "V_max_m": hv["V_max_m"],
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

    def horizontal_percentiles_m(self) -> tuple[float, float] | None:
        """50th and 95th percentiles of the horizontal error (m) over the epochs with a truth
        (None without any)."""
        e = self.enu_err_m[np.all(np.isfinite(self.enu_err_m), axis=1)]
        if not e.shape[0]:
            return None
        p50, p95 = np.percentile(np.hypot(e[:, 0], e[:, 1]), [50.0, 95.0])
        return float(p50), float(p95)

    @property
    def gsdc_score_m(self) -> float | None:
        """The Google Smartphone Decimeter Challenge score: mean of the horizontal p50 and
        p95 errors (m) over the epochs with a truth; None without any."""
        pct = self.horizontal_percentiles_m()
        return None if pct is None else 0.5 * (pct[0] + pct[1])

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
        if t.size and truth.ecef != near_earth_surface(pos):
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

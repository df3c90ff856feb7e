"""A run's solutions as arrays: :class:`SolutionSeries` and its :class:`RunSummary`.

What the entry points of :mod:`robustrtk.pipeline.api` return and the ``robustrtk solve``
command writes: times, positions in a stated frame (``ecef`` or ``local``), status, σ and
the run's diagnostics, with writers (``.pos``, CSV) and a pandas view.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from robustrtk.core import GPS_EPOCH, FloatArray, InputError, IntArray, Solution
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.io.solution_csv import write_solution_csv
from robustrtk.io.solution_pos import satellites, write_pos
from robustrtk.io.solution_table import POS_FRAMES
from robustrtk.pipeline.results import DiagRow, flag_counts

PathLike = str | os.PathLike[str]

#: Statuses counted as a fix (integer ambiguities resolved).
FIXED_STATUSES = ("fixed", "partial")


@dataclass(frozen=True)
class RunSummary:
    """The numbers of a run, as the end-of-run summary prints them.

    Attributes
    ----------
    epochs : int
        Epochs in the series (solved or not).
    solved : int
        Epochs with a position (status other than ``none``).
    by_status : dict of str to int
        Epochs per status.
    fixed : int
        Epochs with status ``fixed`` or ``partial``.
    fix_rate : float
        ``fixed / epochs`` (NaN when there is no epoch).
    time_to_first_fix_s : float
        Seconds from the first epoch to the first fixed one (NaN when none is fixed).
    rows_downweighted : int
        DD rows whose robust factor γ was above 1 (variance inflated) but finite.
    rows_rejected : int
        DD rows with γ = ∞ (left out of the update).
    epochs_flagged : int
        Epochs with at least one down-weighted or rejected row.
    """

    epochs: int
    solved: int
    by_status: dict[str, int]
    fixed: int
    fix_rate: float
    time_to_first_fix_s: float
    rows_downweighted: int
    rows_rejected: int
    epochs_flagged: int


@dataclass(frozen=True)
class SolutionSeries:
    """T epochs of solutions as arrays, with the records and diagnostics they came from.

    Attributes
    ----------
    t_s : ndarray, shape (T,)
        Epoch times (s): GPST seconds since 1980-01-06 for GNSS, the table's clock for
        pseudolite tables.
    pos_m : ndarray, shape (T, 3)
        Positions (m) in ``frame``: ECEF for GNSS, the site's local frame for pseudolites;
        NaN rows where unsolved.
    cov_m2 : ndarray, shape (T, 3, 3)
        Position covariances (m²) in the same frame.
    status : ndarray of str, shape (T,)
        ``fixed``, ``partial``, ``float``, ``dgnss``, ``code``, ``single`` or ``none``.
    n_used : ndarray of int, shape (T,)
        Observations (DDs, or satellites for SPP) used; the satellites used are
        :attr:`n_sat`.
    ratio : ndarray, shape (T,)
        Ratio-test value of the epoch's ambiguity search (NaN when none).
    frame : {"ecef", "local"}
    mode : str
        ``spp``, ``dgnss``, ``rtk`` or ``dpl``.
    solutions : tuple of Solution
        The per-epoch records (what the writers take).
    diagnostics : tuple of DiagRow
        One row per DD and epoch (DD modes; empty for SPP).
    info : dict
        Facts about the run (references, epochs paired, signals, base position...).
    """

    t_s: FloatArray
    pos_m: FloatArray
    cov_m2: FloatArray
    status: npt.NDArray[np.str_]
    n_used: IntArray
    ratio: FloatArray
    frame: str
    mode: str
    solutions: tuple[Solution, ...] = ()
    diagnostics: tuple[DiagRow, ...] = ()
    info: dict[str, object] = field(default_factory=dict)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_solutions(
        cls,
        solutions: Iterable[Solution],
        mode: str,
        diagnostics: Iterable[DiagRow] = (),
        info: Mapping[str, object] | None = None,
        *,
        frame: str,
    ) -> SolutionSeries:
        """Stack :class:`Solution` records whose positions are in ``frame`` (``ecef`` or
        ``local``), as their producer states it: the frame is never judged from the
        positions' magnitude, so one wild epoch cannot turn a GNSS run into a local one.

        Raises
        ------
        InputError
            ``frame`` is neither ``ecef`` nor ``local``.
        """
        if frame not in POS_FRAMES:
            raise InputError(f"frame: expected one of {', '.join(POS_FRAMES)}, got {frame!r}")
        sols = tuple(solutions)
        T = len(sols)
        pos = np.array([np.asarray(s.pos_m, float) for s in sols], float).reshape(T, 3)
        cov = np.array([np.asarray(s.cov_m2, float) for s in sols], float).reshape(T, 3, 3)
        return cls(
            t_s=np.array([s.t_s for s in sols], float).reshape(T),
            pos_m=pos,
            cov_m2=cov,
            status=np.array([s.status for s in sols], dtype=str).reshape(T),
            n_used=np.array([s.n_used for s in sols], dtype=np.int64).reshape(T),
            ratio=np.array([s.ratio for s in sols], float).reshape(T),
            frame=frame,
            mode=mode,
            solutions=sols,
            diagnostics=tuple(diagnostics),
            info=dict(info or {}),
        )

    # ------------------------------------------------------------------ derived values
    def __len__(self) -> int:
        return int(self.t_s.shape[0])

    @property
    def n_sat(self) -> IntArray:
        """Satellites used per epoch, references included, shape (T,): the ``ns`` column of
        :meth:`to_pos` (:func:`robustrtk.io.solution_pos.satellites`; ``n_used`` of the
        epochs whose producer does not count satellites, i.e. single-point rows, and of a
        series built without its records)."""
        if len(self.solutions) != len(self):
            return np.asarray(self.n_used, dtype=np.int64).copy()
        return np.array([satellites(s) for s in self.solutions], dtype=np.int64).reshape(len(self))

    @property
    def sigma_m(self) -> FloatArray:
        """Standard deviations of the position components in ``frame``, shape (T, 3), m:
        ``σ_k = sqrt(C_kk)``."""
        with np.errstate(invalid="ignore"):
            return np.sqrt(np.diagonal(self.cov_m2, axis1=1, axis2=2))

    @property
    def solved(self) -> npt.NDArray[np.bool_]:
        """Epochs with a position, shape (T,)."""
        return (self.status != "none") & np.all(np.isfinite(self.pos_m), axis=1)

    def llh(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Geodetic latitude, longitude (deg) and ellipsoidal height (m), each (T,) (WGS84).

        Raises
        ------
        InputError
            The series is in a local frame (pseudolites).
        """
        self._need_ecef("llh")
        lat, lon, h = ecef2geodetic(self.pos_m)
        return np.degrees(lat), np.degrees(lon), h

    def sigma_enu_m(self) -> FloatArray:
        """σ east, north, up (m), shape (T, 3): ``C_enu = R C_ecef Rᵀ`` with ``R`` the
        ECEF→ENU rotation at each epoch's own position
        (:func:`robustrtk.geometry.frames.ecef2enu_rotation`)."""
        self._need_ecef("sigma_enu_m")
        lat, lon, _ = ecef2geodetic(np.where(np.isfinite(self.pos_m), self.pos_m, 0.0))
        rot = ecef2enu_rotation(lat, lon).reshape(-1, 3, 3)
        c = rot @ self.cov_m2 @ np.swapaxes(rot, 1, 2)
        with np.errstate(invalid="ignore"):
            return np.sqrt(np.diagonal(c, axis1=1, axis2=2))

    def fix_rate(self) -> float:
        """Fraction of all epochs with status ``fixed`` or ``partial`` (NaN for no epoch)."""
        n = len(self)
        return float(np.isin(self.status, FIXED_STATUSES).sum() / n) if n else float("nan")

    def time_to_first_fix_s(self) -> float:
        """Seconds from the first epoch to the first ``fixed``/``partial`` one (NaN when none)."""
        idx = np.flatnonzero(np.isin(self.status, FIXED_STATUSES))
        return float(self.t_s[idx[0]] - self.t_s[0]) if idx.size else float("nan")

    def summary(self) -> RunSummary:
        """Epoch counts, fix rate, time to first fix and the rows the robust filter flagged
        (for SPP, the satellites its FDE excluded: ``info["excluded_per_epoch"]``)."""
        excluded = self.info.get("excluded_per_epoch")
        tally = self.info.get("row_tally")
        return summarize(
            self.solutions,
            self.diagnostics,
            excluded if isinstance(excluded, (list, tuple)) else None,
            tally if isinstance(tally, dict) and not self.diagnostics else None,
        )

    # ------------------------------------------------------------------ output
    def to_pos(
        self,
        path: PathLike,
        *,
        frame: str = "llh",
        inputs: Sequence[str] = (),
        ref_pos_ecef_m: Sequence[float] | FloatArray | None = None,
    ) -> None:
        """Write an RTKLIB ``.pos`` (``frame`` ``llh`` or ``ecef``; GNSS series only), atomically;
        ``inputs`` and ``ref_pos_ecef_m`` become its ``% inp file`` and ``% ref pos`` lines."""
        self._need_ecef("to_pos")
        write_pos(
            self.solutions,
            path,
            frame=frame,
            inputs=inputs,
            ref_pos_ecef_m=ref_pos_ecef_m,
            pos_frame=self.frame,
        )

    def to_csv(self, path: PathLike) -> None:
        """Write the solution CSV of ``robustrtk solve --out x.csv`` (any frame), atomically."""
        write_solution_csv(self.solutions, path)

    def columns(self) -> dict[str, np.ndarray]:
        """The series as named columns of length T (what :meth:`to_dataframe` tabulates).

        ECEF series: ``gpst`` (datetime64[ns], GPS time scale), ``t_s``, ``x_ecef_m``,
        ``y_ecef_m``, ``z_ecef_m``, ``lat_deg``, ``lon_deg``, ``height_m``, ``sd_e_m``,
        ``sd_n_m``, ``sd_u_m``; local series: ``t_s``, ``x_m``, ``y_m``, ``z_m``,
        ``sd_x_m``, ``sd_y_m``, ``sd_z_m``; then ``status``, ``n_used``, ``n_sat``, ``ratio``.
        """
        cols: dict[str, np.ndarray] = {}
        if self.frame == "ecef":
            ns = np.where(np.isfinite(self.t_s), np.round(self.t_s * 1e9), 0).astype(np.int64)
            cols["gpst"] = np.datetime64(GPS_EPOCH, "ns") + ns.astype("timedelta64[ns]")
            cols["t_s"] = self.t_s
            for k, name in enumerate(("x_ecef_m", "y_ecef_m", "z_ecef_m")):
                cols[name] = self.pos_m[:, k]
            lat, lon, h = self.llh()
            cols["lat_deg"], cols["lon_deg"], cols["height_m"] = lat, lon, h
            sd = self.sigma_enu_m()
            for k, name in enumerate(("sd_e_m", "sd_n_m", "sd_u_m")):
                cols[name] = sd[:, k]
        else:
            cols["t_s"] = self.t_s
            sd = self.sigma_m
            for k, axis in enumerate("xyz"):
                cols[f"{axis}_m"] = self.pos_m[:, k]
            for k, axis in enumerate("xyz"):
                cols[f"sd_{axis}_m"] = sd[:, k]
        cols["status"] = self.status
        cols["n_used"] = self.n_used
        cols["n_sat"] = self.n_sat
        cols["ratio"] = self.ratio
        return cols

    def to_dataframe(self) -> Any:
        """A ``pandas.DataFrame`` of :meth:`columns`, one row per epoch.

        Raises
        ------
        ImportError
            pandas is not installed (it is optional: ``pip install pandas``).
        """
        try:
            import pandas as pd
        except ImportError:
            raise ImportError(
                "SolutionSeries.to_dataframe needs pandas, which robustrtk does not install: "
                "pip install pandas (or use SolutionSeries.columns(), a dict of numpy arrays)"
            ) from None
        return pd.DataFrame(self.columns())

    def _need_ecef(self, what: str) -> None:
        if self.frame != "ecef":
            raise InputError(f"{what}: needs ECEF (GNSS) positions; this series is in a local frame")


def summarize(
    solutions: Sequence[Solution],
    diagnostics: Iterable[DiagRow] = (),
    excluded_per_epoch: Sequence[int] | None = None,
    row_tally: Mapping[str, int] | None = None,
) -> RunSummary:
    """:class:`RunSummary` of solutions and their diagnostics rows.

    A row is *down-weighted* when its robust factor satisfies ``1 < γ < ∞`` and *rejected*
    when ``γ = ∞`` (algorithms.md §1); engine events (``kind == "event"``) are not rows.
    ``excluded_per_epoch`` (SPP: satellites excluded by FDE at each epoch) counts as
    rejected rows. ``row_tally`` (a run's ``info["row_tally"]``,
    :meth:`~robustrtk.pipeline.results.RowTally.as_dict`) gives the row and epoch counts of
    a run that kept no rows; it is added to what ``diagnostics`` counts.
    """
    by_status: dict[str, int] = {}
    for s in solutions:
        by_status[s.status] = by_status.get(s.status, 0) + 1
    n = len(solutions)
    fixed = sum(by_status.get(k, 0) for k in FIXED_STATUSES)
    first = next((s.t_s for s in solutions if s.status in FIXED_STATUSES), None)
    ttff = float(first - solutions[0].t_s) if first is not None else float("nan")
    tally: Mapping[str, int] = row_tally or {}
    down, rej, flagged = flag_counts(diagnostics)
    if excluded_per_epoch is not None:
        for sol, k in zip(solutions, excluded_per_epoch, strict=True):
            if k > 0:
                rej += int(k)
                flagged.add(sol.t_s)
    return RunSummary(
        epochs=n,
        solved=n - by_status.get("none", 0),
        by_status=dict(sorted(by_status.items())),
        fixed=fixed,
        fix_rate=fixed / n if n else float("nan"),
        time_to_first_fix_s=ttff,
        rows_downweighted=down + int(tally.get("rows_downweighted", 0)),
        rows_rejected=rej + int(tally.get("rows_rejected", 0)),
        epochs_flagged=len(flagged) + int(tally.get("epochs_flagged", 0)),
    )


__all__ = ["FIXED_STATUSES", "PathLike", "RunSummary", "SolutionSeries", "summarize"]

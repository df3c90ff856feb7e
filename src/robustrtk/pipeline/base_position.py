"""Where the base receiver is, and a check of a given base position.

:func:`resolve_base_position` by ``receivers.base_position``: a fixed ECEF point (or the
file header's), a trajectory file, or the base's own single-point solution per epoch
(moving base). :func:`check_base_position` refuses a fixed position far from the base's own
solution; :func:`first_fix_position` gives the filters' start from the rover's first
solvable epoch.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from robustrtk.core import FloatArray, InputError, ObsBatch
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.receivers import PositionSource, TrajectoryPosition
from robustrtk.io.solution_csv import read_solution_csv
from robustrtk.io.solution_pos import read_pos
from robustrtk.pipeline.config import Config, preset
from robustrtk.pipeline.gnss_inputs import PathLike
from robustrtk.pipeline.spp import SppEpoch, select_band1, solve_spp, solve_spp_each


def resolve_base_position(
    base: ObsBatch,
    base_pos_m: FloatArray | Sequence[float] | PositionSource | PathLike | None,
    cfg: Config | None = None,
    eph: EphemerisSource | None = None,
) -> FloatArray | PositionSource:
    """Where the base is, by ``cfg.receivers.base_position``.

    ``fixed``: the given ECEF position (checked), else the file header's with a warning.
    ``trajectory``: a :class:`~robustrtk.geometry.receivers.PositionSource`, or the path of a
    trajectory file (RTKLIB ``.pos`` or our solution CSV) interpolated per epoch.
    ``moving``: the base's own least-squares SPP solution at each of its epochs (RTKLIB's
    moving-base mode; needs ``eph``); epochs it cannot solve have no base position.
    """
    kind = "fixed" if cfg is None else cfg.receivers.base_position
    if kind == "moving":
        if base_pos_m is not None:
            raise InputError("base position: moving base takes its position from its own solution; give none")
        if eph is None:
            raise InputError("base position: a moving base needs navigation data")
        return own_solution_track(base, eph, 15.0 if cfg is None else cfg.gnss.elev_mask_deg)
    if kind == "trajectory":
        if isinstance(base_pos_m, (str, os.PathLike)):
            return trajectory_file(base_pos_m)
        if base_pos_m is None or not hasattr(base_pos_m, "position"):
            raise InputError("base position: trajectory mode expects a trajectory file (.pos or .csv)")
        return base_pos_m
    if hasattr(base_pos_m, "position"):
        return base_pos_m  # type: ignore[return-value]
    if base_pos_m is None:
        if base.approx_pos_m is None or not np.all(np.isfinite(base.approx_pos_m)):
            raise InputError("base position: none given and none in the base file header")
        warnings.warn(
            "base position taken from the RINEX header (APPROX POSITION XYZ); header "
            "positions may be wrong by metres: pass the surveyed position",
            stacklevel=3,
        )
        return np.asarray(base.approx_pos_m, float)
    if isinstance(base_pos_m, (str, os.PathLike)):
        raise InputError(f"base position: a file ({os.fspath(base_pos_m)}) needs base_position = trajectory")
    pos = np.asarray(base_pos_m, float).reshape(-1)
    if pos.shape != (3,) or not np.all(np.isfinite(pos)):
        raise InputError(f"base position: expected three finite ECEF numbers, got {base_pos_m!r}")
    return pos


def trajectory_file(path: PathLike) -> TrajectoryPosition:
    """A base trajectory from an RTKLIB ``.pos`` or a solution CSV (positions per epoch)."""
    p = os.fspath(path)
    table = read_solution_csv(p) if p.lower().endswith(".csv") else read_pos(p)
    ok = np.all(np.isfinite(table.pos_m), axis=1)
    if not ok.any():
        raise InputError("trajectory: no epoch with a position", p)
    return TrajectoryPosition(table.t_s[ok], table.pos_m[ok])


def own_solution_track(base: ObsBatch, eph: EphemerisSource, elev_mask_deg: float) -> TrajectoryPosition:
    """The base's least-squares SPP at each of its epochs (moving base), as a trajectory.

    Only the base's own epoch tags carry a position (``max_gap_s = 0``: no interpolation),
    so a rover epoch is solved against the base position of the same instant.
    """
    cfg = preset("spp").updated(elev_mask_deg=elev_mask_deg)
    sols = solve_spp(select_band1(base), eph, cfg)
    t = np.array([s.t_s for s in sols], float)
    pos = np.array([s.pos_ecef_m if s.status == "single" else np.full(3, np.nan) for s in sols], float)
    if not np.isfinite(pos).any():
        raise InputError("moving base: the base has no epoch with a single-point solution")
    return TrajectoryPosition(t, pos.reshape(-1, 3), max_gap_s=0.0, tol_s=0.6)


def _spp_of_epoch(band1: ObsBatch, i: int, eph: EphemerisSource, cfg: Config) -> SppEpoch:
    """Least-squares SPP of epoch ``i`` of ``band1`` alone (its observation arrays cut to
    that epoch)."""
    return _spp_of_epochs(band1, [i], eph, cfg)[0]


def _spp_of_epochs(band1: ObsBatch, idx: Sequence[int], eph: EphemerisSource, cfg: Config) -> list[SppEpoch]:
    """Least-squares SPP of each epoch ``idx`` of ``band1`` alone, in one vectorised pass
    (:func:`robustrtk.pipeline.spp.solve_spp_each`: each epoch's numbers as in a run of
    its own)."""
    k = np.asarray(idx, dtype=np.int64)
    some = replace(
        band1,
        t_s=band1.t_s[k],
        code_m=band1.code_m[k],
        phase_cyc=band1.phase_cyc[k],
        doppler_hz=band1.doppler_hz[k],
        cn0_dbhz=band1.cn0_dbhz[k],
        lli=band1.lli[k],
    )
    return solve_spp_each(some, eph, cfg)


def first_fix_position(rover: ObsBatch, eph: EphemerisSource, elev_mask_deg: float) -> FloatArray:
    """Least-squares SPP of the first solvable rover epoch (band-1 code): the filters' start."""
    band1 = select_band1(rover)
    spp_cfg = preset("spp").updated(elev_mask_deg=elev_mask_deg)
    for i in range(len(band1)):
        sol = _spp_of_epoch(band1, i, eph, spp_cfg)
        if sol.status == "single":
            return np.asarray(sol.pos_ecef_m, float)
    raise InputError("rover: no epoch with enough satellites for an initial position")


#: Largest accepted distance (m) between a given base position and the base's own SPP.
BASE_POSITION_TOL_M = 100.0


def base_spp_position(
    base: ObsBatch, eph: EphemerisSource, elev_mask_deg: float, n: int = 5
) -> FloatArray | None:
    """Median least-squares SPP of up to ``n`` solvable base epochs among its first ones
    (None when none solves): a quick check of a given base position."""
    band1 = select_band1(base)
    spp_cfg = preset("spp").updated(elev_mask_deg=elev_mask_deg)
    found: list[FloatArray] = []
    step = max(1, len(band1) // (4 * n))
    candidates = list(range(0, min(len(band1), 40 * n * step), step))
    # the candidates in order, ``n`` solved together at a time, until ``n`` of them solve
    for c0 in range(0, len(candidates), n):
        for sol in _spp_of_epochs(band1, candidates[c0 : c0 + n], eph, spp_cfg):
            if sol.status == "single" and np.all(np.isfinite(sol.pos_ecef_m)):
                found.append(np.asarray(sol.pos_ecef_m, float))
                if len(found) >= n:
                    break
        if len(found) >= n:
            break
    if not found:
        return None
    # np.median's numbers (middle value, or the mean of the two middle ones) for these
    # finite rows, without the numpy.ma import that np.median costs a command's start
    s = np.sort(np.array(found), axis=0)
    k = s.shape[0] // 2
    return s[k].copy() if s.shape[0] % 2 else (s[k - 1] + s[k]) / 2.0


def check_base_position(
    base: ObsBatch,
    eph: EphemerisSource,
    pos_m: FloatArray,
    elev_mask_deg: float,
    force: bool = False,
    tol_m: float = BASE_POSITION_TOL_M,
) -> float | None:
    """Refuse a fixed base position far from the base's own single-point solution.

    Parameters
    ----------
    base : ObsBatch
        Base observations.
    eph : EphemerisSource
        Broadcast ephemerides.
    pos_m : ndarray, shape (3,)
        The given base position (ECEF m).
    elev_mask_deg : float
        Elevation mask of the check's SPP.
    force : bool
        Accept any distance (the Earth-surface check still applies).
    tol_m : float
        Largest accepted distance (m).

    Returns
    -------
    float or None
        Distance (m) to the base's SPP; None when no base epoch could be solved.

    Raises
    ------
    InputError
        Position not near the Earth's surface, or farther than ``tol_m`` without ``force``.
    """
    pos = np.asarray(pos_m, float).reshape(3)
    r = float(np.linalg.norm(pos))
    if not (6.2e6 < r < 6.5e6):
        raise InputError(
            f"--base-pos: {r / 1e3:.6g} km from the Earth's centre; expected ECEF metres of a point "
            "near the Earth's surface"
        )
    spp = base_spp_position(base, eph, elev_mask_deg)
    if spp is None:
        return None
    d = float(np.linalg.norm(spp - pos))
    if d > tol_m and not force:
        raise InputError(
            f"--base-pos: {d:.1f} m from the base's own single-point solution "
            f"({spp[0]:.1f},{spp[1]:.1f},{spp[2]:.1f}); expected within {tol_m:.0f} m "
            "(check the position and its frame, or pass --force)"
        )
    return d


__all__ = [
    "BASE_POSITION_TOL_M",
    "base_spp_position",
    "check_base_position",
    "first_fix_position",
    "own_solution_track",
    "resolve_base_position",
    "trajectory_file",
]

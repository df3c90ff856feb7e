"""Inter-node ranges (algorithms.md §21): from our own DD carrier-phase RTK between the two
receivers' files (:func:`rtk_range_link`: fixed base at a surveyed position, else moving
base; per epoch, or one session value for static nodes), or from a file
(:func:`read_range_file`); a constant is :meth:`RangeLink.constant`."""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from robustrtk.core import FloatArray, InputError, ObsBatch
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.receivers import PositionSource
from robustrtk.io.rinex_nav import NavData
from robustrtk.pipeline.base_position import own_solution_track
from robustrtk.pipeline.coop.types import PathLike, RangeLink
from robustrtk.pipeline.gnss_inputs import load_obs, nav_source
from robustrtk.pipeline.rtk_gnss import rtk_gnss_config, solve_rtk


def rtk_range_link(
    a_obs: ObsBatch | PathLike,
    b_obs: ObsBatch | PathLike,
    nav: NavData | EphemerisSource | PathLike | Sequence[PathLike],
    *,
    a: str = "node1",
    b: str = "node2",
    b_pos_m: FloatArray | None = None,
    session: bool = False,
    freqs: str = "L1+L2",
    elev_mask_deg: float = 15.0,
    max_gap_s: float = 30.0,
) -> tuple[RangeLink, dict[str, object]]:
    """The range between two receivers from our DD carrier-phase RTK (``a`` rover, ``b`` base).

    ``b_pos_m`` surveyed: fixed base there; None: moving base (the base at its own
    single-point solution each epoch; the baseline vector is what RTK resolves, its length is
    the range). Per epoch ``r = |p_a − p_b|``, ``var = uᵀ C u`` with ``u`` the baseline unit
    vector and ``C`` the rover covariance (fixed and float epochs; others absent).
    ``session`` (static nodes): one value, the median over the fixed epochs (all solved ones
    when none is fixed), variance ``max(median var, (1.4826 MAD)²)``. Else an epoch without
    an RTK solution between two that are at most ``max_gap_s`` apart gets the interpolated
    range (:meth:`RangeLink.at`; 30 s as the base-epoch age, RTKLIB's ``maxage``).

    Returns
    -------
    RangeLink, info (fix counts, statuses)
    """
    eph = nav_source(nav)
    cfg = rtk_gnss_config(freqs=freqs, elev_mask_deg=elev_mask_deg)
    b_full = load_obs(b_obs, None)
    track: PositionSource | None = None
    if b_pos_m is None:
        cfg = cfg.updated(base_position="moving")
        track = own_solution_track(b_full, eph, elev_mask_deg)
    res = solve_rtk(a_obs, b_full, eph, None if b_pos_m is None else np.asarray(b_pos_m, float), cfg)
    t, r, v, fixed = [], [], [], []
    for s in res.solutions:
        if s.status not in ("fixed", "partial", "float") or not np.all(np.isfinite(s.pos_m)):
            continue
        pb = np.asarray(b_pos_m, float) if track is None else np.asarray(track.position(s.t_s), float)
        if not np.all(np.isfinite(pb)):
            continue
        d = np.asarray(s.pos_m, float) - pb
        rng_m = float(np.linalg.norm(d))
        u = d / rng_m
        t.append(s.t_s)
        r.append(rng_m)
        v.append(float(u @ np.asarray(s.cov_m2, float) @ u))
        fixed.append(s.status == "fixed")
    if not t:
        raise InputError("range from RTK: no epoch with an RTK solution between the two receivers")
    ta, ra, va, fa = np.array(t), np.array(r), np.array(v), np.array(fixed)
    info: dict[str, object] = {"rtk_epochs": int(ta.size), "rtk_fixed": int(fa.sum())}
    if session:
        sel = fa if fa.any() else np.ones(fa.size, bool)
        med = float(np.median(ra[sel]))
        mad = 1.4826 * float(np.median(np.abs(ra[sel] - med)))
        var = max(float(np.median(va[sel])), mad**2, 1e-8)
        info["session_range_m"] = med
        return RangeLink.constant(a, b, med, np.sqrt(var)), info
    return RangeLink(a, b, ta, ra, np.maximum(va, 1e-8), max_gap_s=max_gap_s), info


def read_range_file(path: PathLike, a: str, b: str, default_sigma_m: float = 0.05) -> RangeLink:
    """A range series: lines ``gpst_s range_m [sigma_m]`` (spaces or commas; ``#`` comments).

    Raises
    ------
    InputError
        Naming the file and line of a malformed row, a non-positive range or σ, or
        non-increasing times.
    """
    p = os.fspath(path)
    try:
        with open(p, encoding="utf-8") as fh:
            lines = fh.read().splitlines()
    except OSError as exc:
        raise InputError(f"cannot read the range file ({exc.strerror or exc})", p) from None
    except UnicodeDecodeError:
        raise InputError("range file is not text (expected lines 'gpst_s range_m [sigma_m]')", p) from None
    t: list[float] = []
    r: list[float] = []
    s: list[float] = []
    for n, line in enumerate(lines, 1):
        body = line.split("#", 1)[0].replace(",", " ").split()
        if not body:
            continue
        if len(body) not in (2, 3):
            raise InputError(f"expected 'gpst_s range_m [sigma_m]', got {len(body)} fields", p, n)
        try:
            vals = [float(x) for x in body]
        except ValueError:
            raise InputError(
                f"expected numbers 'gpst_s range_m [sigma_m]', got {line.strip()!r}", p, n
            ) from None
        sig = vals[2] if len(vals) == 3 else default_sigma_m
        if not (np.isfinite(vals[0]) and vals[1] > 0 and sig > 0):
            raise InputError("range_m and sigma_m must be positive, gpst_s finite", p, n)
        if t and vals[0] <= t[-1]:
            raise InputError(f"gpst_s must increase (after {t[-1]})", p, n)
        t.append(vals[0])
        r.append(vals[1])
        s.append(sig)
    if not t:
        raise InputError("range file has no rows (expected lines 'gpst_s range_m [sigma_m]')", p)
    return RangeLink(a, b, np.array(t), np.array(r), np.array(s) ** 2)


__all__ = ["read_range_file", "rtk_range_link"]

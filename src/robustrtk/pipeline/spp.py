"""Single point positioning (SPP) from code pseudoranges and broadcast ephemerides.

Two estimators, one :class:`robustrtk.pipeline.config.Config` (default :func:`preset`
``("spp")``); ``cfg.estimator.filter`` names the estimator (``lsq``, ``ekf``, ``ukf``):

* :func:`solve_spp` — per-epoch weighted least squares (Gauss–Newton) with one receiver
  clock per system, and RAIM-like fault detection and exclusion (FDE), on one L1/E1/B1
  code per satellite (:mod:`robustrtk.measurement.undifferenced`).
* :func:`solve_spp_kalman` — a robust Kalman filter (EKF or UKF) on code, Doppler and
  carrier phase of one or two bands, with an optional Rauch–Tung–Striebel smoother; model
  in :mod:`robustrtk.pipeline.spp_kalman`.

Both use the same corrections, variance model and least-squares core
(:mod:`robustrtk.measurement.undifferenced`). Settings read: ``elev_mask_deg``,
``code_sigma_m``, ``snr_mask_dbhz``, ``tropo``, ``iono``, ``robust`` (``none`` turns the
least-squares FDE off; the Kalman SPP's policy with ``k0``/``k1``) and the ``cfg.spp``
section; the Kalman SPP also ``filter``, ``ukf_*``, ``phase_sigma_m``, ``sigma_acc_m_s2``,
``reinit_epochs`` and ``smoother``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator
from typing import Any

import numpy as np

from robustrtk.core import FloatArray, ObsBatch
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.frames import ecef2geodetic
from robustrtk.io.rinex_nav import NavData
from robustrtk.measurement.undifferenced import (
    LsqSettings,
    LsqSolution,
    carrier_frequency,
    epoch_geometry,
    lsq_fde,
)
from robustrtk.pipeline.config import Config, preset
from robustrtk.pipeline.loop import EpochLoop
from robustrtk.pipeline.results import notify_progress
from robustrtk.pipeline.spp_batch import BlockFde, BlockGeometry, block_fde
from robustrtk.pipeline.spp_common import (
    BAND1_PREFERENCE,
    HEIGHT_RANGE_M,
    MAX_SIGMA_M,
    SppEpoch,
    lsq_settings,
    nav_and_source,
    select_band1,
    unsolved_epoch,
)

#: Post-fit residuals larger than this many times their modelled σ (unit-weight σ̂ of an
#: epoch whose chi-square test failed after FDE) mean a wrong minimum, not a mis-set σ
#: (a σ set 10× too small gives σ̂ ≈ 14 on the Pixel 5 drive; a wild epoch σ̂ > 4000).
MAX_UNIT_SIGMA = 100.0
#: An exactly determined solution (no redundancy, so no residual test) farther than
#: ``MAX_SPEED_M_S · Δt + JUMP_SLACK_M`` from the last accepted one is refused.
MAX_SPEED_M_S = 1_000.0
JUMP_SLACK_M = 1_000.0


def sanity_reason(
    lsq: LsqSolution, chi2_ok: bool, prev_pos_m: FloatArray | None = None, dt_s: float = math.inf
) -> str:
    """Why a least-squares epoch cannot be reported (empty string when it can).

    The checks: the residuals agree with their variance model (when the chi-square test
    fails after FDE, the unit-weight σ̂ is at most :data:`MAX_UNIT_SIGMA`: residuals
    hundreds of σ long belong to a wrong minimum); the geodetic height lies in
    :data:`HEIGHT_RANGE_M`; the 3-D σ is at most :data:`MAX_SIGMA_M`; an exactly determined
    solution (as many rows as unknowns: nothing checks it) stays within
    ``MAX_SPEED_M_S · dt_s + JUMP_SLACK_M`` of the last accepted position ``prev_pos_m``.
    """
    dof = int(lsq.rows.size - lsq.n_unknowns)
    if not chi2_ok and dof > 0:
        s0 = math.sqrt(float(np.sum(lsq.v**2 / lsq.var)) / dof)
        if not s0 <= MAX_UNIT_SIGMA:
            return f"residuals {s0:.3g} times their sigma after exclusion"
    pos = np.asarray(lsq.pos, float)
    if not np.all(np.isfinite(pos)):
        return "non-finite position"
    h = float(ecef2geodetic(pos)[2])
    if not HEIGHT_RANGE_M[0] <= h <= HEIGHT_RANGE_M[1]:
        return f"height {h:.3g} m off the Earth's surface"
    var = float(np.trace(np.asarray(lsq.cov, float)[:3, :3]))
    if not (math.isfinite(var) and var <= MAX_SIGMA_M**2):
        return f"position sigma {math.sqrt(var) if var >= 0 else float('nan'):.3g} m over {MAX_SIGMA_M:.0f} m"
    if prev_pos_m is not None and dof <= 0:
        jump = float(np.linalg.norm(pos - prev_pos_m))
        if jump > MAX_SPEED_M_S * abs(dt_s) + JUMP_SLACK_M:
            return (
                f"jump of {jump / 1e3:.3g} km from the last solution, with no redundant satellite to check it"
            )
    return ""


def solve_spp_epochwise(
    batch: ObsBatch,
    nav: NavData | EphemerisSource,
    cfg: Config | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> list[SppEpoch]:
    """Per-epoch weighted least-squares SPP with FDE, one epoch at a time (the reference
    :func:`solve_spp` is tested against; same arguments and results).

    Parameters and returns as :func:`solve_spp` (without its ``block_epochs``).

    Notes
    -----
    Each epoch starts from the previous epoch's accepted position; one that fails the
    sanity check from there is solved again from the Earth's centre before it is refused,
    so one wrong minimum never seeds the next epochs.
    """
    cfg = cfg or preset("spp")
    b1 = batch if len(batch.signals) == 1 else select_band1(batch)
    loop = EpochLoop(EpochwiseSpp(b1, nav, cfg))
    out: list[SppEpoch] = []
    for i in range(len(b1)):
        out.append(loop.step(i))
        notify_progress(progress, i + 1, len(b1), out[-1].status)
    return out


class EpochwiseSpp:
    """The per-epoch work of :func:`solve_spp_epochwise` (a :class:`~robustrtk.pipeline.loop.
    Stage`): ``step(i)`` solves epoch ``i`` of the one-signal batch ``b1``, carrying the last
    accepted position."""

    def __init__(self, b1: ObsBatch, nav: NavData | EphemerisSource, cfg: Config) -> None:
        self.b1 = b1
        self.settings = lsq_settings(cfg)
        self.navd, self.eph = nav_and_source(nav)
        self.prev: FloatArray | None = None
        self.prev_t = math.nan

    def step(self, i: int) -> SppEpoch:
        """Epoch ``i`` from the last accepted position, else (or when refused from there)
        from the Earth's centre."""
        b1, navd, settings, prev, prev_t = self.b1, self.navd, self.settings, self.prev, self.prev_t
        t = float(b1.t_s[i])
        geom = epoch_geometry(b1, i, self.eph)
        lsq, excl, ok = lsq_fde(t, geom, navd, settings, prev)
        why = "no solution (too few usable satellites, or below the Earth's surface)"
        if lsq is not None:
            why = sanity_reason(lsq, ok, prev, t - prev_t)
            if why and prev is not None:
                lsq, excl, ok = lsq_fde(t, geom, navd, settings, None)
                why = "no solution" if lsq is None else sanity_reason(lsq, ok, prev, t - prev_t)
        if lsq is None or why:
            return unsolved_epoch(t, why, tuple(excl))
        self.prev, self.prev_t = lsq.pos, t
        return SppEpoch(
            t, lsq.pos.copy(), lsq.clk, lsq.cov[:3, :3].copy(), int(lsq.rows.size), "single", tuple(excl), ok
        )


#: Epochs solved together by :func:`solve_spp` (memory grows with it: about 40 kB per
#: epoch for 40 satellites; speed levels off above a few hundred).
BLOCK_EPOCHS = 1024


def solve_spp(
    batch: ObsBatch,
    nav: NavData | EphemerisSource,
    cfg: Config | None = None,
    progress: Callable[[int, int], None] | None = None,
    block_epochs: int = BLOCK_EPOCHS,
) -> list[SppEpoch]:
    """Weighted least-squares SPP with FDE, each epoch on its own, solved by blocks of
    epochs (:mod:`robustrtk.pipeline.spp_batch`).

    Parameters
    ----------
    batch : ObsBatch
        Observations; the L1/E1/B1 column per system is selected with
        :func:`select_band1` unless the batch already has a single signal.
    nav : NavData or EphemerisSource
    cfg : Config, optional
        Default ``preset("spp")``; read through
        :func:`robustrtk.pipeline.spp_common.lsq_settings` (the estimator choice is the
        caller's: this function is the least-squares one whatever ``cfg.estimator.filter``).
    progress : callable (done, total), optional
    block_epochs : int
        Epochs per block.

    Returns
    -------
    list of SppEpoch, one per epoch (status ``"none"`` with NaN position and a ``reason``
    when unsolved or when the solution fails :func:`sanity_reason`).

    Notes
    -----
    The results are those of :func:`solve_spp_epochwise` to the rounding of the sums
    (about 1e-7 m; the ``.pos`` files of the shared datasets are byte-identical). Every
    epoch of a block starts from the last position accepted before the block (the one at a
    time path: from the previous epoch's), to which Gauss–Newton converges from either; one
    that fails the sanity check from there is solved again from the Earth's centre before it
    is refused, so one wrong minimum never seeds the next epochs.
    """
    cfg = cfg or preset("spp")
    settings = lsq_settings(cfg)
    navd, eph = nav_and_source(nav)
    b1 = batch if len(batch.signals) == 1 else select_band1(batch)
    loop = EpochLoop(BlockSolver(b1, eph, navd, settings))
    out: list[SppEpoch] = []
    n = len(b1)
    for lo in range(0, n, max(1, int(block_epochs))):
        hi = min(n, lo + max(1, int(block_epochs)))
        out.extend(loop.step((lo, hi, None)))
        if progress is not None:
            for i in range(lo, hi):
                notify_progress(progress, i + 1, n, out[i].status)
    return out


def solve_spp_each(
    batch: ObsBatch, nav: NavData | EphemerisSource, cfg: Config | None = None
) -> list[SppEpoch]:
    """:func:`solve_spp` of each epoch of ``batch`` as a batch of its own, all in one
    vectorised pass: every epoch starts from the Earth's centre and has no previous
    solution (so no jump test and no second start), as a one-epoch :func:`solve_spp` gives
    it (a sample of epochs apart in time, such as a check of a base position takes).

    Parameters and returns as :func:`solve_spp`.
    """
    cfg = cfg or preset("spp")
    navd, eph = nav_and_source(nav)
    b1 = batch if len(batch.signals) == 1 else select_band1(batch)
    return BlockSolver(b1, eph, navd, lsq_settings(cfg)).solve_each(0, len(b1))


def solve_spp_chunks(
    chunks: Iterable[ObsBatch],
    nav: NavData | EphemerisSource,
    cfg: Config | None = None,
    systems: str | None = None,
    block_epochs: int = BLOCK_EPOCHS,
) -> Iterator[list[SppEpoch]]:
    """:func:`solve_spp` over a stream of batches (consecutive blocks of epochs, such as
    :func:`robustrtk.io.rinex_chunks.iter_rinex_obs` yields), one list of epochs per block
    of at most ``block_epochs``: memory is bounded by the batch, not the run.

    The band-1 signal of each system is chosen per batch (:func:`select_band1` over the
    batch's epochs); the last accepted position carries from one batch to the next. The
    results are those of :func:`solve_spp` on the whole file except where a batch lacks
    the signal the whole file would choose and has another of the same band, which it then
    uses (whole-file: those epochs have no code of that system).
    """
    cfg = cfg or preset("spp")
    settings = lsq_settings(cfg)
    navd, eph = nav_and_source(nav)
    solver: BlockSolver | None = None
    step = max(1, int(block_epochs))
    for batch in chunks:
        b1 = batch if len(batch.signals) == 1 and systems is None else select_band1(batch, systems)
        solver = BlockSolver(b1, eph, navd, settings, after=solver)
        loop = EpochLoop(solver)
        for lo in range(0, len(b1), step):
            yield loop.step((lo, min(len(b1), lo + step), None))


class BlockSolver:
    """The least-squares SPP of a one-signal batch, block after block of epochs, carrying
    the last accepted position from one block to the next.

    Parameters
    ----------
    b1 : ObsBatch
        One signal per satellite (``K = 1``).
    eph : EphemerisSource
    nav : NavData
    settings : LsqSettings
    after : BlockSolver, optional
        The solver of the previous batch of a stream: its last accepted position carries on.
    """

    def __init__(
        self,
        b1: ObsBatch,
        eph: EphemerisSource,
        nav: NavData,
        settings: LsqSettings,
        after: BlockSolver | None = None,
    ) -> None:
        self.b1, self.eph, self.nav, self.settings = b1, eph, nav, settings
        self.systems = tuple(sorted(set(b1.system)))
        self.sys_col = np.array([self.systems.index(s) for s in b1.system], dtype=np.int64)
        self.letter, self.code = eph.query_codes(b1.tx_ids)
        self.freq_hz = carrier_frequency(b1.wavelength_m[:, 0])
        self.prev: FloatArray | None = None if after is None else after.prev
        self.prev_t: float = math.nan if after is None else after.prev_t
        self.chi2: dict[int, float] = {} if after is None else after.chi2

    def geometry(self, lo: int, hi: int) -> BlockGeometry:
        """Satellite states of the code rows of epochs ``lo:hi``."""
        b1 = self.b1
        code = b1.code_m[lo:hi, :, 0]
        t = np.asarray(b1.t_s[lo:hi], float)
        n_ep, n_sat = code.shape
        has = np.isfinite(code)
        ei, si = np.nonzero(has)
        pos_r, clk_r, ok_r = self.eph.code_states(t[ei], self.letter[si], self.code[si], code[has])
        sat_pos = np.full((n_ep, n_sat, 3), np.nan)
        sat_clk = np.full((n_ep, n_sat), np.nan)
        ok = np.zeros((n_ep, n_sat), bool)
        sat_pos[ei, si], sat_clk[ei, si], ok[ei, si] = pos_r, clk_r, ok_r
        return BlockGeometry(
            t,
            code,
            np.asarray(b1.cn0_dbhz[lo:hi, :, 0], float),
            np.broadcast_to(self.freq_hz, (n_ep, n_sat)),
            sat_pos,
            sat_clk,
            ok,
            self.sys_col,
            self.systems,
        )

    def step(self, block: tuple[int, int, FloatArray | None]) -> list[SppEpoch]:
        """:meth:`solve` of ``(lo, hi, seed)``: the block as a :class:`~robustrtk.pipeline.
        loop.Stage` of the epoch loop."""
        return self.solve(*block)

    def solve(self, lo: int, hi: int, seed: FloatArray | None = None) -> list[SppEpoch]:
        """The epochs ``lo:hi`` (after those before them), each started from ``seed`` (ECEF m;
        default the last accepted position, else the Earth's centre)."""
        g = self.geometry(lo, hi)
        n_ep = hi - lo
        if seed is None:
            seed = np.zeros(3) if self.prev is None else self.prev
        res = block_fde(g, self.nav, self.settings, np.tile(seed, (n_ep, 1)), self.chi2)
        why = block_reasons(res)
        dof = res.lsq.act.sum(axis=1) - res.lsq.n_unknowns
        dof_r = dof
        retry_idx = np.flatnonzero(res.lsq.solved & ((why != "") | (dof <= 0)))
        retry: BlockFde | None = None
        if retry_idx.size:
            retry = block_fde(
                g.take(retry_idx), self.nav, self.settings, np.zeros((retry_idx.size, 3)), self.chi2
            )
            why_r = block_reasons(retry)
            dof_r = retry.lsq.act.sum(axis=1) - retry.lsq.n_unknowns
        out: list[SppEpoch] = []
        pos_of = {int(i): k for k, i in enumerate(retry_idx.tolist())}
        views = {id(res): _Rows(res, self.systems)}
        if retry is not None:
            views[id(retry)] = _Rows(retry, self.systems)
        t_list = g.t_s.tolist()
        solved, why_l, dof_l = res.lsq.solved.tolist(), why.tolist(), dof.tolist()
        for i in range(n_ep):
            t = t_list[i]
            src, k = res, i
            reason = "no solution (too few usable satellites, or below the Earth's surface)"
            if solved[i]:
                reason = why_l[i] or (self._jump(res, i, t) if dof_l[i] <= 0 else "")
                if reason and self.prev is not None:
                    assert retry is not None
                    src, k = retry, pos_of[i]
                    if not retry.lsq.solved[k]:
                        reason = "no solution"
                    else:
                        reason = str(why_r[k]) or (self._jump(retry, k, t) if dof_r[k] <= 0 else "")
            if reason:
                out.append(unsolved_epoch(t, reason, self._ids(src.excluded[k])))
                continue
            rows = views[id(src)]
            self.prev, self.prev_t = rows.pos[k], t
            out.append(
                SppEpoch(
                    t,
                    rows.pos[k],
                    rows.clock(k),
                    rows.cov[k],
                    rows.n_used[k],
                    "single",
                    self._ids(src.excluded[k]),
                    rows.chi2_ok[k],
                )
            )
        return out

    def solve_each(self, lo: int, hi: int) -> list[SppEpoch]:
        """The epochs ``lo:hi``, each as if it were the first epoch of a run: started from
        the Earth's centre, with no previous solution (the epochs of a one-epoch
        :meth:`solve` each, without changing the last accepted position)."""
        g = self.geometry(lo, hi)
        res = block_fde(g, self.nav, self.settings, np.zeros((hi - lo, 3)), self.chi2)
        why = block_reasons(res).tolist()
        rows = _Rows(res, self.systems)
        out: list[SppEpoch] = []
        for i, (t, solved) in enumerate(zip(g.t_s.tolist(), res.lsq.solved.tolist(), strict=True)):
            reason = (
                why[i] if solved else "no solution (too few usable satellites, or below the Earth's surface)"
            )
            if reason:
                out.append(unsolved_epoch(t, reason, self._ids(res.excluded[i])))
            else:
                out.append(
                    SppEpoch(
                        t,
                        rows.pos[i],
                        rows.clock(i),
                        rows.cov[i],
                        rows.n_used[i],
                        "single",
                        self._ids(res.excluded[i]),
                        rows.chi2_ok[i],
                    )
                )
        return out

    def _ids(self, cols: list[int]) -> tuple[str, ...]:
        return tuple(self.b1.tx_ids[j] for j in cols)

    def _jump(self, r: BlockFde, k: int, t: float) -> str:
        """The jump test of :func:`sanity_reason` for an exactly determined solution."""
        dof = int(r.lsq.act[k].sum() - r.lsq.n_unknowns[k])
        if self.prev is None or dof > 0:
            return ""
        jump = float(np.linalg.norm(r.lsq.pos[k] - self.prev))
        if jump > MAX_SPEED_M_S * abs(t - self.prev_t) + JUMP_SLACK_M:
            return (
                f"jump of {jump / 1e3:.3g} km from the last solution, with no redundant satellite to check it"
            )
        return ""


class _Rows:
    """A block's solutions as per-epoch Python values and array rows (read once)."""

    def __init__(self, r: BlockFde, systems: tuple[str, ...]) -> None:
        self.pos = r.lsq.pos.copy()
        self.cov = r.lsq.cov[:, :3, :3].copy()
        self.n_used = r.lsq.act.sum(axis=1).tolist()
        self.chi2_ok = r.chi2_ok.tolist()
        self.clk = r.lsq.clk.tolist()
        self.clk_set = r.lsq.clk_set.tolist()
        self.systems = systems

    def clock(self, k: int) -> dict[str, float]:
        """Receiver clock per system solved (m)."""
        return {s: c for s, c, on in zip(self.systems, self.clk[k], self.clk_set[k], strict=True) if on}


def block_reasons(r: BlockFde) -> np.ndarray:
    """:func:`sanity_reason` of every solved epoch of a block, without the jump test (which
    needs the previous accepted epoch): an object array of str, empty where accepted or
    unsolved."""
    lsq = r.lsq
    n_ep = lsq.solved.size
    why = np.full(n_ep, "", dtype=object)
    dof = lsq.act.sum(axis=1) - lsq.n_unknowns
    test = np.sum(np.where(lsq.act, lsq.v**2 / lsq.var, 0.0), axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        s0 = np.sqrt(test / np.where(dof > 0, dof, 1))
    h = ecef2geodetic(np.nan_to_num(lsq.pos))[2]
    var = np.trace(lsq.cov[:, :3, :3], axis1=1, axis2=2)
    with np.errstate(invalid="ignore"):
        bad_s0 = ~r.chi2_ok & (dof > 0) & ~(s0 <= MAX_UNIT_SIGMA)
        bad_pos = ~np.all(np.isfinite(lsq.pos), axis=1)
        bad_h = ~((h >= HEIGHT_RANGE_M[0]) & (h <= HEIGHT_RANGE_M[1]))
        bad_var = ~(np.isfinite(var) & (var <= MAX_SIGMA_M**2))
    for i in np.flatnonzero(lsq.solved & (bad_s0 | bad_pos | bad_h | bad_var)).tolist():
        if bad_s0[i]:
            why[i] = f"residuals {s0[i]:.3g} times their sigma after exclusion"
        elif bad_pos[i]:
            why[i] = "non-finite position"
        elif bad_h[i]:
            why[i] = f"height {h[i]:.3g} m off the Earth's surface"
        else:
            sig = math.sqrt(var[i]) if var[i] >= 0 else float("nan")
            why[i] = f"position sigma {sig:.3g} m over {MAX_SIGMA_M:.0f} m"
    return why


def solve_spp_kalman(*args: Any, **kwargs: Any) -> list[SppEpoch]:
    """The Kalman SPP, :func:`robustrtk.pipeline.spp_kalman.solve_spp_kalman` (same arguments);
    its module is imported on the first call, so the other modes do not load it."""
    from robustrtk.pipeline.spp_kalman import solve_spp_kalman as run

    return run(*args, **kwargs)


__all__ = [
    "BAND1_PREFERENCE",
    "BlockSolver",
    "EpochwiseSpp",
    "SppEpoch",
    "select_band1",
    "solve_spp",
    "solve_spp_chunks",
    "solve_spp_each",
    "solve_spp_epochwise",
    "solve_spp_kalman",
]

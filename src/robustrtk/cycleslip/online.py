r"""Slip detectors that take one epoch at a time (files and streams alike).

:class:`OnlineSlipDetector` keeps, per signal row (named ``"<sat>:<slot>"``) and per
satellite pair of rows, the little state the whole-array detectors read back from earlier
rows of their ``(T, N)`` series, and returns for each epoch exactly the flags that
:func:`~robustrtk.cycleslip.lli.half_cycle_transitions`,
:func:`~robustrtk.cycleslip.geometry_free.gf_slips`,
:func:`~robustrtk.cycleslip.geometry_free.gf_drift_slips` and
:func:`~robustrtk.cycleslip.doppler.doppler_phase_slips` give for that epoch's row of the
whole series (the same floating-point operations on the same operands):

* half-cycle jump: the half-cycle bit differs from that of the row's last phase;
* geometry-free: :math:`|L_{GF}(t) - L_{GF}(t_{prev})| >` threshold, or the previous
  valid epoch older than ``gf_max_gap_s``;
* geometry-free drift: :math:`|L_{GF}(t) - L_{GF}(t_0)| >` threshold with :math:`t_0`
  the first epoch of the current arc at or after :math:`t - w` (an arc is broken by an
  epoch without the pair or with a loss-of-lock bit);
* Doppler: observed minus trapezoidal Doppler-predicted phase change since the row's
  previous phase, only when the receiver's previous epoch is at most 2 s old.

The pair of a satellite is its first two rows in the epoch's row order (slot order of
:func:`robustrtk.measurement.signals.signal_rows`): a source must give every epoch the
same rows for a satellite (NaN where a signal is absent), as the batch rows do.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field, replace

import numpy as np

from robustrtk.core import BoolArray, ObsEpoch

#: Largest gap (s) between an epoch and the receiver's previous one over which the
#: Doppler prediction is trusted (that of the whole-array RTK front end).
DOPPLER_MAX_DT_S = 2.0


@dataclass
class _Pair:
    """Geometry-free state of one satellite's pair of rows."""

    t_prev: float = float("nan")
    gf_prev: float = float("nan")
    seen_at: int = -2  # epoch counter of the last epoch with a finite combination
    arc: deque[tuple[float, float]] = field(default_factory=deque)


@dataclass
class _Row:
    """Doppler and half-cycle state of one signal row."""

    t_prev: float = float("nan")
    phase_prev: float = float("nan")
    doppler_prev: float = float("nan")
    half_prev: int = -1  # -1: no phase yet


@dataclass(frozen=True)
class EpochSlips:
    """One epoch's front-end output.

    Attributes
    ----------
    epoch : ObsEpoch
        The epoch with the loss-of-lock bit set on half-cycle jumps.
    slip : ndarray of bool, shape (N,)
        Detector slips (geometry-free, drift, Doppler) per row.
    half_cycle : ndarray of bool, shape (N,)
        Half-cycle-ambiguity bit per row.
    """

    epoch: ObsEpoch
    slip: BoolArray
    half_cycle: BoolArray


class OnlineSlipDetector:
    """Per-epoch slip detection of one receiver's signal rows (column 0).

    Parameters
    ----------
    gf, doppler : bool
        Run the geometry-free and the Doppler tests.
    gf_threshold_m, gf_max_gap_s : float
        As in :func:`~robustrtk.cycleslip.geometry_free.gf_slips`.
    gf_window_s, gf_window_threshold_m : float
        Drift test (:func:`~robustrtk.cycleslip.geometry_free.gf_drift_slips`); off when
        ``gf_window_s <= 0``.
    doppler_threshold_cyc, sign : float
        As in :func:`~robustrtk.cycleslip.doppler.doppler_phase_slips`.

    Notes
    -----
    Feed every epoch of the receiver in time order (not only the epochs that get solved):
    the state is what the whole series would have shown before this epoch.
    """

    def __init__(
        self,
        *,
        gf: bool,
        doppler: bool,
        gf_threshold_m: float = 0.05,
        gf_max_gap_s: float = 120.0,
        gf_window_s: float = 0.0,
        gf_window_threshold_m: float = 0.08,
        doppler_threshold_cyc: float = 0.5,
        sign: float = -1.0,
    ) -> None:
        self.gf = gf
        self.doppler = doppler
        self.gf_threshold_m = gf_threshold_m
        self.gf_max_gap_s = gf_max_gap_s
        self.gf_window_s = gf_window_s
        self.gf_window_threshold_m = gf_window_threshold_m
        self.doppler_threshold_cyc = doppler_threshold_cyc
        self.sign = sign
        self.rows: dict[str, _Row] = {}
        self.pairs: dict[tuple[str, str], _Pair] = {}
        self.n_epochs = 0
        self.t_last = float("nan")

    def step(self, epoch: ObsEpoch) -> EpochSlips:
        """Flags of one epoch (the next in time); the state moves to it."""
        t = float(epoch.t_s)
        ids = epoch.tx_ids
        n = len(ids)
        phase = epoch.phase_cyc[:, 0] if n else np.zeros(0)
        lli = np.asarray(epoch.lli[:, 0], dtype=np.int8) if n else np.zeros(0, np.int8)
        # half-cycle jumps become loss-of-lock bits (half_cycle_transitions)
        half = (lli.astype(np.int64) & 2) != 0
        jumps = np.zeros(n, dtype=bool)
        rows = self.rows
        for i, name in enumerate(ids):
            if not np.isfinite(phase[i]):
                continue
            st = rows.get(name)
            if st is None:
                st = rows[name] = _Row()
            h = int(half[i])
            jumps[i] = st.half_prev >= 0 and st.half_prev != h
            st.half_prev = h
        if jumps.any():
            lli = lli | jumps.astype(np.int8)
            full = np.asarray(epoch.lli).copy()
            full[:, 0] = lli
            epoch = replace(epoch, lli=full)
        flags = np.zeros(n, dtype=bool)
        if self.gf and n:
            self._gf(t, epoch, phase, lli, flags)
        if self.doppler and n:
            dt_epoch = t - self.t_last if self.n_epochs else 0.0
            self._doppler(t, ids, phase, epoch.doppler_hz[:, 0], flags, dt_epoch <= DOPPLER_MAX_DT_S)
        else:
            for i, name in enumerate(ids):
                if np.isfinite(phase[i]):
                    st = rows[name]
                    st.t_prev, st.phase_prev = t, float(phase[i])
        self.n_epochs += 1
        self.t_last = t
        return EpochSlips(epoch, flags, half)

    def _gf(self, t: float, epoch: ObsEpoch, phase: np.ndarray, lli: np.ndarray, flags: BoolArray) -> None:
        first: dict[str, list[int]] = {}
        for i, name in enumerate(epoch.tx_ids):
            r = first.setdefault(name.split(":", 1)[0], [])
            if len(r) < 2:
                r.append(i)
        lam = epoch.wavelength_m[:, 0]
        k = self.n_epochs
        w = self.gf_window_s
        for r in first.values():
            if len(r) < 2:
                continue
            a, b = r
            key = (epoch.tx_ids[a], epoch.tx_ids[b])
            gf = float(lam[a] * phase[a] - lam[b] * phase[b])
            st = self.pairs.get(key)
            if st is None:
                st = self.pairs[key] = _Pair()
            if not np.isfinite(gf):
                continue
            slip = False
            if np.isfinite(st.gf_prev):
                slip = abs(gf - st.gf_prev) > self.gf_threshold_m or t - st.t_prev > self.gf_max_gap_s
            if w > 0:
                lost = ((int(lli[a]) | int(lli[b])) & 1) != 0
                if st.seen_at != k - 1 or lost:
                    st.arc.clear()
                else:
                    while st.arc and st.arc[0][0] < t - w - 1e-6:
                        st.arc.popleft()
                    if st.arc and abs(gf - st.arc[0][1]) > self.gf_window_threshold_m:
                        slip = True
                st.arc.append((t, gf))
            st.t_prev, st.gf_prev, st.seen_at = t, gf, k
            if slip:
                flags[a] = flags[b] = True

    def _doppler(
        self,
        t: float,
        ids: tuple[str, ...],
        phase: np.ndarray,
        dop: np.ndarray,
        flags: BoolArray,
        recent: bool,
    ) -> None:
        rows = self.rows
        for i, name in enumerate(ids):
            ph = phase[i]
            if not np.isfinite(ph):
                continue
            st = rows[name]
            if np.isfinite(st.phase_prev):
                d0, d1 = st.doppler_prev, dop[i]
                if np.isfinite(d0) and np.isfinite(d1):
                    dmean = 0.5 * (d0 + d1)
                else:
                    dmean = d0 if np.isfinite(d0) else d1
                if np.isfinite(dmean) and recent:
                    resid = (ph - st.phase_prev) - self.sign * dmean * (t - st.t_prev)
                    flags[i] |= bool(abs(resid) > self.doppler_threshold_cyc)
            st.t_prev, st.phase_prev, st.doppler_prev = t, float(ph), float(dop[i])


__all__ = ["DOPPLER_MAX_DT_S", "EpochSlips", "OnlineSlipDetector"]

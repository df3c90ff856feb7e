"""Ionospheric corrections of the batch smoother: the broadcast model's error, estimated.

The broadcast (Klobuchar) model removes about half of the ionospheric delay (IS-GPS-200,
20.3.3.5.2.5: "approximately 50 % RMS"); what it leaves varies slowly and smoothly over
the sky, metres by day at low latitudes and mid-latitude afternoons, and a smoother cannot
average it away: on a short track it is a bias of the whole solution. With two bands the
error is observable — the delay scales as ``1/f²`` while geometry and clocks do not — so the
smoother (:mod:`robustrtk.pipeline.spp_fgo`) estimates it (docs/algorithms.md §48) as a
correction field on the thin ionospheric shell (height :data:`SHELL_HEIGHT_M`), one per
:data:`SEGMENT_S` of track: a vertical delay and its north and east gradients,

    ``δI_s = M(el_s) (a + g_N d_N,s + g_E d_E,s)``  (metres of L1 slant delay),

``M`` the thin-shell mapping function and ``d_N, d_E`` the offsets (in 1000 km) of the
satellite's pierce point from the receiver's. A code row on band ``b`` gains ``γ_b δI_s``,
``γ_b = (f_L1 / f_b)²``. The field is shared by all satellites, so satellites seen on one
band are corrected by what the two-band ones show.

* prior on the first segment: ``a, g_N, g_E = 0 ± KLOBUCHAR_RMS_FRACTION · I_v`` (per
  1000 km for the gradients), ``I_v`` the model's own vertical delay at the receiver;
* between consecutive segments each of the three changes by ``0 ± r Δt``, ``r`` the rate
  of change of a quiet ionosphere (:data:`IONO_RATE_M_S`).

The two bands' code also differ by the satellite's inter-frequency group delay; only where
the navigation message gives it for the pair (Galileo BGD, BeiDou TGD1/TGD2) does the
band difference measure the ionosphere's level. For the others (GPS and QZSS: TGD is for
L1/L2 P(Y); the civil signals' ISC are not in the LNAV message) each satellite's second
band gets its own constant bias unknown (prior :data:`FREE_BIAS_SIGMA_M`): its band
difference then tells how the ionosphere changes and varies across the sky, not its level.

The field is estimated only where the two bands can tell it and kept only where it is there:

* :func:`field_observable`: most epochs have at least :data:`MIN_CALIBRATED_PER_EPOCH`
  satellites of a calibrated system on both bands (without them the field rests on the
  one-band code, whose gradients look like a horizontal shift of the receiver);
* :func:`field_statistic`: the solved field's mean terms differ from zero (a χ² test at
  0.1 % with the code's time correlation counted); otherwise the track is solved again
  without it — a drive whose ionosphere the broadcast model explains gets the smoother it
  had, not the noise of a field estimated from a phone's code.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from robustrtk.core import FloatArray
from robustrtk.estimation.fgo import BatchResult, Linearized


class RowSet(Protocol):
    """Rows that linearise at a point: ``linearize(x) -> Linearized``."""

    def linearize(self, x: FloatArray) -> Linearized: ...


#: Fraction of the broadcast model's delay taken as its RMS error (IS-GPS-200
#: 20.3.3.5.2.5: the model removes about 50 % RMS of the delay).
KLOBUCHAR_RMS_FRACTION = 0.5
#: Length of the segments over which the correction field is one set of unknowns (s).
SEGMENT_S = 60.0
#: Rate of change of the model's error (m/s of L1 delay): 0.3 TECU per minute (a quiet
#: mid-latitude ionosphere's rate of TEC change), 0.162 m of L1 delay each.
IONO_RATE_M_S = 0.3 * 0.162 / 60.0
#: Least σ of the priors (m): a model giving no delay (night, or the model off) still
#: leaves the delay it did not model.
MIN_PRIOR_SIGMA_M = 0.1
#: Systems whose navigation message gives the satellites' group delay of both bands used.
CALIBRATED_SYSTEMS = ("E", "C")
#: σ of the prior of an unknown inter-frequency bias (m; 33 ns, beyond any satellite's).
FREE_BIAS_SIGMA_M = 10.0
#: Tie between one free satellite's second-band bias unknowns of consecutive minutes (m): a
#: satellite's hardware delays are constant over a pass (millimetres are a constant to the
#: metres of a phone's code).
BIAS_LINK_SIGMA_M = 1.0e-3
#: Height of the thin ionospheric shell (m), as the broadcast model's.
SHELL_HEIGHT_M = 350.0e3
#: Mean Earth radius of the shell geometry (m).
EARTH_RADIUS_M = 6371.0e3


#: Satellites of a calibrated system seen on both bands that an epoch needs for the field to
#: be observable there: the vertical and two gradients take three, one more tests them.
MIN_CALIBRATED_PER_EPOCH = 4


def field_observable(two_band: np.ndarray, calibrated: np.ndarray) -> bool:
    """Whether the two bands can tell the field: in most epochs (more than half) at least
    :data:`MIN_CALIBRATED_PER_EPOCH` satellites of a calibrated system are seen on both bands.

    Without them the field's level and gradients rest on the one-band code, where the
    gradients look like a horizontal shift of the receiver: they would move the track, not
    correct it (the Pixel 5 drive, GPS L5 only: 2.05 → 3.91 m).

    Parameters
    ----------
    two_band : ndarray of bool, shape (T, N)
        Code on both bands at the epoch.
    calibrated : ndarray of bool, shape (N,)
        The satellite's system broadcasts the group delays of both bands.
    """
    n = np.sum(two_band & np.asarray(calibrated, bool)[None, :], axis=1)
    return bool(n.size) and float(np.mean(n >= MIN_CALIBRATED_PER_EPOCH)) > 0.5


#: χ²(3) quantile of the significance test of the field's mean terms (0.1 % false alarms:
#: when in doubt, no field).
FIELD_CHI2 = 16.27


def field_statistic(
    res: BatchResult, unk: IonoUnknowns, e: np.ndarray, j: np.ndarray, b: np.ndarray
) -> float:
    """The test of the solved field against zero, ``m̄ᵀ C̄⁻¹ m̄`` (significant beyond
    :data:`FIELD_CHI2`; 0 when it cannot be formed), ``m̄`` the mean
    over the segments of the field's three terms (vertical delay, north and east gradients),
    ``C̄`` its covariance from the solve's information matrix times ``(1 + ρ) / (1 − ρ)``, ``ρ``
    the lag-one correlation of each code row's standardised residuals from epoch to epoch (a
    code's multipath lasts many epochs: the white-noise covariance alone would call the code's
    own slow noise a model error).

    Parameters
    ----------
    res : BatchResult
        The smoother's solve with the field (group ``"P"``: the code rows).
    unk : IonoUnknowns
    e, j, b : ndarray of int, shape (m,)
        Epoch, satellite and band of each code row.
    """
    first = np.unique(unk.seg_col[unk.seg_col >= 0])
    if first.size == 0 or res.normal is None:
        return 0.0
    cols = (first[:, None] + np.arange(3)[None, :]).ravel()  # segment-major, 3 terms each
    rhs = np.zeros((res.normal.shape[0], cols.size))
    rhs[cols, np.arange(cols.size)] = 1.0
    lu = spla.splu(
        sp.csc_matrix(res.normal),
        permc_spec="MMD_AT_PLUS_A",
        diag_pivot_thresh=0.0,
        options={"SymmetricMode": True},
    )
    C = lu.solve(rhs)[cols]
    n_seg = first.size
    A = np.tile(np.eye(3), n_seg) / n_seg  # (3, 3 n_seg): the mean over the segments
    mean = A @ res.x[cols]
    cov = A @ C @ A.T
    u, w = res.std_residual["P"], res.weights["P"]
    o = np.lexsort((e, b, j))
    same = (j[o][1:] == j[o][:-1]) & (b[o][1:] == b[o][:-1]) & (e[o][1:] == e[o][:-1] + 1)
    same &= (w[o][1:] > 0) & (w[o][:-1] > 0)
    uo = np.clip(u[o], -5.0, 5.0)
    den = 0.5 * float(np.sum(uo[1:][same] ** 2 + uo[:-1][same] ** 2))
    rho = min(max(float(np.sum(uo[1:][same] * uo[:-1][same])) / den if den > 0 else 0.0, 0.0), 0.99)
    cov = cov * (1.0 + rho) / (1.0 - rho)
    try:
        stat = float(mean @ np.linalg.solve(cov, mean))
    except np.linalg.LinAlgError:
        return 0.0
    return stat


def shell_geometry(el_rad: FloatArray, az_rad: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Mapping function and pierce-point offsets on the thin shell.

    ``sin z' = R cos(el) / (R + H)``, ``M = 1 / cos z'``; the Earth-central angle between
    receiver and pierce point ``ψ = π/2 − el − z'``; offsets ``d_N = R ψ cos(az)``,
    ``d_E = R ψ sin(az)`` (in 1000 km).

    Returns
    -------
    mapping, d_north_mm, d_east_mm : ndarray, same shape as ``el_rad``
    """
    s = EARTH_RADIUS_M * np.cos(el_rad) / (EARTH_RADIUS_M + SHELL_HEIGHT_M)
    zp = np.arcsin(np.clip(s, -1.0, 1.0))
    psi = np.pi / 2 - el_rad - zp
    d = EARTH_RADIUS_M * psi / 1.0e6
    return 1.0 / np.cos(zp), d * np.cos(az_rad), d * np.sin(az_rad)


@dataclass(frozen=True)
class IonoUnknowns:
    """Where the field's unknowns are and what constrains them.

    Columns follow the epoch blocks, minute by minute: the minute's three field terms, then
    the second-band bias of each free satellite seen on both bands in that minute. A free
    satellite's bias is one constant, written as one unknown per minute tied to the previous
    one by :data:`BIAS_LINK_SIGMA_M`: the same estimate as a single unknown, but each column
    touches one minute of epochs, so the sparse factorisation stays local (a single column
    per satellite couples its whole pass and made the solve several times slower).

    Attributes
    ----------
    seg_col : ndarray of int, shape (T,)
        Column of the first of epoch ``i``'s three field unknowns (−1: none).
    seg_index : ndarray of int, shape (T,)
        Minute (segment) of each epoch (−1: none).
    prior_sigma_m : ndarray, shape (3,)
        σ of the first segment's prior (m, m per 1000 km).
    link_from, link_to : ndarray of int
        First columns of consecutive segments.
    link_sigma_m : ndarray
    bias_tab : ndarray of int, shape (S, N)
        Column of satellite ``j``'s second-band bias in segment ``s`` (−1: none).
    first : int
        Column of the first unknown (they follow the epoch blocks).
    size : int
        Number of unknowns.
    """

    seg_col: np.ndarray
    seg_index: np.ndarray
    prior_sigma_m: FloatArray
    link_from: np.ndarray
    link_to: np.ndarray
    link_sigma_m: FloatArray
    bias_tab: np.ndarray
    first: int
    size: int

    def bias_of(self, e: np.ndarray, j: np.ndarray) -> np.ndarray:
        """Bias column of rows at epochs ``e`` of satellites ``j`` (−1: none)."""
        s = self.seg_index[e]
        out = np.full(e.size, -1, int)
        ok = s >= 0
        out[ok] = self.bias_tab[s[ok], j[ok]]
        return out


def iono_unknowns(
    t_s: FloatArray,
    has_code: np.ndarray,
    vertical_m: float,
    first: int,
    free_two_band: np.ndarray,
) -> IonoUnknowns:
    """Lay out the unknowns (module docstring).

    Parameters
    ----------
    t_s : ndarray, shape (T,)
    has_code : ndarray of bool, shape (T,)
        Epochs with at least one code row.
    vertical_m : float
        The broadcast model's vertical L1 delay at the receiver (m), for the priors.
    first : int
        Column of the first unknown.
    free_two_band : ndarray of bool, shape (T, N)
        Code on both bands of a satellite whose second band needs its own bias unknown.
    """
    T = len(t_s)
    N = free_two_band.shape[1] if free_two_band.ndim == 2 else 0
    seg_col = np.full(T, -1, int)
    seg_index = np.full(T, -1, int)
    seg = np.floor((t_s - t_s[0]) / SEGMENT_S).astype(int) if T else np.zeros(0, int)
    segs = np.unique(seg[has_code]).tolist()
    bias_tab = np.full((len(segs), N), -1, int)
    l_from: list[int] = []
    l_to: list[int] = []
    l_sig: list[float] = []
    k = first
    prev_t = None
    for si, s in enumerate(segs):
        e = np.flatnonzero((seg == s) & has_code)
        seg_col[e] = k
        seg_index[e] = si
        t_mid = float(np.mean(t_s[e]))
        if prev_t is not None:
            l_from.append(k - 3)
            l_to.append(k)
            l_sig.append(max(IONO_RATE_M_S * (t_mid - prev_t), 1e-3))
        prev_t = t_mid
        k += 3
        q = np.flatnonzero(free_two_band[e].any(axis=0)) if N else np.zeros(0, int)
        bias_tab[si, q] = k + np.arange(q.size)
        k += q.size
    prior = np.full(3, max(KLOBUCHAR_RMS_FRACTION * abs(vertical_m), MIN_PRIOR_SIGMA_M))
    return IonoUnknowns(
        seg_col,
        seg_index,
        prior,
        np.array(l_from, int),
        np.array(l_to, int),
        np.array(l_sig),
        bias_tab,
        first,
        k - first,
    )


@dataclass(frozen=True)
class IonoCodeTerm:
    """The ``γ_b δI_s`` (and second-band bias) terms of code rows, added to rows whose
    ``linearize`` reads the epoch blocks only (``inner``, built with the full width ``n``)."""

    inner: RowSet  # rows of the epoch blocks, built with the full width n
    n_blocks: int
    seg_col: np.ndarray  # (m,) first field column of each row (−1: none)
    coef: FloatArray  # (m, 3): γ_b M, γ_b M d_N, γ_b M d_E
    bias_col: np.ndarray  # (m,) column of the row's second-band bias (−1: none)
    n: int

    def linearize(self, x: FloatArray) -> Linearized:
        lin = self.inner.linearize(x[: self.n_blocks])
        m = self.seg_col.size
        f = np.flatnonzero(self.seg_col >= 0)
        b = np.flatnonzero(self.bias_col >= 0)
        cols3 = self.seg_col[f, None] + np.arange(3)[None, :]
        r = lin.r.copy()
        r[f] -= np.sum(self.coef[f] * x[cols3], axis=1)
        r[b] -= x[self.bias_col[b]]
        rows = np.concatenate([np.repeat(f, 3), b])
        cols = np.concatenate([cols3.ravel(), self.bias_col[b]])
        vals = np.concatenate([self.coef[f].ravel(), np.ones(b.size)])
        J = lin.J + sp.csr_matrix((vals, (rows, cols)), shape=(m, self.n))
        return Linearized(r, lin.sigma, J.tocsr())


@dataclass(frozen=True)
class BlocksOnly:
    """Rows that read the epoch blocks only (built with the full width ``n``)."""

    inner: RowSet
    n_blocks: int

    def linearize(self, x: FloatArray) -> Linearized:
        return self.inner.linearize(x[: self.n_blocks])


@dataclass(frozen=True)
class IonoPriorRows:
    """The priors and links of :class:`IonoUnknowns` as rows (linear)."""

    unk: IonoUnknowns
    n: int

    def linearize(self, x: FloatArray) -> Linearized:
        u = self.unk
        used = u.seg_col[u.seg_col >= 0]
        first = int(used.min()) if used.size else -1
        c0 = first + np.arange(3) if first >= 0 else np.zeros(0, int)
        # each free satellite's bias: a prior on its first column, ties between its next ones
        tab = u.bias_tab
        b_first: list[int] = []
        b_from: list[int] = []
        b_to: list[int] = []
        for j in range(tab.shape[1]):
            c = tab[:, j][tab[:, j] >= 0]
            if c.size:
                b_first.append(int(c[0]))
                b_from += c[:-1].tolist()
                b_to += c[1:].tolist()
        bc = np.array(b_first, int)
        lf = np.concatenate([(u.link_from[:, None] + np.arange(3)).ravel(), np.array(b_from, int)])
        lt = np.concatenate([(u.link_to[:, None] + np.arange(3)).ravel(), np.array(b_to, int)])
        m0, m1, m2 = c0.size, lf.size, bc.size
        rows = np.concatenate([np.arange(m0), m0 + np.repeat(np.arange(m1), 2), m0 + m1 + np.arange(m2)])
        cols = np.concatenate([c0, np.column_stack([lt, lf]).ravel(), bc])
        vals = np.concatenate([np.ones(m0), np.tile([1.0, -1.0], m1), np.ones(m2)])
        J = sp.csr_matrix((vals, (rows, cols)), shape=(m0 + m1 + m2, self.n))
        r = np.concatenate([-x[c0], -(x[lt] - x[lf]), -x[bc]])
        sigma = np.concatenate(
            [
                u.prior_sigma_m[: c0.size],
                np.repeat(u.link_sigma_m, 3),
                np.full(len(b_from), BIAS_LINK_SIGMA_M),
                np.full(m2, FREE_BIAS_SIGMA_M),
            ]
        )
        return Linearized(r, sigma, J)


__all__ = [
    "BIAS_LINK_SIGMA_M",
    "CALIBRATED_SYSTEMS",
    "MIN_CALIBRATED_PER_EPOCH",
    "EARTH_RADIUS_M",
    "FREE_BIAS_SIGMA_M",
    "IONO_RATE_M_S",
    "KLOBUCHAR_RMS_FRACTION",
    "MIN_PRIOR_SIGMA_M",
    "SEGMENT_S",
    "SHELL_HEIGHT_M",
    "BlocksOnly",
    "IonoCodeTerm",
    "IonoPriorRows",
    "IonoUnknowns",
    "RowSet",
    "iono_unknowns",
    "field_observable",
    "field_statistic",
    "shell_geometry",
]

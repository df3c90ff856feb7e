"""Ionospheric corrections of the batch smoother: the broadcast model's error, estimated.

The broadcast (Klobuchar) model removes about half of the ionospheric delay (IS-GPS-200,
20.3.3.5.2.5: "approximately 50 % RMS"); what it leaves is a slowly varying error of each
satellite's slant delay, metres by day at low latitudes and mid-latitude afternoons, which a
smoother cannot average away: on a short track it is a bias of the whole solution. With two
bands the error is observable — the delay scales as ``1/f²`` while geometry and clocks do
not — so the smoother (:mod:`robustrtk.pipeline.spp_fgo`) estimates it
(docs/algorithms.md §44): per satellite one unknown ``δI`` (metres of L1 slant delay) per
:data:`SEGMENT_S` of track, entering each code row of band ``b`` as ``γ_b δI`` with
``γ_b = (f_L1 / f_b)²``;

* a prior ``δI = 0 ± KLOBUCHAR_RMS_FRACTION · I_klob`` per segment (the model's own stated
  accuracy, ``I_klob`` its L1 slant delay at the segment's epochs);
* between consecutive segments of a satellite ``δI_k+1 − δI_k = 0 ± r · Δt``, ``r`` the
  rate of change of a quiet ionosphere (:data:`IONO_RATE_M_S`), ``Δt`` between the segments'
  mean times.

A satellite seen on one band only keeps its unknowns with the prior: its code is then
weighted as what it is, a range with the model's error in it. The two bands' code also
differ by the satellite's inter-frequency group delay; only where the navigation message
gives it for the pair (Galileo BGD, BeiDou TGD1/TGD2) does the band difference measure the
ionosphere. For the others (GPS and QZSS: TGD is for L1/L2 P(Y), the civil signals' ISC
are not in the LNAV message) each satellite's second band gets its own constant bias
unknown (prior :data:`FREE_BIAS_SIGMA_M`), so that its band difference tells only how
the ionosphere changes, not its level. A common error of all
satellites of a system goes to the receiver clock and inter-frequency bias, as it should.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from robustrtk.core import FloatArray
from robustrtk.estimation.fgo import Linearized

#: Fraction of the broadcast model's slant delay taken as its RMS error (IS-GPS-200
#: 20.3.3.5.2.5: the model removes about 50 % RMS of the delay).
KLOBUCHAR_RMS_FRACTION = 0.5
#: Length of the segments over which one satellite's model error is one unknown (s).
SEGMENT_S = 60.0
#: Rate of change of a satellite's ionospheric model error (m/s of L1 delay): 0.3 TECU per
#: minute (a quiet mid-latitude ionosphere's rate of TEC change), 0.162 m of L1 delay each.
IONO_RATE_M_S = 0.3 * 0.162 / 60.0
#: Least σ of the prior (m): a model giving no delay (night, or the model off) still leaves
#: the delay it did not model.
MIN_PRIOR_SIGMA_M = 0.1
#: Systems whose navigation message gives the satellites' group delay of both bands used.
CALIBRATED_SYSTEMS = ("E", "C")
#: σ of the prior of an unknown inter-frequency bias (m; 33 ns, beyond any satellite's).
FREE_BIAS_SIGMA_M = 10.0


@dataclass(frozen=True)
class IonoUnknowns:
    """Where the ionospheric unknowns are and what constrains them.

    Attributes
    ----------
    col : ndarray of int, shape (T, N)
        Column of epoch ``i``, satellite ``j``'s unknown (−1 where the satellite has no
        code row at that epoch).
    prior_sigma_m : ndarray, shape (n_iono,)
        σ of each unknown's prior (m), ``inf`` (no prior) but on an arc's first segment.
    link_from, link_to : ndarray of int
        Columns of consecutive segments of one satellite.
    link_sigma_m : ndarray
    first : int
        Column of the first unknown (they follow the epoch blocks).
    bias_col : ndarray of int, shape (N,)
        Column of each satellite's second-band bias unknown (−1: none), after the
        ionospheric ones.
    """

    col: np.ndarray
    prior_sigma_m: FloatArray
    link_from: np.ndarray
    link_to: np.ndarray
    link_sigma_m: FloatArray
    first: int
    bias_col: np.ndarray

    @property
    def count(self) -> int:
        return int(self.prior_sigma_m.size)

    @property
    def n_bias(self) -> int:
        return int(np.sum(self.bias_col >= 0))

    @property
    def size(self) -> int:
        return self.count + self.n_bias


def iono_unknowns(
    t_s: FloatArray,
    has_code: np.ndarray,
    iono_l1_m: FloatArray,
    first: int,
    free_bias: np.ndarray | None = None,
) -> IonoUnknowns:
    """Lay out the unknowns (module docstring).

    Parameters
    ----------
    t_s : ndarray, shape (T,)
    has_code : ndarray of bool, shape (T, N)
        Epochs where a satellite has at least one code row.
    iono_l1_m : ndarray, shape (T, N)
        The broadcast model's L1 slant delay (m; NaN where not computed).
    first : int
        Column of the first unknown.
    free_bias : ndarray of bool, shape (N,), optional
        Satellites whose second band needs its own bias unknown.
    """
    T, N = has_code.shape
    col = np.full((T, N), -1, int)
    seg = np.floor((t_s - t_s[0]) / SEGMENT_S).astype(int) if T else np.zeros(0, int)
    prior: list[float] = []
    l_from: list[int] = []
    l_to: list[int] = []
    l_sig: list[float] = []
    k = first
    delay = np.abs(np.nan_to_num(iono_l1_m, nan=0.0))
    for j in range(N):
        rows = np.flatnonzero(has_code[:, j])
        if rows.size == 0:
            continue
        prev_col, prev_t = -1, 0.0
        for s in np.unique(seg[rows]).tolist():
            e = rows[seg[rows] == s]
            col[e, j] = k
            t_mid = float(np.mean(t_s[e]))
            # the prior once per arc (its first segment); later segments follow by the links
            sigma = max(KLOBUCHAR_RMS_FRACTION * float(np.mean(delay[e, j])), MIN_PRIOR_SIGMA_M)
            prior.append(sigma if prev_col < 0 else np.inf)
            if prev_col >= 0:
                l_from.append(prev_col)
                l_to.append(k)
                l_sig.append(max(IONO_RATE_M_S * (t_mid - prev_t), 1e-3))
            prev_col, prev_t = k, t_mid
            k += 1
    bias_col = np.full(N, -1, int)
    if free_bias is not None:
        q = np.flatnonzero(free_bias)
        bias_col[q] = k + np.arange(q.size)
    return IonoUnknowns(
        col, np.array(prior), np.array(l_from, int), np.array(l_to, int), np.array(l_sig), first, bias_col
    )


@dataclass(frozen=True)
class IonoCodeTerm:
    """The ``γ_b δI`` term of code rows, added to rows whose ``linearize`` reads the epoch
    blocks only (``inner``, built with the full width ``n``)."""

    inner: object  # has .linearize(x_blocks) -> Linearized of width n
    n_blocks: int
    col: np.ndarray  # (m,) column of each row's unknown
    gamma: FloatArray  # (m,)
    bias_col: np.ndarray  # (m,) column of the row's second-band bias (−1: none)
    n: int

    def linearize(self, x: FloatArray) -> Linearized:
        lin: Linearized = self.inner.linearize(x[: self.n_blocks])  # type: ignore[attr-defined]
        m = self.col.size
        b = np.flatnonzero(self.bias_col >= 0)
        r = lin.r - self.gamma * x[self.col]
        r[b] -= x[self.bias_col[b]]
        rows = np.concatenate([np.arange(m), b])
        cols = np.concatenate([self.col, self.bias_col[b]])
        vals = np.concatenate([self.gamma, np.ones(b.size)])
        J = lin.J + sp.csr_matrix((vals, (rows, cols)), shape=(m, self.n))
        return Linearized(r, lin.sigma, J.tocsr())


@dataclass(frozen=True)
class BlocksOnly:
    """Rows that read the epoch blocks only (built with the full width ``n``)."""

    inner: object
    n_blocks: int

    def linearize(self, x: FloatArray) -> Linearized:
        return self.inner.linearize(x[: self.n_blocks])  # type: ignore[attr-defined,no-any-return]


@dataclass(frozen=True)
class IonoPriorRows:
    """The priors and links of :class:`IonoUnknowns` as rows (linear)."""

    unk: IonoUnknowns
    n: int

    def linearize(self, x: FloatArray) -> Linearized:
        u = self.unk
        cols = u.first + np.arange(u.count)
        has = np.isfinite(u.prior_sigma_m)
        cols = cols[has]
        m0, m1 = cols.size, u.link_from.size
        J0 = sp.csr_matrix((np.ones(m0), (np.arange(m0), cols)), shape=(m0, self.n))
        r_i = np.repeat(np.arange(m1), 2)
        c_i = np.column_stack([u.link_to, u.link_from]).ravel()
        v_i = np.tile([1.0, -1.0], m1)
        J1 = sp.csr_matrix((v_i, (r_i, c_i)), shape=(m1, self.n))
        bc = u.bias_col[u.bias_col >= 0]
        J2 = sp.csr_matrix((np.ones(bc.size), (np.arange(bc.size), bc)), shape=(bc.size, self.n))
        r = np.concatenate([-x[cols], -(x[u.link_to] - x[u.link_from]), -x[bc]])
        sigma = np.concatenate([u.prior_sigma_m[has], u.link_sigma_m, np.full(bc.size, FREE_BIAS_SIGMA_M)])
        return Linearized(r, sigma, sp.vstack([J0, J1, J2], format="csr"))


__all__ = [
    "CALIBRATED_SYSTEMS",
    "FREE_BIAS_SIGMA_M",
    "IONO_RATE_M_S",
    "KLOBUCHAR_RMS_FRACTION",
    "MIN_PRIOR_SIGMA_M",
    "SEGMENT_S",
    "BlocksOnly",
    "IonoCodeTerm",
    "IonoPriorRows",
    "IonoUnknowns",
    "iono_unknowns",
]

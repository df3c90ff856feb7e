"""Per-satellite code-bias states of the Kalman SPP (docs/algorithms.md §43).

A phone's code error is not white: multipath and NLOS give each satellite a bias that
changes over seconds to minutes. Weighted as white noise, it is averaged epoch after epoch
as if it had independent samples, and the track tied by the carrier phase follows the
running mean of the biased code. Here each code signal ``k`` (one satellite, one band)
gets a state ``b_k`` (m), a first-order Gauss–Markov process::

    code row   P_k + … = rho + clk_s + [L5] ifb_s + b_k + e_k,   e_k white
    b_k(t + dt) = φ b_k(t) + w,   φ = exp(−|dt|/τ),   var w = σ_b,k² (1 − φ²)

with steady-state σ ``σ_b,k = σ_b / sin(el_k)`` (the code's elevation law, elevation when
the state starts) and the white part's σ reduced so that the row's total σ at zenith stays
the configured ``code_sigma_m``: ``σ_e² = σ_code² − σ_b²``. A new signal (first seen, or
absent at the previous epoch) starts from ``b = 0`` with variance ``σ_b,k²``. The datum of
the biases is their prior: zero mean, ``σ_b``; a bias common to all satellites is the
clock's. What the states change is the weighting in time: an epoch's code adds little new
information on a bias it shares with the previous epochs, so the carrier phase and the
Doppler carry the track's shape and the code its mean over ``τ``-long stretches of many
satellites.

``σ_b`` and ``τ`` come from the receiver's own code minus carrier
(:func:`code_bias_from_cmc`): the between-satellite CMC of continuing carrier arcs, split
into a white part (the scatter of its epoch-to-epoch changes) and the rest, whose
autocorrelation gives ``τ``.

Optionally (``code_elevation_delay``) one more state ``δz`` (m) common to all code rows,
with column ``1/sin el − 1``: the elevation-dependent mean of the multipath and NLOS delays,
which the clock cannot take (:func:`elevation_delay_coefficients`), Gauss–Markov with the
same ``σ_b`` and its own correlation time. :class:`CodeErrorStates` holds what a run uses.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from robustrtk.core import FloatArray, ObsBatch
from robustrtk.estimation.state import StateLayout
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.measurement.code_noise import row_sin_elevations
from robustrtk.pipeline.config import Config
from robustrtk.pipeline.spp_dynamics import TransitionModel
from robustrtk.pipeline.spp_signals import Signals

#: First element of a code-bias state key ``("code", label)`` (label as ``"G05:P1"``).
CODE_BIAS = "code"

CodeBiasKey = tuple[str, str]


def code_bias_key(label: str) -> CodeBiasKey:
    """The state key of the code row labelled ``label`` (``"G05:P1"``)."""
    return (CODE_BIAS, label)


def is_code_bias(key: Hashable) -> bool:
    """Is ``key`` a code-bias state (not a carrier-phase arc bias)?"""
    return isinstance(key, tuple) and len(key) == 2 and key[0] == CODE_BIAS


@dataclass(frozen=True)
class CodeBiasModel:
    """Steady-state σ at zenith and correlation time of the per-signal code biases.

    Attributes
    ----------
    sigma_m : float
        ``σ_b`` at zenith (m).
    tau_s : float
        Correlation time ``τ`` (s).
    """

    sigma_m: float
    tau_s: float

    def phi(self, dt_s: float) -> float:
        """Transition factor ``exp(−|dt|/τ)`` over ``dt_s`` seconds."""
        return float(np.exp(-abs(dt_s) / self.tau_s))

    def white_var(self, code_var_m2: float, sin_el: float) -> float:
        """Variance left to the white part of a code row whose total variance is
        ``code_var_m2`` (m²) at elevation sine ``sin_el``: ``code_var − σ_b²/sin²el``,
        at least a tenth of ``code_var`` (the white part never vanishes)."""
        return max(code_var_m2 - self.sigma_m**2 / sin_el**2, 0.1 * code_var_m2)


@dataclass(frozen=True)
class CodeBiasProcess:
    """``inner``'s transition with the code-bias states (every key :func:`is_code_bias`
    accepts, or only ``keys`` when given) following the Gauss–Markov process of ``model``
    (``var_m2``: the steady-state variance of each key, m², ``model.sigma_m²`` where
    absent); every other state as ``inner`` has it."""

    inner: TransitionModel
    model: CodeBiasModel
    var_m2: Mapping[Hashable, float] = field(default_factory=dict)
    keys: tuple[Hashable, ...] | None = None
    name: str = "spp+code-bias"

    def transition(self, layout: StateLayout, dt_s: float) -> tuple[FloatArray, FloatArray]:
        F, Q = self.inner.transition(layout, dt_s)
        phi = self.model.phi(dt_s)
        for a, key in enumerate(layout.amb_keys):
            if (self.keys is None and is_code_bias(key)) or (self.keys is not None and key in self.keys):
                r = layout.n_fixed + a
                F[r, r] = phi
                Q[r, r] = self.var_m2.get(key, self.model.sigma_m**2) * (1.0 - phi * phi)
        return F, Q


def add_bias_columns(
    H: FloatArray, d: FloatArray, keys: Sequence[Hashable | None], layout: StateLayout, x_prior: FloatArray
) -> None:
    """Put the code-bias column of each row with a key into ``H`` (in place, 1) and take
    the prior bias out of its innovation ``d`` (in place)."""
    for r, key in enumerate(keys):
        if key is not None:
            a = layout.amb_index(key)
            H[r, a] = 1.0
            d[r] -= x_prior[a]


def code_bias_from_cmc(
    t_s: FloatArray, cmc_m: FloatArray, cont: np.ndarray, sin_el: FloatArray, min_arc: int = 60
) -> tuple[float, float, float] | None:
    """``σ_b``, ``τ`` and the white σ of a receiver's code from its code minus carrier.

    The CMC of one signal, ``P − λΦ``, is its code error plus its arc's constant (the
    ambiguity), twice the ionosphere (slow) and, on a phone, the difference of the code and
    the phase clocks (common to all signals, tens of metres from epoch to epoch). The
    common part is removed through the epoch-to-epoch changes: ``c_k = median_i ΔCMC_i,k``
    over the continuing signals, cumulated. Then, scaled by ``sin el`` (zenith):

    - white σ: ``1.4826 · MAD(ΔCMC − c) / √2`` (a white error enters two changes);
    - total σ: ``1.4826 · MAD`` of each arc of at least ``min_arc`` epochs about its own
      straight line (the arc's constant and the ionosphere's drift removed);
    - ``σ_b = √(total² − white²)``;
    - ``τ``: the arcs' median autocorrelation of the detrended CMC at lag ``L ≥ 1`` is,
      for white noise plus a Gauss–Markov process, ``(σ_b²/σ²) e^{−L dt/τ}``; ``τ`` is the
      least-squares fit of ``ln(ρ(L) σ²/σ_b²) = −L dt/τ`` over the lags up to a tenth of
      ``min_arc`` epochs (detrending an arc pulls longer lags down, so ``τ`` errs short)
      where that ratio is in (0.05, 0.999).

    Parameters
    ----------
    t_s : ndarray, shape (T,)
    cmc_m : ndarray, shape (T, R)
        Code minus carrier (m) of ``R`` signals, NaN where either is absent.
    cont : ndarray of bool, shape (T, R)
        The carrier arc continues from the previous epoch (no loss of lock, no gap).
    sin_el : ndarray, shape (T, R)
        Elevation sine of each cell (NaN where unknown).
    min_arc : int
        Fewest epochs of an arc used for the total σ and τ.

    Returns
    -------
    (sigma_b_m, tau_s, white_sigma_m) or None
        None with fewer than five such arcs or no correlated part.
    """
    t = np.asarray(t_s, float)
    cmc = np.asarray(cmc_m, float)
    s = np.asarray(sin_el, float)
    ok = np.isfinite(cmc) & np.isfinite(s)
    cont = np.asarray(cont, bool) & ok
    cont[1:] &= ok[:-1]
    cont[0] = False
    d = np.full_like(cmc, np.nan)
    d[1:] = cmc[1:] - cmc[:-1]
    d[~cont] = np.nan
    have = np.isfinite(d).any(axis=1)
    common = np.zeros(t.size)
    common[have] = np.nanmedian(d[have], axis=1)
    y = cmc - np.cumsum(common)[:, None]  # scaled by sin el after detrending (CMC ~ 1e7 m)
    dz = (d - common[:, None]) * s
    dz = dz[np.isfinite(dz)]
    if dz.size < 100:
        return None
    white = 1.4826 * float(np.median(np.abs(dz))) / np.sqrt(2.0)
    dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    arc = np.cumsum(~cont, axis=0)
    max_lag = max(1, min_arc // 10)
    resid: list[FloatArray] = []
    acf: list[FloatArray] = []
    for j in range(cmc.shape[1]):
        for a in np.unique(arc[ok[:, j], j]):
            idx = np.flatnonzero(ok[:, j] & (arc[:, j] == a))
            if idx.size < min_arc:
                continue
            tt = t[idx] - t[idx[0]]
            z = (y[idx, j] - np.polyval(np.polyfit(tt, y[idx, j], 1), tt)) * s[idx, j]
            resid.append(z)
            v = float(np.mean(z * z))
            acf.append(np.array([np.mean(z[:-L] * z[L:]) / v for L in range(1, max_lag + 1)]))
    if len(resid) < 5:
        return None
    zs = np.concatenate(resid)
    total = 1.4826 * float(np.median(np.abs(zs)))
    if total <= white:
        return None
    sigma_b = float(np.sqrt(total**2 - white**2))
    share = sigma_b**2 / total**2
    rho = np.median(np.vstack(acf), axis=0) / share
    lag_s = np.arange(1, max_lag + 1) * dt
    use = (rho > 0.05) & (rho < 0.999)
    if not use.any():
        return None
    # least squares of ln ρ(L) = −L dt / τ through the origin
    tau = -float(np.sum(lag_s[use] ** 2) / np.sum(lag_s[use] * np.log(rho[use])))
    return sigma_b, float(tau), white


def cmc_of_signals(
    batch: ObsBatch, sig: Signals, eph: EphemerisSource, pos_m: FloatArray
) -> tuple[FloatArray, FloatArray, np.ndarray, FloatArray]:
    """Times, code minus carrier (m), arc continuation and elevation sines of the Kalman
    SPP's signals (both bands as columns, shape (T, 2 N')) seen from ``pos_m`` (ECEF):
    the inputs of :func:`code_bias_from_cmc`. An arc continues when both epochs have code
    and phase, the loss-of-lock bit is clear and the interval is under 1.5 nominal ones."""
    t = np.asarray(batch.t_s, float)
    T = t.size
    cmc = (sig.code_m - sig.phase_cyc * sig.wavelength_m[None]).reshape(T, -1)
    lli = np.nan_to_num(sig.lli).astype(np.int64).reshape(T, -1)
    ok = np.isfinite(cmc)
    cont = ok & ~(lli & 1).astype(bool)
    cont[1:] &= ok[:-1]
    cont[0] = False
    if T > 1:
        dt = np.diff(t)
        cont[1:] &= (dt < 1.5 * float(np.median(dt)))[:, None]
    s_rows = row_sin_elevations(batch, eph, pos_m)[:, sig.rows]
    sin_el = np.repeat(s_rows, 2, axis=1)
    return t, cmc, cont, sin_el


def model_from_data(
    batch: ObsBatch, sig: Signals, eph: EphemerisSource, pos_m: FloatArray
) -> CodeBiasModel | None:
    """The :class:`CodeBiasModel` the receiver's own code minus carrier gives
    (:func:`code_bias_from_cmc`), None where it gives none (no carrier phase, arcs too
    short)."""
    t, cmc, cont, sin_el = cmc_of_signals(batch, sig, eph, pos_m)
    est = code_bias_from_cmc(t, cmc, cont, sin_el)
    if est is None:
        return None
    return CodeBiasModel(sigma_m=est[0], tau_s=est[1])


class CodeBiasStates:
    """The code-bias states of one Kalman SPP run: which rows have one, their steady-state
    variances, the process model and the design columns.

    Parameters
    ----------
    model : CodeBiasModel
    """

    def __init__(self, model: CodeBiasModel) -> None:
        self.model = model
        self.var_m2: dict[Hashable, float] = {}

    def tag(
        self,
        kinds: Sequence[str],
        labels: Sequence[str],
        H_pos: Sequence[FloatArray],
        var: list[float],
        pos_m: FloatArray,
    ) -> list[Hashable | None]:
        """The bias key of each code row (None for other kinds). Each code row's variance
        in ``var`` (m², in place) becomes its white part (:meth:`CodeBiasModel.white_var`);
        a key not seen before gets its steady-state variance ``σ_b² / sin² el``.

        ``H_pos`` (m rows of shape (3,)) are the rows' position columns (``−u``, the line of sight),
        ``pos_m`` the receiver's ECEF position they were linearised at."""
        p = np.asarray(pos_m, float)
        up = p / np.linalg.norm(p) if np.linalg.norm(p) > 0 else np.array([0.0, 0.0, 1.0])
        keys: list[Hashable | None] = []
        for r, kind in enumerate(kinds):
            if kind != "P":
                keys.append(None)
                continue
            sin_el = float(np.clip(-np.asarray(H_pos[r]) @ up, 0.1, 1.0))
            key = code_bias_key(labels[r])
            var[r] = self.model.white_var(var[r], sin_el)
            if key not in self.var_m2:
                self.var_m2[key] = self.model.sigma_m**2 / sin_el**2
            keys.append(key)
        return keys

    def start(self, keys: Sequence[Hashable | None], layout_keys: Sequence[Hashable]) -> list[Hashable]:
        """The keys of ``keys`` not in ``layout_keys`` (states to start, at 0); the
        steady-state variance of keys that ended is forgotten."""
        present = set(layout_keys)
        seen = {k for k in keys if k is not None}
        new = [k for k in keys if k is not None and k not in present]
        for k in list(self.var_m2):
            if k not in seen:
                del self.var_m2[k]
        return new

    def process(self, inner: TransitionModel) -> CodeBiasProcess:
        """``inner`` with these states' Gauss–Markov transition."""
        return CodeBiasProcess(inner, self.model, dict(self.var_m2))


#: State key of the elevation-dependent common code delay.
ELEVATION_DELAY_KEY = ("code-elevation", "delay")


def elevation_delay_coefficients(
    kinds: Sequence[str], H_pos: Sequence[FloatArray], pos_m: FloatArray
) -> FloatArray:
    """The column of the elevation-dependent code delay ``δz`` in each row:
    ``1/sin el − 1`` for code rows (zero at the zenith, where it would be the clock's),
    0 for the others. ``H_pos`` are the rows' position columns (``−u``), ``pos_m`` the ECEF
    position they were linearised at."""
    p = np.asarray(pos_m, float)
    n = float(np.linalg.norm(p))
    up = p / n if n > 0 else np.array([0.0, 0.0, 1.0])
    out = np.zeros(len(kinds))
    for r, kind in enumerate(kinds):
        if kind == "P":
            out[r] = 1.0 / float(np.clip(-np.asarray(H_pos[r]) @ up, 0.1, 1.0)) - 1.0
    return out


@dataclass(frozen=True)
class CodeErrorStates:
    """The code-error states of one Kalman SPP run (either or both): a Gauss–Markov bias
    per code signal (:class:`CodeBiasStates`) and one elevation-dependent delay common to all
    code rows (``elevation``: its ``(σ, τ)``, m and s)."""

    biases: CodeBiasStates | None
    elevation: CodeBiasModel | None

    def prepare(
        self,
        kinds: Sequence[str],
        labels: Sequence[str],
        H_pos: Sequence[FloatArray],
        var: list[float],
        pos_m: FloatArray,
        layout_keys: Sequence[Hashable],
    ) -> EpochStates:
        """One epoch's rows: their keys and columns, the states to keep and to start
        (with their variances); code-row variances in ``var`` become their white part when
        there are per-signal biases (:meth:`CodeBiasStates.tag`)."""
        keys: list[Hashable | None] = [None] * len(kinds)
        new: list[Hashable] = []
        start_var: dict[Hashable, float] = {}
        present: set[Hashable] = set()
        if self.biases is not None:
            keys = self.biases.tag(kinds, labels, H_pos, var, pos_m)
            new = self.biases.start(keys, layout_keys)
            start_var = {k: self.biases.var_m2[k] for k in new}
            present = {k for k in keys if k is not None}
        coef = None
        if self.elevation is not None:
            coef = elevation_delay_coefficients(kinds, H_pos, pos_m)
            present.add(ELEVATION_DELAY_KEY)
            if ELEVATION_DELAY_KEY not in layout_keys:
                new.append(ELEVATION_DELAY_KEY)
                start_var[ELEVATION_DELAY_KEY] = self.elevation.sigma_m**2
        return EpochStates(keys, coef, present, new, start_var)

    @classmethod
    def of(
        cls,
        cfg: Config,
        batch: ObsBatch,
        sig: Signals,
        eph: EphemerisSource,
        pos_m: FloatArray,
    ) -> CodeErrorStates | None:
        """The states ``cfg.spp`` asks for (``code_bias``, ``code_elevation_delay``), their
        σ and τ configured or from the data (:func:`model_from_data`, seen from ``pos_m``);
        None when none is asked for or the data give no σ for any."""
        sp = cfg.spp
        if not (sp.code_bias or sp.code_elevation_delay):
            return None
        est = None
        if sp.code_bias_sigma_m is None or (sp.code_bias and sp.code_bias_tau_s is None):
            est = model_from_data(batch, sig, eph, pos_m)
        sigma = sp.code_bias_sigma_m if sp.code_bias_sigma_m is not None else (est.sigma_m if est else None)
        biases = elevation = None
        if sigma is not None and sp.code_bias:
            tau = sp.code_bias_tau_s if sp.code_bias_tau_s is not None else (est.tau_s if est else None)
            if tau is not None:
                biases = CodeBiasStates(CodeBiasModel(sigma, tau))
        if sigma is not None and sp.code_elevation_delay:
            elevation = CodeBiasModel(sigma, sp.code_elevation_delay_tau_s)
        if biases is None and elevation is None:
            return None
        return cls(biases, elevation)

    def process(self, inner: TransitionModel) -> TransitionModel:
        """``inner`` with these states' Gauss–Markov transitions."""
        out = inner
        if self.biases is not None:
            out = CodeBiasProcess(out, self.biases.model, dict(self.biases.var_m2))
        if self.elevation is not None:
            var: dict[Hashable, float] = {ELEVATION_DELAY_KEY: self.elevation.sigma_m**2}
            out = CodeBiasProcess(out, self.elevation, var, keys=(ELEVATION_DELAY_KEY,))
        return out


@dataclass(frozen=True)
class EpochStates:
    """What :meth:`CodeErrorStates.prepare` found for one epoch's rows."""

    keys: list[Hashable | None]  # per-signal bias key of each row (None: no bias)
    elevation_coef: FloatArray | None  # column of the elevation delay, shape (m,)
    present: set[Hashable]  # the states these rows keep
    new: list[Hashable]  # states to start (at 0)
    start_var: dict[Hashable, float]  # their variances (m²)

    def columns(self, H: FloatArray, d: FloatArray, layout: StateLayout, x_prior: FloatArray) -> None:
        """The states' columns into ``H`` and their prior share out of ``d`` (in place)."""
        add_bias_columns(H, d, self.keys, layout, x_prior)
        if self.elevation_coef is not None:
            a = layout.amb_index(ELEVATION_DELAY_KEY)
            H[:, a] = self.elevation_coef
            d -= self.elevation_coef * x_prior[a]


__all__ = [
    "CODE_BIAS",
    "CodeBiasKey",
    "CodeBiasModel",
    "CodeBiasProcess",
    "CodeBiasStates",
    "CodeErrorStates",
    "ELEVATION_DELAY_KEY",
    "EpochStates",
    "elevation_delay_coefficients",
    "add_bias_columns",
    "code_bias_from_cmc",
    "cmc_of_signals",
    "code_bias_key",
    "is_code_bias",
    "model_from_data",
]

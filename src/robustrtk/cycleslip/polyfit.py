r"""Polynomial-fit cycle-slip detection and repair for single-frequency phase.

For a single-frequency system (such as an L1 pseudolite room) there is no second carrier
to form a geometry-free combination, so slips are found in the time series of the phase
itself: a polynomial of degree ``p`` is fitted by least squares to the last ``W`` accepted
epochs of each series and extrapolated to the current epoch; a residual that is too large
for the fit's prediction uncertainty plus the measurement noise is a slip.

With the fit times scaled to :math:`\tau = (t_i - t)/s \in [-1, 0)` (``s`` the window span),
design rows :math:`a_i = (1, \tau_i, \dots, \tau_i^p)` and :math:`A` stacking them, the
prediction at the current epoch (:math:`\tau = 0`) is the constant coefficient
:math:`\hat c_0` and

.. math::

    d = \varphi(t) - \hat c_0, \qquad
    \sigma_d^2 = \sigma^2 \left(1 + [(A^T A)^{-1}]_{00}\right), \qquad
    \text{slip} \iff |d| > k\,\sigma_d

where :math:`\sigma = \max(\sigma_0, \hat\sigma)`, :math:`\sigma_0` the stated noise
(``noise_cyc``) and :math:`\hat\sigma = \sqrt{\mathrm{RSS}/(m - p - 1)}` the fit's own
residual scale (so unmodelled dynamics raise the threshold instead of raising alarms).
A detected jump is repaired by :math:`n = \mathrm{round}(d)` when :math:`n \neq 0`,
:math:`|d - n| \le r\,\sigma_d` and :math:`r\,\sigma_d < 0.5` (exactly one integer is
compatible with ``d``); otherwise the series is reset (a new arc starts and the caller
must re-initialise that ambiguity).

Which series to feed
--------------------
The detector assumes the series is smooth at the fit's degree over the window.
Undifferenced phase contains the receiver (and, for pseudolites, transmitter) clock
drifts, which are neither smooth nor small; feed it between-receiver single differences
of a common-clock pair, **double differences**, or geometry-minus-phase series (phase
minus the range predicted from a known trajectory), whose dynamics are those of the
relative geometry only. Use an epoch rate high enough that the rover's motion is
polynomial over ``window`` epochs (e.g. 10 Hz for a rail or a trolley indoors).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from robustrtk.core import BoolArray, FloatArray, InputError


class PolyFitDetector:
    """Streaming polynomial-fit slip detector over N phase series.

    Parameters
    ----------
    window : int
        Number of past accepted epochs in each fit (``W``), at least ``degree + 2``.
    degree : int
        Polynomial degree ``p`` (2 = constant acceleration).
    threshold_sigma : float
        ``k``: a residual beyond ``k * sigma_d`` is a slip.
    noise_cyc : float
        Standard deviation of one phase sample of the series (cycles), e.g. 3 mm / 0.19 m
        for an L1 double difference with 3 mm noise.
    repair_sigma : float
        ``r``: a jump within ``r * sigma_d`` of a nonzero integer is repaired.
    use_fit_rms : bool
        Use ``max(noise_cyc, fit rms)`` as ``sigma`` (default) instead of ``noise_cyc``.
    min_points : int or None
        Epochs needed in the window before testing (default ``degree + 2``); until then
        epochs are accepted untested.
    max_gap_s : float
        A series whose previous valid epoch is older than this restarts (as after NaN).
    flag_after_gap : bool
        When a series that was being tracked returns after a NaN gap (or a gap longer than
        ``max_gap_s``), its first epoch is flagged as an unrepairable slip (continuity
        cannot be verified). A series appearing for the first time is never flagged.

    Notes
    -----
    Outputs of :meth:`step` per series:

    * ``slip_mask`` True where a slip was detected (repaired or not), or after a gap when
      ``flag_after_gap``;
    * ``repaired_phase`` the input minus the integer corrections accumulated in the
      current arc (NaN where the input is NaN);
    * ``jump_cyc`` the integer removed where the slip was repaired, NaN where it could not
      be (the caller must reset that ambiguity: see :func:`reset_mask`), 0 elsewhere.

    The last estimated (float) jumps are kept in :attr:`last_jump_float_cyc` and the last
    test statistics ``|d| / sigma_d`` in :attr:`last_test_stat` (NaN where not tested).
    """

    def __init__(
        self,
        window: int = 10,
        degree: int = 2,
        threshold_sigma: float = 6.0,
        noise_cyc: float = 0.02,
        *,
        repair_sigma: float = 4.0,
        use_fit_rms: bool = True,
        min_points: int | None = None,
        max_gap_s: float = math.inf,
        flag_after_gap: bool = True,
    ) -> None:
        if degree < 0:
            raise InputError(f"degree must be >= 0, got {degree}")
        if window < degree + 2:
            raise InputError(f"window must be >= degree + 2 = {degree + 2}, got {window}")
        if not (threshold_sigma > 0 and noise_cyc > 0 and repair_sigma > 0):
            raise InputError("threshold_sigma, noise_cyc and repair_sigma must be positive")
        self.window = int(window)
        self.degree = int(degree)
        self.threshold_sigma = float(threshold_sigma)
        self.noise_cyc = float(noise_cyc)
        self.repair_sigma = float(repair_sigma)
        self.use_fit_rms = bool(use_fit_rms)
        self.min_points = int(min_points) if min_points is not None else self.degree + 2
        if not (self.degree + 1 <= self.min_points <= self.window):
            raise InputError(f"min_points must lie in [{self.degree + 1}, {self.window}], got {min_points}")
        self.max_gap_s = float(max_gap_s)
        self.flag_after_gap = bool(flag_after_gap)
        self._n: int | None = None
        self._t_prev = -math.inf

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Forget every series (the next :meth:`step` starts afresh)."""
        self._n = None
        self._t_prev = -math.inf

    def _init(self, n: int) -> None:
        self._n = n
        self._t_buf = np.full((n, self.window), np.nan)
        self._ph_buf = np.full((n, self.window), np.nan)
        self._offset = np.zeros(n)
        self._seen = np.zeros(n, dtype=bool)
        self._gap_pending = np.zeros(n, dtype=bool)
        self._last_t = np.full(n, -math.inf)
        self.last_jump_float_cyc = np.full(n, np.nan)
        self.last_test_stat = np.full(n, np.nan)

    def _clear(self, rows: BoolArray) -> None:
        self._t_buf[rows] = np.nan
        self._ph_buf[rows] = np.nan
        self._offset[rows] = 0.0

    def _append(self, rows: BoolArray, t_s: float, values: FloatArray) -> None:
        if not rows.any():
            return
        self._t_buf[rows, :-1] = self._t_buf[rows, 1:]
        self._ph_buf[rows, :-1] = self._ph_buf[rows, 1:]
        self._t_buf[rows, -1] = t_s
        self._ph_buf[rows, -1] = values[rows]

    # ------------------------------------------------------------------- step
    def _predict(self, rows: BoolArray, t_s: float) -> tuple[FloatArray, FloatArray]:
        """Prediction and its innovation std ``sigma_d`` for the series in ``rows``."""
        tb = self._t_buf[rows]
        pb = self._ph_buf[rows]
        w = np.isfinite(pb)
        m = w.sum(axis=1)
        span = t_s - np.nanmin(tb, axis=1)
        tau = np.where(w, (tb - t_s) / span[:, None], 0.0)
        powers = np.arange(self.degree + 1)
        A = np.where(w[..., None], tau[..., None] ** powers, 0.0)  # (R, W, p+1)
        b = np.where(w, pb, 0.0)
        AtA = np.einsum("rwi,rwj->rij", A, A)
        Atb = np.einsum("rwi,rw->ri", A, b)
        inv = np.linalg.inv(AtA)
        coef = np.einsum("rij,rj->ri", inv, Atb)
        resid = np.where(w, b - np.einsum("rwi,ri->rw", A, coef), 0.0)
        dof = m - (self.degree + 1)
        sigma = np.full(len(m), self.noise_cyc)
        if self.use_fit_rms:
            ok = dof > 0
            rms = np.sqrt((resid**2).sum(axis=1)[ok] / dof[ok])
            sigma[ok] = np.maximum(sigma[ok], rms)
        sigma_d = sigma * np.sqrt(1.0 + inv[:, 0, 0])
        return coef[:, 0], sigma_d

    def step(self, t_s: float, phase_cyc: npt.ArrayLike) -> tuple[BoolArray, FloatArray, FloatArray]:
        """Test one epoch.

        Parameters
        ----------
        t_s : float
            Epoch time (s); strictly increasing between calls, any spacing.
        phase_cyc : array_like, shape (N,)
            Phase of each series (cycles); NaN where absent. N is fixed at the first call.

        Returns
        -------
        slip_mask : ndarray of bool, shape (N,)
        repaired_phase : ndarray, shape (N,)
            Cycles; NaN where the input is NaN.
        jump_cyc : ndarray, shape (N,)
            Integer removed (repaired), NaN (reset needed) or 0; see the class notes.
        """
        ph = np.atleast_1d(np.asarray(phase_cyc, dtype=float))
        if ph.ndim != 1:
            raise InputError(f"phase_cyc must have shape (N,), got {ph.shape}")
        if self._n is None:
            self._init(ph.shape[0])
        elif ph.shape[0] != self._n:
            raise InputError(f"phase_cyc has {ph.shape[0]} series, expected {self._n}")
        t = float(t_s)
        if not t > self._t_prev:
            raise InputError(f"epoch time {t} s is not after the previous one {self._t_prev} s")
        self._t_prev = t
        n = ph.shape[0]

        valid = np.isfinite(ph)
        slip = np.zeros(n, dtype=bool)
        jump = np.zeros(n)
        self.last_jump_float_cyc = np.full(n, np.nan)
        self.last_test_stat = np.full(n, np.nan)

        # Gaps: a missing epoch or one too far from the last restarts the series.
        gone = ~valid
        self._gap_pending |= gone & self._seen
        self._clear(gone)
        late = valid & (t - self._last_t > self.max_gap_s) & self._seen
        self._gap_pending |= late
        self._clear(late)

        back = valid & self._gap_pending
        if self.flag_after_gap:
            slip[back] = True
            jump[back] = np.nan
        self._gap_pending[valid] = False

        corrected = ph - self._offset
        count = np.isfinite(self._ph_buf).sum(axis=1)
        test = valid & (count >= self.min_points)
        if test.any():
            pred, sigma_d = self._predict(test, t)
            d = corrected[test] - pred
            self.last_jump_float_cyc[test] = d
            self.last_test_stat[test] = np.abs(d) / sigma_d
            det = np.abs(d) > self.threshold_sigma * sigma_d
            k = np.round(d)
            tol = self.repair_sigma * sigma_d
            fixable = det & (k != 0) & (np.abs(d - k) <= tol) & (tol < 0.5)
            idx = np.flatnonzero(test)
            fix_rows = idx[fixable]
            self._offset[fix_rows] += k[fixable]
            corrected[fix_rows] -= k[fixable]
            slip[fix_rows] = True
            jump[fix_rows] = k[fixable]
            reset_rows = idx[det & ~fixable]
            if reset_rows.size:
                rmask = np.zeros(n, dtype=bool)
                rmask[reset_rows] = True
                self._clear(rmask)
                corrected[reset_rows] = ph[reset_rows]
                slip[reset_rows] = True
                jump[reset_rows] = np.nan

        self._append(valid, t, corrected)
        self._last_t[valid] = t
        self._seen |= valid
        repaired = np.where(valid, corrected, np.nan)
        return slip, repaired, jump


def reset_mask(slip_mask: npt.ArrayLike, jump_cyc: npt.ArrayLike) -> BoolArray:
    """Cells where a slip was found that could not be repaired (ambiguity must be reset).

    Parameters
    ----------
    slip_mask, jump_cyc : array_like, same shape
        Outputs of :meth:`PolyFitDetector.step` or :func:`polyfit_slips`.

    Returns
    -------
    ndarray of bool
        ``slip_mask & isnan(jump_cyc)``.
    """
    return np.asarray(slip_mask, dtype=bool) & np.isnan(np.asarray(jump_cyc, dtype=float))


def polyfit_slips(
    t_s: npt.ArrayLike,
    phase_cyc: npt.ArrayLike,
    window: int = 10,
    degree: int = 2,
    threshold_sigma: float = 6.0,
    noise_cyc: float = 0.02,
    **kwargs: object,
) -> tuple[BoolArray, FloatArray, FloatArray]:
    """Run :class:`PolyFitDetector` over a whole record.

    Parameters
    ----------
    t_s : array_like, shape (T,)
        Strictly increasing epoch times (s), any spacing.
    phase_cyc : array_like, shape (T, N) or (T,)
        Phase series (cycles), NaN where absent; see the module notes on which series to
        feed (double differences, not undifferenced phase).
    window, degree, threshold_sigma, noise_cyc, **kwargs
        Passed to :class:`PolyFitDetector`.

    Returns
    -------
    slip_mask : ndarray of bool, shape like ``phase_cyc``
    repaired_phase : ndarray, shape like ``phase_cyc``
    jump_cyc : ndarray, shape like ``phase_cyc``
    """
    t = np.asarray(t_s, dtype=float)
    ph = np.asarray(phase_cyc, dtype=float)
    one_d = ph.ndim == 1
    ph2 = ph[:, None] if one_d else ph
    if ph2.ndim != 2 or t.ndim != 1 or ph2.shape[0] != t.shape[0]:
        raise InputError(f"expected t_s (T,) and phase_cyc (T, N) or (T,), got {t.shape} and {ph.shape}")
    det = PolyFitDetector(window, degree, threshold_sigma, noise_cyc, **kwargs)  # type: ignore[arg-type]
    slip = np.zeros(ph2.shape, dtype=bool)
    rep = np.full(ph2.shape, np.nan)
    jump = np.zeros(ph2.shape)
    for i in range(t.shape[0]):
        slip[i], rep[i], jump[i] = det.step(t[i], ph2[i])
    if one_d:
        return slip[:, 0], rep[:, 0], jump[:, 0]
    return slip, rep, jump

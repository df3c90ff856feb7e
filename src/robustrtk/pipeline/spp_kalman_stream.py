"""Real-time Kalman SPP: one receiver's epochs as they arrive, one solution per epoch.

:class:`KalmanSppStream` is the per-epoch front end of the Kalman SPP
(:class:`~robustrtk.pipeline.spp_kalman.KalmanSppFilter`, the filter the file solve
``solve --mode spp --kalman`` steps): each epoch (all its signals, as an
:class:`~robustrtk.io.epoch_source.EpochSource` yields it) becomes the signals of one epoch
(:func:`~robustrtk.pipeline.spp_signals.spp_signals`) and their satellite states, and the
filter, carried from epoch to epoch, solves it with code, Doppler and the carrier phase of
continuing arcs (the time-differenced phase: an arc's bias cancels between its epochs).
:class:`SppStreamSolver` gives it the interface ``robustrtk run`` drives
(:class:`~robustrtk.pipeline.stream.StreamSolver`'s): rover epochs and ephemerides in,
solutions out, no base.

What the file solve decides from the whole file, the stream decides as it goes:

* the signal of each system and band: the first the preference order
  (:data:`~robustrtk.pipeline.spp_common.BAND1_PREFERENCE`,
  :data:`~robustrtk.pipeline.spp_signals.BAND2_PREFERENCE`) finds with code, kept from then
  on (the file takes the first with code anywhere in it: the same signal unless a receiver
  sends two of one band and the first appears late);
* the systems with a clock in the state: those ``cfg.gnss.systems`` names, else every
  system the preference knows (the file: those it has). A clock no row observes does not
  touch the others' estimates (nothing couples it back), so the solutions are those of the
  file solve to rounding;
* the ephemerides: those that have arrived (an epoch before any is unsolved; a satellite
  without its own yet is left out), unless fixed ones are given.

So a stream replayed with the file's navigation data solves every epoch as the file solve
does. Nothing per epoch is kept (no smoothing: ``smoother`` and ``fgo`` are post-processing);
the memory is that of the filter.
"""

from __future__ import annotations

import numpy as np

from robustrtk.core import FloatArray, InputError, ObsBatch, ObsEpoch, Solution
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.navdata import NavData
from robustrtk.io.epoch_source import epoch_batch
from robustrtk.io.raw_collect import merge_nav
from robustrtk.pipeline.config import Config
from robustrtk.pipeline.spp_codebias import CodeErrorStates
from robustrtk.pipeline.spp_common import BAND1_PREFERENCE, SppEpoch, reported, unsolved_epoch
from robustrtk.pipeline.spp_kalman import KalmanSppFilter
from robustrtk.pipeline.spp_rows import KalmanSppRun
from robustrtk.pipeline.spp_signals import BAND2_PREFERENCE, SatStatesTable, Signals, spp_columns, spp_signals
from robustrtk.pipeline.stream import StreamStatus


def stream_config_error(cfg: Config) -> str | None:
    """Why ``cfg`` cannot be run as a stream (one line naming the setting), or None."""
    sp = cfg.spp
    if cfg.mode != "spp":
        return f"mode: the stream Kalman SPP runs mode spp, got {cfg.mode!r}"
    if cfg.estimator.filter not in ("ekf", "ukf"):
        return f"filter: the Kalman SPP runs ekf or ukf, got {cfg.estimator.filter!r}"
    if cfg.estimator.smoother:
        return "smoother: smoothing needs the whole record (post-processing: solve --smooth)"
    if sp.fgo:
        return "fgo: the batch smoother needs the whole record (post-processing: solve --fgo)"
    if (sp.code_bias or sp.code_elevation_delay) and (
        sp.code_bias_sigma_m is None or (sp.code_bias and sp.code_bias_tau_s is None)
    ):
        return (
            "code_bias_sigma_m: a stream cannot take the code errors' σ and τ from the whole "
            "record; set code_bias_sigma_m (and code_bias_tau_s)"
        )
    return None


class _StreamFilter(KalmanSppFilter):
    """The filter of a stream: code-error states with their configured σ and τ (the only
    record at hand is the current epoch, :attr:`current`)."""

    current: ObsBatch | None = None

    def code_error_states(self, sig: Signals, pos_m: FloatArray) -> CodeErrorStates | None:
        assert self.current is not None
        return CodeErrorStates.of(self.cfg, self.current, sig, self.run.eph, pos_m)


class KalmanSppStream:
    """The Kalman SPP of epochs pushed one at a time (module notes).

    Parameters
    ----------
    cfg : Config
        Mode ``spp`` with a Kalman filter (:func:`stream_config_error` says why not).
    eph : EphemerisSource, optional
        The ephemerides (:meth:`set_ephemerides` when they arrive or change).

    Raises
    ------
    InputError
        ``cfg`` cannot be run as a stream.
    """

    def __init__(self, cfg: Config, eph: EphemerisSource | None = None) -> None:
        why = stream_config_error(cfg)
        if why is not None:
            raise InputError(why)
        self.cfg = cfg
        given = cfg.gnss.systems.upper() if cfg.gnss.systems else "".join(BAND1_PREFERENCE)
        self.letters = "".join(sorted(set(given)))
        dual = cfg.spp.dual_frequency
        self.band2 = [s for s in self.letters if dual and BAND2_PREFERENCE.get(s)]
        self.eph = eph
        self.filter: _StreamFilter | None = None
        self.chosen: dict[tuple[str, int], str] = {}  # (system, band index) -> signal
        self.seq = 0

    def set_ephemerides(self, eph: EphemerisSource) -> None:
        """The ephemerides from the next epoch on."""
        self.eph = eph
        if self.filter is not None:
            self.filter.run.set_ephemerides(eph)

    def signals(self, epoch: ObsEpoch, nav: NavData) -> tuple[ObsBatch, Signals]:
        """The epoch (as a one-epoch batch) and its signals, each system's as chosen before
        (module notes)."""
        batch = epoch_batch(epoch)
        dual = self.cfg.spp.dual_frequency
        cols = spp_columns(batch, nav, dual, self.letters, self.chosen)
        for s, ks in cols.items():
            for b, k in enumerate(ks):
                if k >= 0:
                    self.chosen.setdefault((s, b), batch.signals[k])
        return batch, spp_signals(batch, nav, dual, self.letters, columns=cols)

    def step(self, epoch: ObsEpoch) -> SppEpoch:
        """One epoch: its solution (status ``single`` or ``none``, as the file solve's)."""
        seq = self.seq
        self.seq += 1
        t = float(epoch.t_s)
        eph = self.eph
        if eph is None:
            return unsolved_epoch(t, "no ephemerides yet")
        if self.filter is None:
            run = KalmanSppRun(tuple(self.letters), self.band2, eph, self.cfg)
            self.filter = _StreamFilter(run, self.cfg, record=False)
        batch, sig = self.signals(epoch, eph.nav)
        self.filter.current = batch
        sats = SatStatesTable(sig, np.array([t]), eph).of(0)
        return reported([self.filter.solve_epoch(t, sig, 0, seq, sats)])[0]


class SppStreamSolver:
    """Kalman SPP of a rover stream with :class:`~robustrtk.pipeline.stream.StreamSolver`'s
    interface (``robustrtk run --mode spp``): no base.

    Parameters
    ----------
    cfg : Config
        As :class:`KalmanSppStream`.
    nav : NavData or EphemerisSource, optional
        Fixed ephemerides (a RINEX navigation file): the stream's own are then ignored.
    """

    def __init__(self, cfg: Config, nav: NavData | EphemerisSource | None = None) -> None:
        eph = nav if isinstance(nav, EphemerisSource) or nav is None else EphemerisSource(nav)
        self.core = KalmanSppStream(cfg, eph)
        self.fixed_nav = nav is not None
        self.navs: list[NavData] = []
        self.last: StreamStatus | None = None

    def on_nav(self, nav: NavData) -> None:
        """New ephemerides (ignored when fixed ones were given)."""
        if self.fixed_nav:
            return
        self.navs = [nav] if not self.navs else [merge_nav([*self.navs, nav])]
        self.core.set_ephemerides(EphemerisSource(self.navs[0]))

    def on_rover(self, epoch: ObsEpoch) -> list[Solution]:
        """A rover epoch; its solution (none when unsolved)."""
        e = self.core.step(epoch)
        if e.status == "none":
            return []
        sol = e.to_solution()
        self.last = StreamStatus(sol.t_s, sol.status, sol.n_used, 0.0, 0.0, 0)
        return [sol]

    def on_base(self, epoch: ObsEpoch) -> list[Solution]:
        """No base in SPP."""
        raise InputError("--base: spp solves the rover alone")

    def set_receiver_type(self, role: str, receiver_type: str) -> None:
        """Nothing to decide from it in SPP."""

    def set_base_position(self, pos_m: FloatArray) -> None:
        """No base in SPP."""

    def end_base(self) -> list[Solution]:
        return []

    def flush(self) -> list[Solution]:
        """Nothing is held: every epoch was solved as it came."""
        return []


__all__ = ["KalmanSppStream", "SppStreamSolver", "stream_config_error"]

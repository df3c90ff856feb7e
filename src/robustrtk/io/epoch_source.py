"""Epoch sources: one receiver's observation epochs in time order, and navigation events.

An :class:`EpochSource` is an iterable of :data:`SourceEvent`: an
:class:`~robustrtk.core.ObsEpoch` (all the receiver's signals at one tag; epochs come in
increasing time) or a :class:`~robustrtk.geometry.navdata.NavData` (ephemerides decoded
since the last such event). Files and streams are the same to a consumer:

* :class:`BatchSource` — an :class:`~robustrtk.core.ObsBatch` read whole (RINEX, or a
  binary log read at once) and, optionally, its navigation data first;
* :class:`StreamDecoder` — bytes of UBX or RTCM 3 in any chunking (a socket, a file being
  replayed): :meth:`StreamDecoder.feed` returns the epochs and ephemerides those bytes
  completed. UBX: an epoch is one RXM-RAWX message; RTCM 3: an epoch is complete with its
  last message (multiple-message bit 0), and an epoch that a later one overtakes before
  it is complete is dropped and counted, as :func:`~robustrtk.io.rtcm3.read_rtcm3` does.
  Corrupt frames (CRC), garbage and unknown messages are skipped and counted by the
  decoders (:attr:`StreamDecoder.counts`).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import Literal, Protocol

import numpy as np

from robustrtk.core import InputError, ObsBatch, ObsEpoch
from robustrtk.geometry.navdata import NavData
from robustrtk.io.raw_collect import ObsCollector, count
from robustrtk.io.rtcm3 import Rtcm3Decoder, count_rtcm3_frames
from robustrtk.io.ubx import UbxDecoder, count_ubx_frames

#: What a source yields: an observation epoch or newly decoded ephemerides.
SourceEvent = ObsEpoch | NavData

StreamFormat = Literal["ubx", "rtcm3"]


class EpochSource(Protocol):
    """Observation epochs of one receiver in time order, and navigation events."""

    def __iter__(self) -> Iterator[SourceEvent]: ...


class BatchSource:
    """The epochs of a batch read whole (its navigation data first, when given)."""

    def __init__(self, batch: ObsBatch, nav: NavData | None = None) -> None:
        self.batch = batch
        self.nav = nav

    def __iter__(self) -> Iterator[SourceEvent]:
        if self.nav is not None:
            yield self.nav
        for i in range(len(self.batch)):
            yield self.batch.epoch(i)


def epoch_batch(epoch: ObsEpoch, like: ObsBatch | None = None) -> ObsBatch:
    """A one-epoch :class:`ObsBatch` holding ``epoch`` (meta and receiver from ``like``)."""

    def one(a: np.ndarray | None) -> np.ndarray | None:
        return None if a is None else np.asarray(a)[None]

    return ObsBatch(
        t_s=np.array([epoch.t_s]), tx_ids=epoch.tx_ids, system=epoch.system, signals=epoch.signals,
        code_m=np.asarray(epoch.code_m)[None], phase_cyc=np.asarray(epoch.phase_cyc)[None],
        doppler_hz=np.asarray(epoch.doppler_hz)[None], cn0_dbhz=np.asarray(epoch.cn0_dbhz)[None],
        lli=np.asarray(epoch.lli)[None], wavelength_m=np.asarray(epoch.wavelength_m),
        code_sigma_m=one(epoch.code_sigma_m), phase_sigma_cyc=one(epoch.phase_sigma_cyc),
        receiver=like.receiver if like is not None else "", meta=dict(like.meta) if like is not None else {},
    )  # fmt: skip


def detect_format(head: bytes) -> StreamFormat | None:
    """``"ubx"`` or ``"rtcm3"`` by which framing finds more valid frames in ``head``."""
    n_ubx, n_rtcm = count_ubx_frames(head), count_rtcm3_frames(head)
    if max(n_ubx, n_rtcm) == 0:
        return None
    return "ubx" if n_ubx >= n_rtcm else "rtcm3"


class StreamDecoder:
    """Incremental decoding of one receiver's UBX or RTCM 3 byte stream.

    Parameters
    ----------
    fmt : {"ubx", "rtcm3"}, optional
        Format; detected from the first bytes that hold a valid frame when None.
    t_ref_s : float, optional
        RTCM 3 only: GPST (s) within half a week of the stream's epochs (its messages carry
        the time of week, not the week).
    glo_channels : dict str -> int, optional
        GLONASS frequency channels (``"R07"`` -> 5) known from elsewhere (a navigation file,
        another stream's ephemerides), shared: the decoder reads it where its own stream has
        not told a satellite's channel (an RTCM 3 MSM4/MSM6 phase is in metres: no channel, no
        phase in cycles) and adds those its stream tells (observations, GLONASS ephemerides).
        Several decoders in threads may share one dict (single-key reads and ``setdefault``).
    beidou_gpst : bool
        RTCM 3 only: the BeiDou MSM epochs are tagged in GPS time (an encoder's defect,
        :class:`robustrtk.io.rtcm3.Rtcm3Decoder`); BDT, the standard, when False.
    """

    def __init__(
        self,
        fmt: StreamFormat | None = None,
        t_ref_s: float | None = None,
        glo_channels: dict[str, int] | None = None,
        beidou_gpst: bool = False,
    ) -> None:
        self.fmt: StreamFormat | None = fmt
        self.t_ref_s = t_ref_s
        self.beidou_gpst = beidou_gpst
        self.glo_channels = glo_channels
        self.decoder: UbxDecoder | Rtcm3Decoder | None = None
        self.head = b""
        self.n_nav = 0
        self.nav_marks: dict[str, int] | None = None
        self.stats: dict[str, int] = {}
        if fmt is not None:
            self._start(fmt)

    def _start(self, fmt: StreamFormat) -> None:
        if fmt == "rtcm3" and self.t_ref_s is None:
            raise InputError("RTCM 3 stream: expected the approximate time (--time-ref), none given")
        self.fmt = fmt
        self.decoder = (
            UbxDecoder() if fmt == "ubx" else Rtcm3Decoder(t_ref_s=self.t_ref_s, beidou_gpst=self.beidou_gpst)
        )
        if self.glo_channels is not None:
            self.decoder.obs.glo_channels = self.glo_channels  # the decoder reads and adds to it

    @property
    def counts(self) -> dict[str, int]:
        """The decoder's framing and message counters, and the stream's own."""
        dec = {} if self.decoder is None else self.decoder.counts
        return {**dec, **self.stats}

    @property
    def station(self) -> dict[str, object]:
        """RTCM 3 station data (1005/1006/1033) decoded so far (empty for UBX)."""
        return dict(self.decoder.station) if isinstance(self.decoder, Rtcm3Decoder) else {}

    @property
    def receiver_type(self) -> str:
        """The receiver's make and model as the stream tells it (the ``receiver_type`` of a
        decoded file): ``"u-blox"`` for UBX, the RTCM 1033 receiver descriptor once it came,
        else ``""``."""
        if isinstance(self.decoder, UbxDecoder):
            return "u-blox"
        return str(self.station.get("receiver", "") or "")

    def feed(self, data: bytes) -> list[SourceEvent]:
        """Decode ``data``; the epochs and ephemerides it completed, in order."""
        if self.decoder is None:
            self.head += data
            fmt = detect_format(self.head)
            if fmt is None:
                if len(self.head) > 1 << 16:
                    count(self.stats, "undetected bytes dropped", len(self.head))
                    self.head = b""
                return []
            data, self.head = self.head, b""
            self._start(fmt)
        assert self.decoder is not None
        self.decoder.feed(data)
        return self._events(final=False)

    def close(self) -> list[SourceEvent]:
        """End of input: the events left (a last RTCM 3 epoch completes here only if its
        last message arrived)."""
        if self.decoder is None:
            return []
        self.decoder.close()
        return self._events(final=True)

    def _events(self, final: bool) -> list[SourceEvent]:
        dec = self.decoder
        assert dec is not None
        out: list[SourceEvent] = []
        if dec.nav.n_records > self.n_nav:
            self.n_nav = dec.nav.n_records
            nav = dec.nav.nav_data(since=self.nav_marks)  # the records since the last event
            self.nav_marks = dec.nav.marks()
            out.append(nav)
            if self.glo_channels is not None and len(nav.glonass):
                for sat, ch in nav.glo_channels().items():
                    self.glo_channels.setdefault(sat, ch)
        obs = dec.obs
        tags = obs.epoch_tags_ns()
        if not tags:
            return out
        if isinstance(dec, UbxDecoder):
            done = set(tags)  # one RXM-RAWX is one whole epoch
        else:
            complete = dec.complete_epochs_ns()
            done = {t for t in tags if t in complete}
            newest_done = max(done) if done else None
            stale = {t for t in tags if t not in done and newest_done is not None and t < newest_done}
            if final:
                stale |= {t for t in tags if t not in done}
            if stale:
                obs.pop_epochs(stale)
                count(self.stats, "incomplete epochs dropped", len(stale))
        if not done:
            return out
        part: ObsCollector = obs.pop_epochs(done)
        batch = part.batch()
        out.extend(batch.epoch(i) for i in range(len(batch)))
        return out


def stream_events(chunks: Iterable[bytes], decoder: StreamDecoder) -> Iterator[SourceEvent]:
    """The events of a byte stream given in chunks (then the decoder's close)."""
    for data in chunks:
        yield from decoder.feed(data)
    yield from decoder.close()


__all__ = [
    "BatchSource",
    "EpochSource",
    "SourceEvent",
    "StreamDecoder",
    "StreamFormat",
    "detect_format",
    "epoch_batch",
    "stream_events",
]

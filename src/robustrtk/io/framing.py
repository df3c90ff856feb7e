"""What the incremental frame splitters of byte streams (RTCM 3, UBX) share."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterator
from typing import Generic, TypeVar

from robustrtk.io.raw_collect import count

FrameT = TypeVar("FrameT")


class ByteFramer(ABC, Generic[FrameT]):
    """A frame splitter: :meth:`feed` bytes, get the frames they complete; :meth:`close` at
    the end of input.

    Attributes
    ----------
    counts : dict str -> int
        Tallies of the stream (``frames``, ``skipped_bytes``, ``truncated`` and the
        format's own checksum failures).
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self.counts: dict[str, int] = {}

    @abstractmethod
    def feed(self, data: bytes) -> Iterator[FrameT]:
        """Frames completed by ``data`` (bytes may arrive in any pieces)."""

    def _may_start_frame(self) -> bool:
        """Whether the bytes waiting at the head of the buffer may begin a frame."""
        return True

    def close(self) -> list[FrameT]:
        """End of input: frames still waiting behind an incomplete one (a false sync whose
        length runs past the end) are returned; the incomplete frame is counted as
        ``truncated``."""
        out: list[FrameT] = []
        truncated = False
        while self._buf:
            truncated = truncated or self._may_start_frame()
            del self._buf[:1]
            count(self.counts, "skipped_bytes", 1)
            out.extend(self.feed(b""))
        if truncated:
            count(self.counts, "truncated")
        return out


__all__ = ["ByteFramer"]

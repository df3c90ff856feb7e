"""Surveyed transmitter positions (pseudolites): a fixed table, clocks unknown."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import numpy.typing as npt

from robustrtk.core import FloatArray


class SurveyedSource:
    """:class:`~robustrtk.core.TransmitterSource` backed by a table of fixed positions.

    Pseudolite antennas do not move, so ``positions`` ignores the time and the
    pseudoranges. Their clocks are not known (each transmitter runs its own oscillator;
    the offset cancels in the between-receiver difference), so ``clock_m`` is NaN.

    Parameters
    ----------
    transmitters : mapping of str to array-like, shape (3,)
        Transmitter id -> antenna position (m) in the site frame (e.g.
        ``Site.transmitters``).
    """

    def __init__(self, transmitters: Mapping[str, npt.ArrayLike]):
        ids = list(transmitters)
        pos = np.asarray([np.asarray(transmitters[t], dtype=float) for t in ids], dtype=float)
        if pos.size and pos.shape != (len(ids), 3):
            raise ValueError(f"transmitter positions must have shape (N, 3), got {pos.shape}")
        self._index = {t: i for i, t in enumerate(ids)}
        self._pos_m = pos.reshape(len(ids), 3)
        self._pos_m.setflags(write=False)

    @property
    def tx_ids(self) -> tuple[str, ...]:
        """Known transmitter ids, in table order."""
        return tuple(self._index)

    def positions(
        self,
        t_s: float,
        tx_ids: Sequence[str],
        code_m: FloatArray | None = None,
    ) -> tuple[FloatArray, FloatArray]:
        """Positions ``(N, 3)`` (m) of ``tx_ids`` and their clocks ``(N,)`` (NaN: unknown).

        Unknown ids give NaN rows. ``t_s`` and ``code_m`` are accepted for protocol
        compatibility and not used.
        """
        idx = np.fromiter((self._index.get(t, -1) for t in tx_ids), dtype=np.int64, count=len(tx_ids))
        pos = np.full((idx.shape[0], 3), np.nan)
        known = idx >= 0
        pos[known] = self._pos_m[idx[known]]
        return pos, np.full(idx.shape[0], np.nan)

""":class:`SdAmbiguityMeans` against the element-by-element numpy form it replaced (the same
numbers bit for bit), and the remembered DD operator of :func:`dd_rows` against the one
built afresh."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.measurement.dd import dd_rows
from robustrtk.measurement.glonass import SdAmbiguityMeans


class _Oracle:
    """The running means as first written (numpy scalars per row)."""

    def __init__(self, max_gap_s: float = 30.0) -> None:
        self.max_gap_s = max_gap_s
        self._sum: dict[str, float] = {}
        self._n: dict[str, int] = {}
        self._var1: dict[str, float] = {}
        self._t: dict[str, float] = {}

    def update(self, t_s, tx_ids, sd_cyc, var1_cyc2, restart):  # type: ignore[no-untyped-def]
        mean = np.full(len(tx_ids), np.nan)
        var = np.full(len(tx_ids), np.nan)
        for i, tx in enumerate(tx_ids):
            v = float(sd_cyc[i])
            if not np.isfinite(v):
                continue
            n = self._n.get(tx, 0)
            fresh = (
                n == 0
                or bool(restart[i])
                or t_s - self._t.get(tx, -np.inf) > self.max_gap_s
                or abs(v - self._sum[tx] / n) > 6.0 * np.sqrt(max(float(var1_cyc2[i]), 1e-6))
            )
            if fresh:
                self._sum[tx], self._n[tx], self._var1[tx] = v, 1, float(var1_cyc2[i])
            else:
                self._sum[tx] += v
                self._n[tx] = n + 1
                self._var1[tx] += float(var1_cyc2[i])
            self._t[tx] = t_s
            n = self._n[tx]
            mean[i] = self._sum[tx] / n
            var[i] = self._var1[tx] / n**2
        return mean, var


value = st.one_of(
    st.floats(-1e7, 1e7, allow_nan=False),
    st.just(float("nan")),
    st.floats(-3.0, 3.0),
)
epoch = st.tuples(
    st.floats(0.0, 50.0),  # time step
    st.lists(
        st.tuples(value, st.floats(0.0, 4.0) | st.just(float("nan")), st.booleans()), min_size=4, max_size=4
    ),
)


@settings(max_examples=150, deadline=None)
@given(st.lists(epoch, min_size=1, max_size=12))
def test_running_means_bit_for_bit(epochs) -> None:
    ids = ("R01:L1", "R02:L1", "G05:L1", "R07:L2")
    new, old = SdAmbiguityMeans(), _Oracle()
    t = 0.0
    for dt, rows in epochs:
        t += dt
        sd = np.array([r[0] for r in rows])
        var1 = np.array([r[1] for r in rows])
        restart = np.array([r[2] for r in rows])
        m1, v1 = new.update(t, ids, sd, var1, restart)
        m0, v0 = old.update(t, ids, sd, var1, restart)
        assert m1.dtype == m0.dtype and v1.dtype == v0.dtype
        assert m1.tobytes() == m0.tobytes() and v1.tobytes() == v0.tobytes()


def _fresh_D(tx_ids, i_tx, i_ref):  # type: ignore[no-untyped-def]
    N, m = len(tx_ids), len(i_tx)
    D = np.zeros((m, 2 * N))
    ar = np.arange(m)
    D[ar, i_tx] = 1.0
    D[ar, i_ref] = -1.0
    D[ar, N + i_tx] = -1.0
    D[ar, N + i_ref] = 1.0
    return D


@settings(max_examples=100, deadline=None)
@given(st.lists(st.booleans(), min_size=6, max_size=6), st.lists(st.booleans(), min_size=6, max_size=6))
def test_dd_rows_operator_remembered(ok1, ok2) -> None:
    ids = ("G01", "G02", "G03", "E11", "E12", "E13")
    groups = ("G:L1",) * 3 + ("E:L1",) * 3
    refs = {"G:L1": "G02", "E:L1": "E11"}
    for ok in (ok1, ok2, ok1):
        rows = dd_rows(ids, groups, np.array(ok), refs)
        assert not rows.D.flags.writeable
        assert np.array_equal(rows.D, _fresh_D(ids, rows.i_tx, rows.i_ref))
        assert rows.labels == tuple(f"{ids[a]}-{ids[b]}" for a, b in zip(rows.i_tx, rows.i_ref, strict=True))
        assert rows.tx == tuple(ids[a] for a in rows.i_tx)
        assert rows.group == tuple(groups[a] for a in rows.i_tx)

"""The incremental base buffer pairs exactly as the whole-array rule."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.pipeline.base_buffer import BaseBuffer, pair_base_epochs


def pairs_incremental(
    tr: np.ndarray, tb: np.ndarray, usable: np.ndarray, tol_s: float, max_age_s: float
) -> list[tuple[int, int, float, bool]]:
    """Rover and base epochs merged by tag (a base epoch at ``t_b − tol``, before rover
    epochs of the same key), each rover epoch paired when it comes up."""
    buf: BaseBuffer[int] = BaseBuffer(tol_s, max_age_s)
    events = sorted(
        [(float(t) - tol_s, 0, j) for j, t in enumerate(tb)] + [(float(t), 1, i) for i, t in enumerate(tr)]
    )
    out = []
    for _, kind, k in events:
        if kind == 0:
            assert buf.push(float(tb[k]), k, bool(usable[k])) == k
        else:
            got = buf.pair(float(tr[k]), k)
            if got is not None:
                p, payload = got
                assert payload == p.i_base
                out.append((p.i_rover, p.i_base, p.age_s, p.exact))
    return sorted(out)


@settings(max_examples=200, deadline=None)
@given(
    n_r=st.integers(0, 40),
    n_b=st.integers(0, 40),
    seed=st.integers(0, 2**31),
    tol_s=st.sampled_from([0.005, 0.5]),
    max_age_s=st.sampled_from([0.0, 1.5, 30.0]),
)
def test_incremental_pairs_equal_whole_array(
    n_r: int, n_b: int, seed: int, tol_s: float, max_age_s: float
) -> None:
    rng = np.random.default_rng(seed)
    steps = [0.001, 0.5, 1.0, 1.0, 2.0, 5.0, 40.0]
    tr = 100.0 + np.cumsum(rng.choice(steps, n_r))
    tb = (
        100.0
        + np.cumsum(rng.choice(steps, n_b))
        + rng.choice([0.0, 0.003, -0.2], n_b) * (rng.random(n_b) < 0.3)
    )
    tb = np.unique(tb)
    usable = rng.random(tb.size) < 0.8
    want = pair_base_epochs(tr, tb, tol_s, max_age_s, usable)
    expect = sorted((p.i_rover, p.i_base, p.age_s, p.exact) for p in want)
    assert pairs_incremental(tr, tb, usable, tol_s, max_age_s) == expect


def test_buffer_memory_is_bounded_by_the_age_window() -> None:
    buf: BaseBuffer[int] = BaseBuffer(0.5, 30.0)
    for k in range(10_000):
        buf.push(float(k), k)
        assert buf.pair(float(k) + 0.2, k) is not None
    assert len(buf.t) <= 32

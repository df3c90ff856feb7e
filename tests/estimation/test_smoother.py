"""RTS smoother: equals the batch (all-epoch) least-squares posterior of the linear-Gaussian
model, also when states are added and dropped between epochs; segments are independent."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.estimation.smoother import FilterStep, rts_smooth


def _spd(rng: np.random.Generator, n: int, scale: float = 1.0) -> np.ndarray:
    A = rng.normal(size=(n, n))
    return scale * (A @ A.T + 0.5 * n * np.eye(n))


def _chain(rng: np.random.Generator, dims: list[int]) -> dict:
    """A random linear-Gaussian chain; between epochs the first state of the previous
    epoch may be dropped and the last state of the new epoch may be new (zero row of F)."""
    K = len(dims)
    m0 = rng.normal(size=dims[0])
    P0 = _spd(rng, dims[0])
    F, u, Q, H, R, z = [None], [None], [None], [], [], []
    for k in range(K):
        if k:
            Fk = rng.normal(size=(dims[k], dims[k - 1])) * 0.7
            if rng.random() < 0.5:
                Fk[-1, :] = 0.0  # a state that starts here
            if rng.random() < 0.5:
                Fk[:, 0] = 0.0  # a state that is dropped here
            F.append(Fk)
            u.append(rng.normal(size=dims[k]))
            Q.append(_spd(rng, dims[k], 0.3))
        m = int(rng.integers(1, 4))
        H.append(rng.normal(size=(m, dims[k])))
        R.append(_spd(rng, m, 0.5))
        z.append(rng.normal(size=m) * 3)
    return dict(K=K, dims=dims, m0=m0, P0=P0, F=F, u=u, Q=Q, H=H, R=R, z=z)


def _forward(c: dict) -> list[FilterStep]:
    steps = []
    x, P = c["m0"], c["P0"]
    for k in range(c["K"]):
        if k:
            x = c["F"][k] @ x + c["u"][k]
            P = c["F"][k] @ P @ c["F"][k].T + c["Q"][k]
        xp, Pp = x.copy(), P.copy()
        H, R = c["H"][k], c["R"][k]
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        x = x + K @ (c["z"][k] - H @ x)
        P = (np.eye(len(x)) - K @ H) @ P
        steps.append(FilterStep(c["F"][k], xp, Pp, x, 0.5 * (P + P.T)))
    return steps


def _batch(c: dict) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Posterior of all epochs at once: whitened stacked least squares."""
    dims = c["dims"]
    off = np.concatenate([[0], np.cumsum(dims)])
    N = int(off[-1])
    blocks_A, blocks_b = [], []

    def add(A: np.ndarray, b: np.ndarray, cov: np.ndarray) -> None:
        W = np.linalg.cholesky(np.linalg.inv(cov)).T  # W^T W = cov^-1
        blocks_A.append(W @ A)
        blocks_b.append(W @ b)

    A = np.zeros((dims[0], N))
    A[:, : dims[0]] = np.eye(dims[0])
    add(A, c["m0"], c["P0"])
    for k in range(1, c["K"]):
        A = np.zeros((dims[k], N))
        A[:, off[k] : off[k + 1]] = np.eye(dims[k])
        A[:, off[k - 1] : off[k]] = -c["F"][k]
        add(A, c["u"][k], c["Q"][k])
    for k in range(c["K"]):
        A = np.zeros((len(c["z"][k]), N))
        A[:, off[k] : off[k + 1]] = c["H"][k]
        add(A, c["z"][k], c["R"][k])
    A = np.vstack(blocks_A)
    b = np.concatenate(blocks_b)
    info = A.T @ A
    x = np.linalg.solve(info, A.T @ b)
    cov = np.linalg.inv(info)
    xs = [x[off[k] : off[k + 1]] for k in range(c["K"])]
    Ps = [cov[off[k] : off[k + 1], off[k] : off[k + 1]] for k in range(c["K"])]
    return xs, Ps


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), dims=st.lists(st.integers(1, 4), min_size=2, max_size=7))
def test_rts_equals_batch_posterior_with_changing_dimension(seed: int, dims: list[int]) -> None:
    c = _chain(np.random.default_rng(seed), dims)
    sm = rts_smooth(_forward(c))
    xs, Ps = _batch(c)
    for (x, P), xb, Pb in zip(sm, xs, Ps, strict=True):
        np.testing.assert_allclose(x, xb, rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(P, Pb, rtol=1e-6, atol=1e-6)


def test_last_epoch_is_the_filtered_one_and_segments_do_not_mix() -> None:
    c = _chain(np.random.default_rng(3), [2, 2, 3, 3])
    steps = _forward(c)
    sm = rts_smooth(steps)
    np.testing.assert_allclose(sm[-1][0], steps[-1].x_post)
    # cut the chain before epoch 2: epoch 1 becomes the end of a segment
    s2 = steps[2]
    cut = [*steps[:2], FilterStep(None, s2.x_prior, s2.P_prior, s2.x_post, s2.P_post), *steps[3:]]
    sm_cut = rts_smooth(cut)
    np.testing.assert_allclose(sm_cut[1][0], steps[1].x_post)
    np.testing.assert_allclose(sm_cut[0][0], rts_smooth(steps[:2])[0][0])
    assert not np.allclose(sm[0][0], sm_cut[0][0])

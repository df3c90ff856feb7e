"""RTS smoother: equals the batch (all-epoch) least-squares posterior of the linear-Gaussian
model, also when states are added and dropped between epochs; segments are independent."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.estimation.filters import EKF
from robustrtk.estimation.models import LinearMeasurement, RandomWalkModel
from robustrtk.estimation.smoother import FilterStep, layout_transition, rts_smooth
from robustrtk.estimation.state import GaussianState, StateLayout


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


# --- layout changes through the state operations -------------------------------------------------


#: ambiguity keys dropped / added before each epoch's measurement update (epoch 0: initial)
_PLAN: list[tuple[tuple[str, ...], tuple[str, ...]]] = [
    ((), ("a", "b")),
    (("a",), ("c",)),
    ((), ("d",)),
    (("b", "c"), ("e",)),
    ((), ()),
]


def _by_key_model(
    prev: StateLayout, nxt: StateLayout, q_pos: float, q_amb: float, var_new: float, init: dict
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``F, u, Q`` of ``x_next = F x_prev + u + w`` written key by key (independent of
    :func:`layout_transition`): position random walk, ambiguities constant with a small walk,
    new ambiguities ``N(init, var_new)`` with no predecessor."""
    F = np.zeros((nxt.size, prev.size))
    u = np.zeros(nxt.size)
    Q = np.zeros((nxt.size, nxt.size))
    for i in range(3):
        F[i, i] = 1.0
        Q[i, i] = q_pos
    for key in nxt.amb_keys:
        i1 = nxt.amb_index(key)
        if key in prev.amb_keys:
            F[i1, prev.amb_index(key)] = 1.0
            Q[i1, i1] = q_amb
        else:
            u[i1] = init[key]
            Q[i1, i1] = var_new
    return F, u, Q


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), reref=st.booleans())
def test_rts_over_dropped_and_added_ambiguities_equals_batch(seed: int, reref: bool) -> None:
    rng = np.random.default_rng(seed)
    dt, q_pos, q_amb, var_new = 1.0, 0.04, 1e-3, 25.0
    process = RandomWalkModel(sigma_m_s=np.sqrt(q_pos), q_amb_cyc2_s=q_amb)
    init = {k: float(rng.integers(-20, 20)) for k in "abcde"}
    lay0 = StateLayout(blocks=(("pos", 3),))
    post: GaussianState | None = None
    T: np.ndarray | None = None
    Fl = np.zeros((0, 0))
    steps: list[FilterStep] = []
    c: dict = dict(K=len(_PLAN), dims=[], F=[None], u=[None], Q=[None], H=[], R=[], z=[])
    for drop, add in _PLAN:
        if post is None:
            prior = GaussianState(rng.normal(size=3), _spd(rng, 3), 0.0, lay0)
            prior = prior.add_ambiguities(add, np.array([init[a] for a in add]), var_new)
            c["m0"], c["P0"] = prior.x, prior.P
        else:
            pr = post.drop_ambiguities(drop)
            pr = EKF().predict(pr, process, post.t_s + dt)
            prior = pr.add_ambiguities(add, np.array([init[a] for a in add]), var_new)
            F, u, Q = _by_key_model(post.layout, prior.layout, q_pos * dt, q_amb * dt, var_new, init)
            Fl = layout_transition(post.layout, prior.layout, np.eye(3))
            np.testing.assert_array_equal(Fl, F)
            T = None
            if reref and not drop and not add:
                # re-reference the ambiguities (d, e) → (d − e, −e): F ← T F, u ← T u, Q ← T Q Tᵀ
                T = np.eye(prior.n)
                T[3:, 3:] = [[1.0, -1.0], [0.0, -1.0]]
                prior = prior.transform(T, StateLayout(blocks=prior.layout.blocks, amb_keys=("d-e", "-e")))
                F, u, Q = T @ F, T @ u, T @ Q @ T.T
            # the recorded map reproduces the prior the state operations produced
            np.testing.assert_allclose(F @ post.x + u, prior.x, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(F @ post.P @ F.T + Q, prior.P, rtol=1e-12, atol=1e-12)
            c["F"].append(F)
            c["u"].append(u)
            c["Q"].append(Q)
        n = prior.n
        m = int(rng.integers(2, n + 1))
        H = rng.normal(size=(m, n))
        R = _spd(rng, m, 0.2)
        z = H @ prior.x + rng.normal(size=m) * 2
        new_post = EKF().update(prior, LinearMeasurement(H, z, R)).state
        Fk = None if post is None or T is None else T @ Fl
        steps.append(FilterStep.from_states(prior, new_post, post, np.eye(3), F=Fk))
        c["dims"].append(n)
        c["H"].append(H)
        c["R"].append(R)
        c["z"].append(z)
        post = new_post
    sm = rts_smooth(steps)
    xs, Ps = _batch(c)
    for (x, P), xb, Pb in zip(sm, xs, Ps, strict=True):
        np.testing.assert_allclose(x, xb, rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(P, Pb, rtol=1e-6, atol=1e-6)
    assert steps[0].F is None and steps[1].layout is not None
    assert steps[1].layout.amb_keys == ("b", "c")


def test_layout_transition_reference_and_errors() -> None:
    prev = StateLayout(blocks=(("pos", 3), ("vel", 3)), amb_keys=("a", "b", "c"))
    nxt = StateLayout(blocks=(("pos", 3), ("vel", 3)), amb_keys=("c", "d", "a"))
    Ff = np.eye(6)
    Ff[:3, 3:] = 2.0 * np.eye(3)
    F = layout_transition(prev, nxt, Ff)
    assert F.shape == (9, 9)
    np.testing.assert_array_equal(F[:6, :6], Ff)
    np.testing.assert_array_equal(F[6:, 6:], [[0, 0, 1], [0, 0, 0], [1, 0, 0]])  # c←c, d new, a←a
    np.testing.assert_array_equal(F[:6, 6:], 0.0)
    np.testing.assert_array_equal(F[6:, :6], 0.0)
    np.testing.assert_array_equal(layout_transition(prev, prev), np.eye(9))
    with pytest.raises(ValueError, match="F_fixed"):
        layout_transition(prev, nxt, np.eye(3))
    with pytest.raises(ValueError, match="pass F_fixed"):
        layout_transition(prev, StateLayout(blocks=(("pos", 3),)))
    # a step whose F does not fit the neighbouring states is refused
    s0 = FilterStep(None, np.zeros(2), np.eye(2), np.zeros(2), np.eye(2))
    s1 = FilterStep(np.eye(3), np.zeros(3), np.eye(3), np.zeros(3), np.eye(3))
    with pytest.raises(ValueError, match=r"steps\[1\]\.F"):
        rts_smooth([s0, s1])

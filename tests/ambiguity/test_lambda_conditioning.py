"""LAMBDA on an ill-conditioned real-receiver ambiguity set (26 DD ambiguities, GPS/Galileo/
QZSS L1+L2, kinematic, a few epochs into a run: condition number ~1e5).

An earlier reduction that size-reduced only the sub-diagonal let ``Z`` grow past 2⁵³; it
stopped being unimodular and the "best" candidate sat thousands of cycles from the float
solution while the search reported a small norm.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from robustrtk.ambiguity import lambda_ as lm
from robustrtk.ambiguity.lambda_pure import ops_to_z

DATA = Path(__file__).parent / "data" / "ill_conditioned_26.npz"


def _case() -> tuple[np.ndarray, np.ndarray]:
    d = np.load(DATA)
    return d["a"], d["Q"]


def test_reduction_is_exactly_unimodular_and_reproduces_qz() -> None:
    a, Q = _case()
    L0, d0 = lm.ltdl(Q)
    ops, L, d = lm.reduce_ops(L0, d0)
    Z, Zinv = ops_to_z(a.size, ops)
    assert np.array_equal(Z, np.round(Z))
    assert np.array_equal(Z @ Zinv, np.eye(a.size))
    assert np.abs(Z).max() < 1e6
    assert np.allclose(L.T @ np.diag(d) @ L, Z.T @ Q @ Z, rtol=0, atol=1e-12)
    assert np.all(np.abs(np.tril(L, -1)) <= 0.5 + 1e-9)


def test_best_candidate_norm_is_true_and_not_worse_than_rounding() -> None:
    a, Q = _case()
    F, s = lm.lambda_search(a, Q, 2)
    Qi = np.linalg.inv(Q)
    norms = [float((a - F[:, k]) @ Qi @ (a - F[:, k])) for k in range(2)]
    assert np.allclose(norms, s, rtol=1e-8)
    r = a - np.round(a)
    assert s[0] <= float(r @ Qi @ r) + 1e-9
    # candidates stay near the float solution (the broken reduction put them ~1e4 cycles away)
    assert np.abs(a - F[:, 0]).max() < 2.0

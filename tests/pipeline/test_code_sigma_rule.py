"""The rule that takes the code σ from the data (algorithms.md §29, §38): RTK whenever the
data's σ is larger than the configured one; DGNSS only beyond the robust test's rejection
threshold times it."""

from __future__ import annotations

import numpy as np
import pytest

import robustrtk.pipeline.gnss_inputs as gi
from robustrtk.estimation.registry import make_robust_policy
from robustrtk.estimation.robust import rejection_threshold
from robustrtk.pipeline.gnss import dgnss_config


def test_rejection_threshold_of_each_policy() -> None:
    assert rejection_threshold(make_robust_policy("postfit")) == 3.0
    assert rejection_threshold(make_robust_policy("postfit", k1=4.5)) == 4.5
    assert rejection_threshold(make_robust_policy("prefit+postfit")) == 3.0  # the post-fit test's
    assert rejection_threshold(make_robust_policy("igg3")) == 8.0
    assert rejection_threshold(make_robust_policy("huber")) == np.inf  # down-weights only
    assert rejection_threshold(make_robust_policy("none")) == np.inf


@pytest.mark.parametrize(
    ("rover", "base", "min_ratio", "expected"),
    [
        (0.46, 0.51, 1.0, np.sqrt((0.46**2 + 0.51**2) / 2)),  # geodetic pair, RTK rule: raised
        (0.46, 0.51, 3.0, 0.3),  # the same pair under the DGNSS rule: kept
        (1.88, 2.13, 3.0, np.sqrt((1.88**2 + 2.13**2) / 2)),  # patch antennas: raised
        (1.88, None, 3.0, np.sqrt((1.88**2 + 0.3**2) / 2)),  # no base estimate: 0.3 stands in
        (0.89, 0.89, 3.0, 0.3),  # just under the threshold: kept
        (0.2, 0.2, 1.0, 0.3),  # never lowered
    ],
)
def test_data_code_sigma_rule(
    monkeypatch: pytest.MonkeyPatch, rover: float, base: float | None, min_ratio: float, expected: float
) -> None:
    est = iter([rover, base])
    monkeypatch.setattr(gi, "RowSource", lambda eph: None)
    monkeypatch.setattr(gi, "receiver_code_sigma_m", lambda batch, src, pos: next(est))
    cfg = dgnss_config(code_sigma_m=0.3)
    out, sig = gi.data_code_sigma(cfg, None, None, None, np.zeros(3), np.zeros(3), min_ratio=min_ratio)  # type: ignore[arg-type]
    assert sig == (rover, base)
    assert out.measurement.code_sigma_m == pytest.approx(expected)


def test_without_the_switch_nothing_is_estimated(monkeypatch: pytest.MonkeyPatch) -> None:
    def boom(*a: object) -> float:
        raise AssertionError("estimated")

    monkeypatch.setattr(gi, "receiver_code_sigma_m", boom)
    cfg = dgnss_config(code_sigma_from_data=False)
    out, sig = gi.data_code_sigma(cfg, None, None, None, np.zeros(3), np.zeros(3))  # type: ignore[arg-type]
    assert out is cfg and sig == (None, None)

"""``--adaptive``: alone it selects the state-discrepancy factor, with a value any factor; its
thresholds and passes act only with a factor; bad thresholds are a one-line error."""

from __future__ import annotations

from typing import Any

import pytest
from click.testing import CliRunner

from robustrtk.cli.main import main
from robustrtk.estimation.adaptive import InnovationAdaptiveFactor, StateDiscrepancyFactor
from robustrtk.estimation.registry import make_robust_policy
from robustrtk.estimation.robust import Chain
from robustrtk.pipeline.config import preset
from robustrtk.pipeline.engine import make_adaptive


def _show(*args: str) -> Any:
    return CliRunner().invoke(main, ["solve", "rover.obs", "--show-config", *args])


def _value(out: str, key: str) -> str:
    return next(line for line in out.splitlines() if line.startswith(f"{key} = ")).split(" = ", 1)[1]


@pytest.mark.parametrize(
    ("args", "expect"),
    [
        (["--mode", "dgnss", "--adaptive"], '"state"'),
        (["--mode", "dgnss", "--adaptive", "--adaptive-c1", "3"], '"state"'),
        (["--mode", "rtk", "--adaptive", "innovation"], '"innovation"'),
        (["--kalman", "--adaptive"], '"state"'),
    ],
)
def test_flag_alone_is_the_state_factor(args: list[str], expect: str) -> None:
    r = _show(*args)
    assert r.exit_code == 0, r.output
    assert _value(r.output, "adaptive") == expect


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--mode", "dgnss", "--adaptive-max-iter", "3"], "--adaptive-max-iter: acts only with the state"),
        (["--mode", "dgnss", "--adaptive-c0", "1.5"], "--adaptive-c0: acts only with an adaptive factor"),
        (
            ["--mode", "dgnss", "--adaptive", "--adaptive-c0", "3"],
            "--adaptive-c0: expected adaptive_c0 < adaptive_c1",
        ),
        (["--mode", "dgnss", "--adaptive", "innovation", "--adaptive-c1", "1"], "--adaptive-c1: expected"),
        (
            ["--mode", "dgnss", "--adaptive", "--adaptive-c0", "-1"],
            "--adaptive-c0: expected a finite positive",
        ),
        (["--adaptive"], "--adaptive: acts only with a Kalman SPP"),
        (["--mode", "dgnss", "--prefit-k0", "2"], "--prefit-k0: acts only with the pre-fit + post-fit"),
        (["--kalman", "--no-fgo-iono"], "--fgo-iono: acts only with the batch smoother (--fgo)"),
    ],
)
def test_misuse_is_a_one_line_error(args: list[str], message: str) -> None:
    r = _show(*args)
    text = r.output.strip()
    assert r.exit_code == 2 and "\n" not in text and text.startswith("error: "), r.output
    assert message in text, text


def test_config_builds_the_factor_and_the_policy_with_their_thresholds() -> None:
    st = make_adaptive(preset("dgnss").updated(adaptive="state"))
    assert isinstance(st, StateDiscrepancyFactor) and (st.c0, st.c1, st.max_iter) == (1.0, 2.5, 10)
    st = make_adaptive(preset("dgnss").updated(adaptive="state", adaptive_c0=1.2, adaptive_max_iter=1))
    assert isinstance(st, StateDiscrepancyFactor) and (st.c0, st.c1, st.max_iter) == (1.2, 2.5, 1)
    inn = make_adaptive(preset("dgnss").updated(adaptive="innovation"))
    assert isinstance(inn, InnovationAdaptiveFactor) and (inn.c0, inn.c1) == (2.0, 6.0)
    assert make_adaptive(preset("dgnss")) is None
    assert preset("spp").estimator.adaptive_max_iter == 1  # the paper's single pass for phones


def test_prefit_postfit_thresholds_reach_both_tests() -> None:
    c = make_robust_policy("prefit+postfit", k0=1.2, k1=2.8, prefit_k0=3.0, prefit_k1=9.0)
    assert isinstance(c, Chain)
    assert (c.prefit.k0, c.prefit.k1, c.postfit.k0, c.postfit.k1) == (3.0, 9.0, 1.2, 2.8)
    d = make_robust_policy("prefit+postfit")
    assert isinstance(d, Chain)
    assert (d.prefit.k0, d.prefit.k1, d.postfit.k0, d.postfit.k1) == (2.5, 7.0, 1.5, 3.0)

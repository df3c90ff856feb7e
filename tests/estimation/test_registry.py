"""Estimator registry: built-in names give the same objects as direct construction, unknown
names list the known ones, and a new filter / model / policy is one call."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np
import pytest

from robustrtk.estimation import registry
from robustrtk.estimation.filters import EKF, UKF
from robustrtk.estimation.models import ConstantVelocityModel, RandomWalkModel, StaticModel
from robustrtk.estimation.registry import (
    FILTERS,
    POLICIES,
    PROCESS_MODELS,
    make_filter,
    make_process_model,
    make_robust_policy,
    register_filter,
    register_policy,
    register_process_model,
)
from robustrtk.estimation.robust import (
    POLICY_NAMES,
    Chain,
    DeltaVIGG3,
    Huber,
    NoRobust,
    PostfitIGG3,
    PrefitIGG3,
)
from robustrtk.estimation.state import StateLayout


@pytest.fixture(autouse=True)
def _restore_tables() -> Iterator[None]:
    saved = {t: dict(getattr(registry, t)) for t in ("FILTERS", "PROCESS_MODELS", "POLICIES")}
    yield
    for t, d in saved.items():
        table = getattr(registry, t)
        table.clear()
        table.update(d)


def test_builtin_filters() -> None:
    assert set(FILTERS) == {"ekf", "ukf"}
    assert make_filter("ekf") == EKF()
    assert make_filter("ukf") == UKF()
    assert make_filter("ukf", alpha=0.5, beta=1.0, kappa=2.0) == UKF(alpha=0.5, beta=1.0, kappa=2.0)
    with pytest.raises(TypeError):
        make_filter("ekf", alpha=0.5)


def test_builtin_process_models_match_their_names_and_parameters() -> None:
    assert make_process_model("static", q_m2_s=1e-6) == StaticModel(q_m2_s=1e-6)
    assert make_process_model("random-walk", sigma_m_s=2.0) == RandomWalkModel(sigma_m_s=2.0)
    cv = make_process_model("constant-velocity", sigma_m_s2=0.3, q_amb_cyc2_s=1e-4)
    assert cv == ConstantVelocityModel(sigma_m_s2=0.3, q_amb_cyc2_s=1e-4)
    for name in PROCESS_MODELS:
        assert make_process_model(name).name == name
    lay = StateLayout(blocks=cv.blocks(), amb_keys=("a",))
    F, Q = cv.transition(lay, 2.0)
    F0, Q0 = ConstantVelocityModel(0.3, 1e-4).transition(lay, 2.0)
    np.testing.assert_array_equal(F, F0)
    np.testing.assert_array_equal(Q, Q0)


def test_policies_by_name_and_their_defaults() -> None:
    assert tuple(POLICIES) == POLICY_NAMES
    assert make_robust_policy("none") == NoRobust()
    assert make_robust_policy("igg3") == DeltaVIGG3(k0=2.0, k1=8.0)
    assert make_robust_policy("igg3", k0=1.5, k1=6.0, dv_source="posterior") == DeltaVIGG3(
        1.5, 6.0, source="posterior"
    )
    assert make_robust_policy("huber") == Huber(k0=1.5)
    assert make_robust_policy("postfit") == PostfitIGG3(k0=1.5, k1=3.0)
    assert make_robust_policy("prefit+postfit", prefit_k0=3.0) == Chain(
        PrefitIGG3(3.0, 7.0), PostfitIGG3(1.5, 3.0)
    )


@pytest.mark.parametrize(
    ("make", "kind", "known"),
    [
        (make_filter, "filter", "ekf, ukf"),
        (make_process_model, "process model", "constant-velocity, random-walk, static"),
        (make_robust_policy, "robust policy", "huber, igg3"),
    ],
)
def test_unknown_names_list_the_known_ones(make: Callable[..., object], kind: str, known: str) -> None:
    with pytest.raises(ValueError, match=f"unknown {kind} 'nope'") as err:
        make("nope")
    for k in known.split(", "):
        assert k in str(err.value)


@dataclass
class DampedEKF(EKF):
    """A new filter: an EKF under another name with one parameter."""

    damping: float = 1.0
    name: str = "damped-ekf"


def test_register_a_new_filter_is_one_call() -> None:
    register_filter("damped-ekf", DampedEKF)
    f = make_filter("damped-ekf", damping=0.5)
    assert isinstance(f, DampedEKF) and f.damping == 0.5
    with pytest.raises(ValueError, match="already registered"):
        register_filter("damped-ekf", DampedEKF)
    register_filter("damped-ekf", EKF, replace=True)
    assert type(make_filter("damped-ekf")) is EKF
    with pytest.raises(ValueError, match="damped-ekf"):
        make_process_model("damped-ekf")  # tables are separate
    with pytest.raises(ValueError):
        register_filter("", EKF)


def test_register_process_model_and_policy() -> None:
    register_process_model("slow-walk", lambda **kw: RandomWalkModel(sigma_m_s=0.01, **kw))
    assert make_process_model("slow-walk", q_amb_cyc2_s=1e-3) == RandomWalkModel(0.01, 1e-3)
    register_policy("off", NoRobust)
    assert make_robust_policy("off") == NoRobust()
    with pytest.raises(ValueError, match="already registered"):
        register_policy("none", NoRobust)


def test_tables_are_restored_between_tests() -> None:
    assert "damped-ekf" not in FILTERS and "slow-walk" not in PROCESS_MODELS and "off" not in POLICIES

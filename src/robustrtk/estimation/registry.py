"""Estimators by name: filters, process models and robust policies.

Each table maps a name to a factory called with keyword parameters, e.g.
``make_filter("ukf", alpha=0.5, beta=2.0, kappa=0.0)`` or
``make_process_model("constant-velocity", sigma_m_s2=0.1)``. A new estimator is one call::

    register_filter("my-filter", MyFilter)

after which configurations can name it. Unknown names raise ``ValueError`` listing the
known ones; parameters a factory does not take raise its ``TypeError``.

=====================  ==========================================================
table                  built-in names (factory, parameters)
=====================  ==========================================================
:data:`FILTERS`        ``ekf`` (:class:`EKF`), ``ukf`` (:class:`UKF`: alpha, beta, kappa)
:data:`PROCESS_MODELS` ``static`` (q_m2_s, q_amb_cyc2_s), ``random-walk`` (sigma_m_s,
                       q_amb_cyc2_s), ``constant-velocity`` (sigma_m_s2, q_amb_cyc2_s)
:data:`POLICIES`       :data:`robustrtk.estimation.robust.POLICY_NAMES` (k0, k1, dv_source;
                       prefit_k0, prefit_k1 for ``prefit+postfit``)
=====================  ==========================================================
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import TypeVar

from robustrtk.estimation.filters import EKF, UKF, Filter
from robustrtk.estimation.models import ConstantVelocityModel, ProcessModel, RandomWalkModel, StaticModel
from robustrtk.estimation.robust import (
    POLICY_NAMES,
    Chain,
    DeltaVIGG3,
    Huber,
    NoRobust,
    PostfitIGG3,
    PrefitIGG3,
    RobustPolicy,
    StdResidualIGG3,
)

FilterFactory = Callable[..., Filter]
ProcessModelFactory = Callable[..., ProcessModel]
PolicyFactory = Callable[..., RobustPolicy]

#: Filter factories by name.
FILTERS: dict[str, FilterFactory] = {"ekf": EKF, "ukf": UKF}

#: Process-model factories by name (the names the models report).
PROCESS_MODELS: dict[str, ProcessModelFactory] = {
    "static": StaticModel,
    "random-walk": RandomWalkModel,
    "constant-velocity": ConstantVelocityModel,
}


def _builtin_policy(
    name: str,
    k0: float | None = None,
    k1: float | None = None,
    dv_source: str = "innovation",
    prefit_k0: float | None = None,
    prefit_k1: float | None = None,
) -> RobustPolicy:
    """Policy by name: ``none``, ``igg3`` (Δv̄, Li et al.), ``igg3-std``, ``huber``,
    ``prefit``, ``postfit``, ``prefit+postfit``. ``k0``/``k1`` override the defaults (for
    ``prefit+postfit``: those of its post-fit test, 1.5/3); ``prefit_k0``/``prefit_k1`` set
    the pre-fit test of ``prefit+postfit`` (2.5/7)."""

    def pick(default0: float, default1: float) -> tuple[float, float]:
        return (default0 if k0 is None else k0, default1 if k1 is None else k1)

    if name == "none":
        return NoRobust()
    if name == "igg3":
        a, b = pick(2.0, 8.0)
        return DeltaVIGG3(k0=a, k1=b, source=dv_source)
    if name == "igg3-std":
        a, b = pick(1.5, 3.0)
        return StdResidualIGG3(k0=a, k1=b)
    if name == "huber":
        return Huber(k0=1.5 if k0 is None else k0)
    if name == "prefit":
        a, b = pick(2.5, 7.0)
        return PrefitIGG3(k0=a, k1=b)
    if name == "postfit":
        a, b = pick(1.5, 3.0)
        return PostfitIGG3(k0=a, k1=b)
    if name == "prefit+postfit":
        a, b = pick(1.5, 3.0)
        pre = PrefitIGG3(2.5 if prefit_k0 is None else prefit_k0, 7.0 if prefit_k1 is None else prefit_k1)
        return Chain(pre, PostfitIGG3(k0=a, k1=b))
    raise ValueError(f"unknown robust policy {name!r}; expected one of {', '.join(POLICY_NAMES)}")


#: Robust-policy factories by name (the built-ins bound to each name).
POLICIES: dict[str, PolicyFactory] = {name: partial(_builtin_policy, name) for name in POLICY_NAMES}

_T = TypeVar("_T")


def _lookup(table: dict[str, Callable[..., _T]], kind: str, name: str) -> Callable[..., _T]:
    try:
        return table[name]
    except KeyError:
        known = ", ".join(sorted(table))
        raise ValueError(f"unknown {kind} {name!r}; expected one of {known}") from None


def _register(
    table: dict[str, Callable[..., _T]], kind: str, name: str, factory: Callable[..., _T], replace: bool
) -> None:
    if not isinstance(name, str) or not name:
        raise ValueError(f"{kind} name must be a non-empty string, got {name!r}")
    if not callable(factory):
        raise TypeError(f"{kind} factory for {name!r} is not callable")
    if name in table and not replace:
        raise ValueError(f"{kind} {name!r} is already registered (pass replace=True to override)")
    table[name] = factory


def make_filter(name: str, **params: object) -> Filter:
    """Filter ``name`` built with ``params`` (e.g. ``alpha``, ``beta``, ``kappa`` for ``ukf``).

    Raises
    ------
    ValueError
        Unknown name (the message lists the known ones).
    """
    return _lookup(FILTERS, "filter", name)(**params)


def make_process_model(name: str, **params: object) -> ProcessModel:
    """Process model ``name`` built with its noise ``params`` (see the table above).

    Raises
    ------
    ValueError
        Unknown name (the message lists the known ones).
    """
    return _lookup(PROCESS_MODELS, "process model", name)(**params)


def make_robust_policy(name: str, **params: object) -> RobustPolicy:
    """Robust policy ``name`` (``k0``, ``k1``, ``dv_source`` for the built-in ones).

    Raises
    ------
    ValueError
        Unknown name (the message lists the known ones).
    """
    return _lookup(POLICIES, "robust policy", name)(**params)


def register_filter(name: str, factory: FilterFactory, *, replace: bool = False) -> None:
    """Make ``make_filter(name, **params)`` call ``factory(**params)``.

    Raises
    ------
    ValueError
        ``name`` is empty or already registered and ``replace`` is False.
    """
    _register(FILTERS, "filter", name, factory, replace)


def register_process_model(name: str, factory: ProcessModelFactory, *, replace: bool = False) -> None:
    """Make ``make_process_model(name, **params)`` call ``factory(**params)``.

    Raises
    ------
    ValueError
        ``name`` is empty or already registered and ``replace`` is False.
    """
    _register(PROCESS_MODELS, "process model", name, factory, replace)


def register_policy(name: str, factory: PolicyFactory, *, replace: bool = False) -> None:
    """Make ``make_robust_policy(name, **params)`` call ``factory(**params)``.

    Raises
    ------
    ValueError
        ``name`` is empty or already registered and ``replace`` is False.
    """
    _register(POLICIES, "robust policy", name, factory, replace)


__all__ = [
    "FILTERS",
    "POLICIES",
    "PROCESS_MODELS",
    "FilterFactory",
    "PolicyFactory",
    "ProcessModelFactory",
    "make_filter",
    "make_process_model",
    "make_robust_policy",
    "register_filter",
    "register_policy",
    "register_process_model",
]

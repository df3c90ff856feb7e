"""robustrtk: robust high-precision positioning for hostile signal environments.

Pseudolite rooms, urban canyons and smartphones: double-differenced code and carrier-phase
positioning with EKF/UKF/robust UKF, LAMBDA and partial ambiguity resolution.

The library's entry points, one per mode (docs/api.md)::

    import robustrtk
    sol = robustrtk.solve_rtk("rover.obs", "base.obs", "base.nav", base_pos=[x, y, z])
    sol.fix_rate(), sol.to_pos("rtk.pos"), sol.to_dataframe()

``solve_spp``, ``solve_dgnss``, ``solve_rtk``, ``solve_dpl``, :class:`SolutionSeries`,
``Config`` and ``preset`` are loaded on first use (module ``__getattr__``), so
``import robustrtk`` imports nothing heavy.
"""

from __future__ import annotations

import importlib

from robustrtk.version import __version__ as __version__

#: ``typing.TYPE_CHECKING`` without importing :mod:`typing` (type checkers read it as such).
TYPE_CHECKING = False

#: Public name -> module that defines it, imported on first attribute access. The
#: cooperative pipeline's entry points (``robustrtk.pipeline.coop.solve_coop`` and
#: ``solve_coop_central``) take nodes and range links, not files, and stay in their module.
_LAZY: dict[str, str] = {
    "solve_spp": "robustrtk.pipeline.api",
    "solve_dgnss": "robustrtk.pipeline.api",
    "solve_rtk": "robustrtk.pipeline.api",
    "solve_dpl": "robustrtk.pipeline.api",
    "SolutionSeries": "robustrtk.pipeline.series",
    "RunSummary": "robustrtk.pipeline.series",
    "Config": "robustrtk.pipeline.config",
    "preset": "robustrtk.pipeline.config",
    "InputError": "robustrtk.core",
}

if TYPE_CHECKING:  # pragma: no cover - for type checkers and IDEs only
    from typing import Any

    from robustrtk.core import InputError
    from robustrtk.pipeline.api import solve_dgnss, solve_dpl, solve_rtk, solve_spp
    from robustrtk.pipeline.config import Config, preset
    from robustrtk.pipeline.series import RunSummary, SolutionSeries


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'robustrtk' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_LAZY])


__all__ = [
    "Config",
    "InputError",
    "RunSummary",
    "SolutionSeries",
    "__version__",
    "preset",
    "solve_dgnss",
    "solve_dpl",
    "solve_rtk",
    "solve_spp",
]

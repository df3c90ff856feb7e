"""Cycle-slip detectors. Each returns boolean masks (and, for the polynomial fit, repaired
phases); none touches a filter state.

* :func:`lli_slips`, :func:`half_cycle_flags` — receiver loss-of-lock indicators;
* :class:`PolyFitDetector`, :func:`polyfit_slips` — single-frequency polynomial fit with
  integer repair (for double-differenced or geometry-minus-phase series);
* :func:`gf_slips` — geometry-free two-frequency combination; :func:`gf_drift_slips` — its
  change over a window (a slowly drifting phase);
* :func:`doppler_phase_slips` — phase change against integrated Doppler.
"""

from robustrtk.cycleslip.doppler import doppler_phase_residual_cyc, doppler_phase_slips
from robustrtk.cycleslip.geometry_free import gf_drift_slips, gf_jump_m, gf_slips
from robustrtk.cycleslip.lli import half_cycle_flags, lli_slips
from robustrtk.cycleslip.polyfit import PolyFitDetector, polyfit_slips, reset_mask

__all__ = [
    "PolyFitDetector",
    "doppler_phase_residual_cyc",
    "doppler_phase_slips",
    "gf_jump_m",
    "gf_drift_slips",
    "gf_slips",
    "half_cycle_flags",
    "lli_slips",
    "polyfit_slips",
    "reset_mask",
]

"""The faulty-reference check of DD code groups (``docs/algorithms.md`` §11), applied by
:class:`robustrtk.pipeline.engine.DDEngine` to the code DDs of DPL and DGNSS epochs."""

from __future__ import annotations

import numpy as np

from robustrtk.core import FloatArray
from robustrtk.estimation.state import GaussianState
from robustrtk.measurement.dd import DDRangeModel, DDSet
from robustrtk.pipeline.engine_setup import rereference

#: The reference's standardized innovation against the mean of the others' above which a
#: group is re-expressed against another satellite.
REF_CHECK_K = 3.0


def check_references(state: GaussianState, dd: DDSet, model: DDRangeModel, elev: FloatArray) -> DDSet:
    """Re-express a group's DDs against another satellite when its reference looks faulty.

    A gross error ``e`` on the reference enters every DD of its group as ``−e``: the
    discriminant Δv̄ then sees no outlier (one system) or only a moderate one (the other
    faulty DDs inflate its denominator). Per group with at least two DDs, the prior
    innovations ``d`` are mapped to satellite values ``x = [0, d₁ … dₙ]`` (reference
    first, up to the common receiver term), centred on their median and scaled by each
    satellite's σ (from ``R``: its off-diagonal is the reference's variance),
    ``w = (x − median x)/σ``. When the reference has the largest ``|w|`` and
    ``|w_ref| / mean_{s≠ref} |w_s| > REF_CHECK_K`` the group is re-expressed, for this
    epoch only, against its highest satellite whose own ratio is at most 1
    (:func:`rereference`). The nominal DPL update does not depend on the reference, so
    only what the robust policy sees changes: the faulty reference becomes the single
    DD ``ref − new`` that the policy can single out. Satellites only (``frame="ecef"``)
    and only without a preferred reference: pseudolite runs keep their fixed reference.
    """
    d = dd.z - model.h(state.x)
    grp = np.asarray(dd.group)
    for g in dict.fromkeys(dd.group):
        rows = np.flatnonzero(grp == g)
        if rows.size < 2:
            continue
        Rg = dd.R[np.ix_(rows, rows)]
        var_ref = float(np.median(Rg[~np.eye(rows.size, dtype=bool)]))
        sig = np.sqrt(np.maximum(np.concatenate([[var_ref], np.diag(Rg) - var_ref]), 1e-12))
        x = np.concatenate([[0.0], d[rows]])
        a = np.abs(x - np.median(x)) / sig
        others = (a.sum() - a) / (a.size - 1)
        ratio = np.where(others > 0, a / np.where(others > 0, others, 1.0), np.inf)
        if not (ratio[0] > REF_CHECK_K and a[0] >= a.max()):
            continue
        ok = np.flatnonzero(ratio[1:] <= 1.0)
        if ok.size == 0:
            ok = np.array([int(np.argmin(a[1:]))])
        el = elev[dd.i_tx[rows[ok]]]
        dd = rereference(dd, rows, int(rows[ok[int(np.argmax(el))]]))
    return dd


__all__ = ["REF_CHECK_K", "check_references"]

r"""Compare solution files against a truth point or trajectory.

Reads RTKLIB ``.pos`` files (llh or xyz form, as written by ``rnx2rtkp``) and our own
``.pos`` and CSV solutions (:mod:`robustrtk.io.solution`), and reports per solution:

* ``epochs_solved`` — epochs with a position (RTKLIB ``Q`` 1..6; CSV rows whose status is
  not ``none``), the ``Q`` histogram (CSV statuses mapped as :func:`robustrtk.io.solution.write_pos`
  maps them: fixed and partial 1, float 2, dgnss and code 4, single 5) and, for CSV, the
  status histogram;
* fix rate — fixed (``Q = 1``) epochs in percent of the solved epochs and, when the
  number of rover epochs is known, of the rover epochs;
* time to first fix — seconds from the first solved epoch to the first fixed one;
* error statistics of the fixed (``Q = 1``), float (``Q = 2``) and all solved epochs that
  have a truth (and lie in the truth window when one is given).

Errors are East-North-Up at the truth: with an ECEF truth,
:math:`e_{enu} = R(\varphi_t, \lambda_t)\,(r - r_t)` where :math:`R` is
:func:`robustrtk.geometry.frames.ecef2enu_rotation` at the truth point (for a trajectory:
at the matched truth epoch's position). A truth in a local (pseudolite) frame is used as is,
``x, y, z`` taken as East, North, Up. For each group of :math:`n` epochs with
:math:`h_i = \sqrt{e_i^2 + n_i^2}` and :math:`v_i = |u_i|`:

* ``H_rms_m`` :math:`= \sqrt{\tfrac1n \sum h_i^2}`, ``V_rms_m`` likewise with :math:`v_i`;
* ``H_95_m``, ``V_95_m`` — 95th percentile with linear interpolation between order
  statistics (:func:`numpy.percentile`, ``method="linear"``): with the sorted values
  :math:`x_{(0)} \le \dots \le x_{(n-1)}`, :math:`p = 0.95 (n - 1)`, :math:`j = \lfloor p \rfloor`:
  :math:`x_{(j)} + (p - j)(x_{(j + 1)} - x_{(j)})`;
* ``mean_enu_m`` — mean of the ENU errors (signed);
* ``H_max_m``, ``V_max_m`` — largest :math:`h_i`, :math:`v_i`;
* ``n_3d_err_gt_0.10m`` — epochs with :math:`\|e_{enu}\| > 0.10` m.

These definitions reproduce the reference evaluations (``*.eval.json``) of the RTKLIB runs
in the shared datasets to their printed precision.

Truth trajectories are matched to solution epochs by the nearest truth epoch within
``tol_s`` (0.05 s); solution epochs without one are left out of the error statistics but
still count for the fix rate. A truth window ``[start, end]`` (GPST, inclusive within
1 ms) restricts the error statistics the same way — e.g. a kinematic rover whose truth
point is only valid while it stands still.

Modules: :mod:`robustrtk.eval.truth` (truth reading, matching, windows),
:mod:`robustrtk.eval.comparison` (loading and statistics), :mod:`robustrtk.eval.compare_report`
(tables, JSON) and :mod:`robustrtk.eval.compare_plots` (figure); every public name is
importable from here.
"""

from robustrtk.eval.compare_plots import Q_STYLE, plot_comparison
from robustrtk.eval.compare_report import (
    DETAIL_HEADERS,
    SUMMARY_HEADERS,
    comparison_report,
    detail_table,
    summary_table,
    write_json,
)
from robustrtk.eval.comparison import (
    ERR_3D_THRESHOLD_M,
    GROUPS,
    Q_NAMES,
    Q_OF_STATUS,
    WINDOW_TOL_S,
    SolutionComparison,
    compare_files,
    compare_solution,
    count_rover_epochs,
    default_labels,
    error_group_stats,
    load_solution,
)
from robustrtk.eval.truth import (
    MATCH_TOL_S,
    PathLike,
    Truth,
    parse_time_window,
    parse_truth,
    read_truth_file,
    truth_from_llh,
    truth_from_xyz,
)
from robustrtk.timeutil import gpst_text

__all__ = [
    "DETAIL_HEADERS",
    "ERR_3D_THRESHOLD_M",
    "GROUPS",
    "MATCH_TOL_S",
    "PathLike",
    "Q_NAMES",
    "Q_OF_STATUS",
    "Q_STYLE",
    "SUMMARY_HEADERS",
    "WINDOW_TOL_S",
    "SolutionComparison",
    "Truth",
    "compare_files",
    "compare_solution",
    "comparison_report",
    "count_rover_epochs",
    "default_labels",
    "detail_table",
    "error_group_stats",
    "gpst_text",
    "load_solution",
    "parse_time_window",
    "parse_truth",
    "plot_comparison",
    "read_truth_file",
    "summary_table",
    "truth_from_llh",
    "truth_from_xyz",
    "write_json",
]

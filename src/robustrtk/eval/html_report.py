"""One self-contained HTML report of a solution: what rtkplot shows, in one file.

:func:`build_report` reads a solution (RTKLIB ``.pos`` or robustrtk CSV) and optionally a
truth, the diagnostics CSV of ``solve --diagnostics``, other solutions to put beside it
(``--vs``, e.g. RTKLIB's ``.pos``) and the rover observations with navigation data, and
returns the HTML text; :func:`write_report` writes it atomically. Every figure is a PNG
inlined as a ``data:`` URI, so the file opens anywhere, offline, without scripts.

Sections:

* summary: epochs, time span, status counts, fix rate and time to first fix per solution
  (:class:`~robustrtk.eval.comparison.SolutionComparison`);
* ground track coloured by status (side by side with ``--vs``), status strip and ``ns``;
* ENU error series by status (with a truth; otherwise the deviation from the mean
  position) and the error table: RMS, 95 % and max of |E|, |N|, |U| and H, by status;
* with ``--vs``: the ENU difference of the solution from the first other one at the
  epochs they share;
* with observations and navigation data: satellites per epoch by system and a sky plot
  at the solution's mean position;
* with diagnostics: post-fit residuals and robust factors by satellite, and a table per
  satellite (rows, RMS residual, largest standardised residual, down-weighted and
  rejected shares, median factor).
"""

from __future__ import annotations

import base64
import html
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from robustrtk.core import FloatArray, InputError
from robustrtk.eval.comparison import (
    Q_NAMES,
    SolutionComparison,
    compare_solution,
    default_labels,
    load_solution,
)
from robustrtk.eval.plots import (
    dd_satellite,
    figure_png,
    plot_dd_by_satellite,
    plot_satellite_counts,
    plot_sky,
    plot_status_series,
    plot_status_timeline,
    plot_status_tracks,
)
from robustrtk.eval.truth import MATCH_TOL_S, PathLike, Truth, near_earth_surface
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.io.atomic import atomic_path
from robustrtk.io.solution import DiagTable, SolutionTable, read_diagnostics_csv
from robustrtk.io.tables import html_table
from robustrtk.timeutil import gpst_text
from robustrtk.version import __version__

__all__ = [
    "ReportSolution",
    "axis_error_table",
    "build_report",
    "html_document",
    "report_parts",
    "section",
    "write_report",
]

#: Largest number of epochs the sky plot evaluates (evenly spread).
SKY_MAX_EPOCHS = 400


@dataclass(frozen=True)
class ReportSolution:
    """One solution of the report: its table, ``Q``, comparison and local ENU positions."""

    label: str
    table: SolutionTable
    comparison: SolutionComparison
    enu_m: FloatArray
    ns: np.ndarray


# ----------------------------------------------------------------------------- data
def _enu_frame(tables: Sequence[SolutionTable], truth: Truth | None) -> tuple[FloatArray, FloatArray] | None:
    """Origin (ECEF) and rotation of the local ENU frame; None for local-frame solutions."""
    pos = np.concatenate([tb.pos_m[np.all(np.isfinite(tb.pos_m), axis=1)] for tb in tables])
    if pos.shape[0] == 0 or not near_earth_surface(pos):
        return None
    if truth is not None and truth.ecef:
        origin = truth.pos_m.reshape(-1, 3)[0]
    else:
        origin = np.median(pos, axis=0)
    lat, lon, _ = ecef2geodetic(origin)
    return origin, ecef2enu_rotation(float(lat), float(lon))


def _is_csv(path: PathLike) -> bool:
    """A robustrtk CSV solution (header ``time,...``), as :func:`load_solution` tells it."""
    with open(path, "rb") as fh:
        for raw in fh:
            if raw.strip():
                return raw.strip().lower().startswith(b"time,")
    return False


def _load(
    paths: Sequence[PathLike],
    labels: Sequence[str],
    truth: Truth | None,
    window_s: tuple[float, float] | None,
    tol_s: float,
) -> list[ReportSolution]:
    loaded = [load_solution(p) for p in paths]
    frame = _enu_frame([tb for tb, _ in loaded], truth)
    out = []
    for (tb, q), lab, p in zip(loaded, labels, paths, strict=True):
        cmp = compare_solution(tb, q, truth, label=lab, path=str(p), window_s=window_s, tol_s=tol_s)
        solved = (np.asarray(q) >= 1) & (tb.status != "none") & np.all(np.isfinite(tb.pos_m), axis=1)
        order = np.argsort(tb.t_s[solved], kind="stable")
        pos = tb.pos_m[solved][order]
        enu = pos.copy() if frame is None else (pos - frame[0]) @ frame[1].T
        # ns is a satellite count in a .pos only: a CSV's n_used counts measurement rows
        ns = tb.n_used[solved][order] if not _is_csv(p) else np.full(int(solved.sum()), -1)
        out.append(ReportSolution(lab, tb, cmp, enu, ns))
    return out


def axis_error_table(cmp: SolutionComparison) -> list[dict[str, Any]]:
    """Error statistics of one comparison by status, then over all solved epochs.

    Returns
    -------
    list of dict
        ``group, n, rms_m (E, N, U), p95_m (|E|, |N|, |U|), max_m (|E|, |N|, |U|), h_rms_m,
        h_95_m, h_max_m`` for each status with truth-matched epochs, then ``"all"``.
    """
    e = cmp.enu_err_m
    has = np.all(np.isfinite(e), axis=1)
    groups = [(Q_NAMES.get(int(qv), f"Q{int(qv)}"), has & (cmp.q == qv)) for qv in np.unique(cmp.q)]
    rows = []
    for name, sel in [*groups, ("all", has)]:
        if not np.any(sel):
            continue
        x = e[sel]
        h = np.hypot(x[:, 0], x[:, 1])
        rows.append(
            {
                "group": name,
                "n": int(sel.sum()),
                "rms_m": [float(v) for v in np.sqrt(np.mean(x**2, axis=0))],
                "p95_m": [float(v) for v in np.percentile(np.abs(x), 95, axis=0)],
                "max_m": [float(v) for v in np.max(np.abs(x), axis=0)],
                "h_rms_m": float(np.sqrt(np.mean(h**2))),
                "h_95_m": float(np.percentile(h, 95)),
                "h_max_m": float(np.max(h)),
            }
        )
    return rows


def _matched_difference(
    a: ReportSolution, b: ReportSolution, tol_s: float
) -> tuple[FloatArray, FloatArray, np.ndarray]:
    """ENU of ``a`` minus ``b`` at the epochs of ``a`` that ``b`` has within ``tol_s``."""
    ta, tb = a.comparison.t_s, b.comparison.t_s
    if tb.size == 0 or ta.size == 0:
        return np.zeros(0), np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
    j = np.clip(np.searchsorted(tb, ta), 1, tb.size - 1) if tb.size > 1 else np.zeros(ta.size, dtype=np.int64)
    if tb.size > 1:
        j = np.where(np.abs(tb[j - 1] - ta) <= np.abs(tb[j] - ta), j - 1, j)
    ok = np.abs(tb[j] - ta) <= tol_s
    return ta[ok], a.enu_m[ok] - b.enu_m[j[ok]], a.comparison.q[ok]


def _sky(obs: PathLike, nav: Sequence[PathLike], rx_ecef: FloatArray) -> tuple[Any, ...]:
    """Satellite counts per epoch by system and azimuth/elevation tracks (rad)."""
    from robustrtk.geometry.los import azimuth_elevation
    from robustrtk.pipeline.gnss_inputs import load_obs, nav_source

    batch = load_obs(obs, None)
    eph = nav_source(list(nav) if len(nav) != 1 else nav[0])
    tracked = np.any(np.isfinite(batch.code_m), axis=2)  # (T, N)
    systems = sorted(set(batch.system), key=lambda s: "GRECJSI".find(s) % 10)
    sys_arr = np.array(batch.system)
    counts = {s: tracked[:, sys_arr == s].sum(axis=1) for s in systems}
    T = batch.t_s.shape[0]
    idx = np.unique(np.linspace(0, T - 1, min(T, SKY_MAX_EPOCHS)).astype(int)) if T else np.zeros(0, int)
    az = np.full((idx.size, len(batch.tx_ids)), np.nan)
    el = np.full_like(az, np.nan)
    for r, k in enumerate(idx):
        code = np.nanmin(np.where(np.isfinite(batch.code_m[k]), batch.code_m[k], np.inf), axis=1)
        code = np.where(np.isfinite(code), code, np.nan)
        sat, _ = eph.positions(float(batch.t_s[k]), batch.tx_ids, code)
        a, e = azimuth_elevation(sat, rx_ecef)
        seen = tracked[k] & np.all(np.isfinite(sat), axis=1)
        az[r, seen] = a[seen]
        el[r, seen] = e[seen]
    az_map = {s: az[:, i] for i, s in enumerate(batch.tx_ids) if np.any(np.isfinite(az[:, i]))}
    el_map = {s: el[:, i] for i, s in enumerate(batch.tx_ids) if np.any(np.isfinite(az[:, i]))}
    return batch.t_s, counts, az_map, el_map


def _satellite_rows(diag: DiagTable) -> list[list[object]]:
    sats = np.array([dd_satellite(s) for s in diag.dd.tolist()])
    rows: list[list[object]] = []
    for sat in sorted(set(sats.tolist())):
        sel = sats == sat
        res = diag.residual[sel]
        sr = np.abs(diag.std_residual[sel])
        fac = diag.factor[sel]
        fin = np.isfinite(res)
        rows.append(
            [
                sat,
                int(sel.sum()),
                float(np.sqrt(np.mean(res[fin] ** 2))) if np.any(fin) else math.nan,
                float(np.nanmax(sr)) if np.any(np.isfinite(sr)) else math.nan,
                100.0 * float(np.mean(diag.situation[sel] == 2)),
                100.0 * float(np.mean(diag.situation[sel] == 3)),
                float(np.nanmedian(fac)) if np.any(np.isfinite(fac)) else math.nan,
                float(np.nanmax(fac)) if np.any(np.isfinite(fac)) else math.nan,
            ]
        )
    return rows


# ----------------------------------------------------------------------------- HTML
_CSS = """
body{font-family:system-ui,Segoe UI,Helvetica,Arial,sans-serif;margin:1.5em auto;max-width:1200px;
color:#222;padding:0 1em}h1{font-size:1.5em}h2{font-size:1.2em;border-bottom:1px solid #ccc;margin-top:1.6em}
table{border-collapse:collapse;margin:.5em 0;font-size:.9em}th,td{border:1px solid #ccc;padding:.2em .5em}
td.n{text-align:right;font-variant-numeric:tabular-nums}th{background:#f3f3f3}img{max-width:100%;height:auto;
display:block;margin:.5em 0}.note{color:#555;font-size:.9em}.warn{color:#a40}code{background:#f5f5f5}
"""


def _img(fig: Any, alt: str, dpi: int) -> str:
    data = base64.b64encode(figure_png(fig, dpi=dpi)).decode("ascii")
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{data}">'


def _summary_rows(sols: Sequence[ReportSolution], local: bool = False) -> list[list[object]]:
    """One row per solution; a local-frame (pseudolite) solution's span is in the seconds of
    its own table clock, not a GPS calendar time."""
    rows: list[list[object]] = []
    for s in sols:
        c = s.comparison
        if not c.epochs_solved:
            span = "-"
        elif local:
            span = f"{float(c.t_s[0]):g} – {float(c.t_s[-1]):g} s"
        else:
            span = f"{gpst_text(float(c.t_s[0]))} – {gpst_text(float(c.t_s[-1]))}"
        hist = ", ".join(f"{Q_NAMES.get(k, k)} {v}" for k, v in sorted(c.q_hist.items()))
        rows.append([s.label, c.path, c.epochs_solved, span, hist, c.fix_rate_pct_of_solved, c.ttff_s])
    return rows


def report_parts(
    solution: PathLike,
    *,
    truth: Truth | None = None,
    truth_window_s: tuple[float, float] | None = None,
    diagnostics: PathLike | None = None,
    vs: Sequence[PathLike] = (),
    labels: Sequence[str] = (),
    obs: PathLike | None = None,
    nav: Sequence[PathLike] = (),
    elev_mask_deg: float | None = 15.0,
    match_tol_s: float = MATCH_TOL_S,
    range_m: float | None = None,
    dpi: int = 90,
) -> list[str]:
    """The report's body as HTML fragments (see the module docstring): the note on frames
    and truth, summary, track, errors, satellites and diagnostics sections.

    Parameters
    ----------
    solution : path-like
        RTKLIB ``.pos`` or robustrtk CSV solution.
    truth : Truth, optional
        Point or trajectory (:func:`robustrtk.eval.truth.parse_truth`).
    truth_window_s : (start_s, end_s), optional
        Error statistics only inside this window.
    diagnostics : path-like, optional
        Diagnostics CSV of ``solve --diagnostics`` for ``solution``.
    vs : sequence of path-like
        Other solutions shown beside it (RTKLIB ``.pos`` ...).
    labels : sequence of str
        Labels of ``solution`` then ``vs`` (default: file stems).
    obs, nav : path-like, sequence of path-like
        Rover observations and navigation files: satellites per epoch and sky plot
        (both needed).
    elev_mask_deg : float, optional
        Drawn on the sky plot.
    match_tol_s : float
        Time tolerance of trajectory and solution-to-solution matches (s).
    range_m : float, optional
        Limit of the error axes (± m).
    dpi : int
        Resolution of the inlined PNGs.

    Raises
    ------
    InputError
        Unreadable inputs, ``obs`` without ``nav`` (or the reverse), more labels than
        solutions.
    """
    if (obs is None) != (not nav):
        raise InputError("--obs and --nav go together: satellites need observations and navigation data")
    paths = [solution, *vs]
    if len(labels) > len(paths):
        raise InputError(f"--label given {len(labels)} times for {len(paths)} solution files")
    labs = default_labels(paths)
    labs[: len(labels)] = list(labels)
    sols = _load(paths, labs, truth, truth_window_s, match_tol_s)
    main = sols[0]
    local = _enu_frame([s.table for s in sols], truth) is None
    parts = [
        f'<p class="note">robustrtk {html.escape(__version__)}; times GPST; positions '
        + (
            "in the solution's local frame"
            if local
            else "as East/North/Up (m) about "
            + ("the truth" if truth is not None and truth.ecef else "the median position")
        )
        + (f"; truth: {html.escape(truth.source)}" if truth is not None else "; no truth given")
        + "</p>",
    ]
    for s in sols:
        for w in s.comparison.warnings:
            parts.append(f'<p class="warn">{html.escape(s.label)}: {html.escape(w)}</p>')
    if truth is not None and truth.note and truth_window_s is None:
        parts.append(f'<p class="warn">the truth file says: {html.escape(truth.note)}</p>')

    parts.append("<h2>Summary</h2>")
    parts.append(
        html_table(
            _summary_rows(sols, local),
            [
                "solution",
                "file",
                "epochs",
                "span (table clock)" if local else "span (GPST)",
                "status",
                "fix %",
                "TTFF (s)",
            ],
            digits=1,
        )
    )
    parts.append(
        '<p class="note">status counted by RTKLIB\'s Q: “fixed” is Q=1, which holds full and '
        "partial fixes (a CSV solution's statuses keep them apart); fix % of the solved epochs; "
        "time to first fix from the first solved epoch (‘-’: never fixed)"
        + ("; a pseudolite table's times are seconds of its own clock, not GPS time" if local else "")
        + ".</p>"
    )

    parts.append("<h2>Ground track</h2>")
    xl, yl = ("x (m)", "y (m)") if local else ("East (m)", "North (m)")
    parts.append(
        _img(
            plot_status_tracks({s.label: (s.enu_m, s.comparison.q) for s in sols}, xlabel=xl, ylabel=yl),
            "ground track by status",
            dpi,
        )
    )
    parts.append(
        _img(
            plot_status_timeline({s.label: (s.comparison.t_s, s.comparison.q, s.ns) for s in sols}),
            "status and satellites per epoch (ns of .pos inputs; a CSV's n_used counts DD rows, not shown)",
            dpi,
        )
    )

    t0 = min(float(s.comparison.t_s[0]) for s in sols if s.comparison.epochs_solved)
    if truth is not None:
        parts.append("<h2>Errors against the truth</h2>")
        parts.append(
            _img(
                plot_status_series(
                    {s.label: (s.comparison.t_s, s.comparison.enu_err_m, s.comparison.q) for s in sols},
                    t0_s=t0,
                    range_m=range_m,
                ),
                "ENU error by status",
                dpi,
            )
        )
        heads = [
            "solution",
            "status",
            "n",
            "RMS E",
            "RMS N",
            "RMS U",
            "95% |E|",
            "95% |N|",
            "95% |U|",
            "max |E|",
            "max |N|",
            "max |U|",
            "H RMS",
            "H 95%",
            "H max",
        ]
        rows: list[list[object]] = []
        for s in sols:
            for r in axis_error_table(s.comparison):
                rows.append(
                    [
                        s.label,
                        r["group"],
                        r["n"],
                        *r["rms_m"],
                        *r["p95_m"],
                        *r["max_m"],
                        r["h_rms_m"],
                        r["h_95_m"],
                        r["h_max_m"],
                    ]
                )
        parts.append(
            html_table(rows, heads, digits=3) if rows else '<p class="warn">no solved epoch has a truth</p>'
        )
        parts.append('<p class="note">metres; U is the vertical error, H the horizontal one.</p>')
    else:
        parts.append("<h2>Position about the median</h2>")
        series = {}
        for s in sols:
            med = np.median(s.enu_m, axis=0) if s.enu_m.shape[0] else np.zeros(3)
            series[s.label] = (s.comparison.t_s, s.enu_m - med, s.comparison.q)
        parts.append(
            _img(
                plot_status_series(
                    series,
                    ylabel="about median (m)",
                    t0_s=t0,
                    range_m=range_m,
                    title="ENU position about its median, by status",
                ),
                "ENU position by status",
                dpi,
            )
        )
        parts.append('<p class="note">No truth given: each solution about its own median position.</p>')

    if len(sols) > 1:
        other = sols[1]
        t, d, q = _matched_difference(main, other, match_tol_s)
        parts.append(f"<h2>{html.escape(main.label)} minus {html.escape(other.label)}</h2>")
        if t.size:
            parts.append(
                _img(
                    plot_status_series(
                        {f"{main.label} − {other.label}": (t, d, q)},
                        ylabel="difference (m)",
                        t0_s=t0,
                        range_m=range_m,
                        title=f"ENU difference, coloured by {main.label}'s status",
                    ),
                    "ENU difference between the solutions",
                    dpi,
                )
            )
            h = np.hypot(d[:, 0], d[:, 1])
            parts.append(
                html_table(
                    [
                        [
                            int(t.size),
                            float(np.sqrt(np.mean(h**2))),
                            float(np.percentile(h, 95)),
                            float(np.sqrt(np.mean(d[:, 2] ** 2))),
                            float(np.percentile(np.abs(d[:, 2]), 95)),
                        ]
                    ],
                    ["epochs", "H RMS", "H 95%", "|U| RMS", "|U| 95%"],
                    digits=3,
                )
            )
        else:
            parts.append('<p class="warn">the two solutions share no epoch</p>')

    if obs is not None:
        parts.append("<h2>Satellites</h2>")
        if local:
            parts.append('<p class="warn">local-frame solution: no sky plot</p>')
        else:
            rx = main.table.pos_m[np.all(np.isfinite(main.table.pos_m), axis=1)]
            t_obs, counts, az, el = _sky(obs, nav, np.median(rx, axis=0))
            if counts:
                parts.append(
                    _img(
                        plot_satellite_counts(t_obs, counts, title="Satellites tracked per epoch (code)"),
                        "satellites per epoch",
                        dpi,
                    )
                )
            if az:
                parts.append(_img(plot_sky(az, el, elev_mask_deg=elev_mask_deg), "sky plot", dpi))
            else:
                parts.append('<p class="warn">no satellite position from the navigation data</p>')

    if diagnostics is not None:
        diag = read_diagnostics_csv(diagnostics)
        parts.append("<h2>Residuals and robust factors</h2>")
        if len(diag):
            parts.append(_img(plot_dd_by_satellite(diag), "residuals and robust factors by satellite", dpi))
            heads = [
                "satellite",
                "rows",
                "RMS residual",
                "max |std res|",
                "down-weighted %",
                "rejected %",
                "median factor",
                "max factor",
            ]
            parts.append(html_table(_satellite_rows(diag), heads, digits=3))
            parts.append(
                '<p class="note">One row per DD and epoch, grouped by the DD\'s non-reference satellite; '
                "residuals in the observation's unit (m); factor = variance inflation of the robust "
                "policy.</p>"
            )
        else:
            parts.append('<p class="note">the diagnostics file has no rows</p>')
    return parts


def html_document(title: str, body: Sequence[str]) -> str:
    """A self-contained HTML page: ``title`` as ``<title>`` and ``<h1>``, then ``body``."""
    head = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
    ]
    return "\n".join([*head, *body, "</body></html>"]) + "\n"


def build_report(solution: PathLike, *, title: str | None = None, **kw: Any) -> str:
    """The HTML text of the report (see the module docstring); arguments as
    :func:`report_parts`, ``title`` default ``robustrtk report: <file name>``."""
    return html_document(title or f"robustrtk report: {Path(solution).name}", report_parts(solution, **kw))


def section(heading: str, parts: Sequence[str], intro: str | None = None) -> list[str]:
    """``parts`` of :func:`report_parts` as one section of a larger page: an ``<h2>``
    heading, an optional note, and the parts' own headings one level down."""
    out = [f"<h2>{html.escape(heading)}</h2>"]
    if intro:
        out.append(f'<p class="note">{html.escape(intro)}</p>')
    out += [p.replace("<h2>", "<h3>").replace("</h2>", "</h3>") for p in parts]
    return out


def write_report(text: str, path: PathLike) -> Path:
    """Write the report text atomically (UTF-8); returns the path."""
    target = Path(path)
    with atomic_path(target) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")
    return target

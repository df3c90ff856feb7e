"""``robustrtk demo``: the pseudolite room and RTK on a bundled real pair, in one HTML report.

Two parts, one page (``report.html`` in the output directory):

* **real data** — carrier-phase RTK (:func:`robustrtk.pipeline.api.solve_rtk`, the
  ``rtk`` preset) on the two minutes of a Septentrio mosaic-X5 rover/base pair 0.99 m
  apart bundled in ``robustrtk/data/mosaicx5_static`` (MatRTKLIB's static example, MIT
  licence; see the README beside it), with errors against the rover's known position;
* **simulation** — the ``demo`` pseudolite room solved with the standard UKF and the
  robust UKF (DPL) and with RUKF + partial ambiguity resolution (RTK), as before
  (:func:`robustrtk.eval.cli_support.run_demo`).

Each part is a section built by :func:`robustrtk.eval.html_report.report_parts`.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robustrtk.core import FloatArray
from robustrtk.eval.cli_support import run_demo
from robustrtk.eval.html_report import html_document, report_parts, section, write_report
from robustrtk.eval.metrics import enu_errors
from robustrtk.eval.truth import read_truth_file, truth_from_llh
from robustrtk.geometry.frames import geodetic2ecef_deg
from robustrtk.io.solution import write_diagnostics_csv
from robustrtk.pipeline.api import SolutionSeries, solve_rtk

#: The bundled real-data sample (Hatanaka + gzip RINEX 3.04, broadcast navigation).
SAMPLE_DIR = Path(__file__).resolve().parents[1] / "data" / "mosaicx5_static"

#: Settings of the demo's real-data RTK over the ``rtk`` preset: GPS, Galileo and QZSS on
#: L1+L2 (BeiDou's 26 satellites would double the run time of a demo meant to take seconds;
#: ``robustrtk solve --systems GECJ`` uses them).
DEMO_RTK_SETTINGS: dict[str, object] = {"systems": "GEJ"}


@dataclass(frozen=True)
class SampleFiles:
    """Paths of the bundled pair and its two known positions.

    Attributes
    ----------
    rover, base, nav : Path
        Rover and base observations (``.crx.gz``) and the broadcast navigation file.
    base_pos_m, rover_pos_m : ndarray, shape (3,)
        ECEF (m) of the base (given with the data) and of the rover (the mean of an RTK
        solution over the whole five-minute file, by the data's author: mm-level, not
        independent).
    """

    rover: Path
    base: Path
    nav: Path
    base_pos_m: FloatArray
    rover_pos_m: FloatArray
    rover_llh: tuple[float, float, float]


def _llh(path: Path) -> tuple[float, float, float]:
    lat, lon, h = (float(v) for v in path.read_text(encoding="ascii").split()[:3])
    return lat, lon, h


def sample_files(root: str | os.PathLike[str] | None = None) -> SampleFiles:
    """The bundled sample (or the same layout under ``root``)."""
    d = Path(root) if root is not None else SAMPLE_DIR
    base_llh = _llh(d / "base_position.txt")
    rover_llh = _llh(d / "rover_position.txt")
    return SampleFiles(
        rover=d / "rover.crx.gz",
        base=d / "base.crx.gz",
        nav=d / "base.nav.gz",
        base_pos_m=np.asarray(geodetic2ecef_deg(*base_llh), float).reshape(3),
        rover_pos_m=np.asarray(geodetic2ecef_deg(*rover_llh), float).reshape(3),
        rover_llh=rover_llh,
    )


@dataclass(frozen=True)
class RealRtk:
    """The demo's real-data RTK: the series, its ENU errors and the files written."""

    series: SolutionSeries
    enu_err_m: FloatArray
    pos_path: Path
    diag_path: Path
    files: SampleFiles

    def text(self) -> str:
        """Two lines for the terminal: fix rate, time to first fix, errors of fixed epochs."""
        s = self.series.summary()
        fixed = np.isin(self.series.status, ("fixed", "partial"))
        e = self.enu_err_m[fixed]
        h = np.hypot(e[:, 0], e[:, 1])
        err = (
            f"fixed-epoch error vs the known rover position: H RMS {100 * np.sqrt(np.mean(h**2)):.1f} cm, "
            f"|U| max {100 * np.max(np.abs(e[:, 2])):.1f} cm"
            if e.size
            else "no fixed epoch"
        )
        return (
            f"real data (mosaic-X5 pair, 0.99 m baseline, {s.epochs} epochs at 1 Hz): RTK fix rate "
            f"{100 * s.fix_rate:.1f} %, first fix after {s.time_to_first_fix_s:.0f} s; {err}"
        )


def run_real_rtk(
    out_dir: str | os.PathLike[str], progress: Callable[[int, int], None] | None = None
) -> RealRtk:
    """RTK on the bundled pair; writes ``real/rtk.pos`` and ``real/rtk_diag.csv`` under ``out_dir``."""
    files = sample_files()
    series = solve_rtk(
        files.rover, files.base, files.nav, files.base_pos_m, DEMO_RTK_SETTINGS, progress=progress
    )
    out = Path(out_dir) / "real"
    out.mkdir(parents=True, exist_ok=True)
    pos_path, diag_path = out / "rtk.pos", out / "rtk_diag.csv"
    series.to_pos(pos_path)
    write_diagnostics_csv(
        [
            (d.t_s, d.dd, d.innovation, d.residual, d.std_residual, d.dv, d.factor, d.situation)
            for d in series.diagnostics
        ],
        diag_path,
    )
    err = enu_errors(series.pos_m - files.rover_pos_m, files.rover_pos_m)
    return RealRtk(series, err, pos_path, diag_path, files)


def run_full_demo(
    out_dir: str | os.PathLike[str], seed: int = 1, progress: Callable[[int, int], None] | None = None
) -> tuple[str, Path]:
    """Both parts and the report; returns the text for the terminal and the report's path."""
    out = Path(out_dir)
    real = run_real_rtk(out, progress)
    room_text = run_demo(str(out), seed)
    f = real.files
    lat, lon, h = f.rover_llh
    body = section(
        "Real data: RTK on a Septentrio mosaic-X5 pair, 0.99 m apart",
        report_parts(
            real.pos_path,
            truth=truth_from_llh(f"{lat},{lon},{h}"),
            diagnostics=real.diag_path,
            labels=["robustrtk RTK"],
            obs=f.rover,
            nav=[f.nav],
        ),
        intro="Two minutes at 1 Hz (Nagoya, 2024-06-24), MatRTKLIB's static example (MIT licence), "
        "GPS + Galileo + QZSS L1/L2; the truth is the rover position given with the data.",
    )
    truth = read_truth_file(out / "sim" / "truth.csv")
    for main, other, what in (
        ("dpl_rukf", "dpl_sukf", "DD code (DPL): robust UKF vs standard UKF"),
        ("rtk_rukf_par", "rtk_sukf", "RTK: robust UKF + partial AR vs standard UKF + LAMBDA"),
    ):
        body += section(
            f"Simulated pseudolite room — {what}",
            report_parts(
                out / f"{main}.csv",
                truth=truth,
                vs=[out / f"{other}.csv"],
                labels=[main.upper().replace("_", " "), other.upper().replace("_", " ")],
                diagnostics=out / f"{main}_diag.csv",
            ),
            intro="Five pseudolites, injected code and phase faults (sim/faults.csv); "
            "local frame of the room (m).",
        )
    report = write_report(html_document("robustrtk demo", body), out / "report.html")
    return real.text() + "\n\n" + room_text, report


__all__ = [
    "DEMO_RTK_SETTINGS",
    "SAMPLE_DIR",
    "RealRtk",
    "SampleFiles",
    "run_full_demo",
    "run_real_rtk",
    "sample_files",
]

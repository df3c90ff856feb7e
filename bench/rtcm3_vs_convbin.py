"""RTCM 3 observations decoded by robustrtk and by RTKLIB's ``convbin``, cell by cell.

For each RTCM 3 file given: ``convbin -r rtcm3 -tr TIME -v 3.04 -od -os`` into a temporary
folder, :func:`robustrtk.io.rtcm3.read_rtcm3` with the same approximate time, and every
satellite-signal-epoch that convbin writes compared with ours: code (1 mm), phase (0.001
cycle), Doppler (0.001 Hz), C/N0 (0.001 dB-Hz) and LLI bits. Also counted: cells only one side
has, epochs only one side has. One row per file, then the totals.

The approximate time of a file is ``--time`` (``'YYYY/MM/DD HH:MM:SS'``, GPST), or the line
``NAME<TAB>YYYY/MM/DD HH:MM:SS`` of the file ``--times FILE`` for its file name, or the
time our reader finds (ephemerides, a date in the name), or ``--default-time``; files with none
are listed as such. (Both decoders place the times of week within half a week of the same
approximate time, so a wrong week shifts both alike.)

Usage::

    python bench/rtcm3_vs_convbin.py FILE... [--times times.tsv] [--convbin PATH] [-v]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import traceback
from pathlib import Path
from typing import Any

import numpy as np

from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.io.rtcm3 import read_rtcm3, reference_time_s
from robustrtk.timeutil import WEEK_S, calendar_from_gpst, parse_gpst_instant

CONVBIN = Path(__file__).resolve().parents[2] / "shared" / "tools" / "rtklib-demo5" / "convbin"
TOL = {"code_m": 1e-3, "phase_cyc": 1e-3, "doppler_hz": 1e-3, "cn0_dbhz": 1e-3}


def _time_text(t_s: float) -> str:
    y, mo, d, h, mi, s = calendar_from_gpst(t_s)
    return f"{y:04d}/{mo:02d}/{d:02d} {h:02d}:{mi:02d}:{int(s):02d}"


def compare_file(path: Path, t_ref_s: float, convbin: Path, verbose: bool = False) -> dict[str, Any]:
    """Counters of one file's comparison (see the module docstring)."""
    out: dict[str, Any] = {"file": path.name}
    ours, _, counts = read_rtcm3(path, t_ref_s=t_ref_s)
    out["ours_epochs"] = len(ours)
    out["skipped"] = {
        k: v
        for k, v in counts.items()
        if k.startswith(("bad", "short", "observations before", "BeiDou", "station"))
    }
    with tempfile.TemporaryDirectory() as tmp:
        obs = Path(tmp) / "cb.obs"
        cmd = [str(convbin), "-r", "rtcm3", "-tr", *_time_text(t_ref_s).split(), "-v", "3.04", "-od", "-os"]
        subprocess.run([*cmd, "-o", str(obs), str(path)], capture_output=True, timeout=600, check=False)
        if not obs.is_file() or obs.stat().st_size == 0:
            out["cb_epochs"] = 0
            ref = None
        else:
            try:
                ref = read_rinex_obs(obs)
            except Exception as exc:  # an empty RINEX body: nothing to compare
                out["cb_error"] = str(exc)
                ref = None
    if ref is None or len(ref) == 0:
        out["cb_epochs"] = 0
        out["cells"] = 0
        return out
    out["cb_epochs"] = len(ref)
    t_o = np.round(ours.t_s * 1000).astype(np.int64) if len(ours) else np.zeros(0, np.int64)
    t_r = np.round(ref.t_s * 1000).astype(np.int64)
    common, i_o, i_r = np.intersect1d(t_o, t_r, return_indices=True)
    if common.size < t_r.size:
        # convbin may place epochs in a wrong week (after a bad time field): match those by
        # time of week, and count them
        week_ms = int(WEEK_S * 1000)
        rest_r = np.setdiff1d(np.arange(t_r.size), i_r)
        rest_o = np.setdiff1d(np.arange(t_o.size), i_o)
        _, j_o, j_r = np.intersect1d(t_o[rest_o] % week_ms, t_r[rest_r] % week_ms, return_indices=True)
        out["epochs_cb_other_week"] = int(j_r.size)
        i_o = np.concatenate([i_o, rest_o[j_o]])
        i_r = np.concatenate([i_r, rest_r[j_r]])
        common = t_r[i_r]
    out["epochs_only_cb"] = int(t_r.size - common.size)
    out["epochs_only_ours"] = int(t_o.size - common.size)
    cells = diff = only_cb = only_ours = 0
    worst: dict[str, float] = {}
    examples: list[str] = []
    for n_r, tx in enumerate(ref.tx_ids):
        n_o = ours.tx_ids.index(tx) if tx in ours.tx_ids else None
        for k_r, sig in enumerate(ref.signals):
            rc = ref.code_m[i_r, n_r, k_r]
            rp = ref.phase_cyc[i_r, n_r, k_r]
            present_r = np.isfinite(rc) | np.isfinite(rp)
            if not present_r.any():
                continue
            if n_o is None or sig not in ours.signals:
                only_cb += int(present_r.sum())
                continue
            k_o = ours.signals.index(sig)
            present_o = np.isfinite(ours.code_m[i_o, n_o, k_o]) | np.isfinite(ours.phase_cyc[i_o, n_o, k_o])
            only_cb += int((present_r & ~present_o).sum())
            only_ours += int((present_o & ~present_r).sum())
            both = present_r & present_o
            cells += int(both.sum())
            bad = np.zeros(both.shape, bool)
            for f, tol in TOL.items():
                a = getattr(ours, f)[i_o, n_o, k_o]
                b = getattr(ref, f)[i_r, n_r, k_r]
                fin_a, fin_b = np.isfinite(a), np.isfinite(b)
                mism = both & (fin_a != fin_b)
                dv = np.where(both & fin_a & fin_b, np.abs(np.round(a, 3) - b), 0.0)
                worst[f] = max(worst.get(f, 0.0), float(np.nanmax(dv, initial=0.0)))
                bad_f = mism | (dv > tol * 1.01)
                if verbose and bad_f.any():
                    j = int(np.flatnonzero(bad_f)[0])
                    examples.append(f"{tx} {sig} {f} t={ref.t_s[i_r[j]]:.3f} ours={a[j]!r} cb={b[j]!r}")
                bad |= bad_f
            la = ours.lli[i_o, n_o, k_o].astype(int) & 3
            lb = ref.lli[i_r, n_r, k_r].astype(int) & 3
            bad_l = both & np.isfinite(rp) & (la != lb)
            if verbose and bad_l.any():
                j = int(np.flatnonzero(bad_l)[0])
                examples.append(f"{tx} {sig} lli t={ref.t_s[i_r[j]]:.3f} ours={la[j]} cb={lb[j]}")
            bad |= bad_l
            diff += int(bad.sum())
    for tx in ours.tx_ids:
        if tx not in ref.tx_ids:
            n_o = ours.tx_ids.index(tx)
            only_ours += int(np.isfinite(ours.code_m[i_o, n_o, :]).sum())
    out.update(cells=cells, differ=diff, only_cb=only_cb, only_ours=only_ours, worst=worst)
    out["systems"] = "".join(sorted({t[0] for t in ref.tx_ids}))
    out["signals"] = " ".join(ref.signals)
    out["weeks"] = sorted({int(t // WEEK_S) for t in ref.t_s})
    if examples:
        out["examples"] = examples[:12]
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("files", nargs="+", type=Path)
    ap.add_argument("--time", default=None, help="approximate GPST of every file")
    ap.add_argument("--times", type=Path, default=None, help="NAME<TAB>TIME lines")
    ap.add_argument("--default-time", default=None, help="approximate GPST of files without one")
    ap.add_argument("--convbin", type=Path, default=CONVBIN)
    ap.add_argument("-v", "--verbose", action="store_true")
    a = ap.parse_args(argv)
    times: dict[str, str] = {}
    if a.times is not None:
        for line in a.times.read_text().splitlines():
            if "\t" in line and not line.startswith("#"):
                name, t = line.split("\t", 1)
                times[name.strip()] = t.strip()
    tot = {"cells": 0, "differ": 0, "only_cb": 0, "only_ours": 0, "files": 0, "errors": 0}
    head = ("file", "sys", "ep ours/cb", "cells", "differ", "only cb", "only us")
    print("{:42s} {:6s} {:>11s} {:>8s} {:>6s} {:>7s} {:>7s}".format(*head))
    for p in a.files:
        try:
            text = a.time or times.get(p.name)
            if text is not None:
                t_ref = parse_gpst_instant(text, 0.0, "--time")
            else:
                t_ref = reference_time_s(str(p), p.read_bytes())
                if t_ref is None and a.default_time is not None:
                    t_ref = parse_gpst_instant(a.default_time, 0.0, "--default-time")
            if t_ref is None:
                print(f"{p.name:42s} no time reference")
                continue
            r = compare_file(p, t_ref, a.convbin, a.verbose)
        except Exception:
            tot["errors"] += 1
            print(f"{p.name:42s} ERROR\n{traceback.format_exc()}")
            continue
        tot["files"] += 1
        for k in ("cells", "differ", "only_cb", "only_ours"):
            tot[k] += int(r.get(k, 0))
        print(
            f"{r['file'][:42]:42s} {r.get('systems', ''):6s} {r['ours_epochs']:5d}/{r['cb_epochs']:<5d} "
            f"{r.get('cells', 0):8d} {r.get('differ', 0):6d} {r.get('only_cb', 0):7d} "
            f"{r.get('only_ours', 0):7d}"
        )
        if a.verbose:
            extra = {
                k: r[k]
                for k in (
                    "signals",
                    "weeks",
                    "worst",
                    "skipped",
                    "epochs_only_cb",
                    "epochs_only_ours",
                    "epochs_cb_other_week",
                )
                if k in r
            }
            print(f"    {extra}")
            for e in r.get("examples", []):
                print(f"    {e}")
    print(f"total: {tot}")
    return 1 if tot["differ"] or tot["errors"] else 0


if __name__ == "__main__":
    sys.exit(main())

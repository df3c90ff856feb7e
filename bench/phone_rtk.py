"""Phone-profiled RTK against the real base: robustrtk ``--profile phone`` and RTKLIB demo5.

For each shared dataset with L5/E5a (mosaicx5, kamakura) and each seed, the rover file is
phone-profiled (:func:`robustrtk.sim.phone.phone_profile`, written as RINEX 3.04), then
solved against the real base by robustrtk (RTK preset with the ``phone`` profile) and by
RTKLIB demo5 ``rnx2rtkp`` (the dataset's own ``rtklib/fh.conf`` with ``pos1-frequency``
``l1+l2+l5``, so that L5/E5a is used). Printed per run: fix rate over all rover epochs,
fixed epochs more than 10 cm off (mosaicx5: its surveyed point; kamakura: RTKLIB's
forward-backward fixed trajectory of the geodetic data), the largest fixed-epoch error.

Usage: ``PYTHONPATH=src python bench/phone_rtk.py [--seeds 1,2,3] [--data ../shared/data]
[--param duty_on_s=10 ...]``.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "pipeline"))

from test_rtk_gnss import dataset  # noqa: E402

from robustrtk.geometry.frames import ecef2enu, ecef2geodetic  # noqa: E402
from robustrtk.io.rinex_obs import read_rinex_obs  # noqa: E402
from robustrtk.io.rinex_write import write_rinex_obs  # noqa: E402
from robustrtk.io.solution_pos import read_pos  # noqa: E402
from robustrtk.pipeline.config import profiled  # noqa: E402
from robustrtk.pipeline.rtk_gnss import rtk_gnss_config, solve_rtk  # noqa: E402
from robustrtk.sim.phone import PhoneProfile, parse_params, phone_profile  # noqa: E402
from robustrtk.timeutil import gpst_from_week_tow  # noqa: E402

RNX2RTKP = Path("/work/shared/tools/rtklib-demo5/rnx2rtkp")


def errors_m(root: Path, name: str, t_s: np.ndarray, pos_m: np.ndarray) -> np.ndarray:
    """3-D error (m) of each epoch against the dataset's reference (NaN where none)."""
    err = np.full(t_s.size, np.nan)
    if name == "kamakura":
        ref = np.loadtxt(
            root / "kamakura_kinematic_5km" / "rtklib" / "pseudoref_comb_fh_traj.txt", comments="#"
        )
        tr = gpst_from_week_tow(ref[:, 0].astype(int), ref[:, 1])
        j = np.clip(np.searchsorted(tr, t_s), 0, tr.size - 1)
        for i in np.flatnonzero(np.abs(tr[j] - t_s) < 0.05):
            lat, lon, h = ecef2geodetic(ref[j[i], 2:5])
            err[i] = float(np.linalg.norm(ecef2enu(pos_m[i], float(lat), float(lon), float(h))))
        return err
    truth = dataset(root, name)[4]
    lat, lon, h = ecef2geodetic(truth)
    return np.linalg.norm(ecef2enu(pos_m, float(lat), float(lon), float(h)), axis=1)


def summary(err: np.ndarray, fixed: np.ndarray, n_epochs: int) -> tuple[float, int, float]:
    """(fix %, fixed epochs > 10 cm off, largest fixed error in cm)."""
    bad = int(np.sum(fixed & (err > 0.10)))
    worst = float(np.nanmax(np.where(fixed, err, np.nan)) * 100) if fixed.any() else float("nan")
    return 100.0 * fixed.sum() / n_epochs, bad, worst


def rtklib_conf(root: Path, name: str, out: Path) -> Path:
    d = "mosaicx5_static_1m" if name == "mosaicx5" else "kamakura_kinematic_5km"
    text = (root / d / "rtklib" / "fh.conf").read_text()
    lines = [
        "pos1-frequency     =l1+l2+l5" if ln.startswith("pos1-frequency") else ln for ln in text.splitlines()
    ]
    out.write_text("\n".join(lines) + "\n")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--data", default=str(Path(__file__).resolve().parents[1].parent / "shared" / "data"))
    ap.add_argument("--datasets", default="mosaicx5,kamakura")
    ap.add_argument(
        "--param", action="append", default=[], metavar="NAME=VALUE", help="phone-profile parameter"
    )
    args = ap.parse_args()
    root = Path(args.data)
    print(
        "| dataset | seed | robustrtk fix % | bad fixes | worst fixed cm "
        "| RTKLIB fix % | bad fixes | worst fixed cm |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for name in args.datasets.split(","):
        rover, base, nav, bpos, _ = dataset(root, name)
        geo = read_rinex_obs(rover)
        for seed in (int(s) for s in args.seeds.split(",")):
            ph = phone_profile(geo, PhoneProfile().updated(**parse_params(args.param)), seed=seed).batch
            with tempfile.TemporaryDirectory() as tmp:
                obs = Path(tmp) / "phone.obs"
                write_rinex_obs(ph, obs)
                res = solve_rtk(ph, base, nav, bpos, profiled(rtk_gnss_config(), "phone"))
                t = np.array([s.t_s for s in res.solutions])
                pos = np.array([s.pos_m for s in res.solutions])
                fx = np.isin([s.status for s in res.solutions], ("fixed", "partial"))
                ours = summary(errors_m(root, name, t, pos), fx, len(geo))
                conf = rtklib_conf(root, name, Path(tmp) / "fh.conf")
                pos_path = Path(tmp) / "rtklib.pos"
                subprocess.run(
                    [str(RNX2RTKP), "-k", str(conf), "-o", str(pos_path), str(obs), str(base), str(nav)],
                    check=True,
                    capture_output=True,
                )
                tab = read_pos(pos_path)
                fx_r = tab.status == "fixed"
                theirs = summary(errors_m(root, name, tab.t_s, tab.pos_m), fx_r, len(geo))
            print(
                f"| {name} | {seed} | {ours[0]:.1f} | {ours[1]} | {ours[2]:.1f} | "
                f"{theirs[0]:.1f} | {theirs[1]} | {theirs[2]:.1f} |",
                flush=True,
            )


if __name__ == "__main__":
    main()

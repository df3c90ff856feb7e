"""Least-squares SPP on long files: wall time and peak memory of whole ``robustrtk solve --mode
spp`` processes at 10k, 50k and 200k epochs (is the time linear in epochs, is the memory
bounded?), beside RTKLIB ``rnx2rtkp -p 0`` on the same files. Two robustrtk rows: ``solve``
(the command, which streams a plain RINEX 3/4 file to ``.pos``:
:mod:`robustrtk.cli.gnss_stream`, with its checks and summary) and ``streamed``
(:func:`robustrtk.pipeline.spp_stream.solve_spp_to_pos` alone: a block of epochs read,
solved and written at a time).

The files are made here, once (``--dir`` keeps them): a static receiver at the geonet rover
position (``geonet_0759_3040_static_3km``), every 0.4 s over the day of its broadcast
navigation file ``07590920.05n`` (GPS), one L1 C/A code (``C1C``) and C/N0 (``S1C``) per
satellite above 5°. The pseudoranges are made with this project's own models (broadcast
orbits and clocks with the group delay, Sagnac, Saastamoinen, Klobuchar), a receiver clock
drifting 1 m/s, and 2 m Gaussian noise, so every epoch is solvable as in real data; they are
written as RINEX 3.04 (about 360 bytes per epoch: 72 MB for 200,000 epochs). Then, per
size, ``--repeats`` runs of each program (median wall time, median peak RSS from
``os.wait4``), the median CPU time (user + system, steadier on a loaded machine), and the CPU
time per epoch relative to the smallest size (1.0 = linear).

Usage::

    python bench/bench_spp_scale.py [--sizes 10000,50000,200000] [--repeats 3] [--dir DIR]
                                    [--data DIR] [--rnx2rtkp PATH]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_spp import run_timed  # noqa: E402
from bench_vs_rtklib import SRC, _default_data, find_rnx2rtkp  # noqa: E402

GEONET = "geonet_0759_3040_static_3km"
NAV = "07590920.05n"
RX_ECEF_M = (-3976219.1879, 3382371.6056, 3652511.1425)
INTERVAL_S = 0.4


def _header(t0: float) -> str:
    from robustrtk.timeutil import calendar_from_gpst

    y, mo, d, h, mi, s = calendar_from_gpst(t0)

    def rec(text: str, label: str) -> str:
        return f"{text:<60}{label:<20}\n"

    return "".join(
        [
            rec("     3.04           OBSERVATION DATA    G", "RINEX VERSION / TYPE"),
            rec("bench_spp_scale", "PGM / RUN BY / DATE"),
            rec("SYNTH", "MARKER NAME"),
            rec("".join(f"{v:14.4f}" for v in RX_ECEF_M), "APPROX POSITION XYZ"),
            rec("G    2 C1C S1C", "SYS / # / OBS TYPES"),
            rec(f"{INTERVAL_S:10.3f}", "INTERVAL"),
            rec(
                f"  {y:4d}    {mo:2d}    {d:2d}    {h:2d}    {mi:2d}   {s:10.7f}     GPS", "TIME OF FIRST OBS"
            ),
            rec("", "END OF HEADER"),
        ]
    )


def make_obs(path: Path, nav_path: Path, n_epochs: int, seed: int = 1) -> None:
    """Write ``n_epochs`` synthetic epochs (see the module docstring) to ``path``.

    Run in a process of its own (``--make``): the bench's own process stays small, since a
    child's peak RSS counts the parent's pages it starts with."""
    import numpy as np

    from robustrtk.geometry.ephemeris import EphemerisSource
    from robustrtk.geometry.los import geometric_range
    from robustrtk.io.rinex_nav import read_rinex_nav
    from robustrtk.pipeline.spp_batch import block_atmosphere
    from robustrtk.timeutil import calendar_from_gpst

    rx_m = np.array(RX_ECEF_M)
    nav = read_rinex_nav(nav_path)
    eph = EphemerisSource(nav)
    sats = sorted({str(s) for s in nav.kepler["G"].sat_id})
    letter, code = eph.query_codes(sats)
    toe = np.sort(nav.kepler["G"].toe_s)
    t0 = float(np.ceil(toe[0]))
    rng = np.random.default_rng(seed)
    with open(path, "w") as fh:
        fh.write(_header(t0))
        block = 5000
        for lo in range(0, n_epochs, block):
            t = t0 + INTERVAL_S * np.arange(lo, min(n_epochs, lo + block))
            n_ep, n_sat = t.size, len(sats)
            ei = np.repeat(np.arange(n_ep), n_sat)
            si = np.tile(np.arange(n_sat), n_ep)
            clk_rx = 1.0 * (t - t0) + 1.0e4  # m
            pr = np.full(ei.size, 2.2e7)
            for _ in range(3):  # transmission time consistent with the range
                pos, clk_m, ok = eph.code_states(t[ei], letter[si], code[si], pr)
                rng_m, _ = geometric_range(pos, rx_m)
                pr = np.where(ok, rng_m + clk_rx[ei] - clk_m, 2.2e7)
            pos3 = pos.reshape(n_ep, n_sat, 3)
            el, _, delay = block_atmosphere(
                t,
                pos3,
                np.tile(rx_m, (n_ep, 1)),
                nav,
                "saastamoinen",
                "klobuchar",
                np.full((n_ep, n_sat), 1575.42e6),
            )
            pr = pr.reshape(n_ep, n_sat) + delay + rng.normal(0.0, 2.0, (n_ep, n_sat))
            seen = ok.reshape(n_ep, n_sat) & (el > np.radians(5.0))
            cn0 = 30.0 + 20.0 * np.sin(np.maximum(el, 0.0))
            lines: list[str] = []
            for i in range(n_ep):
                y, mo, d, h, mi, s = calendar_from_gpst(float(t[i]))
                idx = np.flatnonzero(seen[i])
                lines.append(f"> {y:4d} {mo:02d} {d:02d} {h:02d} {mi:02d}{s:11.7f}  0{idx.size:3d}\n")
                lines.extend(f"{sats[j]}{pr[i, j]:14.3f}  {cn0[i, j]:14.3f}  \n" for j in idx.tolist())
            fh.write("".join(lines))


def _median(v: list[float]) -> float:
    return statistics.median(v) if v else float("nan")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="10000,50000,200000")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--dir", type=Path, default=None, help="keep (and reuse) the generated files here")
    ap.add_argument("--data", type=Path, default=_default_data())
    ap.add_argument("--rnx2rtkp", default=None)
    ap.add_argument("--make", nargs=2, metavar=("N", "PATH"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.make:
        sys.path.insert(0, str(SRC))
        make_obs(Path(args.make[1]), args.data / GEONET / NAV, int(args.make[0]))
        return 0
    nav_path = args.data / GEONET / NAV
    if not nav_path.is_file():
        print(f"{nav_path} not found; skipped")
        return 0
    sizes = [int(s) for s in args.sizes.split(",") if s]
    exe = find_rnx2rtkp(args.rnx2rtkp)
    with tempfile.TemporaryDirectory() as tmp_s:
        tmp = Path(tmp_s)
        work = args.dir or tmp
        work.mkdir(parents=True, exist_ok=True)
        env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        env["PYTHONPATH"] = os.pathsep.join(p for p in (str(SRC), os.environ.get("PYTHONPATH", "")) if p)
        env["PYTHONPYCACHEPREFIX"] = str(tmp / "pycache")
        rows = []
        for n in sizes:
            obs = work / f"spp_scale_{n}.obs"
            if not obs.is_file():
                print(f"writing {obs} ...", flush=True)
                make = [sys.executable, __file__, "--data", str(args.data), "--make", str(n), str(obs)]
                subprocess.run(make, check=True)
            mb = obs.stat().st_size / 1e6
            streamed = (
                "import sys; from robustrtk.pipeline.gnss import nav_source; "
                "from robustrtk.pipeline.spp_stream import solve_spp_to_pos; "
                "solve_spp_to_pos(sys.argv[1], nav_source([sys.argv[2]]), sys.argv[3])"
            )
            progs = {
                "solve": (
                    [sys.executable, "-m", "robustrtk", "solve", str(obs), "--nav", str(nav_path)]
                    + ["--mode", "spp", "--out", str(tmp / "ours.pos"), "--quiet"],
                    env,
                ),
                "streamed": (
                    [sys.executable, "-c", streamed, str(obs), str(nav_path), str(tmp / "st.pos")],
                    env,
                ),
            }
            if exe is not None:
                progs["rtklib"] = (
                    [str(exe), "-p", "0", "-o", str(tmp / "rtklib.pos"), str(obs), str(nav_path)],
                    None,
                )
            res: dict[str, tuple[float, float, float]] = {}
            for name, (cmd, e) in progs.items():
                run_timed(cmd, e, tmp / "log.txt")  # warm-up: bytecode, page cache
                wall, cpu, rss = [], [], []
                for _ in range(args.repeats):
                    dt, c, mib, rc = run_timed(cmd, e, tmp / "log.txt")
                    if rc != 0:
                        tail = (tmp / "log.txt").read_text(errors="replace").strip().splitlines()
                        print(f"note: {name} at {n} exited {rc}: {tail[-1] if tail else ''}")
                    wall.append(dt)
                    cpu.append(c)
                    rss.append(mib)
                res[name] = (_median(wall), _median(cpu), _median(rss))
                print(
                    f"{n} epochs ({mb:.0f} MB) {name}: {res[name][0]:.2f} s wall, {res[name][1]:.2f} s CPU, "
                    f"{res[name][2]:.0f} MiB",
                    flush=True,
                )
            rows.append((n, mb, res))
    base = {name: rows[0][2][name][1] / rows[0][0] for name in rows[0][2]}
    names = list(rows[0][2])
    head = ["epochs", "MB"]
    for name in names:
        head += [f"{name} wall s", f"{name} CPU s", f"{name} CPU per epoch vs {sizes[0]}", f"{name} peak MiB"]
    print("\n| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for n, mb, res in rows:
        cells = [str(n), f"{mb:.0f}"]
        for name in names:
            wall, c, rss = res[name]
            cells += [f"{wall:.2f}", f"{c:.2f}", f"{c / n / base[name]:.2f}", f"{rss:.0f}"]
        print("| " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

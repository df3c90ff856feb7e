"""Whole-process RTK side by side: RTKLIB demo5 ``rnx2rtkp`` against ``robustrtk solve --mode rtk``.

For every dataset folder under ``--data`` that holds ``rtklib/fh.conf`` (RTKLIB's
fix-and-hold settings: forward filter, 15° mask, ratio 3, L1+L2) and ``rtklib/fh.pos``
(whose ``% inp file`` lines name the rover, base and navigation files RTKLIB read), both
programs run on the same files, alternating, ``--repeats`` times each:

* RTKLIB: ``rnx2rtkp -k rtklib/fh.conf -o OUT.pos ROVER BASE NAV...``;
* robustrtk: ``python -m robustrtk solve ROVER --base BASE --nav NAV... --rtklib-conf
  rtklib/fh.conf --base-pos X,Y,Z --mode rtk --out OUT.pos --quiet``: the same settings,
  as far as ``--rtklib-conf`` maps them (it names the keys it ignores), or, with
  ``--settings default`` (and when robustrtk refuses the file), its own RTK defaults; and
  the base position of ``fh.conf`` (``ant2-pos1..3``, llh or xyz; ``rinexhead``: the base
  file's header position, solve's default; ``single``: ``--base-position moving``, the
  base's own single-point solution at each epoch, as RTKLIB does).

Each run is one process; its wall time and its own peak resident set size (``ru_maxrss`` of
``os.wait4``) are recorded. Printed per dataset: epochs, median wall s of each, the ratio
robustrtk / RTKLIB (1.0 = parity, below 1 = robustrtk faster), epochs/s of each, the median
peak RSS (MiB) of each and both fix rates (Q = 1 epochs over all epochs: the larger of the two
outputs, since RTKLIB leaves epochs it cannot solve out of its ``.pos``). The last table is
Markdown, for the README and docs/speed.md.

Start-up (interpreter, imports, reading the files) is a fixed cost per process, and on a
short file it is most of robustrtk's time. So each program also runs on the first tenth of
the span (RTKLIB ``-te``, robustrtk ``--time-end``, both at the same GPST second, a tenth of
the way through RTKLIB's own output), and the second table gives the cost of one more epoch,
``(T_full − T_short) / (N_full − N_short)`` from the medians, for each program and their
ratio: what a long run (a day at 1 Hz) costs per epoch once started, and the fixed cost
``T_full − N_full · that``: start-up, and what reading costs whatever the window (robustrtk
scans each file's epoch headers in full and decodes only the window's epochs). A short run a
tenth as long keeps the difference, and so the estimate,
well above the run-to-run noise. ``--no-marginal`` skips it.

The floor: alternating with the two programs, the same interpreter runs ``python -c "import
numpy"`` (same environment), the least any process of a numpy program pays before its first
line of work. The third table sets it beside RTKLIB's whole run: where the floor alone is
longer, no numpy program reaches a ratio of 1 on that file, and ``floor + N_full · ours
ms/ep`` (robustrtk with every start-up cost but numpy's removed) bounds the ratio it could
reach at its present cost per epoch.

The robustrtk process is this checkout's ``src`` (``PYTHONPATH``), with its bytecode cached
in a temporary ``PYTHONPYCACHEPREFIX`` and one unrecorded warm-up run first, as after
``pip install`` (with ``PYTHONDONTWRITEBYTECODE`` every run would recompile the sources).

RTKLIB binary: ``--rnx2rtkp PATH``, default ``../shared/tools/rtklib-demo5/rnx2rtkp`` beside
the repository, then ``rnx2rtkp`` on ``PATH`` (Debian's 2.4.3 differs on multi-GNSS RINEX 3);
when none is found the bench says so and exits 0.

Usage::

    python bench/bench_vs_rtklib.py [--repeats 5] [--rnx2rtkp PATH] [--data DIR]
                                    [--datasets NAME,...] [--settings conf|default]
                                    [--no-marginal]
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SRC = REPO / "src"
DEFAULT_RNX2RTKP = REPO.parent / "shared" / "tools" / "rtklib-demo5" / "rnx2rtkp"


def _default_data() -> Path:
    env = os.environ.get("ROBUSTRTK_SHARED_DATA")
    return Path(env) if env else REPO.parent / "shared" / "data"


@dataclass(frozen=True)
class Dataset:
    """One folder's inputs: RTKLIB's conf, the observation and navigation files, base ECEF (m)."""

    name: str
    folder: Path
    conf: Path
    rover: Path
    base: Path
    navs: tuple[Path, ...]
    base_xyz_m: tuple[float, float, float] | None
    base_args: tuple[str, ...] = ()


@dataclass
class Runs:
    """Wall times (s), peak RSS (MiB) and the output of one program on one dataset."""

    wall_s: list[float] = field(default_factory=list)
    rss_mib: list[float] = field(default_factory=list)
    epochs: int = 0
    fixed: int = 0
    failed: str = ""


def _conf_values(conf: Path) -> dict[str, str]:
    out: dict[str, str] = {}
    for line in conf.read_text(errors="replace").splitlines():
        line = line.split("#", 1)[0].strip()
        if "=" in line:
            k, v = line.split("=", 1)
            out[k.strip()] = v.strip()
    return out


def _geodetic_to_ecef_m(lat_deg: float, lon_deg: float, h_m: float) -> tuple[float, float, float]:
    """WGS84 geodetic (deg, deg, m) to ECEF (m): ``N = a/√(1 − e² sin²φ)``,
    ``X = (N + h) cos φ cos λ``, ``Y = (N + h) cos φ sin λ``, ``Z = (N (1 − e²) + h) sin φ``."""
    import math

    a = 6378137.0
    f = 1.0 / 298.257223563
    e2 = f * (2.0 - f)
    phi, lam = math.radians(lat_deg), math.radians(lon_deg)
    n = a / math.sqrt(1.0 - e2 * math.sin(phi) ** 2)
    return (
        (n + h_m) * math.cos(phi) * math.cos(lam),
        (n + h_m) * math.cos(phi) * math.sin(lam),
        (n * (1.0 - e2) + h_m) * math.sin(phi),
    )


def find_dataset(folder: Path) -> Dataset | str:
    """The dataset of ``folder``, or a one-line reason why it is skipped."""
    conf, pos = folder / "rtklib" / "fh.conf", folder / "rtklib" / "fh.pos"
    if not conf.is_file():
        return "no rtklib/fh.conf"
    if not pos.is_file():
        return "no rtklib/fh.pos (it names the input files)"
    inputs = []
    for line in pos.read_text(errors="replace").splitlines():
        if not line.startswith("%"):
            break
        if line.startswith("% inp file"):
            text = line.split(":", 1)[1].strip()
            named = Path(text)
            # a path of the machine that wrote the file (POSIX or Windows): the file of that
            # name in the folder
            here, by_name = folder / named, folder / re.split(r"[\\/]", text)[-1]
            inputs.append(by_name if not here.is_file() and by_name.is_file() else here)
    if len(inputs) < 3:
        return f"rtklib/fh.pos names {len(inputs)} input files, expected rover, base and navigation"
    missing = [p.name for p in inputs if not p.is_file()]
    if missing:
        return f"missing {', '.join(missing)}"
    vals = _conf_values(conf)
    kind = {"0": "llh", "1": "xyz", "2": "single", "4": "rinexhead"}.get(
        vals.get("ant2-postype", ""), vals.get("ant2-postype", "")
    )
    navs = tuple(inputs[2:])
    if kind == "rinexhead":  # the base file's header position: solve's default
        return Dataset(folder.name, folder, conf, inputs[0], inputs[1], navs, None)
    if kind == "single":  # the base's own single-point solution at each epoch
        moving = ("--base-position", "moving")
        return Dataset(folder.name, folder, conf, inputs[0], inputs[1], navs, None, moving)
    if kind not in ("llh", "xyz"):
        return f"fh.conf ant2-postype {kind!r} (expected llh, xyz, single or rinexhead)"
    try:
        p123 = tuple(float(vals[f"ant2-pos{i}"]) for i in (1, 2, 3))
    except (KeyError, ValueError):
        return "fh.conf has no numeric ant2-pos1..3"
    xyz = p123 if kind == "xyz" else _geodetic_to_ecef_m(*p123)
    return Dataset(folder.name, folder, conf, inputs[0], inputs[1], navs, xyz)  # type: ignore[arg-type]


def find_rnx2rtkp(given: str | None) -> Path | None:
    """The RTKLIB binary: ``given``, else the demo5 build beside the repository, else PATH."""
    if given:
        p = Path(given)
        return p if p.is_file() and os.access(p, os.X_OK) else None
    if DEFAULT_RNX2RTKP.is_file() and os.access(DEFAULT_RNX2RTKP, os.X_OK):
        return DEFAULT_RNX2RTKP
    found = shutil.which("rnx2rtkp")
    return Path(found) if found else None


def run_measured(cmd: list[str], env: dict[str, str] | None, log: Path) -> tuple[float, float, int]:
    """Run ``cmd`` as one process: (wall s, its peak RSS in MiB, exit status)."""
    with open(log, "wb") as fh:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=fh, stderr=subprocess.STDOUT, env=env)
        _pid, status, usage = os.wait4(proc.pid, 0)
        dt = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    return dt, usage.ru_maxrss / 1024.0, proc.returncode


def pos_counts(path: Path) -> tuple[int, int]:
    """(epochs, fixed epochs) of a ``.pos`` file: data lines, and those with Q = 1."""
    n = fixed = 0
    for line in path.read_text(errors="replace").splitlines():
        if not line.strip() or line.startswith("%"):
            continue
        words = line.split()
        if len(words) < 6:
            continue
        n += 1
        fixed += words[5] == "1"  # GPST date, time, lat, lon, height, Q
    return n, fixed


def pos_span_text(path: Path) -> tuple[str, str] | None:
    """The first and last epoch times (``yyyy/mm/dd hh:mm:ss.sss``, as written) of a ``.pos``
    file with calendar times, or None."""
    times = []
    for line in path.read_text(errors="replace").splitlines():
        words = line.split()
        if line.startswith("%") or len(words) < 6 or "/" not in words[0]:
            continue
        times.append(f"{words[0]} {words[1]}")
    return (times[0], times[-1]) if times else None


def span_second(first: str, last: str, fraction: float = 0.1) -> str:
    """The GPST second at ``fraction`` of the way between two ``yyyy/mm/dd hh:mm:ss[.s]``
    times, as ``yyyy/mm/dd hh:mm:ss`` (rounded down)."""
    import datetime as dt

    def parse(text: str) -> dt.datetime:
        return dt.datetime.strptime(text.split(".")[0], "%Y/%m/%d %H:%M:%S")

    a, b = parse(first), parse(last)
    at = a + (b - a) * fraction
    return at.replace(microsecond=0).strftime("%Y/%m/%d %H:%M:%S")


def rtklib_cmd(exe: Path, ds: Dataset, out: Path, end: str | None = None) -> list[str]:
    """``rnx2rtkp -k fh.conf -o OUT [-te DATE TIME] ROVER BASE NAV...``."""
    window = ["-te", *end.split()] if end else []
    cmd = [str(exe), "-k", str(ds.conf), *window, "-o", str(out)]
    return [*cmd, str(ds.rover), str(ds.base), *map(str, ds.navs)]


def robustrtk_cmd(ds: Dataset, out: Path, settings: str = "conf", end: str | None = None) -> list[str]:
    """``solve`` on the dataset's files: with RTKLIB's ``fh.conf`` (``settings="conf"``:
    ``--rtklib-conf``, the matching run) or with robustrtk's own RTK defaults
    (``"default"``); the base position as :func:`find_dataset` read it, in both."""
    cmd = [sys.executable, "-m", "robustrtk", "solve", str(ds.rover), "--base", str(ds.base)]
    for n in ds.navs:
        cmd += ["--nav", str(n)]
    if settings == "conf":
        cmd += ["--rtklib-conf", str(ds.conf)]
    if ds.base_xyz_m is not None:
        cmd += ["--base-pos", ",".join(f"{v:.4f}" for v in ds.base_xyz_m)]
    window = ["--time-end", end] if end else []
    return [*cmd, *ds.base_args, *window, "--mode", "rtk", "--out", str(out), "--quiet"]


def _span_after_warm_up(cmd: list[str], out: Path, tmp: Path) -> tuple[str, str] | None:
    """The span of RTKLIB's output of ``cmd`` (run once more when the warm-up left none)."""
    if not out.is_file():
        run_measured(cmd, None, tmp / "log.txt")
    return pos_span_text(out) if out.is_file() else None


#: The floor: the same interpreter importing numpy and nothing else.
FLOOR_CMD = [sys.executable, "-c", "import numpy"]


def floor_bound(floor_s: float, epochs: int, ours_per_epoch_s: float, rtklib_s: float) -> float:
    """The least ratio robustrtk could reach on a file at its present cost per epoch, with
    every start-up cost removed but the interpreter's and numpy's import:
    ``(floor + N · ours per epoch) / RTKLIB's whole run`` (NaN when a figure is missing)."""
    if not (floor_s == floor_s and ours_per_epoch_s == ours_per_epoch_s and rtklib_s > 0):
        return float("nan")
    return (floor_s + epochs * ours_per_epoch_s) / rtklib_s


def marginal_s(full: Runs, short: Runs) -> float:
    """Seconds per extra epoch: ``(T_full − T_short) / (N_full − N_short)`` from the medians
    (NaN when the two runs do not differ in epochs or one failed)."""
    if full.failed or short.failed or full.epochs <= short.epochs:
        return float("nan")
    return (_median(full.wall_s) - _median(short.wall_s)) / (full.epochs - short.epochs)


def start_table(head: str, md_head: str) -> list[str]:
    """Print a plain-text table's header line and its rule; return the Markdown table's
    header and separator rows (``md_head`` is the header row, ``| a | b |``)."""
    print(head)
    print("-" * len(head))
    return [md_head, "|" + "---|" * (md_head.count("|") - 1)]


def _median(v: list[float]) -> float:
    return statistics.median(v) if v else float("nan")


def _fmt(v: float, spec: str) -> str:
    return format(v, spec) if v == v else "-"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5, help="runs of each program per dataset (median) [5]")
    ap.add_argument("--rnx2rtkp", default=None, help=f"RTKLIB binary [{DEFAULT_RNX2RTKP}, then PATH]")
    ap.add_argument("--data", type=Path, default=_default_data(), help="folder of dataset folders")
    ap.add_argument("--datasets", default=None, help="comma-separated folder names [all with rtklib/fh.conf]")
    ap.add_argument(
        "--settings",
        choices=("conf", "default"),
        default="conf",
        help="robustrtk's settings: RTKLIB's fh.conf (--rtklib-conf) or its own RTK defaults [conf]",
    )
    ap.add_argument(
        "--no-marginal",
        action="store_true",
        help="skip the short runs that give the cost of one more epoch without start-up",
    )
    args = ap.parse_args(argv)
    if args.repeats < 1:
        ap.error("--repeats must be at least 1")
    exe = find_rnx2rtkp(args.rnx2rtkp)
    if exe is None:
        print(f"rnx2rtkp not found ({args.rnx2rtkp or DEFAULT_RNX2RTKP}, nor on PATH); skipped")
        return 0
    if not args.data.is_dir():
        print(f"shared data not found at {args.data}; skipped")
        return 0
    folders = sorted(p for p in args.data.iterdir() if p.is_dir())
    if args.datasets:
        wanted = {w.strip() for w in args.datasets.split(",") if w.strip()}
        folders = [p for p in folders if p.name in wanted or p.name.split("_")[0] in wanted]
    datasets: list[Dataset] = []
    for folder in folders:
        found = find_dataset(folder)
        if isinstance(found, str):
            if (folder / "rtklib").is_dir():
                print(f"note: {folder.name} skipped: {found}")
            continue
        datasets.append(found)
    if not datasets:
        print(f"no dataset with rtklib/fh.conf and rtklib/fh.pos under {args.data}; skipped")
        return 0

    results: dict[str, dict[str, Runs]] = {}
    floor = Runs()
    with tempfile.TemporaryDirectory() as tmp_s:
        tmp = Path(tmp_s)
        env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        env["PYTHONPATH"] = os.pathsep.join(p for p in (str(SRC), os.environ.get("PYTHONPATH", "")) if p)
        env["PYTHONPYCACHEPREFIX"] = str(tmp / "pycache")
        for ds in datasets:
            res = {"rtklib": Runs(), "robustrtk": Runs()}
            outs = {"rtklib": tmp / f"{ds.name}.rtklib.pos", "robustrtk": tmp / f"{ds.name}.robustrtk.pos"}
            cmds = {
                "rtklib": rtklib_cmd(exe, ds, outs["rtklib"]),
                "robustrtk": robustrtk_cmd(ds, outs["robustrtk"], args.settings),
            }
            envs = {"rtklib": None, "robustrtk": env, "rtklib_short": None, "robustrtk_short": env}
            # warm-up (bytecode, page cache), not recorded
            for prog in res:
                _, _, rc = run_measured(cmds[prog], envs[prog], tmp / "log.txt")
                if prog == "robustrtk" and rc != 0 and args.settings == "conf":
                    tail = (tmp / "log.txt").read_text(errors="replace").strip().splitlines()
                    print(
                        f"note: {ds.name}: robustrtk refused fh.conf "
                        f"({tail[-1] if tail else f'exit {rc}'}); its own RTK defaults instead"
                    )
                    cmds[prog] = robustrtk_cmd(ds, outs[prog], "default")
                    run_measured(cmds[prog], envs[prog], tmp / "log.txt")
            settings = "default" if "--rtklib-conf" not in cmds["robustrtk"] else "conf"
            span = None if args.no_marginal else _span_after_warm_up(cmds["rtklib"], outs["rtklib"], tmp)
            if span is not None:
                end = span_second(*span)
                for prog in ("rtklib", "robustrtk"):
                    short = tmp / f"{ds.name}.{prog}.short.pos"
                    outs[f"{prog}_short"] = short
                    res[f"{prog}_short"] = Runs()
                    cmds[f"{prog}_short"] = (
                        rtklib_cmd(exe, ds, short, end)
                        if prog == "rtklib"
                        else robustrtk_cmd(ds, short, settings, end)
                    )
            run_measured(FLOOR_CMD, env, tmp / "floor.log")  # warm-up
            for _ in range(args.repeats):
                dt, rss, rc = run_measured(FLOOR_CMD, env, tmp / "floor.log")
                if rc == 0:
                    floor.wall_s.append(dt)
                    floor.rss_mib.append(rss)
                for prog in res:  # alternating, so a busy spell hits both
                    r = res[prog]
                    if r.failed:
                        continue
                    dt, rss, rc = run_measured(cmds[prog], envs[prog], tmp / f"{prog}.log")
                    if rc != 0:
                        tail = (tmp / f"{prog}.log").read_text(errors="replace").strip().splitlines()
                        r.failed = f"exit {rc}: {tail[-1] if tail else '(no output)'}"
                        continue
                    r.wall_s.append(dt)
                    r.rss_mib.append(rss)
            for prog, r in res.items():
                if not r.failed and outs[prog].is_file():
                    r.epochs, r.fixed = pos_counts(outs[prog])
            results[ds.name] = res

    print(
        f"python {platform.python_version()}, {os.cpu_count()} CPUs, {platform.machine()}; "
        f"RTKLIB {exe}; median of {args.repeats} alternating whole-process runs each; "
        f"robustrtk settings: {'fh.conf (--rtklib-conf)' if args.settings == 'conf' else 'its RTK defaults'}"
    )
    head = (
        f"{'dataset':<28} {'epochs':>6} {'RTKLIB s':>8} {'ours s':>7} {'ratio':>6} {'RTKLIB ep/s':>11} "
        f"{'ours ep/s':>9} {'RTKLIB MiB':>10} {'ours MiB':>8} {'RTKLIB fix %':>12} {'ours fix %':>10}"
    )
    md = start_table(
        head,
        "| dataset | epochs | RTKLIB wall s | robustrtk wall s | robustrtk / RTKLIB | RTKLIB epochs/s | "
        "robustrtk epochs/s | RTKLIB peak MiB | robustrtk peak MiB | RTKLIB fix % | robustrtk fix % |",
    )
    for name, res in results.items():
        a, b = res["rtklib"], res["robustrtk"]
        ta, tb = _median(a.wall_s), _median(b.wall_s)
        ma, mb = _median(a.rss_mib), _median(b.rss_mib)
        ratio = tb / ta if ta == ta and tb == tb else float("nan")
        eps_a = a.epochs / ta if a.epochs and ta == ta else float("nan")
        eps_b = b.epochs / tb if b.epochs and tb == tb else float("nan")
        epochs = max(a.epochs, b.epochs)  # RTKLIB leaves unsolved epochs out of its .pos
        fa = 100.0 * a.fixed / epochs if a.epochs else float("nan")
        fb = 100.0 * b.fixed / epochs if b.epochs else float("nan")
        print(
            f"{name:<28} {epochs:6d} {_fmt(ta, '8.3f'):>8} {_fmt(tb, '7.3f'):>7} {_fmt(ratio, '6.2f'):>6} "
            f"{_fmt(eps_a, '11.0f'):>11} {_fmt(eps_b, '9.0f'):>9} {_fmt(ma, '10.1f'):>10} "
            f"{_fmt(mb, '8.1f'):>8} {_fmt(fa, '12.1f'):>12} {_fmt(fb, '10.1f'):>10}"
        )
        md.append(
            f"| {name} | {epochs} | {_fmt(ta, '.3f')} | {_fmt(tb, '.3f')} | {_fmt(ratio, '.2f')} | "
            f"{_fmt(eps_a, '.0f')} | {_fmt(eps_b, '.0f')} | {_fmt(ma, '.1f')} | {_fmt(mb, '.1f')} | "
            f"{_fmt(fa, '.1f')} | {_fmt(fb, '.1f')} |"
        )
        for prog, r in res.items():
            if r.failed:
                print(f"note: {prog} failed on {name}: {r.failed}")
    print(
        "ratio = robustrtk / RTKLIB wall time (below 1 = robustrtk faster); fix % = Q=1 epochs of all output"
    )
    marg = [(name, res) for name, res in results.items() if "rtklib_short" in res]
    md2: list[str] = []
    if marg:
        print()
        head2 = (
            f"{'dataset':<28} {'epochs full/short':>17} {'RTKLIB ms/ep':>12} {'ours ms/ep':>10} "
            f"{'ratio':>6} {'RTKLIB fixed s':>14} {'ours fixed s':>12}"
        )
        md2 = start_table(
            head2,
            "| dataset | epochs (full / short) | RTKLIB ms per epoch | robustrtk ms per epoch | "
            "robustrtk / RTKLIB | RTKLIB fixed s | robustrtk fixed s |",
        )
        for name, res in marg:
            ma_s = marginal_s(res["rtklib"], res["rtklib_short"])
            mb_s = marginal_s(res["robustrtk"], res["robustrtk_short"])
            r2 = mb_s / ma_s if ma_s > 0 and mb_s == mb_s else float("nan")
            # start-up: the full run's time less its epochs at the marginal cost
            sa = _median(res["rtklib"].wall_s) - res["rtklib"].epochs * ma_s
            sb = _median(res["robustrtk"].wall_s) - res["robustrtk"].epochs * mb_s
            ep = f"{res['robustrtk'].epochs}/{res['robustrtk_short'].epochs}"
            print(
                f"{name:<28} {ep:>17} {_fmt(1000 * ma_s, '12.2f'):>12} {_fmt(1000 * mb_s, '10.2f'):>10} "
                f"{_fmt(r2, '6.2f'):>6} {_fmt(sa, '14.3f'):>14} {_fmt(sb, '12.3f'):>12}"
            )
            md2.append(
                f"| {name} | {ep} | {_fmt(1000 * ma_s, '.2f')} | {_fmt(1000 * mb_s, '.2f')} | "
                f"{_fmt(r2, '.2f')} | {_fmt(sa, '.3f')} | {_fmt(sb, '.3f')} |"
            )
        print(
            "ms/ep = (median full − median short wall time) / (full − short epochs): one more epoch once "
            "started; fixed s = full wall time less its epochs at that cost (start-up, and reading "
            "whatever the window)"
        )
    md3: list[str] = []
    tf = _median(floor.wall_s)
    if tf == tf:
        print()
        head3 = f"{'dataset':<28} {'floor s':>7} {'RTKLIB s':>8} {'floor/RTKLIB':>12} {'bound ratio':>11}"
        print(
            f'floor: python -c "{FLOOR_CMD[2]}" in this interpreter, median {tf:.3f} s, '
            f"peak {_median(floor.rss_mib):.1f} MiB"
        )
        md3 = start_table(
            head3,
            "| dataset | floor s (python + import numpy) | RTKLIB wall s | floor / RTKLIB | "
            "bound: (floor + epochs · robustrtk ms per epoch) / RTKLIB |",
        )
        for name, res in results.items():
            ta = _median(res["rtklib"].wall_s)
            fr = tf / ta if ta > 0 else float("nan")
            per = (
                marginal_s(res["robustrtk"], res["robustrtk_short"])
                if "robustrtk_short" in res
                else float("nan")
            )
            bound = floor_bound(tf, res["robustrtk"].epochs, per, ta)
            print(
                f"{name:<28} {tf:7.3f} {_fmt(ta, '8.3f'):>8} {_fmt(fr, '12.2f'):>12} "
                f"{_fmt(bound, '11.2f'):>11}"
            )
            md3.append(
                f"| {name} | {tf:.3f} | {_fmt(ta, '.3f')} | {_fmt(fr, '.2f')} | {_fmt(bound, '.2f')} |"
            )
        print(
            "floor/RTKLIB ≥ 1: no numpy program reaches RTKLIB's whole-process time on that file; "
            "bound: the ratio robustrtk would reach with all its start-up but numpy's removed"
        )
    print()
    print("\n".join(md))
    if md2:
        print()
        print("\n".join(md2))
    if md3:
        print()
        print("\n".join(md3))
    return 0


if __name__ == "__main__":
    sys.exit(main())

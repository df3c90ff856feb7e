"""Build the real-data sample of ``robustrtk demo`` (``src/robustrtk/data/mosaicx5_static/``).

Source: the static example of MatRTKLIB (https://github.com/taroz/MatRTKLIB, MIT licence,
Copyright (c) 2023 Taro Suzuki), ``examples/data/static/``: a Septentrio mosaic-X5 rover
and base 0.99 m apart in Nagoya, RINEX 3.04 at 1 Hz, 2024-06-24 08:20:00-08:25:00 GPST.
This script keeps the first ``--seconds`` of both observation files (header unchanged
except TIME OF LAST OBS), compresses them with Hatanaka's CRINEX and gzip (the
``hatanaka`` package), gzips the navigation file, and copies the two position files and
the licence.

Usage::

    git clone https://github.com/taroz/MatRTKLIB   # or any checkout of it
    python docs/make_demo_data.py MatRTKLIB/examples/data/static MatRTKLIB/LICENSE
"""

from __future__ import annotations

import argparse
import gzip
import hashlib
from datetime import datetime, timedelta
from pathlib import Path

import hatanaka

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "src" / "robustrtk" / "data" / "mosaicx5_static"


def _epoch_time(line: str) -> datetime:
    """Time of a RINEX 3 epoch line ``> yyyy mm dd hh mm ss.sssssss flag n``."""
    f = line[1:].split()
    sec = float(f[5])
    return datetime(int(f[0]), int(f[1]), int(f[2]), int(f[3]), int(f[4])) + timedelta(seconds=sec)


def trim_rinex3(text: str, seconds: float) -> str:
    """The header and the epochs of the first ``seconds`` of a RINEX 3 observation file."""
    lines = text.splitlines(keepends=True)
    end = next(i for i, ln in enumerate(lines) if ln[60:73] == "END OF HEADER")
    header, body = lines[: end + 1], lines[end + 1 :]
    starts = [i for i, ln in enumerate(body) if ln.startswith(">")]
    t0 = _epoch_time(body[starts[0]])
    keep_to = len(body)
    last = t0
    for i in starts:
        t = _epoch_time(body[i])
        if (t - t0).total_seconds() >= seconds:
            keep_to = i
            break
        last = t
    for k, ln in enumerate(header):
        if ln[60:77] == "TIME OF LAST OBS ":
            s = f"{last.second + last.microsecond / 1e6:13.7f}"
            head = f"  {last.year:4d}{last.month:6d}{last.day:6d}{last.hour:6d}{last.minute:6d}{s}     GPS"
            header[k] = f"{head:<60}TIME OF LAST OBS\n"
    return "".join(header + body[:keep_to])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("static_dir", type=Path, help="MatRTKLIB examples/data/static")
    ap.add_argument("license", type=Path, help="MatRTKLIB LICENSE")
    ap.add_argument("--seconds", type=float, default=120.0)
    args = ap.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    src = args.static_dir
    for name in ("rover", "base"):
        text = (src / f"{name}.obs").read_text(encoding="ascii")
        trimmed = trim_rinex3(text, args.seconds).encode("ascii")
        (OUT / f"{name}.crx.gz").write_bytes(hatanaka.compress(trimmed, compression="gz"))
    (OUT / "base.nav.gz").write_bytes(gzip.compress((src / "base.nav").read_bytes(), mtime=0))
    for name in ("base_position.txt", "rover_position.txt"):
        (OUT / name).write_bytes((src / name).read_bytes())
    (OUT / "LICENSE").write_bytes(args.license.read_bytes())
    for name in ("rover.obs", "base.obs", "base.nav", "base_position.txt", "rover_position.txt"):
        print(f"source {name} sha256 {hashlib.sha256((src / name).read_bytes()).hexdigest()}")
    for p in sorted(OUT.iterdir()):
        print(f"{p.name} {p.stat().st_size} bytes")


if __name__ == "__main__":
    main()

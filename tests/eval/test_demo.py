"""``robustrtk demo``: the bundled real pair fixes, agrees with its known geometry, and the
demo writes one report whose every image decodes."""

from __future__ import annotations

import base64
import os
import shutil
import struct
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from robustrtk.cli.entry import run
from robustrtk.eval.demo import SAMPLE_DIR, run_real_rtk, sample_files
from robustrtk.io.readers import detect_format
from robustrtk.io.rinex_obs import read_rinex_obs

_CANDIDATES = ("/usr/bin/chromium", shutil.which("chromium"), shutil.which("chromium-browser"))
CHROMIUM = next((p for p in _CANDIDATES if p and os.path.exists(p)), None)


def test_the_sample_is_bundled_with_its_licence() -> None:
    names = {p.name for p in SAMPLE_DIR.iterdir()}
    assert {"rover.crx.gz", "base.crx.gz", "base.nav.gz", "LICENSE", "README.md"} <= names
    assert "MIT License" in (SAMPLE_DIR / "LICENSE").read_text()
    readme = (SAMPLE_DIR / "README.md").read_text()
    assert "https://github.com/taroz/MatRTKLIB" in readme and "MIT" in readme
    # Hatanaka-compressed and gzipped, a few minutes at most
    assert (SAMPLE_DIR / "rover.crx.gz").read_bytes()[:2] == b"\x1f\x8b"
    assert detect_format(SAMPLE_DIR / "rover.crx.gz") == "rinex_obs"
    rover = read_rinex_obs(SAMPLE_DIR / "rover.crx.gz")
    base = read_rinex_obs(SAMPLE_DIR / "base.crx.gz")
    for b in (rover, base):
        span = float(b.t_s[-1] - b.t_s[0])
        assert len(b) == 120 and 60.0 <= span <= 300.0
        assert np.all(np.diff(b.t_s) == 1.0)
    assert sum(p.stat().st_size for p in SAMPLE_DIR.iterdir()) < 1_000_000


def test_the_known_geometry_is_a_one_metre_baseline() -> None:
    f = sample_files()
    # the data's description: 0.99 m between the antennas, both near Nagoya (≈ 6371 km radius)
    assert np.linalg.norm(f.rover_pos_m - f.base_pos_m) == pytest.approx(0.99, abs=0.01)
    assert 6.36e6 < np.linalg.norm(f.base_pos_m) < 6.38e6


@pytest.mark.slow
def test_real_rtk_fixes_and_matches_the_known_baseline(tmp_path: Path) -> None:
    real = run_real_rtk(tmp_path)
    s = real.series.summary()
    assert s.fix_rate >= 0.9 and s.time_to_first_fix_s <= 30.0
    fixed = np.isin(real.series.status, ("fixed", "partial"))
    e = real.enu_err_m[fixed]
    # fixed-epoch errors against the rover's known position: centimetre level (short
    # baseline, same receivers and antennas at both ends)
    assert np.all(np.hypot(e[:, 0], e[:, 1]) < 0.02) and np.all(np.abs(e[:, 2]) < 0.04)
    base = real.files.base_pos_m
    length = np.linalg.norm(real.series.pos_m[fixed] - base, axis=1)
    assert np.all(np.abs(length - np.linalg.norm(real.files.rover_pos_m - base)) < 0.02)
    assert real.pos_path.is_file() and real.diag_path.is_file()


class _Imgs(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.src: list[str] = []
        self.h2: list[str] = []
        self._h2 = False

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag == "img":
            self.src.append(dict(attrs).get("src") or "")
        self._h2 = tag == "h2"

    def handle_data(self, data: str) -> None:
        if self._h2:
            self.h2.append(data)
            self._h2 = False


def _png_ok(data: bytes) -> bool:
    if data[:8] != b"\x89PNG\r\n\x1a\n" or data[-8:-4] != b"IEND":
        return False
    w, h = struct.unpack(">II", data[16:24])
    return w > 0 and h > 0


@pytest.mark.slow
def test_demo_writes_one_report_with_real_and_simulated_parts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "demo"
    assert run(["demo", "--out", str(out), "--quiet"]) == 0
    text = capsys.readouterr().out
    report = out / "report.html"
    assert f"report: {report.resolve()}" in text
    assert "real data (mosaic-X5 pair" in text and "RTK fix rate" in text
    page = _Imgs()
    page.feed(report.read_text(encoding="utf-8"))
    assert len(page.h2) == 3 and page.h2[0].startswith("Real data: RTK")
    assert all(h.startswith("Simulated pseudolite room") for h in page.h2[1:])
    assert len(page.src) >= 12
    for src in page.src:
        assert src.startswith("data:image/png;base64,")
        assert _png_ok(base64.b64decode(src.split(",", 1)[1]))
    if CHROMIUM is None:
        pytest.skip("Chromium is not installed: the page was checked without a browser only")
    probe = tmp_path / "probe.html"
    script = (
        "<script>window.addEventListener('load', () => { const i = Array.from(document.images);"
        " document.body.setAttribute('data-images', i.length + '/' +"
        " i.filter(x => x.complete && x.naturalWidth > 0).length); });</script>"
    )
    probe.write_text(
        report.read_text(encoding="utf-8").replace("</body>", script + "</body>"), encoding="utf-8"
    )
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
           "--no-first-run",
           "--enable-logging=stderr", "--v=0", f"--user-data-dir={tmp_path / 'profile'}",
           "--virtual-time-budget=10000", "--dump-dom", probe.as_uri()]  # fmt: skip
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=180)
    assert r.returncode == 0, r.stderr[-2000:]
    n = len(page.src)
    assert f'data-images="{n}/{n}"' in r.stdout
    assert not [ln for ln in r.stderr.splitlines() if "CONSOLE" in ln]

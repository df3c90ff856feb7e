"""``robustrtk report``: one self-contained HTML file whose every image is a valid PNG.

The pure-Python checks parse the HTML and decode each inlined image; the browser check
loads the page in headless Chromium (when installed) and asserts that every image decoded
and the console stayed silent.
"""

from __future__ import annotations

import base64
import os
import shutil
import struct
import subprocess
import xml.etree.ElementTree as ET
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from robustrtk.cli.main import main
from robustrtk.core import Solution
from robustrtk.geometry.frames import enu2ecef_deg
from robustrtk.io.solution import write_diagnostics_csv, write_pos

T0 = 1316327400.0
LAT, LON, H = 35.342, 139.522, 47.5
_CANDIDATES = ("/usr/bin/chromium", shutil.which("chromium"), shutil.which("chromium-browser"))
CHROMIUM = next((p for p in _CANDIDATES if p and os.path.exists(p)), None)


class _Page(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.imgs: list[dict[str, str | None]] = []
        self.h2: list[str] = []
        self.tags: set[str] = set()
        self._in_h2 = False

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.add(tag)
        if tag == "img":
            self.imgs.append(dict(attrs))
        self._in_h2 = tag == "h2"

    def handle_data(self, data: str) -> None:
        if self._in_h2:
            self.h2.append(data)
            self._in_h2 = False


def png_size(data: bytes) -> tuple[int, int]:
    """Width and height of a PNG; AssertionError unless the signature and IHDR are valid."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG"
    length, kind = struct.unpack(">I4s", data[8:16])
    assert kind == b"IHDR" and length == 13
    w, h = struct.unpack(">II", data[16:24])
    assert data[-8:-4] == b"IEND"
    return int(w), int(h)


def check_html_images(path: Path) -> _Page:
    text = path.read_text(encoding="utf-8")
    page = _Page()
    page.feed(text)
    assert page.imgs, "no image"
    for img in page.imgs:
        src = img.get("src") or ""
        assert src.startswith("data:image/png;base64,"), src[:40]
        data = base64.b64decode(src.split(",", 1)[1], validate=True)
        w, h = png_size(data)
        assert w >= 300 and h >= 200 and len(data) > 5000, (img.get("alt"), w, h, len(data))
        assert img.get("alt")
    assert "http://" not in text and "https://" not in text  # nothing to fetch
    assert "<script" not in text
    return page


def _solutions(seed: int, first_fix: int) -> list[Solution]:
    rng = np.random.default_rng(seed)
    out = []
    for k in range(120):
        enu = np.array([10 * np.cos(k / 20), 10 * np.sin(k / 20), 0.0])
        st = "single" if k < 3 else ("float" if k < first_fix else "fixed")
        noise = {"single": 1.0, "float": 0.1, "fixed": 0.01}[st]
        pos = enu2ecef_deg(enu + rng.normal(0, noise, 3), LAT, LON, H)
        out.append(Solution(T0 + k, pos, np.eye(3) * noise**2, st, n_used=8 + k % 3, ratio=5.0))
    return out


def _truth(tmp_path: Path) -> Path:
    p = tmp_path / "truth.pos"
    track = [np.array([10 * np.cos(k / 20), 10 * np.sin(k / 20), 0.0]) for k in range(120)]
    write_pos(
        [
            Solution(T0 + k, enu2ecef_deg(e, LAT, LON, H), np.eye(3) * 1e-6, "fixed")
            for k, e in enumerate(track)
        ],
        p,
    )
    return p


def _diag(tmp_path: Path) -> Path:
    rng = np.random.default_rng(3)
    rows = []
    for k in range(120):
        for sat in ("G05", "G13", "E26", "J02"):
            r = float(rng.normal(0, 0.005))
            situation = 3 if (sat == "G13" and k % 40 == 7) else (2 if k % 17 == 0 else 1)
            factor = float("inf") if situation == 3 else (4.0 if situation == 2 else 1.0)
            rows.append((T0 + k, f"{sat}:L1-G15:L1", r, r, r / 0.005, r / 0.005, factor, situation))
    p = tmp_path / "diag.csv"
    write_diagnostics_csv(rows, p)
    return p


@pytest.fixture(scope="module")
def synthetic_report(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path]:
    tmp = tmp_path_factory.mktemp("report")
    write_pos(_solutions(1, 20), tmp / "ours.pos")
    write_pos(_solutions(2, 45), tmp / "theirs.pos")
    out = tmp / "report.html"
    r = CliRunner().invoke(main, [
        "report", str(tmp / "ours.pos"), "--truth", str(_truth(tmp)), "--diagnostics", str(_diag(tmp)),
        "--vs", str(tmp / "theirs.pos"), "--label", "robustrtk", "--label", "rtklib", "--out", str(out),
        "--kml", str(tmp / "t.kml"), "--gpx", str(tmp / "t.gpx"),
    ])  # fmt: skip
    assert r.exit_code == 0, r.output
    assert f"wrote {out}" in r.output
    return out, tmp / "t.kml", tmp / "t.gpx"


def test_report_images_are_valid_pngs(synthetic_report: tuple[Path, Path, Path]) -> None:
    page = check_html_images(synthetic_report[0])
    assert len(page.imgs) == 5  # track, timeline, errors, difference, residuals
    heads = " | ".join(page.h2)
    for section in ("Summary", "Ground track", "Errors against the truth", "robustrtk minus rtklib",
                    "Residuals and robust factors"):  # fmt: skip
        assert section in heads


def test_report_tables(synthetic_report: tuple[Path, Path, Path]) -> None:
    text = synthetic_report[0].read_text(encoding="utf-8")
    # fix rate and time to first fix of both solutions: first fix at epoch 20 and 45 of 120
    cells = text.replace('<td class="n">', ">")
    assert ">83.3<" in cells and ">62.5<" in cells
    assert ">20.0<" in cells and ">45.0<" in cells
    for head in ("RMS E", "95% |U|", "max |N|", "H 95%", "down-weighted %", "rejected %"):
        assert head in text
    for group in (">fixed<", ">float<", ">single<", ">all<", ">G13<"):
        assert group in text


def test_report_tracks_parse(synthetic_report: tuple[Path, Path, Path]) -> None:
    _, kml, gpx = synthetic_report
    assert ET.parse(kml).getroot().tag.endswith("kml")
    assert ET.parse(gpx).getroot().tag.endswith("gpx")


def test_report_without_truth_or_extras(tmp_path: Path) -> None:
    write_pos(_solutions(1, 20), tmp_path / "a.pos")
    r = CliRunner().invoke(main, ["report", str(tmp_path / "a.pos"), "--out", str(tmp_path / "a.html")])
    assert r.exit_code == 0, r.output
    page = check_html_images(tmp_path / "a.html")
    assert any("median" in h for h in page.h2)


@pytest.mark.parametrize(
    "args, match",
    [
        (["--out", "x.txt"], "--out"),
        (["--out", "x.html", "--obs", "rover.obs"], "--obs and --nav"),
        (["--out", "x.html", "--truth-window", "0,1"], "--truth-window"),
        (["--out", "x.html", "--kml", "t.gpx"], "--kml"),
    ],
)
def test_report_bad_input_is_one_line(tmp_path: Path, args: list[str], match: str) -> None:
    write_pos(_solutions(1, 20), tmp_path / "a.pos")
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        r = CliRunner().invoke(main, ["report", "a.pos", *args])
    finally:
        os.chdir(cwd)
    assert r.exit_code == 2 and match in r.output and len(r.output.strip().splitlines()) == 1, r.output


def test_report_missing_solution_is_one_line(tmp_path: Path) -> None:
    r = CliRunner().invoke(main, ["report", str(tmp_path / "nope.pos"), "--out", str(tmp_path / "x.html")])
    assert r.exit_code == 2 and len(r.output.strip().splitlines()) == 1 and "nope.pos" in r.output
    assert not (tmp_path / "x.html").exists()


# ----------------------------------------------------------------------------- a real browser
_PROBE = """<script>
window.addEventListener('error', e => document.body.setAttribute('data-error', String(e.message)));
window.addEventListener('load', () => {
  // the load event fires once every image has loaded or failed
  const imgs = Array.from(document.images);
  const ok = imgs.filter(i => i.complete && i.naturalWidth > 0 && i.naturalHeight > 0).length;
  document.body.setAttribute('data-images', imgs.length + '/' + ok);
});
</script>"""


def browser_check(html_path: Path, tmp_path: Path) -> tuple[int, int, str]:
    """Load a copy of the page with a probe script in headless Chromium.

    Returns
    -------
    n_images, n_decoded, console : int, int, str
        The console lines Chromium logged (empty when silent).
    """
    assert CHROMIUM is not None
    probe = tmp_path / f"probe_{html_path.name}"
    probe.write_text(
        html_path.read_text(encoding="utf-8").replace("</body>", _PROBE + "</body>"), encoding="utf-8"
    )
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
           "--disable-dev-shm-usage", "--no-first-run", "--enable-logging=stderr", "--v=0",
           f"--user-data-dir={tmp_path / 'chromium-profile'}", "--virtual-time-budget=10000", "--dump-dom",
           probe.as_uri()]  # fmt: skip
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    dom = r.stdout
    assert 'data-error="' not in dom, dom[dom.find("data-error") : dom.find("data-error") + 200]
    key = 'data-images="'
    assert key in dom, "the probe did not run: " + r.stderr[-1000:]
    n, ok = (int(v) for v in dom[dom.index(key) + len(key) :].split('"', 1)[0].split("/"))
    console = "\n".join(line for line in r.stderr.splitlines() if "CONSOLE" in line)
    return n, ok, console


@pytest.mark.skipif(CHROMIUM is None, reason="Chromium is not installed (apt-get install chromium)")
def test_report_in_headless_chromium(synthetic_report: tuple[Path, Path, Path], tmp_path: Path) -> None:
    n, ok, console = browser_check(synthetic_report[0], tmp_path)
    assert n == 5 and ok == n
    assert console == ""


# ----------------------------------------------------------------------------- shared datasets
# robustrtk report on each shared dataset's RTK solution (solve --rtklib-conf rtklib/fh.conf,
# with diagnostics) against RTKLIB's fh.pos, with the truth, satellites and sky plot.
#: dataset -> rover, base, nav, truth, truth window
DATASETS = {
    "geonet_0759_3040_static_3km": ("07590920.05o", "30400920.05o", "07590920.05n", "truth_and_base.txt",
                                    None),
    "mosaicx5_static_1m": ("rover.obs", "base.obs", "base.nav", "rover_position.txt", None),
    "kamakura_kinematic_5km": ("SEPT265G.21O", "3034265G.21O", "SEPT2650.21P", "truth_and_base.txt",
                               "06:30:00,06:30:34"),
}  # fmt: skip


@pytest.fixture(scope="module", params=list(DATASETS))
def shared_report(
    request: pytest.FixtureRequest, shared_data: Path, tmp_path_factory: pytest.TempPathFactory
) -> Path:
    name = request.param
    rover, base, nav, truth, window = DATASETS[name]
    d = shared_data / name
    tmp = tmp_path_factory.mktemp(name)
    runner = CliRunner()
    r = runner.invoke(main, [
        "solve", str(d / rover), "--base", str(d / base), "--nav", str(d / nav), "--rtklib-conf",
        str(d / "rtklib" / "fh.conf"), "--out", str(tmp / "rtk.pos"), "--diagnostics", str(tmp / "diag.csv"),
        "--quiet",
    ])  # fmt: skip
    assert r.exit_code == 0, r.output
    out = tmp / "report.html"
    args = [
        "report", str(tmp / "rtk.pos"), "--vs", str(d / "rtklib" / "fh.pos"), "--label", "robustrtk",
        "--label", "RTKLIB fh", "--truth", str(d / truth), "--diagnostics", str(tmp / "diag.csv"),
        "--obs", str(d / rover), "--nav", str(d / nav), "--range", "0.5", "--out", str(out),
    ]  # fmt: skip
    if window:
        args += ["--truth-window", window]
    r = runner.invoke(main, args)
    assert r.exit_code == 0, r.output
    return out


def test_shared_report_images(shared_report: Path) -> None:
    page = check_html_images(shared_report)
    # track, timeline, errors, difference, satellites, sky, residuals
    assert len(page.imgs) == 7
    assert "Satellites" in page.h2 and "Summary" in page.h2


@pytest.mark.skipif(CHROMIUM is None, reason="Chromium is not installed (apt-get install chromium)")
def test_shared_report_in_headless_chromium(shared_report: Path, tmp_path: Path) -> None:
    n, ok, console = browser_check(shared_report, tmp_path)
    assert n == 7 and ok == 7
    assert console == ""

"""RTKLIB .conf files as settings: the shared datasets' fix-and-hold runs equal their flags."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robustrtk.cli.settings import resolve_config, rtklib_base_pos
from robustrtk.core import InputError
from robustrtk.geometry.frames import geodetic2ecef_deg
from robustrtk.pipeline.rtklib_conf import parse_rtklib_conf, read_rtklib_conf

DATASETS = ("kamakura_kinematic_5km", "geonet_0759_3040_static_3km", "mosaicx5_static_1m")

#: The flags that say what each dataset's ``rtklib/fh.conf`` says.
_COMMON = dict(
    mode="rtk", glonass_ar="auto", dynamics="kinematic", freqs="L1+L2", elev_mask_deg=15.0, snr_mask_dbhz=0.0,
    tropo="saastamoinen", instantaneous=False, hold=True, ratio=3.0, ar_lock_epochs=5, ar_elev_mask_deg=25.0,
    hold_min_fix=20, hold_sigma_cyc=0.1**0.5, slip="lli+gf", gf_threshold_m=0.05, weighting="elevation",
    phase_sigma_m=(2 * 0.005**2) ** 0.5, code_sigma_m=300 * (2 * 0.005**2) ** 0.5,
)  # fmt: skip
FLAGS = {
    "kamakura_kinematic_5km": {**_COMMON, "kinematic_model": "constant-velocity", "sigma_acc_m_s2": 3.0,
                               "systems": "GEJ"},
    "geonet_0759_3040_static_3km": {**_COMMON, "kinematic_model": "random-walk", "systems": "G"},
    "mosaicx5_static_1m": {**_COMMON, "kinematic_model": "constant-velocity", "sigma_acc_m_s2": 3.0,
                           "systems": "GRECJ"},
}  # fmt: skip
#: Keys of the files with no equivalent here, named in the warning.
NO_EQUIVALENT = {
    "pos2-bdsarmode", "pos2-arfilter", "pos2-arthres1", "pos2-arthres2", "pos2-arthres3",
    "pos2-arthres4", "pos2-gainholdamb", "pos2-minfixsats", "pos2-minholdsats", "pos2-mindropsats",
    "pos2-armaxiter", "pos2-aroutcnt", "pos2-syncsol", "pos2-rejionno", "pos2-rejcode",
    "pos2-niter", "stats-errdoppler", "stats-snrmax", "stats-stdbias", "stats-stdiono", "stats-stdtrop",
    "stats-prnaccelv", "stats-prnbias", "stats-prniono", "stats-prntrop", "ant2-maxaveep",
    "ant2-initrst", "misc-timeinterp",
}  # fmt: skip


def _base(root: Path, name: str) -> np.ndarray:
    d = root / name
    if name == "mosaicx5_static_1m":
        return geodetic2ecef_deg(35.134707705, 136.977577939, 104.853)
    for line in (d / "truth_and_base.txt").read_text().splitlines():
        if line.startswith("base_xyz"):
            return np.array([float(v) for v in line.split()[1:4]])
    raise AssertionError("no base_xyz")


@pytest.mark.parametrize("name", DATASETS)
def test_fh_conf_equals_its_flags(shared_data: Path, name: str) -> None:
    conf_path = shared_data / name / "rtklib" / "fh.conf"
    warnings: list[str] = []
    from_conf = resolve_config(None, "gnss", None, {}, warn=warnings.append, rtklib_conf=conf_path)
    flags = dict(FLAGS[name])
    mode = flags.pop("mode")
    from_flags = resolve_config(mode, "gnss", None, flags, warn=None)
    assert from_conf == from_flags
    assert len(warnings) == 1 and str(conf_path) in warnings[0]
    conf = read_rtklib_conf(conf_path)
    ignored = set(conf.ignored_keys)
    expected = set(NO_EQUIVALENT)
    if name == "geonet_0759_3040_static_3km":
        expected.add("stats-prnaccelh")  # pos1-dynamics off: no acceleration noise
    assert ignored == expected
    for key in ignored:
        assert key in warnings[0]
    if name == "mosaicx5_static_1m":  # navsys 61 includes GLONASS: kept, as RTKLIB does
        assert from_conf.gnss.systems == "GRECJ" and "read as auto" in warnings[0] and conf.notes
    else:  # no GLONASS: no note on it
        assert not conf.notes
    # every key of the file is either read or ignored
    keys = {ln.split("=", 1)[0].strip() for ln in conf_path.read_text().splitlines() if "=" in ln}
    assert set(conf.used) | ignored == keys and not set(conf.used) & ignored
    pos = rtklib_base_pos(conf_path, "rtk")
    assert pos is not None
    np.testing.assert_allclose([float(v) for v in pos.split(",")], _base(shared_data, name), atol=1e-3)


def test_flags_and_toml_win(tmp_path: Path) -> None:
    conf = tmp_path / "a.conf"
    conf.write_text("pos1-posmode =kinematic\npos2-arthres =2.5\npos1-elmask =10\n")
    toml = tmp_path / "a.toml"
    toml.write_text("elev_mask_deg = 12.0\n")
    cfg = resolve_config(None, "gnss", toml, {"ratio": 4.0}, warn=None, rtklib_conf=conf)
    assert (cfg.mode, cfg.ar.ratio, cfg.gnss.elev_mask_deg) == ("rtk", 4.0, 12.0)
    cfg = resolve_config("dgnss", "gnss", None, {}, warn=None, rtklib_conf=conf)
    assert cfg.mode == "dgnss" and cfg.gnss.elev_mask_deg == 10.0


def test_numbers_for_enums_and_mode_mapping() -> None:
    c = parse_rtklib_conf("pos1-posmode = 1\npos1-frequency = 3\npos2-armode = 2\npos1-navsys = 9\n")
    assert c.settings["mode"] == "dgnss" and c.settings["freqs"] == "L1+L2+L5"
    assert c.settings["systems"] == "GE"
    assert "pos2-armode" in c.ignored_keys  # no AR in dgnss
    c = parse_rtklib_conf("pos1-posmode =static\npos2-armode =instantaneous\npos2-arlockcnt =3\n")
    assert c.settings["dynamics"] == "static" and c.settings["instantaneous"] is True
    warnings: list[str] = []
    resolve_config(None, "gnss", None, {}, warn=warnings.append, rtklib_conf=None)
    assert not warnings


def test_instantaneous_lists_idle_keys(tmp_path: Path) -> None:
    conf = tmp_path / "inst.conf"
    conf.write_text("pos1-posmode =kinematic\npos2-armode =instantaneous\npos2-arlockcnt =5\n")
    warnings: list[str] = []
    cfg = resolve_config(None, "gnss", None, {}, warn=warnings.append, rtklib_conf=conf)
    assert cfg.ar.instantaneous
    assert len(warnings) == 1 and "pos2-arlockcnt" in warnings[0]


def test_snr_mask_and_llh_base() -> None:
    text = (
        "pos1-posmode =kinematic\npos1-frequency =l1+l2\npos1-snrmask_r =on\npos1-snrmask_b =off\n"
        "pos1-snrmask_L1 =35,35,30,35,35,35,35,35,35\npos1-snrmask_L2 =32,35,35,35,35,35,35,35,35\n"
        "pos1-snrmask_L5 =10,10,10,10,10,10,10,10,10\n"
        "ant2-postype =llh\nant2-pos1 =35.0\nant2-pos2 =139.0\nant2-pos3 =50.0\n"
    )
    c = parse_rtklib_conf(text)
    assert c.settings["snr_mask_dbhz"] == 30.0  # L5 not used
    np.testing.assert_allclose(c.base_pos_m, geodetic2ecef_deg(35.0, 139.0, 50.0))


def test_single_base_is_the_moving_base_and_rinexhead_the_header() -> None:
    c = parse_rtklib_conf("pos1-posmode =kinematic\nant2-postype =single\nant2-pos1 =0\n")
    assert c.settings["base_position"] == "moving" and c.base_pos_m is None
    assert "ant2-postype" in c.used and "ant2-pos1" in c.used and not c.ignored
    c = parse_rtklib_conf("pos1-posmode =kinematic\nant2-postype =rinexhead\n")
    assert "base_position" not in c.settings and c.base_pos_m is None
    c = parse_rtklib_conf("pos1-posmode =kinematic\nant2-postype =posfile\n")
    assert "base_position" not in c.settings
    assert [i for i in c.ignored if i.startswith("ant2-postype (base position type posfile")]


@pytest.mark.parametrize(
    "text, match",
    [
        ("pos1-posmode =ppp-kine\n", "pos1-posmode"),
        ("pos1-posmode =walking\n", "expected one of"),
        ("pos1-elmask =high\n", "expected a number"),
        ("ant2-postype =xyz\nant2-pos1 =1\n", "ant2-pos"),
    ],
)
def test_bad_values_name_key_and_line(text: str, match: str) -> None:
    with pytest.raises(InputError, match=match) as exc:
        parse_rtklib_conf(text, "x.conf")
    assert exc.value.path == "x.conf" and exc.value.line is not None


def test_pseudolite_input_refuses_rtklib_conf(tmp_path: Path) -> None:
    conf = tmp_path / "a.conf"
    conf.write_text("pos1-posmode =kinematic\n")
    with pytest.raises(InputError, match="RINEX"):
        resolve_config(None, "pseudolite", None, {}, warn=None, rtklib_conf=conf)


def test_solve_with_rtklib_conf_equals_flags(shared_data: Path, tmp_path: Path) -> None:
    """The same solution file from --rtklib-conf as from the equivalent flags (geonet, 120 epochs)."""
    from click.testing import CliRunner

    from robustrtk.cli.main import main
    from robustrtk.cli.options import format_value
    from robustrtk.pipeline.config import LEAVES

    name = "geonet_0759_3040_static_3km"
    d = shared_data / name
    files = [str(d / "07590920.05o"), "--base", str(d / "30400920.05o"), "--nav", str(d / "07590920.05n")]
    runner = CliRunner()
    a = runner.invoke(main, ["solve", *files, "--rtklib-conf", str(d / "rtklib" / "fh.conf"), "--quiet",
                             "--out", str(tmp_path / "a.pos")])  # fmt: skip
    assert a.exit_code == 0, a.output
    assert "RTKLIB keys ignored" in a.output and "pos2-bdsarmode" in a.output
    flags: list[str] = []
    for key, val in FLAGS[name].items():
        leaf = LEAVES[key]
        if isinstance(val, bool):
            flags.append(leaf.flag if val else "--no-" + leaf.flag[2:])
        else:
            flags += [leaf.flag, format_value(val) if not isinstance(val, float) else repr(val)]
    base = ",".join(f"{v:.4f}" for v in _base(shared_data, name))
    b = runner.invoke(main, ["solve", *files, *flags, "--base-pos", base, "--quiet", "--out",
                             str(tmp_path / "b.pos")])  # fmt: skip
    assert b.exit_code == 0, b.output
    assert (tmp_path / "a.pos").read_text() == (tmp_path / "b.pos").read_text()

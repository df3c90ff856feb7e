"""``solve`` options: generated from the config tree, layered preset → TOML → flags, and
every option either acts in the chosen mode or is refused with a one-line error."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click
import pytest
from click.testing import CliRunner

from robustrtk.cli.main import main, solve
from robustrtk.cli.options import SOLVE_LEAVES, defaults_text, help_text
from robustrtk.cli.settings import (
    OPTION_TARGETS,
    TARGETS,
    config_toml,
    inactive_reason,
    resolve_config,
    target_label,
)
from robustrtk.core import InputError
from robustrtk.pipeline.config import LEAVES, PRESETS, Config, preset, read_config_dict

OBS = {"pseudolite": "obs.csv", "gnss": "rover.obs"}
#: solve options that are not config leaves (their targets: OPTION_TARGETS, or every mode)
EVERY_MODE = ("--config", "--out", "--format", "--quiet", "--show-config", "--help-all")


def _invoke(args: list[str]) -> Any:
    return CliRunner().invoke(main, ["solve", *args])


def _show(kind: str, mode: str, *extra: str) -> Any:
    return _invoke([OBS[kind], "--mode", mode, "--show-config", *extra])


def _is_one_line_error(r: Any) -> bool:
    text = r.output.strip()
    return r.exit_code == 2 and text.startswith("error: ") and "\n" not in text


def _other_values(key: str, cfg: Config) -> list[Any]:
    """Values of leaf ``key`` other than its value in ``cfg`` (valid where possible)."""
    leaf = LEAVES[key]
    cur = cfg.get(key)
    if leaf.choices:
        return [c for c in leaf.choices if c != cur]
    if leaf.base_type is bool:
        return [not cur]
    special = {"reference": "PL1", "systems": "G", "freqs": "L1", "slip": "lli", "base": "b2", "rover": "r2",
               "k0": 1.0, "k1": 10.0, "adaptive_c0": 1.5, "adaptive_c1": 3.0, "prefit_k0": 2.0,
               "prefit_k1": 8.0, "time_start": "00:00:30", "time_end": "2021/09/22 06:30:34",
               "code_bias_sigma_m": 1.0, "code_bias_tau_s": 60.0}  # fmt: skip
    if cur is None or leaf.base_type is str:
        return [special[key]]
    if leaf.base_type is int:
        return [cur + 1]
    return [cur * 2 if cur > 0 else 1.0]


def _flag_args(key: str, value: Any) -> list[str]:
    leaf = LEAVES[key]
    if leaf.base_type is bool:
        return [leaf.flag if value else "--no-" + leaf.flag[2:]]
    return [leaf.flag, str(value)]


# ----------------------------------------------------------------------------- generated options
def test_solve_has_one_option_per_leaf_with_its_flag_choices_and_no_default() -> None:
    by_name = {p.name: p for p in solve.params}
    assert set(by_name) >= set(SOLVE_LEAVES) and not {k for k in LEAVES if k not in SOLVE_LEAVES} & set(
        by_name
    )
    for key, leaf in SOLVE_LEAVES.items():
        opt = by_name[key]
        assert isinstance(opt, click.Option)
        assert leaf.flag in opt.opts, key
        assert opt.default is None, key
        if leaf.choices:
            assert isinstance(opt.type, click.Choice) and tuple(opt.type.choices) == leaf.choices
        elif leaf.base_type is bool:
            assert opt.is_flag and opt.secondary_opts == ["--no-" + leaf.flag[2:]]
        assert opt.help is not None and opt.help.startswith(leaf.help)
    assert "--smooth" in by_name["smoother"].opts  # compatibility alias


def test_help_shows_the_presets_defaults() -> None:
    assert defaults_text("code_sigma_m") == "dpl 0.25; rtk 0.25; spp 3; dgnss 0.3; rtk (RINEX) 0.3"
    assert defaults_text("ratio") == "3"  # all presets agree
    assert help_text(LEAVES["ratio"]).endswith("(rtk, rtk (RINEX)) [3]")
    r = CliRunner().invoke(main, ["solve", "--help"])
    assert r.exit_code == 0 and "--code-sigma" in r.output and "--no-hold" in r.output
    # in words, per mode: not "[dpl 0.25; rtk 0.25; ...]"
    text = " ".join(r.output.split())
    assert "default 0.25 for pseudolite dpl and rtk; 3 for spp; 0.3 for RINEX dgnss and rtk" in text


def test_short_help_is_grouped_and_help_all_lists_every_flag() -> None:
    r = CliRunner().invoke(main, ["solve", "--help"])
    assert r.exit_code == 0 and len(r.output.splitlines()) <= 80
    heads = [ln for ln in r.output.splitlines() if ln and not ln.startswith(" ")]
    assert heads[1:5] == ["Input:", "Mode:", "Output:", "Settings most often changed (defaults per mode):"]
    for kind in (".pos", ".csv", ".nmea", ".kml", ".gpx"):
        assert kind in r.output
    assert "--format [pos|csv|nmea|kml|gpx]" in r.output and "--help-all" in r.output
    full = CliRunner().invoke(main, ["solve", "--help-all"])
    assert full.exit_code == 0
    for leaf in SOLVE_LEAVES.values():
        assert leaf.flag in full.output, leaf.flag
    for p in solve.params:
        if isinstance(p, click.Option) and p.help:
            assert p.opts[0] in full.output, p.opts
    assert "Ambiguity resolution [ar]:" in full.output and "Single-point positioning [spp]:" in full.output


# ----------------------------------------------------------------------------- layering
def test_resolve_config_layers_preset_file_then_flags(tmp_path: Path) -> None:
    toml = tmp_path / "c.toml"
    toml.write_text('[measurement]\ncode_sigma_m = 0.7\ntropo = "off"\n[ar]\nratio = 2.0\n', encoding="utf-8")
    cfg = resolve_config("rtk", "gnss", toml, {"ratio": 2.5}, warn=None)
    assert cfg == preset("rtk", "gnss").updated(code_sigma_m=0.7, tropo="off", ratio=2.5)
    assert resolve_config(None, "gnss", None, {}) == PRESETS[("gnss", "spp")]
    assert resolve_config(None, "pseudolite", None, {}) == PRESETS[("pseudolite", "dpl")]
    # the file may choose the mode; --mode wins over it
    (tmp_path / "m.toml").write_text('mode = "rtk"\n')
    assert resolve_config(None, "pseudolite", tmp_path / "m.toml", {}).mode == "rtk"
    assert resolve_config("dpl", "pseudolite", tmp_path / "m.toml", {}).mode == "dpl"


def test_file_keys_that_do_not_act_are_a_warning_flags_an_error(tmp_path: Path) -> None:
    toml = tmp_path / "c.toml"
    toml.write_text('ratio = 2.0\nar = "lambda"\ncode_sigma_m = 2.0\n', encoding="utf-8")
    seen: list[str] = []
    cfg = resolve_config("spp", "gnss", toml, {}, warn=seen.append)
    assert cfg.measurement.code_sigma_m == 2.0
    assert len(seen) == 1 and "ratio" in seen[0] and "ar" in seen[0] and "code_sigma_m" not in seen[0]
    with pytest.raises(InputError, match="--ratio: does not apply to mode spp"):
        resolve_config("spp", "gnss", None, {"ratio": 2.0})
    r = _invoke(["rover.obs", "--config", str(toml), "--show-config"])
    assert r.exit_code == 0 and "warning: " in r.stderr and "ratio" in r.stderr


@pytest.mark.parametrize(
    "args, expect",
    [
        (["rover.obs", "--ar", "lambda", "--mode", "spp"], "--ar: does not apply to mode spp"),
        (["rover.obs", "--smooth"], "--smoother: acts only with a Kalman SPP"),
        (["rover.obs", "--site", "s.toml"], "--site: does not apply to mode spp"),
        (["rover.obs", "--base", "b.obs", "--mode", "spp"], "--base: does not apply to mode spp"),
        (
            ["rover.obs", "--filter", "lsq", "--mode", "dgnss"],
            "--filter: lsq (least squares) is for mode spp",
        ),
        (["rover.obs", "--mode", "dpl"], "RINEX input takes spp, dgnss or rtk"),
        (["obs.csv", "--mode", "spp"], "pseudolite tables take dpl or rtk"),
        (["obs.csv", "--elev-mask", "10"], "--elev-mask: does not apply to mode dpl"),
        (
            ["rover.obs", "--mode", "rtk", "--base-name", "b"],
            "--base-name: does not apply to mode rtk (RINEX)",
        ),
        (["rover.obs", "--kalman", "--filter", "lsq"], "--kalman: conflicts with --filter lsq"),
        (["obs.csv", "--kalman"], "--kalman: does not apply to mode dpl"),
        (["obs.csv", "--mode", "rtk", "--ar", "off", "--ratio", "2"], "--ratio: acts only with ambiguity"),
        (["obs.csv", "--mode", "rtk", "--prior-sigma", "0.1"], "--prior-sigma: acts only with the prior AR"),
        (
            ["obs.csv", "--mode", "rtk", "--ar-scheme", "prior", "--hold"],
            "--hold: acts only with continuous ambiguity resolution",
        ),
        (["rover.obs", "--code-sigma", "-1"], "--code-sigma: expected a finite positive number"),
    ],
)
def test_refused_flags_are_one_line_errors(args: list[str], expect: str) -> None:
    r = _invoke([*args, "--show-config"])
    assert _is_one_line_error(r), r.output
    assert expect in r.output


# ----------------------------------------------------------------------------- every option, every mode
@pytest.mark.parametrize("target", TARGETS, ids=[target_label(*t) for t in TARGETS])
def test_every_config_flag_acts_or_is_refused(target: tuple[str, str]) -> None:
    kind, mode = target
    base = _show(kind, mode)
    assert base.exit_code == 0, base.output
    assert base.stdout == config_toml(
        PRESETS[target], f"robustrtk solve: {kind} input, mode {target_label(*target)}", kind
    )
    for key in SOLVE_LEAVES:
        for value in _other_values(key, PRESETS[target]):
            r = _show(kind, mode, *_flag_args(key, value))
            if r.exit_code == 0:
                assert r.stdout != base.stdout, (key, value)
                cfg = resolve_config(mode, kind, None, {key: value}) if key != "mode" else preset(value, kind)
                assert cfg.get(key) == value and inactive_reason(key, cfg, kind) is None, (key, value)
            else:
                assert _is_one_line_error(r), (key, value, r.output)
                assert LEAVES[key].flag in r.output, (key, value, r.output)


@pytest.mark.parametrize("target", TARGETS, ids=[target_label(*t) for t in TARGETS])
def test_every_other_option_acts_or_is_refused(target: tuple[str, str], tmp_path: Path) -> None:
    kind, mode = target
    toml = tmp_path / "c.toml"
    toml.write_text("reinit_epochs = 7\n", encoding="utf-8")
    values = {"--site": "site.toml", "--nav": "n.nav", "--base": "b.obs", "--base-pos": "1,2,3",
              "--diagnostics": "d.csv", "--kalman": None, "--profile": "phone"}  # fmt: skip
    base = _show(kind, mode)
    for opt, value in values.items():
        r = _show(kind, mode, opt, *([] if value is None else [value]))
        if target in OPTION_TARGETS[opt]:
            # acting: accepted (what each does is checked end to end in test_cli)
            assert r.exit_code == 0, (opt, r.output)
        else:
            assert _is_one_line_error(r) and opt in r.output, (opt, r.output)
    kalman = _show(kind, mode, "--kalman")
    if mode == "spp":
        assert kalman.exit_code == 0 and kalman.stdout != base.stdout and 'filter = "ekf"' in kalman.stdout
    r = _show(kind, mode, "--config", str(toml))
    if mode == "spp":  # reinit_epochs acts in the Kalman SPP only: listed in a warning
        assert r.exit_code == 0 and "reinit_epochs" in r.stderr
    else:
        assert r.exit_code == 0 and r.stdout != base.stdout and "reinit_epochs = 7" in r.stdout
    for extra in (["--quiet"], ["--format", "csv"]):
        assert _show(kind, mode, *extra).exit_code == 0


def test_every_solve_option_is_covered_by_the_walks() -> None:
    covered = set(SOLVE_LEAVES) | {"obs"}
    names = {p.name: p for p in solve.params}
    other = {n for n in names if n not in covered}
    flags = {next(o for o in names[n].opts if o.startswith("--")) for n in other}
    assert flags == set(OPTION_TARGETS) | set(EVERY_MODE), flags


# ----------------------------------------------------------------------------- TOML out and back
@pytest.mark.parametrize("target", TARGETS, ids=[target_label(*t) for t in TARGETS])
def test_show_config_reads_back_equal(target: tuple[str, str], tmp_path: Path) -> None:
    r = _show(*target, "--config", str(_write(tmp_path, "ukf_alpha = 0.5\nk0 = 1.2\n")))
    assert r.exit_code == 0, r.output
    out = tmp_path / "shown.toml"
    out.write_text(r.stdout, encoding="utf-8")
    assert Config().updated(**read_config_dict(out)) == resolve_config(
        target[1], target[0], tmp_path / "c.toml", {}, warn=None
    )


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "c.toml"
    p.write_text(text, encoding="utf-8")
    return p


def test_out_is_required_to_solve() -> None:
    r = _invoke(["rover.obs", "--nav", "n.nav"])
    assert _is_one_line_error(r) and "--out" in r.output


# ----------------------------------------------------------------------------- end to end (SPP)
@pytest.fixture(scope="module")
def geonet(shared_data: Path) -> Path:
    d = shared_data / "geonet_0759_3040_static_3km"
    if not d.is_dir():
        pytest.skip(f"dataset not found at {d}")
    return d


def test_spp_flags_and_config_change_the_result(geonet: Path, tmp_path: Path) -> None:
    toml = _write(tmp_path, "[measurement]\ncode_sigma_m = 1.5\n")

    def run(name: str, *extra: str) -> bytes:
        out = tmp_path / f"{name}.csv"
        args = [str(geonet / "07590920.05o"), "--nav", str(geonet / "07590920.05n"), "--mode", "spp"]
        r = _invoke([*args, "--quiet", "--out", str(out), *extra])
        assert r.exit_code == 0, r.output
        return out.read_bytes()

    default = run("default")
    assert len(default.splitlines()) > 100
    runs = {
        "ekf": run("ekf", "--filter", "ekf"),
        "ukf": run("ukf", "--filter", "ukf"),
        "sigma": run("sigma", "--code-sigma", "1.0"),
        "toml": run("toml", "--config", str(toml)),
    }
    for name, text in runs.items():
        assert text != default, name
    assert runs["ekf"] != runs["ukf"]
    assert run("kalman", "--kalman") == runs["ekf"]


def test_config_toml_escapes_strings() -> None:
    import tomllib

    odd = 'a"b\\c\nd\x7fe\té'
    cfg = preset("dpl", "pseudolite").updated(reference=odd, rover=odd)
    data = tomllib.loads(config_toml(cfg))
    assert data["measurement"]["reference"] == odd and data["receivers"]["rover"] == odd

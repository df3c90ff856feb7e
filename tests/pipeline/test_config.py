"""The typed config tree: TOML loading, flat keys and aliases, presets, choices,
applicability per mode, and a TOML round trip of random valid settings."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from robustrtk.core import InputError
from robustrtk.estimation.robust import POLICY_NAMES
from robustrtk.measurement.weighting import WEIGHTINGS
from robustrtk.pipeline.config import (
    LEAVES,
    MODES,
    PRESETS,
    SECTIONS,
    SIGMA_RANGE,
    SLIP_DETECTORS,
    Config,
    check_applies,
    config_from_dict,
    load_config,
    preset,
    read_config_dict,
)


# ----------------------------------------------------------------------------- a TOML writer
def _toml_str(s: str) -> str:
    out = []
    for ch in s:
        if ch in '"\\':
            out.append("\\" + ch)
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v)
    assert isinstance(v, str)
    return _toml_str(v)


def to_toml(cfg: Config) -> str:
    """Sectioned TOML of ``cfg.to_dict()`` (None values left out)."""
    data = cfg.to_dict()
    lines = [f"mode = {_toml_value(data['mode'])}"]
    for section in SECTIONS:
        lines.append(f"[{section}]")
        for attr, v in data[section].items():
            if v is not None:
                key = next(k for k, lf in LEAVES.items() if lf.section == section and lf.attr == attr)
                lines.append(f"{key} = {_toml_value(v)}")
    return "\n".join(lines) + "\n"


def _write(tmp_path: Path, text: str | bytes, name: str = "c.toml") -> Path:
    p = tmp_path / name
    if isinstance(text, bytes):
        p.write_bytes(text)
    else:
        p.write_text(text, encoding="utf-8")
    return p


# ----------------------------------------------------------------------------- TOML loading
def test_flat_and_sectioned_toml_give_the_same_settings(tmp_path: Path) -> None:
    flat = _write(tmp_path, 'ratio = 2.0\nrobust = "huber"\ncode_sigma_m = 1\nsmoother = true\n', "flat.toml")
    sect = _write(
        tmp_path,
        '[ar]\nratio = 2.0\n[robust]\nrobust = "huber"\n[measurement]\ncode_sigma_m = 1\n'
        "[estimator]\nsmoother = true\n",
        "sect.toml",
    )
    assert read_config_dict(flat) == read_config_dict(sect)
    assert read_config_dict(flat) == {"ratio": 2.0, "robust": "huber", "code_sigma_m": 1.0, "smoother": True}
    assert isinstance(read_config_dict(flat)["code_sigma_m"], float)  # ints widen to float leaves
    cfg = load_config(sect, preset("rtk", "pseudolite"))
    assert cfg.ar.ratio == 2.0 and cfg.robust.policy == "huber" and cfg.measurement.code_sigma_m == 1.0
    # mixed: top-level keys and sections in one file
    mixed = _write(tmp_path, 'mode = "rtk"\nratio = 2.5\n[gnss]\nsystems = "GE"\n', "mixed.toml")
    assert read_config_dict(mixed) == {"mode": "rtk", "ratio": 2.5, "systems": "GE"}


@pytest.mark.parametrize(
    "text, names",
    [
        ("bogus = 1\n", "'bogus'"),
        ("[ar]\nbogus = 1\n", "'bogus'"),
        ('k0 = "two"\n', "k0: expected float"),
        ('[ar]\nratio = "high"\n', "ratio: expected float"),
        ("[estimator]\nsmoother = 1\n", "smoother: expected bool"),
        ("par_min = 2.5\n", "par_min: expected int"),
        ("[nosuch]\nratio = 2.0\n", "'nosuch'"),
        ("[ar]\ncode_sigma_m = 0.5\n", "[ar] 'code_sigma_m'"),
        ('[gnss]\nrobust = "none"\n', "[gnss] 'robust'"),
        ("robust = \n", "invalid TOML"),
    ],
)
def test_bad_toml_is_an_input_error_naming_the_key(tmp_path: Path, text: str, names: str) -> None:
    p = _write(tmp_path, text)
    with pytest.raises(InputError) as exc:
        load_config(p)
    assert names in str(exc.value) and str(p) in str(exc.value)
    assert "\n" not in str(exc.value)


def test_a_choice_outside_the_literal_is_refused_by_validate(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="robust: expected one of"):
        load_config(_write(tmp_path, 'robust = "tukey"\n'))
    with pytest.raises(InputError, match="filter: lsq"):
        load_config(_write(tmp_path, 'mode = "dgnss"\nfilter = "lsq"\n'))


def test_non_utf8_and_missing_files_are_input_errors(tmp_path: Path) -> None:
    p = _write(tmp_path, b'robust = "igg3"\n# caf\xe9\n')
    with pytest.raises(InputError, match="not UTF-8"):
        read_config_dict(p)
    with pytest.raises(InputError, match="file not found"):
        read_config_dict(tmp_path / "missing.toml")
    with pytest.raises(InputError, match="directory"):
        read_config_dict(tmp_path)


# ----------------------------------------------------------------------------- flat keys
def test_updated_routes_aliases_to_their_sections() -> None:
    cfg = Config().updated(robust="none", ar="lambda", slip="gf", filter="ekf", ratio=2.0, mode="rtk")
    assert cfg.robust.policy == "none"
    assert cfg.ar.method == "lambda"
    assert cfg.slip.detectors == "gf" and cfg.slip_detectors() == frozenset({"gf"})
    assert cfg.estimator.filter == "ekf"
    assert cfg.ar.ratio == 2.0 and cfg.mode == "rtk"
    assert cfg.get("robust") == "none" and cfg.flat()["ar"] == "lambda"
    assert Config().updated(ratio=None) == Config()  # None means "not given"
    with pytest.raises(InputError, match="unknown setting 'policy'"):
        Config().updated(policy="none")  # the attribute name is not a key


def test_every_leaf_has_a_unique_key_and_flag() -> None:
    flags = [leaf.flag for leaf in LEAVES.values()]
    assert len(set(flags)) == len(flags)
    assert LEAVES["code_sigma_m"].flag == "--code-sigma"
    assert LEAVES["base"].flag == "--base-name"  # --base is the base observation file


def test_every_preset_validates_and_has_its_mode() -> None:
    for (kind, mode), cfg in PRESETS.items():
        assert cfg.validate() is cfg
        assert cfg.mode == mode and preset(mode, kind) is cfg
    with pytest.raises(InputError, match="gnss input takes"):
        preset("dpl", "gnss")


def test_literal_choices_match_the_implementations() -> None:
    assert LEAVES["robust"].choices == POLICY_NAMES
    assert LEAVES["weighting"].choices == WEIGHTINGS
    assert LEAVES["mode"].choices == MODES


@pytest.mark.parametrize("mode", MODES)
def test_check_applies_refuses_keys_that_do_not_act_in_the_mode(mode: str) -> None:
    for key, leaf in LEAVES.items():
        if mode in leaf.modes:
            check_applies([key], mode)
        else:
            with pytest.raises(InputError, match=f"{leaf.flag}: does not apply to mode {mode}"):
                check_applies([key], mode)


def test_check_applies_names_the_key_for_a_file_and_the_flag_for_the_command_line() -> None:
    with pytest.raises(InputError) as exc:
        check_applies(["code_sigma_m", "ratio"], "spp", source="c.toml")
    assert str(exc.value).startswith("c.toml") and "ratio: does not apply to mode spp" in str(exc.value)
    with pytest.raises(InputError, match="--ratio: does not apply to mode spp"):
        check_applies(["ratio"], "spp")


# ----------------------------------------------------------------------------- round trip
_POSITIVE = {
    "init_sigma_m", "code_sigma_m", "phase_sigma_m", "ratio", "sigma_vel_m_s", "sigma_acc_m_s2",
    "amb_init_sigma_cyc", "hold_sigma_cyc", "ukf_alpha", "init_sigma_vel_m_s", "q_static_m2_s",
    "gf_threshold_m", "doppler_threshold_cyc", "sigma_acc_up_m_s2", "doppler_sigma_m_s", "amb_var0_m2",
    "raim_alpha",
}  # fmt: skip
_INT_MIN = {"par_min": 1, "max_iter": 1}


def _leaf_strategy(key: str) -> st.SearchStrategy[Any]:
    leaf = LEAVES[key]
    if leaf.choices:
        return st.sampled_from(leaf.choices)
    if leaf.base_type is bool:
        return st.booleans()
    if leaf.base_type is int:
        return st.integers(min_value=_INT_MIN.get(key, 0), max_value=2**62)
    if key == "freqs":
        return st.sampled_from(["L1", "L1+L2", "L1+L2+L5", "L2+L5", "1,5"])
    if "sigma" in key:
        return st.floats(min_value=SIGMA_RANGE[0], max_value=SIGMA_RANGE[1])
    if key.startswith("q_") or key in ("amb_var0_m2", "slip_var_m2"):
        lo_v = 1e-300 if key in _POSITIVE else 0.0
        return st.floats(min_value=lo_v, max_value=SIGMA_RANGE[1] ** 2)
    if key == "slip":
        return st.just("none") | st.lists(
            st.sampled_from(SLIP_DETECTORS), min_size=1, max_size=4, unique=True
        ).map("+".join)
    if leaf.base_type is str:
        text = st.text(max_size=12)
        return st.none() | text if leaf.optional else text
    if key in ("elev_mask_deg", "ar_elev_mask_deg"):
        return st.floats(min_value=0.0, max_value=89.9)
    lo = 1e-300 if key in _POSITIVE or key in ("k0", "k1") else 0.0
    num = st.floats(min_value=lo, max_value=1e300, allow_nan=False, allow_infinity=False)
    return st.none() | num if leaf.optional else num


_SETTINGS = st.fixed_dictionaries({k: _leaf_strategy(k) for k in LEAVES})


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much]
)
@given(flat=_SETTINGS)
def test_random_valid_settings_round_trip_through_toml(flat: dict[str, Any]) -> None:
    cfg = Config().updated(**flat)
    try:
        cfg.validate()
    except InputError:
        assume(False)
    text = to_toml(cfg)
    back = config_from_dict(tomllib.loads(text))
    assert back == cfg
    for key in LEAVES:
        a, b = back.get(key), cfg.get(key)
        assert a == b or (isinstance(a, float) and math.isclose(a, b)), key


def test_field_types_are_those_of_get_type_hints() -> None:
    """The tree's evaluated annotations (each distinct string once) are the dictionaries
    ``typing.get_type_hints`` gives, for the tree, every section and a class of another
    module."""
    import dataclasses
    import typing

    from robustrtk.pipeline.config import Config, field_types

    sections = [t for t in typing.get_type_hints(Config).values() if dataclasses.is_dataclass(t)]
    assert len(sections) >= 9

    @dataclasses.dataclass
    class Local:
        a: int | None = None
        b: Any = None
        c: None = None
        d: tuple[str, ...] = ()
        e: Path | None = None

    for cls in [Config, *sections, Local]:
        assert field_types(cls) == typing.get_type_hints(cls), cls.__name__

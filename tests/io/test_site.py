"""Site TOML: round trip, defaults, bad fields named; SurveyedSource lookups."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from robustrtk.core import CLIGHT, InputError
from robustrtk.geometry.surveyed import SurveyedSource
from robustrtk.io.site import Site, read_site, write_site

GOOD = """\
frame = "local"
wavelength_m = 0.19029367
reference = "PL6"

[transmitters]
PL10 = [0.0, 0.0, 2.0]
PL1 = [-3.6, -2.4, 1.9]
PL6 = [0.2, 0.3, 1.95]

[receivers.base]
position = [-1.2, -0.6, -1.6]

[receivers.rover]
initial_position = [1, 2, -1.5]
"""


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "site.toml"
    p.write_text(text)
    return p


def test_read_good_site(tmp_path: Path) -> None:
    s = read_site(_write(tmp_path, GOOD))
    assert s.frame == "local" and s.reference == "PL6"
    assert s.wavelength_m == 0.19029367
    assert list(s.transmitters) == ["PL1", "PL6", "PL10"]  # natural order
    np.testing.assert_array_equal(s.transmitters["PL1"], [-3.6, -2.4, 1.9])
    np.testing.assert_array_equal(s.base_pos_m, [-1.2, -0.6, -1.6])
    assert s.rover_initial_pos_m is not None
    np.testing.assert_array_equal(s.rover_initial_pos_m, [1.0, 2.0, -1.5])
    assert s.path == tmp_path / "site.toml"
    pos = s.tx_positions_m(("PL6", "X"))
    np.testing.assert_array_equal(pos[0], [0.2, 0.3, 1.95])
    assert np.all(np.isnan(pos[1]))


def test_defaults(tmp_path: Path) -> None:
    text = "[transmitters]\nA=[0,0,1]\nB=[1,0,1]\n[receivers.base]\nposition=[0,0,0]\n"
    s = read_site(_write(tmp_path, text))
    assert s.frame == "local" and s.reference is None and s.rover_initial_pos_m is None
    assert s.wavelength_m == pytest.approx(CLIGHT / 1575.42e6, rel=1e-15)


coord = st.floats(-1e4, 1e4, allow_nan=False, allow_infinity=False)
vec = st.tuples(coord, coord, coord)


@settings(max_examples=30, deadline=None)
@given(
    txs=st.dictionaries(
        st.from_regex(r"[A-Za-z][A-Za-z0-9 ._-]{0,8}", fullmatch=True), vec, min_size=2, max_size=6
    ),
    base=vec,
    rover=st.none() | vec,
    wl=st.floats(1e-3, 10.0),
    use_ref=st.booleans(),
)
def test_round_trip(
    tmp_path_factory: pytest.TempPathFactory,
    txs: dict[str, tuple[float, float, float]],
    base: tuple[float, float, float],
    rover: tuple[float, float, float] | None,
    wl: float,
    use_ref: bool,
) -> None:
    from robustrtk.io.site import MIN_SEPARATION_M

    points = [np.array(v) for v in [*txs.values(), base]]
    assume(
        all(np.linalg.norm(a - b) >= MIN_SEPARATION_M for i, a in enumerate(points) for b in points[i + 1 :])
    )
    site = Site(
        frame="local",
        wavelength_m=wl,
        reference=sorted(txs)[0] if use_ref else None,
        transmitters={k: np.array(v) for k, v in txs.items()},
        base_pos_m=np.array(base),
        rover_initial_pos_m=None if rover is None else np.array(rover),
    )
    p = write_site(site, tmp_path_factory.mktemp("s") / "site.toml")
    got = read_site(p)
    assert got.wavelength_m == wl and got.reference == site.reference
    assert set(got.transmitters) == set(txs)
    for k, v in txs.items():
        np.testing.assert_array_equal(got.transmitters[k], v)
    np.testing.assert_array_equal(got.base_pos_m, base)
    if rover is None:
        assert got.rover_initial_pos_m is None
    else:
        np.testing.assert_array_equal(got.rover_initial_pos_m, rover)


@pytest.mark.parametrize(
    ("old", "new", "pattern"),
    [
        ('frame = "local"', 'frame = "ecef"', r"frame: expected 'local'"),
        ("PL1 = [-3.6, -2.4, 1.9]", "PL1 = [1, 2]", r"transmitters\.PL1: expected a list of 3"),
        ("PL1 = [-3.6, -2.4, 1.9]", 'PL1 = [1, "a", 2]', r"transmitters\.PL1: expected a list"),
        ('reference = "PL6"', 'reference = "PL7"', r"reference: unknown transmitter 'PL7'"),
        ("position = [-1.2, -0.6, -1.6]", "pos = [0, 0, 0]", r"receivers\.base\.position: missing"),
        ("wavelength_m = 0.19029367", "wavelength_m = -1", r"wavelength_m: expected a positive"),
        ("wavelength_m = 0.19029367", "wavelenght_m = 0.19", r"wavelenght_m: unknown key"),
        ("[receivers.rover]", "[receivers.rovr]", r"receivers\.rovr: unknown receiver"),
        (
            "initial_position = [1, 2, -1.5]",
            "initial_position = [1, 2, nan]",
            r"receivers\.rover\.initial_position: expected a list of 3 finite",
        ),
    ],
)
def test_bad_fields_are_named(tmp_path: Path, old: str, new: str, pattern: str) -> None:
    assert old in GOOD
    p = _write(tmp_path, GOOD.replace(old, new))
    with pytest.raises(InputError, match=pattern) as ei:
        read_site(p)
    assert str(ei.value).startswith(str(p))


def test_toml_syntax_error_names_line(tmp_path: Path) -> None:
    p = _write(tmp_path, GOOD.replace("PL6 = [0.2", "PL6 = = [0.2"))
    with pytest.raises(InputError, match="TOML syntax error") as ei:
        read_site(p)
    assert ei.value.line == 8


def test_too_few_transmitters_and_missing_file(tmp_path: Path) -> None:
    p = _write(tmp_path, "[transmitters]\nA=[0,0,1]\n[receivers.base]\nposition=[0,0,0]\n")
    with pytest.raises(InputError, match="transmitters: expected a table of at least 2"):
        read_site(p)
    with pytest.raises(InputError, match="not found"):
        read_site(tmp_path / "missing.toml")


def test_surveyed_source() -> None:
    src = SurveyedSource({"PL1": [1.0, 2.0, 3.0], "PL4": (4.0, 5.0, 6.0)})
    pos, clk = src.positions(12.5, ["PL4", "PL9", "PL1"])
    np.testing.assert_array_equal(pos, [[4, 5, 6], [np.nan] * 3, [1, 2, 3]])
    assert clk.shape == (3,) and np.all(np.isnan(clk))
    pos0, clk0 = src.positions(0.0, [])
    assert pos0.shape == (0, 3) and clk0.shape == (0,)
    assert src.tx_ids == ("PL1", "PL4")

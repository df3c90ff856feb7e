"""Outputs never destroy inputs and are one transaction: aliases refused before any work,
a signal during the commit deferred, a failed rename rolled back, a full disk one line."""

from __future__ import annotations

import errno
import os
import signal
from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from robustrtk.cli.main import main
from robustrtk.core import InputError
from robustrtk.io import atomic
from robustrtk.io.atomic import atomic_paths


@pytest.fixture(scope="module")
def room(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("room")
    res = CliRunner().invoke(main, ["simulate", "demo", "--seed", "1", "--out", str(out), "--epochs", "20"])
    assert res.exit_code == 0, res.output
    return out


def _invoke(args: list[object]) -> Result:
    return CliRunner().invoke(main, [str(a) for a in args])


def _refused(res: Result, *words: str) -> str:
    assert res.exit_code == 2, (res.exit_code, res.output, res.exception)
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert lines and lines[-1].startswith("error: ") and "Traceback" not in res.output, res.output
    for w in words:
        assert w in lines[-1], (w, lines[-1])
    assert len(lines[-1]) <= 300
    return lines[-1]


def _hidden(d: Path) -> list[str]:
    return sorted(p.name for p in d.iterdir() if p.name.startswith("."))


# ---------------------------------------------------------------------- aliases
def test_out_over_the_observations_is_refused_and_they_stay(room: Path, tmp_path: Path) -> None:
    obs = tmp_path / "obs.csv"
    obs.write_bytes((room / "obs.csv").read_bytes())
    before = obs.read_bytes()
    res = _invoke(["solve", obs, "--site", room / "site.toml", "--mode", "dpl", "--out", obs])
    _refused(res, "--out", "input OBS")
    assert obs.read_bytes() == before


def test_out_and_diagnostics_on_one_file_are_refused(room: Path, tmp_path: Path) -> None:
    s = tmp_path / "s.csv"
    res = _invoke(["solve", room / "obs.csv", "--site", room / "site.toml", "--out", s, "--diagnostics", s])
    _refused(res, "--diagnostics", "--out", "same file")
    assert not s.exists()


def test_a_hard_link_or_another_spelling_of_an_input_is_caught(room: Path, tmp_path: Path) -> None:
    site = tmp_path / "site.toml"
    site.write_bytes((room / "site.toml").read_bytes())
    link = tmp_path / "link.csv"
    os.link(site, link)
    res = _invoke(["solve", room / "obs.csv", "--site", site, "--out", link])
    _refused(res, "--out", "--site")
    other = tmp_path / "sub" / ".." / "site.toml"
    (tmp_path / "sub").mkdir()
    res = _invoke(
        ["solve", room / "obs.csv", "--site", site, "--out", room / "x.csv", "--diagnostics", other]
    )
    _refused(res, "--diagnostics", "--site")
    assert site.read_bytes() == (room / "site.toml").read_bytes()


# ---------------------------------------------------------------------- messages
def test_repeated_frequencies_are_refused(shared_data: Path, tmp_path: Path) -> None:
    d = shared_data / "geonet_0759_3040_static_3km"
    res = _invoke(["solve", d / "30400920.05o", "--base", d / "07590920.05o", "--nav", d / "30400920.05n",
                   "--mode", "rtk", "--freqs", "L1+L1", "--out", tmp_path / "o.pos"])  # fmt: skip
    _refused(res, "freqs", "given twice")


def test_unknown_system_letters_in_rtk_mode(shared_data: Path, tmp_path: Path) -> None:
    d = shared_data / "geonet_0759_3040_static_3km"
    res = _invoke(["solve", d / "30400920.05o", "--base", d / "07590920.05o", "--nav", d / "30400920.05n",
                   "--mode", "rtk", "--systems", "XYZ", "--out", tmp_path / "o.pos"])  # fmt: skip
    _refused(res, "--systems", "unknown system letter", "XYZ")


def test_base_of_another_day_is_no_common_epochs(shared_data: Path, tmp_path: Path) -> None:
    d = shared_data / "geonet_0759_3040_static_3km"
    lines = (d / "07590920.05o").read_text().splitlines(keepends=True)
    end = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
    # epoch lines " 05  4  2 ..." become the next day
    body = [ln[:7] + " 3" + ln[9:] if ln.startswith(" 05  4  2") else ln for ln in lines[end:]]
    base = tmp_path / "07590930.05o"
    base.write_text("".join(lines[:end] + body))
    res = _invoke(["solve", d / "30400920.05o", "--base", base, "--nav", d / "30400920.05n", "--mode", "rtk",
                   "--base-pos", "-3978241.0,3382840.0,3649900.0", "--out", tmp_path / "o.pos"])  # fmt: skip
    _refused(res, "--base", "no common epochs", "2005/04/03")


# ---------------------------------------------------------------------- the commit
def _old(tmp_path: Path) -> tuple[Path, Path]:
    a, b = tmp_path / "diag.csv", tmp_path / "sol.pos"
    a.write_text("old diag\n")
    b.write_text("old sol\n")
    return a, b


def _write_new(tmps: list[str]) -> None:
    for t, text in zip(tmps, ("new diag\n", "new sol\n"), strict=True):
        Path(t).write_text(text)


def test_a_signal_during_the_renames_waits_for_the_commit(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    a, b = _old(tmp_path)
    real = os.replace
    calls: list[str] = []

    def replace_then_signal(src: str, dst: os.PathLike[str]) -> None:
        real(src, dst)
        calls.append(str(dst))
        if len(calls) == 1:  # between the two renames
            os.kill(os.getpid(), signal.SIGINT)

    monkeypatch.setattr(atomic.os, "replace", replace_then_signal)
    with pytest.raises(KeyboardInterrupt), atomic_paths([a, b]) as tmps:
        _write_new(tmps)
    assert (a.read_text(), b.read_text()) == ("new diag\n", "new sol\n")
    assert _hidden(tmp_path) == []


def test_a_failed_second_rename_restores_the_first(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    a, b = _old(tmp_path)
    real = os.replace

    def fail_on_solution(src: str, dst: os.PathLike[str]) -> None:
        if str(dst) == str(b):
            raise OSError(errno.EIO, "Input/output error")
        real(src, dst)

    monkeypatch.setattr(atomic.os, "replace", fail_on_solution)
    with pytest.raises(InputError, match="sol.pos"), atomic_paths([a, b]) as tmps:
        _write_new(tmps)
    monkeypatch.undo()
    assert (a.read_text(), b.read_text()) == ("old diag\n", "old sol\n")
    assert _hidden(tmp_path) == []


def test_a_full_disk_is_one_input_error_naming_the_target(tmp_path: Path) -> None:
    a, b = _old(tmp_path)
    with pytest.raises(InputError) as info, atomic_paths([a, b]) as tmps:
        Path(tmps[0]).write_text("new diag\n")
        raise OSError(errno.ENOSPC, "No space left on device", tmps[1])
    assert str(b) in str(info.value) and ".tmp" not in str(info.value) and "No space" in str(info.value)
    assert (a.read_text(), b.read_text()) == ("old diag\n", "old sol\n")
    assert _hidden(tmp_path) == []


def test_a_signal_right_after_a_temporary_is_created_leaves_none(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    real = atomic._create_empty

    def create_then_signal(path: str) -> None:
        real(path)
        os.kill(os.getpid(), signal.SIGINT)

    monkeypatch.setattr(atomic, "_create_empty", create_then_signal)
    with pytest.raises(KeyboardInterrupt), atomic_paths([tmp_path / "a.csv", tmp_path / "b.csv"]):
        pass
    assert list(tmp_path.iterdir()) == []


def test_an_error_naming_a_temporary_names_the_target(tmp_path: Path) -> None:
    with pytest.raises(InputError) as info, atomic_paths([tmp_path / "out.pos"]) as (tmp,):
        raise InputError("something wrong", path=tmp)
    assert str(info.value) == f"{tmp_path / 'out.pos'}: something wrong"


def test_a_huge_config_is_refused_before_parsing(room: Path, tmp_path: Path) -> None:
    big = tmp_path / "big.toml"
    big.write_text("elev_mask_deg = [" + ",".join(["1"] * 600_000) + "]\n")
    res = _invoke(
        [
            "solve",
            room / "obs.csv",
            "--site",
            room / "site.toml",
            "--config",
            big,
            "--out",
            tmp_path / "o.csv",
        ]
    )
    _refused(res, "--config", "at most 1 MiB")


def test_temporaries_are_private_new_files_beside_the_target(tmp_path: Path) -> None:
    """Each temporary is a new file of mode 0600 named ``.<name>.<random>.tmp`` in the
    target's folder; an existing name (a link, say) is never opened."""
    target = tmp_path / "out.pos"
    with atomic_paths([target, tmp_path / "d.csv"]) as (tmp, tmp2):
        p = Path(tmp)
        assert p.parent == tmp_path and p.name.startswith(".out.pos.") and p.name.endswith(".tmp")
        assert p.stat().st_size == 0 and (p.stat().st_mode & 0o777) == 0o600 and tmp != tmp2
        Path(tmp).write_text("new\n")
        Path(tmp2).write_text("d\n")
    assert target.read_text() == "new\n" and _hidden(tmp_path) == []
    (tmp_path / "victim").write_text("keep\n")
    link = tmp_path / "link"
    link.symlink_to(tmp_path / "victim")
    with pytest.raises(FileExistsError):
        atomic._create_empty(str(link))
    assert (tmp_path / "victim").read_text() == "keep\n"

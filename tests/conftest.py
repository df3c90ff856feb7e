"""Shared fixtures: the real datasets live in ``../shared/data`` beside the repository."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

_ROOT = Path(__file__).resolve().parents[1]


def _shared_data_dir() -> Path:
    env = os.environ.get("ROBUSTRTK_SHARED_DATA")
    if env:
        return Path(env)
    return _ROOT.parent / "shared" / "data"


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """Path of the shared real datasets; skips the test when the folder is absent."""
    path = _shared_data_dir()
    if not path.is_dir():
        pytest.skip(f"shared datasets not found at {path} (set ROBUSTRTK_SHARED_DATA)")
    return path


def _shared_folder(shared_data: Path, *parts: str) -> Path:
    """A folder of the shared datasets; skips the test when it is absent."""
    path = shared_data.joinpath(*parts)
    if not path.is_dir():
        pytest.skip(f"{path} absent")
    return path


@pytest.fixture(scope="session")
def galway_s1(shared_data: Path) -> Path:
    """The galway M8P static recording (``galway_m8p_l1_lowcost/s1_static``)."""
    return _shared_folder(shared_data, "galway_m8p_l1_lowcost", "s1_static")


@pytest.fixture(scope="session")
def pixel5_drive(shared_data: Path) -> Path:
    """The Pixel 5 drive's RINEX and navigation files (``gsdc2021_mtv1_pixel5_phone/Pixel5/supplemental``)."""
    return _shared_folder(shared_data, "gsdc2021_mtv1_pixel5_phone", "Pixel5", "supplemental")


@pytest.fixture(autouse=True)
def _lambda_backend_from_this_environment() -> None:
    """Every test starts with the LAMBDA backend of its own environment: the variable is read
    when a run begins (``lambda_.backend``), not at each look-up, and an earlier test's
    ``monkeypatch`` may have changed and restored it."""
    from robustrtk.ambiguity import lambda_

    lambda_.backend()


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    """One line when the shared real datasets are absent, so that the skips are explained."""
    path = _shared_data_dir()
    if path.is_dir():
        return
    skipped = terminalreporter.stats.get("skipped", [])
    n = sum(1 for rep in skipped if "shared datasets not found" in str(getattr(rep, "longrepr", "")))
    if n:
        plural = "s" if n != 1 else ""
        terminalreporter.write_line(
            f"{n} test{plural} skipped: the shared real datasets are not at {path} "
            "(set ROBUSTRTK_SHARED_DATA)"
        )

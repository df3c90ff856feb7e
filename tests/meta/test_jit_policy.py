"""The kernel policy (``robustrtk.jit``, algorithms.md §27): pure first, compiled once the
projected pure cost passes the kernels' fixed cost; deterministic, reset for every run."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from robustrtk import jit

SRC = Path(__file__).resolve().parents[2] / "src"


@pytest.fixture(autouse=True)
def _auto(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    monkeypatch.delenv("ROBUSTRTK_NO_JIT", raising=False)
    monkeypatch.delenv("ROBUSTRTK_JIT", raising=False)
    jit.begin_run(None)
    yield
    jit.begin_run(None)


def test_mode_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    assert jit.mode() == "auto"
    for raw, want in (("on", "on"), ("1", "on"), ("OFF", "off"), ("0", "off"), ("auto", "auto")):
        monkeypatch.setenv("ROBUSTRTK_JIT", raw)
        assert jit.mode() == want
    monkeypatch.setenv("ROBUSTRTK_NO_JIT", "1")
    assert jit.mode() == "off"
    monkeypatch.delenv("ROBUSTRTK_NO_JIT")
    monkeypatch.setenv("ROBUSTRTK_JIT", "sometimes")
    with pytest.raises(ValueError, match="ROBUSTRTK_JIT='sometimes'"):
        jit.mode()
    monkeypatch.delenv("ROBUSTRTK_JIT")
    with jit.use("off"):
        assert jit.mode() == "off" and not jit.compiled()
        with jit.use("on"):
            assert jit.compiled()
        assert not jit.compiled()


def test_without_a_known_length_the_switch_comes_at_break_even() -> None:
    step = jit.FIXED_COST_US / 10
    for _ in range(9):
        jit.charge(step)
        assert not jit.compiled()
    jit.charge(step)
    assert jit.compiled()
    jit.begin_run(None)  # a new run decides afresh
    assert not jit.compiled() and jit.meter().spent_us == 0.0


@pytest.mark.parametrize(
    ("var", "expected"),
    [
        ("ROBUSTRTK_JIT", "expected auto, on or off"),
        ("ROBUSTRTK_LAMBDA_BACKEND", "expected auto, c, numba or pure"),
    ],
)
def test_a_bad_policy_in_the_environment_is_one_line_and_exit_2(
    tmp_path: Path, var: str, expected: str
) -> None:
    """Not a run without ambiguity resolution: the solve stops before its first epoch."""
    import os

    from robustrtk.eval.demo import sample_files

    f = sample_files()
    xyz = ",".join(f"{v:.4f}" for v in f.base_pos_m)
    env = {**os.environ, "PYTHONPATH": str(SRC), var: "fast"}
    out = tmp_path / "o.pos"
    args = ["solve", str(f.rover), "--base", str(f.base), "--nav", str(f.nav), "--base-pos", xyz]
    proc = subprocess.run(
        [sys.executable, "-m", "robustrtk", *args, "--mode", "rtk", "--out", str(out), "--quiet"],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and f"{var}='fast'" in lines[0] and expected in lines[0]
    assert not out.exists()


@pytest.mark.parametrize("n_epochs", [50, 500, 5000])
def test_a_run_switches_at_the_first_epoch_whose_projected_rest_exceeds_the_fixed_cost(n_epochs: int) -> None:
    per_epoch = 4000.0  # µs of pure work per epoch
    jit.begin_run(n_epochs)
    switched_at = None
    for e in range(1, n_epochs + 1):
        jit.charge(per_epoch)
        jit.end_epoch()
        if jit.compiled():
            switched_at = e
            break
    # brute force of the rule: the first e with per_epoch · (N − e) > fixed cost
    want = next((e for e in range(1, n_epochs + 1) if per_epoch * (n_epochs - e) > jit.FIXED_COST_US), None)
    assert switched_at == want
    if n_epochs * per_epoch <= jit.FIXED_COST_US:
        assert switched_at is None  # a run too short to pay never loads the kernels


def test_a_search_on_a_short_run_stays_pure_and_a_long_one_loads_numba() -> None:
    pytest.importorskip("numba")
    probe = (
        "import sys\nimport numpy as np\nfrom robustrtk import jit\n"
        "from robustrtk.ambiguity.lambda_ import kernels, lambda_search\n"
        "a, Q = np.array([0.2, -1.3]), np.array([[0.5, 0.1], [0.1, 0.4]])\n"
        "jit.begin_run(10)\nfor _ in range(10):\n    lambda_search(a, Q)\n    jit.end_epoch()\n"
        "print('numba' in sys.modules)\n"
        "jit.begin_run(None)\njit.charge(jit.FIXED_COST_US)\nlambda_search(a, Q)\n"
        "print(kernels() is not None and 'numba' in sys.modules)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", probe],
        # the numba kernels under the policy (the C ones, when built, serve outside it)
        env={"PYTHONPATH": str(SRC), "PATH": "/usr/bin:/bin", "ROBUSTRTK_LAMBDA_BACKEND": "numba"},
        capture_output=True,
        text=True,
        check=True,
        timeout=300,
    ).stdout.split()
    assert out == ["False", "True"]


def test_a_run_that_switches_midway_is_reproducible_and_agrees_with_the_pure_run(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The bundled real pair with the fixed cost lowered so that the switch falls mid-run: the
    same process gives the same output twice (the decision is reset per run and counts work,
    not time), and it agrees with the pure-only run to rounding."""
    pytest.importorskip("numba")
    # the LAMBDA kernels under the policy too (the C ones, when built, serve outside it)
    monkeypatch.setenv("ROBUSTRTK_LAMBDA_BACKEND", "numba")
    jit.refresh()
    from robustrtk.eval.demo import DEMO_RTK_SETTINGS, sample_files
    from robustrtk.pipeline.api import solve_rtk

    f = sample_files()

    def run() -> tuple[np.ndarray, list[str], jit.Meter]:
        s = solve_rtk(f.rover, f.base, f.nav, f.base_pos_m, DEMO_RTK_SETTINGS)
        return np.asarray(s.pos_m), list(s.status), jit.meter()

    with jit.use("off"):
        pos_pure, st_pure, _ = run()
    monkeypatch.setattr(jit, "FIXED_COST_US", 2.0e4)
    pos1, st1, m1 = run()
    pos2, st2, m2 = run()
    assert m1.switched and m2.switched
    assert m1.epochs_done == m2.epochs_done == len(st1)
    np.testing.assert_array_equal(pos1, pos2)
    assert st1 == st2 == st_pure
    ok = np.isfinite(pos_pure).all(axis=1)
    np.testing.assert_allclose(pos1[ok], pos_pure[ok], rtol=0, atol=1e-6)

"""Start-up cost: the CLI and a solve's modules import no heavy library at import time.

Each check runs in a fresh interpreter (``sys.modules`` of the test process is shared with
every other test). Times are measured by ``bench/bench_startup.py``, not here.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src"

HEAVY = ("scipy", "matplotlib", "pyarrow", "threadpoolctl", "hatanaka")
#: Not even for ``--help``: numpy (about 0.1 s), a JIT compiler, the distributed engine.
NOT_FOR_HELP = ("numpy", "numba", "dask", "distributed")


def _loaded_after(code: str, top_level: bool = True) -> set[str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(SRC), env.get("PYTHONPATH", "")])
    names = "{m.split('.')[0] for m in sys.modules}" if top_level else "set(sys.modules)"
    probe = code + f"\nimport json, sys\nprint(json.dumps(sorted({names})))\n"
    proc = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return set(json.loads(proc.stdout.strip().splitlines()[-1]))


def test_cli_entry_imports_no_heavy_library() -> None:
    loaded = _loaded_after("import robustrtk.cli.entry, robustrtk.cli.main")
    assert not loaded & {*HEAVY, *NOT_FOR_HELP}, sorted(loaded & {*HEAVY, *NOT_FOR_HELP})


def test_help_imports_no_heavy_library() -> None:
    code = (
        "import contextlib, io\n"
        "from robustrtk.cli.entry import run\n"
        "with contextlib.redirect_stdout(io.StringIO()) as out:\n"
        "    status = run(['--help'])\n"
        "assert status == 0 and 'solve' in out.getvalue()\n"
        "with contextlib.redirect_stdout(io.StringIO()) as out:\n"
        "    status = run(['solve', '--help'])\n"
        "assert status == 0 and '--mode' in out.getvalue()\n"
    )
    loaded = _loaded_after(code)
    assert not loaded & {*HEAVY, *NOT_FOR_HELP}, sorted(loaded & {*HEAVY, *NOT_FOR_HELP})


def test_command_list_does_not_build_the_configuration_options() -> None:
    """``robustrtk --help`` lists the commands without importing the configuration tree; the
    solve's one option per leaf is made when ``solve`` parses or shows its help."""
    code = (
        "import contextlib, io, sys\n"
        "from robustrtk.cli.entry import run\n"
        "with contextlib.redirect_stdout(io.StringIO()) as out:\n"
        "    assert run(['--help']) == 0\n"
        "assert 'solve' in out.getvalue()\n"
        "assert 'robustrtk.pipeline.config' not in sys.modules, 'config imported by --help'\n"
        "assert 'dataclasses' not in sys.modules, 'no command module makes a dataclass at import'\n"
        "with contextlib.redirect_stdout(io.StringIO()) as out:\n"
        "    assert run(['solve', '--help']) == 0\n"
        "assert '--ratio' in out.getvalue() and 'robustrtk.pipeline.config' in sys.modules\n"
    )
    loaded = _loaded_after(code, top_level=False)
    assert "robustrtk.cli.options" in loaded


def test_solve_lists_its_own_options_then_one_per_leaf() -> None:
    from robustrtk.cli.main import solve
    from robustrtk.cli.options import SOLVE_LEAVES

    names = [p.name for p in solve.params]
    assert names[0] == "obs" and names.index("show_config") < names.index(next(iter(SOLVE_LEAVES)))
    assert names[-len(SOLVE_LEAVES) :] == list(SOLVE_LEAVES)
    assert len(names) == len(set(names))


@pytest.mark.parametrize(
    "module",
    [
        "robustrtk.pipeline.rtk_gnss",
        "robustrtk.pipeline.gnss",
        "robustrtk.pipeline.solve",
        "robustrtk.cli.gnss",
        "robustrtk.io.readers",
    ],
)
def test_solve_modules_import_no_heavy_library(module: str) -> None:
    loaded = _loaded_after(f"import robustrtk.cli.main, {module}")
    assert "numpy" in loaded or module == "robustrtk.cli.gnss"
    assert not loaded & set(HEAVY), sorted(loaded & set(HEAVY))


def _geonet_solve_modules(shared_data: Path, tmp_path: Path, lambda_backend: str = "auto") -> set[str]:
    """Every module loaded by the end of a whole RTK solve of geonet (120 epochs)."""
    d = shared_data / "geonet_0759_3040_static_3km"
    if not (d / "07590920.05o").is_file():
        pytest.skip(f"geonet dataset not found in {shared_data}")
    args = [
        "solve", str(d / "07590920.05o"), "--base", str(d / "30400920.05o"),
        "--nav", str(d / "30400920.05n"), "--base-pos", "-3978241.958,3382840.234,3649900.853",
        "--mode", "rtk", "--out", str(tmp_path / "g.pos"), "--quiet",
    ]  # fmt: skip
    env = f"import os\nos.environ['ROBUSTRTK_LAMBDA_BACKEND'] = {lambda_backend!r}\n"
    code = env + f"from robustrtk.cli.entry import run\nassert run({args!r}) == 0\n"
    loaded = _loaded_after(code, top_level=False)
    assert (tmp_path / "g.pos").stat().st_size > 0
    return loaded


@pytest.mark.parametrize("lambda_backend", ["auto", "pure"])
def test_rtk_solve_never_imports_scipy_or_matplotlib(
    shared_data: Path, tmp_path: Path, lambda_backend: str
) -> None:
    """A whole RTK solve (geonet, 120 epochs) runs on numpy alone, with the C LAMBDA kernels
    or the pure references: scipy (70 MiB, 0.5 s of ``scipy.stats``), matplotlib, pyarrow
    and numba stay out of the process."""
    loaded = _geonet_solve_modules(shared_data, tmp_path, lambda_backend)
    heavy = {m for m in loaded if m.split(".")[0] in ("scipy", "matplotlib", "pyarrow", "numba")}
    assert not heavy, sorted(heavy)[:10]


#: Modules a RINEX RTK solve with default flags has no use for: the pseudolite site and table
#: readers (and the TOML parser they load), the RTS smoother (off), the diagnostics
#: CSV (not asked for), the NMEA writer, and the other subcommands; the IMM (the code
#: modes' auto dynamics) and the merging of navigation from several kinds of file; and
#: tempfile (with shutil, random, bz2 and lzma: the atomic writer makes its own
#: temporaries, and bzip2 input loads bz2 when it comes); the RINEX 4 navigation reader
#: (geonet's navigation is RINEX 2); the per-epoch slip detector of streams.
NOT_FOR_RTK_SOLVE = (
    "robustrtk.io.site", "robustrtk.io.obstable", "tomllib", "robustrtk.estimation.smoother",
    "robustrtk.io.diagnostics", "robustrtk.io.solution_nmea", "robustrtk.cli.batch", "robustrtk.cli.compare",
    "robustrtk.cli.convert", "robustrtk.cli.coop", "robustrtk.cli.experiment", "robustrtk.cli.inject",
    "robustrtk.cli.report", "robustrtk.estimation.imm", "robustrtk.io.raw_collect", "tempfile", "shutil",
    "random", "bz2", "lzma", "robustrtk.io.rinex_nav4", "robustrtk.cycleslip.online",
)  # fmt: skip


def test_rtk_solve_imports_only_what_it_uses(shared_data: Path, tmp_path: Path) -> None:
    loaded = _geonet_solve_modules(shared_data, tmp_path)
    assert "robustrtk.pipeline.rtk_gnss" in loaded and "robustrtk.io.solution_pos" in loaded
    assert not loaded & set(NOT_FOR_RTK_SOLVE), sorted(loaded & set(NOT_FOR_RTK_SOLVE))
    # np.median and np.unique load numpy.ma (about 10 ms) on first use: the epoch loop's
    # medians (integrity snapshot, adaptive factor) are core.median_of
    assert "numpy.ma" not in loaded


@pytest.mark.parametrize(
    ("folder", "obs", "nav"),
    [
        ("geonet_0759_3040_static_3km", "07590920.05o", "30400920.05n"),  # RINEX 2: the whole-file path
        ("gsdc2021_mtv1_pixel5_phone/Pixel5/supplemental", "Pixel5_GnssLog.21o", "hour1180.21n"),  # streamed
    ],
)
def test_least_squares_spp_imports_no_filter(
    shared_data: Path, tmp_path: Path, folder: str, obs: str, nav: str
) -> None:
    """A least-squares SPP solve (whole-file or streamed) runs without the Kalman filters,
    the robust policies or the adaptive estimators (``robustrtk.estimation``): their
    classes cost start-up time (about 0.04 s) and the solve has no use for them."""
    d = shared_data / folder
    if not (d / obs).is_file():
        pytest.skip(f"{folder} not found in {shared_data}")
    out = tmp_path / "s.pos"
    args = ["solve", str(d / obs), "--nav", str(d / nav), "--mode", "spp", "--out", str(out), "--quiet"]
    code = f"from robustrtk.cli.entry import run\nassert run({args!r}) == 0\n"
    loaded = _loaded_after(code, top_level=False)
    assert out.stat().st_size > 0 and "robustrtk.pipeline.spp" in loaded
    est = sorted(m for m in loaded if m.startswith("robustrtk.estimation."))
    assert not est, est


def test_subcommands_load_when_named_and_help_lists_them_all() -> None:
    code = (
        "import contextlib, io, sys\n"
        "from robustrtk.cli.main import LAZY_COMMANDS, main\n"
        "early = {m for m, _ in LAZY_COMMANDS.values()} & set(sys.modules)\n"
        "assert early <= {'robustrtk.cli.gnss'}, early  # info: the solve's own module\n"
        "from robustrtk.cli.entry import run\n"
        "with contextlib.redirect_stdout(io.StringIO()) as out:\n"
        "    assert run(['convert', '--help']) == 0\n"
        "assert 'robustrtk.cli.convert' in sys.modules and 'robustrtk.cli.batch' not in sys.modules\n"
        "with contextlib.redirect_stdout(io.StringIO()) as out:\n"
        "    assert run(['--help']) == 0\n"
        "listed = [ln.split()[0] for ln in out.getvalue().split('Commands:')[1].splitlines() if ln.strip()]\n"
        "assert listed == sorted(main.commands), (listed, sorted(main.commands))\n"
        "assert set(LAZY_COMMANDS) <= set(listed), listed\n"
    )
    from robustrtk.cli.main import LAZY_COMMANDS

    loaded = _loaded_after(code, top_level=False)
    assert {m for m, _ in LAZY_COMMANDS.values()} <= loaded


def test_mistyped_command_suggests_a_command_of_its_own_module() -> None:
    from click.testing import CliRunner

    from robustrtk.cli.main import main

    res = CliRunner().invoke(main, ["bach"])
    assert res.exit_code == 2
    assert "No such command 'bach'" in res.output and "Did you mean 'batch'?" in res.output


def test_console_entry_asks_for_one_blas_thread_unless_told(monkeypatch: pytest.MonkeyPatch) -> None:
    from robustrtk.cli.entry import BLAS_THREAD_VARS, single_threaded_blas

    for var in BLAS_THREAD_VARS:
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("MKL_NUM_THREADS", "4")  # the user's choice stays
    single_threaded_blas()
    assert os.environ["OPENBLAS_NUM_THREADS"] == "1" and os.environ["OMP_NUM_THREADS"] == "1"
    assert os.environ["MKL_NUM_THREADS"] == "4"


def test_an_rtk_solve_started_by_the_console_entry_loads_no_threadpoolctl(
    shared_data: Path, tmp_path: Path
) -> None:
    """The console entry asks for one BLAS thread before numpy loads, so the epoch loop has
    nothing to limit; a program that imported numpy first still gets the limit."""
    d = shared_data / "geonet_0759_3040_static_3km"
    if not (d / "07590920.05o").is_file():
        pytest.skip(f"geonet dataset not found in {shared_data}")
    args = [
        "solve", str(d / "07590920.05o"), "--base", str(d / "30400920.05o"),
        "--nav", str(d / "30400920.05n"), "--mode", "rtk", "--out", str(tmp_path / "g.pos"), "--quiet",
    ]  # fmt: skip
    run = f"from robustrtk.cli.entry import run\nassert run({args!r}) == 0\n"
    fresh = (
        "import os\nfrom robustrtk.blas import BLAS_THREAD_VARS\n"
        "for v in BLAS_THREAD_VARS:\n    os.environ.pop(v, None)\n"
    )
    entry = fresh + "from robustrtk.blas import single_threaded_blas\nsingle_threaded_blas()\n" + run
    assert "threadpoolctl" not in _loaded_after(entry, top_level=False)
    numpy_first = (
        fresh
        + "import numpy\nfrom robustrtk.blas import single_threaded_blas\nsingle_threaded_blas()\n"
        + run
    )
    assert "threadpoolctl" in _loaded_after(numpy_first, top_level=False)

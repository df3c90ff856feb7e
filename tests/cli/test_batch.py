"""``robustrtk batch``: job lists, engines, byte-identical outputs, failed jobs reported."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest
from click.testing import CliRunner

from robustrtk.campaign import jobs as jobs_mod
from robustrtk.campaign import runner
from robustrtk.campaign.jobs import Job, read_jobs
from robustrtk.campaign.runner import JobResult
from robustrtk.cli.batch import output_counts, solve_job
from robustrtk.cli.entry import run
from robustrtk.cli.main import main
from robustrtk.errors import InputError

GEONET = (
    "geonet_0759_3040_static_3km",
    "07590920.05o",
    "30400920.05o",
    "30400920.05n",
    "-3978241.958,3382840.234,3649900.853",
)
MOSAIC = (
    "mosaicx5_static_1m",
    "rover.obs",
    "base.obs",
    "base.nav",
    "-3817681.1213,3562839.4311,3650159.1593",
)
KAMAKURA = (
    "kamakura_kinematic_5km",
    "SEPT265G.21O",
    "3034265G.21O",
    "SEPT2650.21P",
    "-3959400.631,3385704.533,3667523.111",
)


# ----------------------------------------------------------------------------- job lists
J = '[[job]]\nrover = "r"\nbase = "b"\nnav = "n"\n'  # a minimal valid job


def test_toml_jobs_resolve_paths_defaults_and_positions(tmp_path: Path) -> None:
    (tmp_path / "sub").mkdir()
    f = tmp_path / "sub" / "jobs.toml"
    f.write_text(
        '[defaults]\nmode = "dgnss"\nout_dir = "sol"\nnav = "n1.nav"\n\n'
        '[[job]]\nrover = "r1.obs"\nbase = "b.obs"\nbase_pos = [1.5, -2, 3e6]\n\n'
        '[[job]]\nname = "two"\nrover = "/abs/r2.obs"\nbase = "b.obs"\nnav = ["a.nav", "b.nav"]\n'
        'mode = "rtk"\nout = "x/two.csv"\nbase_pos = "4;5;6"\nargs = ["--ar", "par"]\n'
    )
    j1, j2 = read_jobs(f)
    d = tmp_path / "sub"
    assert (j1.name, j1.mode, j1.rover, j1.nav) == ("r1", "dgnss", str(d / "r1.obs"), (str(d / "n1.nav"),))
    assert j1.out == str(d / "sol" / "r1.pos") and j1.base_pos == "1.5,-2.0,3000000.0"
    assert (j2.rover, j2.out, j2.base_pos, j2.args) == (
        "/abs/r2.obs",
        str(d / "x" / "two.csv"),
        "4.0,5.0,6.0",
        ("--ar", "par"),
    )
    assert j2.nav == (str(d / "a.nav"), str(d / "b.nav"))
    argv = j2.solve_args()
    assert argv[:2] == ["solve", "/abs/r2.obs"] and argv[-3:] == ["--out", j2.out, "--quiet"]
    assert argv[argv.index("--mode") + 1] == "rtk" and argv.count("--nav") == 2 and "--ar" in argv


def test_csv_jobs_and_folder_of_lists(tmp_path: Path) -> None:
    (tmp_path / "a.csv").write_text(
        "# a comment\nname,rover,base,nav,base_pos,mode,out\n"
        'one,r.obs,b.obs,n1.nav;n2.nav,"1,2,3",rtk,o/one.pos\n'
        "\n"
        "two,r2.obs,,n.nav,,spp,o/two.pos\n"
    )
    (tmp_path / "b.toml").write_text(
        '[[job]]\nname = "three"\nrover = "r3.obs"\nbase = "b.obs"\nnav = "n.nav"\n'
    )
    (tmp_path / "notes.txt").write_text("ignored")
    names = [j.name for j in read_jobs(tmp_path)]
    assert names == ["one", "two", "three"]  # files in name order, rows in order
    one, two = read_jobs(tmp_path / "a.csv")
    assert one.nav == (str(tmp_path / "n1.nav"), str(tmp_path / "n2.nav")) and one.base_pos == "1.0,2.0,3.0"
    assert two.base is None and two.mode == "spp" and two.base_pos is None


@pytest.mark.parametrize(
    ("text", "suffix", "match"),
    [
        (J + 'colour = 1\n', ".toml", r"job 1: unknown key\(s\) colour"),
        ('[[job]]\nbase = "b"\nnav = "n"\n', ".toml", "job 1: rover: a rover observation file is required"),
        ('[[job]]\nrover = "r"\nnav = "n"\n', ".toml", "job 1: base: mode rtk needs a base"),
        ('[[job]]\nrover = "r"\nbase = "b"\n', ".toml", "job 1: nav: expected one or more"),
        (J + 'mode = "ppp"\n', ".toml", "mode: expected one of spp, dgnss, rtk"),
        (J + 'base_pos = [1, 2]\n', ".toml", "base_pos: expected three"),
        (J + 'out = "r.txt"\n', ".toml", "out: expected a file ending in"),
        (J + 'args = ["--out", "x"]\n', ".toml", "--out belong in the job"),
        (J + J, ".toml",
         "job 2: name: 'r' is also the name of"),
        ("[[job]\n", ".toml", "not valid TOML"),
        ("rover,base,nav,colour\nr,b,n,1\n", ".csv", r"jobs.csv:1: unknown column\(s\) colour"),
        ("rover,base,nav\nr,b\n", ".csv", "jobs.csv:2: expected 3 fields"),
        ("rover,base,nav\n", ".csv", "the job list holds no job"),
    ],
)  # fmt: skip
def test_bad_job_lists_name_file_line_and_field(tmp_path: Path, text: str, suffix: str, match: str) -> None:
    f = tmp_path / f"jobs{suffix}"
    f.write_text(text)
    with pytest.raises(InputError, match=match):
        read_jobs(f)


def test_missing_job_list_and_empty_folder(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="job list not found"):
        read_jobs(tmp_path / "nope.toml")
    with pytest.raises(InputError, match=r"no \*.toml or \*.csv"):
        read_jobs(tmp_path)


def test_job_keys_documented() -> None:
    doc = (Path(__file__).resolve().parents[2] / "docs" / "batch.md").read_text()
    for key in jobs_mod.JOB_KEYS:
        assert f"`{key}`" in doc, key


# ----------------------------------------------------------------------------- engines
def test_engine_choice_and_one_line_errors_without_dask(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setattr(runner, "dask_available", lambda: False)
    assert runner.resolve_engine("auto", None) == "local"
    with pytest.raises(InputError, match=r"--engine dask: .*pip install 'robustrtk\[dask\]'"):
        runner.resolve_engine("dask", None)
    with pytest.raises(InputError, match="--scheduler: the dask engine needs dask"):
        runner.resolve_engine("auto", "tcp://127.0.0.1:8786")
    monkeypatch.setattr(runner, "dask_available", lambda: True)
    assert runner.resolve_engine("auto", None) == "dask"
    with pytest.raises(InputError, match="--scheduler: needs the dask engine"):
        runner.resolve_engine("local", "tcp://127.0.0.1:8786")
    # through the command: one line, exit status 2
    monkeypatch.setattr(runner, "dask_available", lambda: False)
    f = tmp_path / "j.toml"
    f.write_text(J)
    res = CliRunner().invoke(main, ["batch", str(f), "--engine", "dask"])
    assert res.exit_code == 2
    assert res.output.strip().splitlines() == [
        "error: --engine dask: the dask engine needs dask and distributed: pip install 'robustrtk[dask]' "
        "(or run with --engine local)"
    ]


def test_engine_choices_are_the_runner_engines() -> None:
    from robustrtk.cli.batch import ENGINE_CHOICES

    assert ENGINE_CHOICES == runner.ENGINES


def test_output_counts_reads_pos_and_csv(tmp_path: Path) -> None:
    pos = tmp_path / "a.pos"
    row = "2024/06/24 08:20:0{} 35.1 136.9 105.0 {} 10\n"
    pos.write_text("% header\n" + row.format(0, 1) + row.format(1, 2))
    assert output_counts(str(pos)) == {"fixed": 1, "float": 1}
    c = tmp_path / "a.csv"
    c.write_text(
        "time,x,y,z,sx,sy,sz,status\n1,0,0,0,0,0,0,partial\n2,0,0,0,0,0,0,float\n3,0,0,0,0,0,0,float\n"
    )
    assert output_counts(str(c)) == {"partial": 1, "float": 2}


# ----------------------------------------------------------------------------- real data
def _jobs_file(tmp_path: Path, root: Path, datasets: list[tuple[str, ...]], bad: bool) -> Path:
    lines = []
    for folder, rover, base, nav, pos in datasets:
        d = root / folder
        if not (d / rover).is_file():
            pytest.skip(f"{folder} not found in {root}")
        lines.append(
            f'[[job]]\nname = "{folder.split("_")[0]}"\nrover = "{d / rover}"\nbase = "{d / base}"\n'
            f'nav = "{d / nav}"\nbase_pos = "{pos}"\nout = "batch/{folder.split("_")[0]}.pos"\n'
        )
    if bad:  # a rover that is not RINEX: this job fails, the others must finish
        junk = tmp_path / "junk.obs"
        junk.write_text("this is not a RINEX file\n")
        folder, _rover, base, nav, pos = datasets[0]
        d = root / folder
        lines.append(
            f'[[job]]\nname = "broken"\nrover = "{junk}"\nbase = "{d / base}"\nnav = "{d / nav}"\n'
            f'base_pos = "{pos}"\nout = "batch/broken.pos"\n'
        )
    f = tmp_path / "jobs.toml"
    f.write_text("\n".join(lines))
    return f


def _single_run(tmp_path: Path, job_args: list[str], name: str) -> bytes:
    out = tmp_path / "single" / f"{name}.pos"
    out.parent.mkdir(exist_ok=True)
    argv = list(job_args)
    argv[argv.index("--out") + 1] = str(out)
    assert run(argv) == 0
    return out.read_bytes()


def _check_campaign(tmp_path: Path, f: Path, engine: str) -> None:
    jobs = read_jobs(f)
    summary = tmp_path / "summary.csv"
    res = CliRunner().invoke(
        main,
        ["batch", str(f), "--engine", engine, "--workers", "2", "--summary", str(summary)],
        catch_exceptions=False,
    )
    assert res.exit_code == 1, res.output  # one job failed
    rows = {r["job"]: r for r in csv.DictReader(summary.open())}
    assert set(rows) == {j.name for j in jobs}
    assert (
        rows["broken"]["ok"] == "0"
        and rows["broken"]["status"] == "2"
        and "junk.obs" in rows["broken"]["error"]
    )
    assert not (tmp_path / "batch" / "broken.pos").exists()
    assert "FAILED" in res.output and f"{len(jobs) - 1} of {len(jobs)} jobs ok, 1 failed" in res.output
    for j in jobs:
        if j.name == "broken":
            continue
        assert rows[j.name]["ok"] == "1", rows[j.name]
        got = Path(j.out).read_bytes()
        assert got == _single_run(tmp_path, j.solve_args(), j.name), j.name
        assert int(rows[j.name]["epochs"]) == sum(
            1 for ln in got.decode().splitlines() if not ln.startswith("%")
        )


def test_batch_local_pool_same_bytes_as_single_run_and_failed_job_reported(
    shared_data: Path, tmp_path: Path
) -> None:
    _check_campaign(tmp_path, _jobs_file(tmp_path, shared_data, [GEONET], bad=True), "local")


@pytest.mark.slow
def test_batch_dask_three_datasets_byte_identical(shared_data: Path, tmp_path: Path) -> None:
    pytest.importorskip("distributed")
    f = _jobs_file(tmp_path, shared_data, [GEONET, MOSAIC, KAMAKURA], bad=True)
    _check_campaign(tmp_path, f, "dask")


def _maybe_raise(job: Job) -> JobResult:
    if job.name == "b":
        raise RuntimeError("task exploded\nsecond line")
    return JobResult(job.name, job.out, True, epochs=1)


def test_an_exception_in_a_task_fails_that_job_only(tmp_path: Path) -> None:
    f = tmp_path / "j.toml"
    f.write_text(
        "".join(
            f'[[job]]\nname = "{n}"\nrover = "r"\nbase = "b"\nnav = "n"\nout = "{n}.pos"\n' for n in "abc"
        )
    )
    done: list[str] = []
    res = runner.run_jobs(
        read_jobs(f), _maybe_raise, engine="local", workers=2, on_done=lambda r, n, t: done.append(r.name)
    )
    assert [r.name for r in res] == ["a", "b", "c"] and sorted(done) == ["a", "b", "c"]
    assert [r.ok for r in res] == [True, False, True]
    assert res[1].error == "RuntimeError: task exploded second line" and res[1].status == 1


def test_solve_job_reports_the_solve_error_line(tmp_path: Path) -> None:
    f = tmp_path / "j.toml"
    f.write_text(f'[[job]]\nrover = "{tmp_path / "missing.obs"}"\nbase = "b.obs"\nnav = "n.nav"\n')
    (job,) = read_jobs(f)
    res = solve_job(job)
    assert not res.ok and res.status == 2 and res.epochs == 0
    assert "n.nav: cannot read navigation file" in res.error and not res.error.startswith("error:")


def test_the_local_cluster_s_workers_run_quiet_and_the_caller_s_settings_stay() -> None:
    """The workers of the local cluster run with :data:`runner.LOCAL_CLUSTER_CONFIG` (no
    sampling profiler, slow monitors); the calling process's Dask settings are as before."""
    pytest.importorskip("distributed")
    import dask

    keys = list(runner.LOCAL_CLUSTER_CONFIG)
    before = {k: dask.config.get(k) for k in keys}
    assert before != runner.LOCAL_CLUSTER_CONFIG  # Dask's defaults differ, so the test can fail
    with runner.task_executor("dask", 1) as ex:
        seen = {k: ex.submit(dask.config.get, k).result(timeout=60) for k in keys}
    assert seen == runner.LOCAL_CLUSTER_CONFIG
    assert {k: dask.config.get(k) for k in keys} == before

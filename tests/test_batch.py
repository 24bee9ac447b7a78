"""`calibc batch`: the job file and its errors, one job as `calibc solve --json` would give
it, resuming from the results file, the summary, and the advice when Dask is missing.
The runs here use the default local cluster (one worker process); test_batch_cluster.py
runs a batch on a Dask cluster of separate processes."""

from __future__ import annotations

import importlib.util
import json
import os
import re
import sys
from dataclasses import replace
from pathlib import Path

import pytest
from batch_project import EXAMPLES, STATUS, direct, intervals, write_project
from cli_run import run as invoke

from calib_dsl.batch import run as run_module
from calib_dsl.batch import schedule
from calib_dsl.batch.jobs import Job, batch_jobs, read_job_file
from calib_dsl.batch.run import run_job

# the runs need Dask; reading job files and running one job do not
needs_dask = pytest.mark.skipif(importlib.util.find_spec("distributed") is None,
                                reason="calibc batch runs on Dask: pip install -e .[dev]")


def read_lines(path: Path) -> dict[str, dict]:
    lines = [json.loads(x) for x in path.read_text(encoding="utf-8").splitlines()]
    ids = [x["id"] for x in lines]
    assert len(ids) == len(set(ids)), f"an id has two lines: {ids}"
    return {x["id"]: x for x in lines}


# -- the job file ---------------------------------------------------------------------------------

def test_job_file_defaults_paths_and_values(tmp_path):
    jobs = {j.id: j for j in read_job_file(str(write_project(tmp_path / "p")))}
    assert list(jobs) == list(STATUS)
    folder = tmp_path / "p"
    a, b, rows = jobs["a"], jobs["b-hc4"], jobs["rows"]
    # relative paths are the job file's folder's, made absolute; top-level keys are defaults
    assert a.model == str(folder / "line.cal") and a.data == (str(folder / "a.csv"),)
    assert b.data == (f"m={folder / 'runs' / 'b.csv'}",) and b.strategy == "hc4"
    assert a.strategy == "tight" and a.formulation == "matrix" and a.identify and a.diagnose
    assert rows.rows == ("1..3",) and rows.exclude == ("m=2",) and rows.data == ()
    assert jobs["wide-e"].defines == ("e=0.05",) and jobs["tight-e"].defines == ("e=0.001",)
    assert jobs["arm"].model == str(EXAMPLES / "planar_arm.cal")
    assert jobs["arm"].formulation == "rotation"
    assert jobs["circle"].lsq and not jobs["circle"].identify
    assert rows.argv() == [str(folder / "line.cal"), "--strategy", "tight", "--formulation",
                           "matrix", "--tol", "1e-05", "--max-sweeps", "1000", "--rows", "1..3",
                           "--exclude", "m=2", "--identify", "--diagnose"]
    assert replace(rows, inner=False).argv()[-2:] == ["--no-inner", "--diagnose"]


BAD_FILES = [  # (job file text, line, col, message part)
    ('model = "m.cal"\n[[job]]\nid = "a"\ndata = 3\n', 4, 1,
     "data: must be a string or a list of strings"),
    ('model = "m.cal"\n[[job]]\nid = "a"\nstrat = "hc4"\n', 4, 1, "unknown key 'strat'"),
    ('colour = "red"\n[[job]]\nid = "a"\nmodel = "m.cal"\n', 1, 1, "unknown key 'colour'"),
    ('model = "m.cal"\n[[job]]\nid = "a"\n[[job]]\nid = "a"\n', 5, 1, "'a' is used twice"),
    ('model = "m.cal"\n[[job]]\nid = a\n', 3, 6, "not valid TOML"),
    ('model = "m.cal"\n', 1, 1, "no jobs"),
    ('[[job]]\nid = "a"\nmodel = "m.cal"\n[[job]]\nid = "b"\n', 4, 1, "job 2 has no 'model'"),
    ('model = "m.cal"\n[[job]]\nid = "a"\nrows = "m=5..2"\n', 4, 1, "the range 5..2 is empty"),
    ('model = "m.cal"\n[[job]]\nid = "a"\nexclude = "x"\n', 4, 1, "'x' is not a row number"),
    ('model = "m.cal"\n[[job]]\nid = "a"\nstrategy = "fast"\n', 4, 1,
     "'fast' is not one of tight, hc4"),
    ('model = "m.cal"\n[[job]]\nid = "a"\n\n  define = {e = "x"}\n', 5, 3,
     "e = x: the value must be a number"),
    ('model = "m.cal"\n[[job]]\nid = "a"\ndefine = {e = true}\n', 4, 1, "must be a number"),
    ('model = "m.cal"\nmax-sweeps = 0\n[[job]]\nid = "a"\n', 2, 1, "an integer >= 1"),
    ('model = "m.cal"\n[[job]]\nid = ""\n', 3, 1, "id: must be a non-empty string"),
    ('id = "a"\n[[job]]\nmodel = "m.cal"\n', 1, 1, "'id' belongs to each [[job]]"),
]


@pytest.mark.parametrize("text, line, col, message", BAD_FILES)
def test_bad_job_file_is_a_user_error(tmp_path, text, line, col, message):
    jobs = tmp_path / "jobs.toml"
    jobs.write_text(text, encoding="utf-8")
    res = invoke("batch", jobs, "-o", tmp_path / "out.jsonl")
    assert res.exit_code == 2
    first = res.stderr.splitlines()[0]
    assert first.startswith(f"{jobs}:{line}:{col}: error: "), res.stderr
    assert message in first
    assert "Traceback" not in res.output and not (tmp_path / "out.jsonl").exists()


def test_unreadable_job_file_and_misplaced_options(tmp_path):
    res = invoke("batch", tmp_path / "nope.toml", "-o", tmp_path / "o.jsonl")
    assert res.exit_code == 2 and "cannot read the job file" in res.stderr
    jobs = write_project(tmp_path)
    res = invoke("batch", jobs, "-o", tmp_path / "o.jsonl", "-D", "e=1")
    assert res.exit_code == 2
    assert res.stderr.strip() == ("error: -D goes with --data-glob; a job file sets it for "
                                  "each job (or for all at its top)")


def test_data_glob_makes_one_job_per_file(tmp_path):
    write_project(tmp_path)
    old = Path.cwd()
    os.chdir(tmp_path)
    try:
        jobs = batch_jobs("line.cal", "m=runs/*.csv", strategy="hc4", defines=("e=0.02",))
    finally:
        os.chdir(old)
    assert [j.id for j in jobs] == ["runs/b.csv", "runs/c.csv"]
    assert jobs[1] == Job("runs/c.csv", str(tmp_path / "line.cal"),
                          data=(f"m={tmp_path / 'runs' / 'c.csv'}",), defines=("e=0.02",),
                          strategy="hc4")
    res = invoke("batch", "line.cal", "--data-glob", "runs/*.txt", "-o", "o", cwd=tmp_path)
    assert res.exit_code == 2 and "--data-glob runs/*.txt: no file matches" in res.stderr
    for option, value, message in (("--rows", "m=0..2", "--rows 'm=0..2': row 0"),
                                   ("--exclude", "x", "--exclude 'x': 'x' is not a row"),
                                   ("-D", "e", "-D e: write NAME=VALUE")):
        res = invoke("batch", "line.cal", "--data-glob", "runs/*", option, value, "-o", "o",
                     cwd=tmp_path)
        assert res.exit_code == 2 and res.stderr.startswith(f"error: {message}"), res.stderr
    assert not (tmp_path / "o").exists()


# -- one job ------------------------------------------------------------------------------------

@pytest.mark.parametrize("job_id", ["a", "tight-e", "missing", "circle"])
def test_a_job_is_what_calibc_solve_json_gives(tmp_path, job_id, untimed):
    """The line's result is the document `calibc solve --json` writes for the job's
    arguments (but the time); an error, the message it prints."""
    job = {j.id: j for j in read_job_file(str(write_project(tmp_path)))}[job_id]
    line = run_job(job)
    assert line["id"] == job_id and line["status"] == STATUS[job_id]
    assert line["job"] == json.loads(json.dumps(job.spec()))
    res = invoke("solve", *job.argv(), "--json", tmp_path / "direct.json")
    if line["status"] == "error":
        assert res.exit_code == 2 and "result" not in line
        assert line["error"] == res.stderr.strip()
        return
    assert res.exit_code == (1 if line["status"] == "infeasible" else 0)
    expected = json.loads((tmp_path / "direct.json").read_text(encoding="utf-8"))
    got = json.loads(json.dumps(line["result"]))
    assert got["seconds"] >= 0
    assert untimed(got) == untimed(expected)


def test_an_internal_error_is_a_failed_line(tmp_path, monkeypatch):
    job = read_job_file(str(write_project(tmp_path)))[0]

    def boom(*args, **kwargs):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(run_module, "solve_report", boom)
    line = run_job(job)
    assert line["status"] == "failed" and line["id"] == "a"
    assert line["error"] == "internal error: ZeroDivisionError: a bug"


# -- a batch, and resuming it --------------------------------------------------------------------

@pytest.mark.slow
@needs_dask
def test_batch_then_resume(tmp_path, monkeypatch):
    jobs = write_project(tmp_path / "p")
    out = tmp_path / "out.jsonl"
    first = invoke("batch", jobs, "-o", out, "--workers", "1")
    assert first.exit_code == 1  # two jobs ended in errors: their lines say so
    lines = read_lines(out)
    assert {k: v["status"] for k, v in lines.items()} == STATUS
    for line in lines.values():  # each as run here, bit for bit
        status, found = direct(line["job"])
        assert status == line["status"]
        assert found == (line["error"] if status == "error" else intervals(line["result"]))
    assert re.search(r"^\[9/9\] \S+: \w+ \(\d+\.\d\d s\)$",
                     first.stderr.replace("calibc batch: ", ""), re.M)
    table = first.stdout.splitlines()
    assert table[0].split()[:3] == ["id", "status", "narrowed"]
    assert re.match(r"a +contracted +2/2 +\S+ +\S+ +\d+\.\d\d$", table[1])
    assert "proven inconsistent: " in next(t for t in table if t.startswith("tight-e "))
    assert "not found" in next(t for t in table if t.startswith("missing "))
    assert table[-1] == "9 jobs: 6 contracted, 2 error, 1 infeasible"

    # a rerun finds every job done: no cluster is started, the file stays as it was
    before = out.read_bytes()
    monkeypatch.setattr(schedule, "_client", lambda *a: pytest.fail("a cluster was started"))
    again = invoke("batch", jobs, "-o", out)
    assert "9 of 9 jobs already in" in again.stderr and again.stdout == first.stdout
    assert "warning" not in again.stderr
    assert out.read_bytes() == before
    # a job changed under its id is still skipped, with a warning
    jobs.write_text(jobs.read_text().replace('id = "a"\n', 'id = "a"\nlsq = true\n'))
    changed = invoke("batch", jobs, "-o", out)
    assert "warning: the line of a records another job" in changed.stderr
    assert out.read_bytes() == before
    jobs.write_text(jobs.read_text().replace("lsq = true\n", "", 1))
    monkeypatch.undo()

    # a line removed, and the last one cut short (a kill mid-write): those two run again
    text = out.read_text(encoding="utf-8").splitlines(keepends=True)
    gone, cut = json.loads(text[0])["id"], json.loads(text[-1])["id"]
    out.write_text("".join(text[1:-1]) + text[-1][:25], encoding="utf-8")
    resumed = invoke("batch", jobs, "-o", out, "--workers", "1")
    assert "7 of 9 jobs already in" in resumed.stderr
    ran = re.findall(r"\[\d/2\] (\S+):", resumed.stderr)
    assert sorted(ran) == sorted([gone, cut])
    after = out.read_text(encoding="utf-8").splitlines(keepends=True)
    assert after[:7] == text[1:-1]  # the kept lines untouched
    assert set(read_lines(out)) == set(STATUS)

    # --retry-errors runs the errors again, and only them; --force runs everything
    retried = invoke("batch", jobs, "-o", out, "--workers", "1", "--retry-errors", "--quiet")
    assert retried.stderr == "" and set(read_lines(out)) == set(STATUS)
    assert [json.loads(x)["id"] for x in out.read_text().splitlines()[-2:]] in (
        ["missing", "malformed"], ["malformed", "missing"])
    forced = invoke("batch", jobs, "-o", out, "--workers", "1", "--force")
    assert "already in" not in forced.stderr and "[9/9]" in forced.stderr
    assert set(read_lines(out)) == set(STATUS)


@pytest.mark.slow
@needs_dask
def test_data_glob_batch(tmp_path):
    write_project(tmp_path)
    res = invoke("batch", "line.cal", "--data-glob", "m=runs/*.csv", "-D", "e=0.05",
                 "--strategy", "hc4", "-o", "out.jsonl", "--workers", "1", cwd=tmp_path)
    assert res.exit_code == 0, res.output
    lines = read_lines(tmp_path / "out.jsonl")
    assert sorted(lines) == ["runs/b.csv", "runs/c.csv"]
    for line in lines.values():
        assert line["job"]["defines"] == ["e=0.05"] and line["job"]["strategy"] == "hc4"
        assert line["status"] == "contracted"
        assert direct(line["job"]) == ("contracted", intervals(line["result"]))
    assert res.stdout.splitlines()[-1] == "2 jobs: 2 contracted"


def test_without_dask_one_line_of_advice(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # `import distributed` fails
    res = invoke("batch", write_project(tmp_path), "-o", tmp_path / "o.jsonl")
    assert res.exit_code == 2
    assert res.stderr.count("\n") == 1 and "pip install calibc[batch]" in res.stderr


def test_a_job_with_outliers_is_what_solve_outliers_gives(tmp_path, untimed):
    """`outliers = 1` in a job: the line is `calibc solve --outliers 1 --json`'s document,
    the moved row named as the certain outlier."""
    (tmp_path / "d.csv").write_text("x,v\n0,0.1\n1,0.6\n2,1.1\n3,3.0\n4,2.1\n5,2.6\n")
    (tmp_path / "line.cal").write_text(
        "param p in [0, 1]; param q in [-1, 1];\n"
        'table m = "d.csv" { x : +- 1e-9; v : +- 0.01; }\n'
        "for k in 1..rows(m) { m.v[k] == p * m.x[k] + q; }\n")
    job, line = _one_job(tmp_path, untimed, "line.cal", "outliers = 1")
    assert job.outliers == 1 and job.argv()[-2:] == ["--outliers", "1"]
    assert line["result"]["outliers"]["certain"] == [4]


def _one_job(tmp_path: Path, untimed, model: str, key: str) -> tuple[Job, dict]:
    """The job of `model` with one more key line, run as a batch job: its line's result is
    what `calibc solve` writes with the job's arguments."""
    (tmp_path / "jobs.toml").write_text(f'[[job]]\nid = "one"\nmodel = "{model}"\n{key}\n')
    (job,) = read_job_file(str(tmp_path / "jobs.toml"))
    line = run_job(job)
    res = invoke("solve", *job.argv(), "--json", tmp_path / "direct.json")
    assert res.exit_code == 0, res.output
    expected = json.loads((tmp_path / "direct.json").read_text(encoding="utf-8"))
    assert untimed(json.loads(json.dumps(line["result"]))) == untimed(expected)
    return job, line


def test_a_job_that_shaves_is_what_solve_shave_gives(tmp_path, untimed):
    """`shave = 3` in a job: the line is `calibc solve --shave 3 --json`'s document, with the
    same shaved ends (no time budget: the same result on every worker)."""
    from tests.inner.test_shave import write_circle

    write_circle(tmp_path)
    job, line = _one_job(tmp_path, untimed, "circle.cal", "shave = 3")
    assert job.shave == 3 and job.argv()[-2:] == ["--shave", "3"]
    assert sorted(line["result"]["shaved"]["parameters"]) == ["cx", "cy", "radius"]

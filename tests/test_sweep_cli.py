"""``rustcloth.sweep.main``: the command ``python -m rustcloth sweep`` dispatches to."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
from rustcloth.sweep import main, read_index


@pytest.fixture
def sweep_file(tmp_path):
    path = tmp_path / "sweep.toml"
    path.write_text('base = "hanging"\nsteps = 200\n'
                    '[grid]\n"cloth.k_bend" = [5.0, 50.0]\n"cloth.nx" = [8]\n"cloth.ny" = [8]\n'
                    '"watchdog.max_stretch" = [1.0001, 3.0]\n'
                    '[record]\nevery = 50\n')
    return path


def test_a_sweep_runs_with_a_progress_line_and_ends_with_a_summary(sweep_file, tmp_path,
                                                                   capsys):
    out = tmp_path / "out"
    assert main([str(sweep_file), "--out", str(out), "--workers", "2", "--threads", "1",
                 "--progress", "plain"]) == 0
    captured = capsys.readouterr()
    assert captured.err.startswith("4 runs, 0 already complete\n")
    assert "[4/4] 2 ok, 2 failed" in captured.err
    assert "4 runs in" in captured.out and "4 ran now, 0 already complete" in captured.out
    assert "ok              2" in captured.out and "diverged        2" in captured.out
    assert "overstretched at step" in captured.out  # the failures, with their reasons
    assert [r["status"] for r in read_index(out)] == ["diverged", "ok", "diverged", "ok"]
    # Again: nothing to do.
    assert main([str(sweep_file), "--out", str(out), "--progress", "none"]) == 0
    assert "0 ran now, 4 already complete" in capsys.readouterr().out


def test_the_default_folder_is_named_after_the_sweep_file(sweep_file, tmp_path):
    assert main([str(sweep_file), "--progress", "none", "--workers", "1"]) == 0
    assert (tmp_path / "sweep" / "index.csv").exists()


def test_dry_run_lists_the_runs_and_runs_none(sweep_file, tmp_path, capsys):
    assert main([str(sweep_file), "--out", str(tmp_path / "out"), "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert out.strip().endswith("4 runs") and "cloth.k_bend=50.0" in out
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["missing.toml"], "cannot read 'missing.toml'"),
        (["{sweep}", "--workers", "0"], "argument --workers: must be at least 1, not '0'"),
        (["{sweep}", "--time-limit", "-3"], "argument --time-limit: must be a positive"),
        (["{sweep}", "--backend", "dask"], "argument --backend: invalid choice"),
        (["{sweep}", "--address", "auto"], "--address is for the ray backend"),
        (["{bad}"], "cloth.k_bnd: unknown field `k_bnd`"),
    ],
)
def test_bad_values_give_one_line_and_exit_2(sweep_file, tmp_path, capsys, args, message):
    bad = tmp_path / "bad.toml"
    bad.write_text('base = "hanging"\nsteps = 5\n[grid]\n"cloth.k_bnd" = [1.0]\n')
    args = [a.format(sweep=sweep_file, bad=bad) for a in args]
    assert main([*args, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert err.startswith("rustcloth sweep: error: ") and message in err, err


def test_help_documents_every_option_with_its_default(capsys):
    assert main(["--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    for option in ("--out", "--backend", "--workers", "--threads", "--address", "--time-limit",
                   "--retry-failed", "--progress", "--dry-run"):
        assert option in text
    assert "(default: local)" in text and "(default: auto)" in text


# -- a sweep file is code -----------------------------------------------------------------------
def test_dry_run_imports_nothing(tmp_path, capsys):
    # `--dry-run` ("check the description and list the runs") imported and ran the functions
    # a sweep file names: with `scene_fn = "make.py:make"`, make.py ran at import and make()
    # once per run.
    (tmp_path / "make.py").write_text(
        "import pathlib\npathlib.Path(__file__).with_name('imported').write_text('yes')\n"
        "def make(k_bend):\n    raise AssertionError('called')\n")
    (tmp_path / "sweep.toml").write_text('scene_fn = "make.py:make"\nseconds = 1.0\n'
                                         '[grid]\nk_bend = [1.0, 2.0]\n')
    assert main([str(tmp_path / "sweep.toml"), "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "k_bend=2.0" in out and "2 runs (scene_fn is not called" in out
    assert not (tmp_path / "imported").exists()


def test_a_sweep_file_cannot_run_a_shell_command(tmp_path, capsys):
    # `scene_fn = "os:system"` ran `touch pwned` for each run, even under --dry-run.
    (tmp_path / "sweep.toml").write_text('scene_fn = "os:system"\nsteps = 1\n'
                                         '[grid]\ncommand = ["touch pwned"]\n')
    for extra in ([], ["--dry-run"]):
        code = main([str(tmp_path / "sweep.toml"), "--out", str(tmp_path / "out"), *extra])
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1 and "--module os" in err, err
    assert not (tmp_path / "pwned").exists() and not (tmp_path / "out").exists()


def test_help_says_a_sweep_file_is_code(capsys):
    assert main(["--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "A sweep file is code" in text and "--module NAME" in text


# -- errors in one line -------------------------------------------------------------------------
@pytest.mark.parametrize("out", ["{file}", "/dev/full", "{file}/below"])
def test_an_unusable_out_folder_is_one_line(sweep_file, tmp_path, capsys, out):
    # `--out` naming a file (or /dev/full) is a one-line error, not a NotADirectoryError
    # traceback.
    afile = tmp_path / "afile"
    afile.write_text("")
    for progress in ("none", "plain"):
        code = main([str(sweep_file), "--out", out.format(file=afile), "--progress", progress])
        err = capsys.readouterr().err
        assert code == 2 and "Traceback" not in err, err
        assert err.startswith("rustcloth sweep: error: Not a directory") and err.count("\n") == 1


@pytest.mark.parametrize(("text", "needle"), [
    ('base = "hanging"\nseconds = 1e308\n', "seconds = 1e+308 is more than 10,000,000"),
    ('base = "hanging"\nsteps = 1180591620717411303424\n', "steps must be a whole number"),
    ("x = " + "[" * 5000 + "]" * 5000 + "\n", "nested too deeply"),
])
def test_a_run_too_long_or_a_file_too_deep_is_one_line(tmp_path, capsys, text, needle):
    # A step count too large for a run (`seconds = 1e308`, `steps = 2**70`) or a TOML nested
    # thousands deep is refused in one line, by --dry-run too, before anything is listed.
    (tmp_path / "sweep.toml").write_text(text)
    for extra in ([], ["--dry-run"]):
        code = main([str(tmp_path / "sweep.toml"), "--out", str(tmp_path / "out"), *extra])
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1 and needle in err, err


def test_sweep_errors_exit_2_from_the_shell(sweep_file, tmp_path):
    # From the shell too: one line and exit status 2, not a traceback and 1.
    (tmp_path / "afile").write_text("")
    proc = subprocess.run([sys.executable, "-m", "rustcloth", "sweep", str(sweep_file),
                           "--out", str(tmp_path / "afile")], capture_output=True, text=True,
                          timeout=60, env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert proc.stderr.count("\n") == 1 and "Not a directory" in proc.stderr

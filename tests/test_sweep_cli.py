"""``rustcloth.sweep.main``: the command ``python -m rustcloth sweep`` dispatches to."""

from __future__ import annotations

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
    assert "progress: a plain line" in captured.err or "progress: tqdm" in captured.err
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
        (["{sweep}", "--workers", "0"], "argument --workers: 0 is not >= 1"),
        (["{sweep}", "--time-limit", "-3"], "argument --time-limit: -3.0 is not a positive"),
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

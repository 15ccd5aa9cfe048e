"""The command line: sub-commands, help, one-line errors with exit code 2, exports, and the
hand-off to the sub-commands other modules own."""

from __future__ import annotations

import re
import subprocess
import sys
import types

import numpy as np
import pytest
import rustcloth
from conftest import small_scene
from rustcloth import cli


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    code = cli.main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line_error(err: str, *needles: str) -> None:
    assert "Traceback" not in err
    assert err.count("\n") == 1 and err.endswith("\n"), err
    for needle in needles:
        assert needle in err


# -- bad --seconds values: one line naming the option, exit status 2, nothing run ----------
def test_run_seconds_nan_is_a_one_line_error(capsys):
    code, out, err = run_cli(capsys, "run", "--seconds", "nan")
    assert code == 2 and out == ""
    assert_one_line_error(err, "--seconds", "'nan'")


def test_run_seconds_not_positive_or_infinite_is_refused(capsys):
    # Not clamped to a step: a run of another length than asked would pass for the right one.
    for value in ("-1", "-3", "0", "-inf", "inf"):
        code, out, err = run_cli(capsys, "run", f"--seconds={value}")
        assert code == 2 and out == ""
        assert_one_line_error(err, "--seconds", "positive")


def test_run_seconds_past_the_step_limit_is_refused(capsys):
    # The step count is checked before the run starts, or it would run practically forever.
    for value in ("1e308", str(cli.MAX_STEPS * 0.001 * 2)):
        code, out, err = run_cli(capsys, "run", "hanging", "--seconds", value)
        assert code == 2 and out == ""
        assert_one_line_error(err, "--seconds", f"{cli.MAX_STEPS:,}")


def test_run_seconds_nan_exits_2_from_the_shell():
    proc = subprocess.run([sys.executable, "-m", "rustcloth", "run", "--seconds", "nan"],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and proc.stdout == ""
    assert_one_line_error(proc.stderr, "--seconds")


# -- run ---------------------------------------------------------------------------------------
def test_run_takes_a_toml_path(capsys, tmp_path):
    path = tmp_path / "small.toml"
    path.write_text(small_scene().to_toml())
    code, out, err = run_cli(capsys, "run", str(path), "--seconds", "0.05")
    assert code == 0, err
    assert out.startswith("small: 48 particles (8x6)") and "50 steps" in out
    assert "summary: 50 steps" in out


def test_run_covers_fractions_of_a_second(capsys):
    code, out, _ = run_cli(capsys, "run", "hanging", "--seconds", "0.25")
    assert code == 0 and "summary: 250 steps" in out
    code, out, _ = run_cli(capsys, "run", "hanging", "--seconds", "2.5",
                           "--integrator", "verlet")
    rows = [line.split()[0] for line in out.splitlines() if re.match(r"\s+\d+\.\d\d ", line)]
    assert code == 0 and rows == ["1.00", "2.00", "2.50"] and "verlet" in out


def test_run_prints_a_stability_warning_as_one_line(capsys):
    code, _, err = run_cli(capsys, "run", "hanging", "--integrator", "explicit_euler",
                           "--seconds", "0.01")
    assert code == 0
    assert err.startswith("warning: dt = 0.001 s exceeds") and err.count("\n") == 1


def test_run_reports_an_unknown_scene_in_one_line(capsys, tmp_path):
    code, _, err = run_cli(capsys, "run", "no_such_scene")
    assert code == 2
    assert_one_line_error(err, "no_such_scene", "hanging")
    code, _, err = run_cli(capsys, "run", str(tmp_path / "missing.toml"))
    assert code == 2
    assert_one_line_error(err, "missing.toml")


def test_run_refuses_an_unknown_integrator_in_one_line(capsys):
    code, _, err = run_cli(capsys, "run", "--integrator", "euler")
    assert code == 2
    assert_one_line_error(err, "--integrator", "'euler'")


def test_run_export_usd_holds_the_run(capsys, tmp_path):
    pytest.importorskip("pxr")
    from pxr import Usd, UsdGeom

    path = tmp_path / "out.usd"
    code, out, err = run_cli(capsys, "run", "hanging", "--seconds", "0.2", "--fps", "10",
                             "--export", str(path))
    assert code == 0, err
    assert f"wrote {path}: 3 frames at 10 fps" in out
    stage = Usd.Stage.Open(str(path))
    assert stage.GetTimeCodesPerSecond() == 10
    points = UsdGeom.Mesh(stage.GetDefaultPrim()).GetPointsAttr()
    assert points.GetTimeSamples() == [0.0, 1.0, 2.0]
    twin = rustcloth.Simulation("hanging")
    for code_ in (0.0, 1.0, 2.0):
        assert np.array_equal(np.asarray(points.Get(code_)), twin.positions)
        twin.step(100)


def test_run_export_obj_sequence_and_last_frame(capsys, tmp_path):
    pytest.importorskip("trimesh")
    code, out, err = run_cli(capsys, "run", "hanging", "--seconds", "0.1", "--fps", "20",
                             "--export", str(tmp_path / "seq" / "c_##.obj"))
    assert code == 0, err
    assert sorted(p.name for p in (tmp_path / "seq").iterdir()) == ["c_00.obj", "c_01.obj",
                                                                    "c_02.obj"]
    code, out, err = run_cli(capsys, "run", "hanging", "--seconds", "0.1",
                             "--export", str(tmp_path / "new" / "last.glb"))
    assert code == 0 and (tmp_path / "new" / "last.glb").stat().st_size > 0


def test_run_export_refuses_a_bad_path_before_running(capsys, tmp_path):
    for path, needle in (("out.xyz", ".usd"), ("seq_##.ply", ".obj only")):
        code, out, err = run_cli(capsys, "run", "--seconds", "1000", "--export",
                                 str(tmp_path / path))
        assert code == 2 and out == ""
        assert_one_line_error(err, needle)


def test_run_fps_above_one_frame_per_step_is_refused(capsys, tmp_path):
    pytest.importorskip("pxr")
    code, _, err = run_cli(capsys, "run", "--fps", "5000", "--export", str(tmp_path / "a.usda"))
    assert code == 2
    assert_one_line_error(err, "--fps", "one frame per step")


@pytest.mark.parametrize(("module", "extra", "suffix"),
                         [("pxr", "usd", "out.usd"), ("trimesh", "export", "out.obj")])
def test_run_export_without_its_extra_says_which(capsys, monkeypatch, tmp_path, module, extra,
                                                 suffix):
    monkeypatch.setitem(sys.modules, module, None)
    code, out, err = run_cli(capsys, "run", "--export", str(tmp_path / suffix))
    assert code == 2 and out == ""
    assert_one_line_error(err, f"pip install 'rustcloth[{extra}]'")


# -- help and version --------------------------------------------------------------------------
def test_version_is_the_package_version(capsys):
    code, out, _ = run_cli(capsys, "--version")
    assert code == 0 and out == f"rustcloth {rustcloth.__version__}\n"


def test_help_lists_every_command_without_markup(capsys):
    code, out, _ = run_cli(capsys, "--help")
    assert code == 0
    for command in ("run", "scenes", "demo", "render", "accuracy", "sweep"):
        assert f"\n    {command} " in out
    assert "``" not in out and ":func:" not in out


def test_run_help_gives_every_option_a_text_and_a_default(capsys):
    code, out, _ = run_cli(capsys, "run", "--help")
    assert code == 0
    out = " ".join(out.split())
    assert "(default: drape)" in out and "(default: 5.0)" in out and "(default: 30.0)" in out
    assert "(default: the scene's)" in out and "(default: no export)" in out
    assert "['" not in out and "``" not in out  # no Python list, no reStructuredText


def test_scenes_lists_the_builtin_scenes(capsys):
    code, out, _ = run_cli(capsys, "scenes")
    assert code == 0 and out.split() == rustcloth.scenes()


def test_no_command_is_a_one_line_error(capsys):
    code, _, err = run_cli(capsys)
    assert code == 2
    assert_one_line_error(err, "COMMAND")


# -- sub-commands owned elsewhere -------------------------------------------------------------
@pytest.fixture
def fake_sweep(monkeypatch):
    """A stand-in rustcloth.sweep whose main records its arguments."""
    module = types.ModuleType("rustcloth.sweep")
    module.calls = []

    def main(argv):
        module.calls.append(argv)
        return 7

    module.main = main
    monkeypatch.setitem(sys.modules, "rustcloth.sweep", module)
    return module


def test_delegated_command_gets_its_arguments_verbatim(capsys, fake_sweep):
    code, _, _ = run_cli(capsys, "sweep", "--help", "--frames", "2", "drape")
    assert code == 7 and fake_sweep.calls == [["--help", "--frames", "2", "drape"]]


def test_demo_options_are_not_taken_for_the_scene(capsys, monkeypatch):
    # Without moderngl, `demo --frames 2` ran the headless fallback with "--frames" as the
    # scene name. Now the arguments go to the demo unchanged, or not at all.
    calls = []
    app = types.ModuleType("rustcloth.app")
    app.main_demo = lambda argv: calls.append(argv) or 0
    monkeypatch.setitem(sys.modules, "rustcloth.app", app)
    assert run_cli(capsys, "demo", "--frames", "2")[0] == 0
    assert calls == [["--frames", "2"]]


@pytest.mark.parametrize(("argv", "module", "extra"), [
    (["demo", "--frames", "2"], "moderngl", "viewer"),
    (["render", "drape"], "PIL", "viewer"),
    (["render", "drape", "--mp4"], "imageio_ffmpeg", "video"),
    (["accuracy", "--quick"], "matplotlib", "study"),
])
def test_missing_extra_is_one_line_and_exit_2(capsys, monkeypatch, tmp_path, argv, module,
                                              extra):
    if extra == "video":
        # Without the viewer extra too, render names that one first (it cannot start without).
        for needed in ("moderngl", "PIL", "imageio"):
            pytest.importorskip(needed)
    monkeypatch.setitem(sys.modules, module, None)
    monkeypatch.chdir(tmp_path)  # render checks its output folder, out/drape, first
    code, out, err = run_cli(capsys, *argv)
    assert code == 2 and out == ""
    assert_one_line_error(err, f"rustcloth {argv[0]}", f"pip install 'rustcloth[{extra}]'")


def test_a_module_missing_inside_a_delegated_command_names_its_extra(capsys, fake_sweep):
    def main(argv):
        raise ModuleNotFoundError("No module named 'ray'", name="ray")

    fake_sweep.main = main
    code, _, err = run_cli(capsys, "sweep")
    assert code == 2
    assert_one_line_error(err, "rustcloth[ray]")


def test_sweep_before_its_module_exists_is_one_line(capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "rustcloth.sweep", None)
    code, _, err = run_cli(capsys, "sweep", "--help")
    assert code == 2
    assert_one_line_error(err, "rustcloth sweep", "not available")


# -- one command line ---------------------------------------------------------------------------
EXTRA_MODULES = ("moderngl", "glcontext", "glfw", "PIL", "imageio", "imageio_ffmpeg",
                 "matplotlib", "pxr", "trimesh", "ray")


def test_every_help_works_without_its_extra():
    # Help is what a person reads before installing an extra, so every command's help is
    # printed here in a fresh interpreter where no optional extra can be imported.
    code = ("import sys\n"
            f"for name in {EXTRA_MODULES!r}: sys.modules[name] = None\n"
            "from rustcloth.cli import main\n"
            "sys.exit(main(sys.argv[1:]))\n")
    for command in ("run", "scenes", "demo", "render", "accuracy", "sweep"):
        proc = subprocess.run([sys.executable, "-c", code, command, "--help"],
                              capture_output=True, text=True, timeout=60)
        assert proc.returncode == 0, (command, proc.stderr)
        assert proc.stdout.startswith(f"usage: rustcloth {command}") and proc.stderr == ""
        text = " ".join(proc.stdout.split())
        # Render's help said "(default: out/SCENE) (default: None)".
        assert "(default: None)" not in text, (command, text)
        assert not re.search(r"\(default: [^)]*\) \(default:", text), (command, text)
        assert "default: (" not in text, (command, text)  # a Python tuple


def test_every_parser_is_the_shared_one():
    # Five parsers in four files had three copies of the argument types, the formatter and
    # the parser, and errors in three styles.
    from rustcloth import _cli
    from rustcloth.study import accuracy
    from rustcloth.sweep import cli as sweep_cli
    from rustcloth.viewer import cli as viewer_cli

    parsers = [cli.build_parser(), viewer_cli.demo_parser(), viewer_cli.render_parser(),
               accuracy.build_parser(), sweep_cli.parser()]
    for parser in parsers:
        assert isinstance(parser, _cli.Parser) and parser.formatter_class is _cli.Formatter
    for module in (cli, viewer_cli, accuracy, sweep_cli):
        assert not [name for name in vars(module) if name.startswith(("_positive", "_Parser",
                                                                      "_Formatter"))]


def test_a_deeply_nested_scene_is_one_line(capsys, tmp_path):
    # A TOML nested thousands deep is a one-line error, not a RecursionError traceback.
    path = tmp_path / "deep.toml"
    path.write_text("[cloth]\nx = " + "[" * 5000 + "]" * 5000 + "\n")
    code, out, err = run_cli(capsys, "run", str(path))
    assert code == 2 and out == ""
    assert_one_line_error(err, "rustcloth run: error: ")


def test_run_export_to_a_folder_without_files_fails_before_running(capsys):
    # `run --export /proc/x.usd` simulated the whole run, then died in a pxr traceback.
    pytest.importorskip("pxr")
    code, out, err = run_cli(capsys, "run", "--seconds", "1000", "--export", "/proc/x.usd")
    assert code == 2 and out == ""
    assert_one_line_error(err, "rustcloth run: error: ", "'/proc'")


@pytest.mark.parametrize("argv", [["render", "hanging", "--out", "/dev/full"],
                                  ["render", "hanging", "--out", "/dev/full/x"],
                                  ["accuracy", "--out", "/dev/full/x"],
                                  ["sweep", "/dev/full"]])
def test_an_unusable_path_is_one_line_exit_2(capsys, argv):
    # A path that cannot be written is a one-line error (exit 2), not an OSError traceback.
    code, out, err = run_cli(capsys, *argv)
    assert code == 2 and out == ""
    assert_one_line_error(err, f"rustcloth {argv[0]}: error: ", "/dev/full")


def test_user_errors_from_a_command_are_one_line(capsys, fake_sweep):
    # Whatever a command raises for a bad input (a package error, a ValueError, a TypeError,
    # an OSError) is said in one line with exit 2; the dispatcher guards every command.
    for error in (rustcloth.ParameterError("cloth.nx: must be > 1", "cloth.nx"),
                  ValueError("bad value"), TypeError("bad type"),
                  FileNotFoundError(2, "No such file or directory", "x.toml")):
        def main(argv, error=error):
            raise error

        fake_sweep.main = main
        code, out, err = run_cli(capsys, "sweep")
        assert code == 2 and out == ""
        assert_one_line_error(err, "rustcloth sweep: error: ")


@pytest.mark.parametrize("module", ["trimesh", "PIL"])
def test_run_export_without_an_export_module_fails_before_running(capsys, monkeypatch,
                                                                   tmp_path, module):
    # With only trimesh, `run --export x.glb` ran the whole simulation, then printed a
    # traceback (trimesh imports Pillow only when it writes) and wrote nothing.
    ran = []
    monkeypatch.setattr(cli, "Simulation", lambda *a: ran.append(a))
    monkeypatch.setitem(sys.modules, module, None)
    code, out, err = run_cli(capsys, "run", "hanging", "--seconds", "0.01",
                             "--export", str(tmp_path / "x.glb"))
    assert code == 2 and ran == [] and not (tmp_path / "x.glb").exists()
    assert_one_line_error(err, "rustcloth run", "pip install 'rustcloth[export]'")

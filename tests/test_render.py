"""Replay videos: recorded motion, the ghost, the MP4, bad input.

Rendering runs headless through ``MUJOCO_GL=egl`` (set in conftest.py); the
tests that draw skip only when no OpenGL backend works on the machine.
Frames are tiny (160x120, 320x240) and few.
"""

from __future__ import annotations

import json
import math
import os
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

from simpro_mj.commands.main import main
from simpro_mj.config.scenario import load_scenario
from simpro_mj.plant.model import MODEL_PATH, load_spec
from simpro_mj.report.runner import execute
from simpro_mj.sim.build import Build

PITCH_STEP_S = 1.0  # step_pitch.yaml: 3 deg at t = 1 s


@pytest.fixture(scope="module")
def pitch_run(tmp_path_factory) -> Path:
    """A 3 s pitch step (the 3 deg set-point is reached after about 1.5 s)."""
    out = tmp_path_factory.mktemp("render") / "step_pitch"
    # K K_I = 1, no set-point filter: the response these checks were written for
    scenario = load_scenario(
        "step_pitch.yaml",
        [
            "duration_s=3",
            "controller.outer.gains=[1, 1, 1]",
            "controller.setpoint_filter.type=none",
        ],
    )
    execute(scenario, out, plots=False, quiet=True)
    return out


def _scene(pitch_run, width=320, height=240, camera="side"):
    from simpro_mj.report.recording import load_recording
    from simpro_mj.report.scene import ReplayScene

    rec = load_recording(pitch_run)
    try:
        scene = ReplayScene(rec.scenario, width, height, camera)
    except Exception as exc:  # noqa: BLE001 - no OpenGL backend on this machine
        pytest.skip(f"no offscreen OpenGL: {exc}")
    return rec, scene


# ---------------------------------------------------------------- recording


def test_qpos_recorded_is_the_simulated_state(pitch_run):
    """qpos.npz holds the full qpos at every logged row; its slides are q_i."""
    from simpro_mj.report.recording import load_recording

    rec = load_recording(pitch_run)
    m = mujoco.MjModel.from_xml_path(str(MODEL_PATH))
    assert rec.qpos.shape == (len(rec.columns["time_s"]), m.nq) == (3001, 13)
    # timeseries.csv holds 12 significant digits, qpos.npz the float64 bits
    np.testing.assert_allclose(rec.time_s, rec.columns["time_s"], rtol=1e-11, atol=1e-15)
    for i in (1, 2, 3):
        col = rec.qpos_names.index(f"leg{i}")
        np.testing.assert_allclose(rec.qpos[:, col], rec.columns[f"q{i}_m"], rtol=1e-11)
    # the pitch hinge moves by the step (3 deg) within a few tenths of a degree
    pitch = rec.qpos[:, rec.qpos_names.index("pitch")]
    assert math.degrees(pitch[-1] - pitch[0]) == pytest.approx(3.0, abs=0.3)


def test_ghost_changes_nothing_in_the_dynamics():
    """The mocap ghost is visual only: every logged column and qpos bit-identical without it."""
    # K K_I = 1, no set-point filter: the response these checks were written for
    scenario = load_scenario(
        "step_pitch.yaml",
        [
            "duration_s=3",
            "controller.outer.gains=[1, 1, 1]",
            "controller.setpoint_filter.type=none",
        ],
    )
    spec = load_spec(scenario.plant.tree())
    with_ghost = spec.compile()
    ghost = with_ghost.body("ghost")
    assert with_ghost.body_mocapid[ghost.id] == 0 and with_ghost.body_jntnum[ghost.id] == 0
    geoms = np.flatnonzero(with_ghost.geom_bodyid == ghost.id)
    assert len(geoms) == 2
    assert not with_ghost.geom_contype[geoms].any() and not with_ghost.geom_conaffinity[geoms].any()
    assert with_ghost.body_mass[ghost.id] == 0.0

    spec.delete(spec.body("ghost"))
    without = spec.compile()
    assert without.nbody == with_ghost.nbody - 1 and without.nq == with_ghost.nq

    a = Build(scenario, model=with_ghost).simulation().run()
    b = Build(scenario, model=without).simulation().run()
    assert a.status == b.status == "ok"
    assert a.columns.keys() == b.columns.keys()
    for name in a.columns:
        assert a.columns[name].tobytes() == b.columns[name].tobytes(), name
    assert a.qpos.tobytes() == b.qpos.tobytes()
    # the run really moved (a test of two frozen runs would prove nothing)
    assert math.degrees(a.columns["pitch_rad"][-1] - a.columns["pitch_rad"][0]) > 2.0


# ---------------------------------------------------------------- what is drawn


def _tilt_deg(ids: np.ndarray, geom_id: int) -> float:
    """Tilt of a geom's silhouette in the side view: the slope of its mean row per column.

    The side camera looks along +y with +x to the right: a positive pitch
    (R = Ry(pitch), eq. 8) lowers the +x end, i.e. the rows grow to the right.
    """
    rows, cols = np.nonzero(ids == geom_id)
    assert len(cols) > 200, "geom not in view"
    uc = np.unique(cols)
    mean_row = np.array([rows[cols == c].mean() for c in uc])
    slope = np.polyfit(uc, mean_row, 1)[0]
    return math.degrees(math.atan(slope))


def test_pitch_step_tilts_the_rendered_platform_and_ghost(pitch_run):
    """Segmentation of the side view: the platform tilts by the logged pitch, the right way."""
    from simpro_mj.report.recording import ghost_poses, nearest_rows

    rec, scene = _scene(pitch_run)
    m = scene.model
    frame, ghost = m.geom("platform_frame").id, m.geom("ghost_frame").id
    tilt, ghost_tilt, pitch, ref = [], [], [], []
    for t in (0.9, 2.9):  # before the step, after it has settled
        row = int(nearest_rows(rec.time_s, np.array([t]))[0])
        gp, gq = ghost_poses(rec.columns, np.array([row]))
        scene.pose(rec.qpos[row], gp[0], gq[0])
        tilt.append(_tilt_deg(scene.segmentation(), frame))
        scene.option.geomgroup[2] = 0  # the ghost alone (the platform hides it where they meet)
        ghost_tilt.append(_tilt_deg(scene.segmentation(), ghost))
        scene.option.geomgroup[2] = 1
        pitch.append(math.degrees(rec.columns["pitch_rad"][row]))
        ref.append(math.degrees(rec.columns["pitch_ref_rad"][row]))
    scene.close()
    # the side view is parallel to the pitch plane, so the image keeps angles;
    # 0.4 deg covers the pixel quantisation of a ~130 px wide silhouette
    assert tilt[1] - tilt[0] == pytest.approx(pitch[1] - pitch[0], abs=0.4)
    assert tilt[1] - tilt[0] > 2.0  # the right way: +x end down
    assert ghost_tilt[1] - ghost_tilt[0] == pytest.approx(ref[1] - ref[0], abs=0.4)


def test_render_a_one_second_clip(pitch_run, tmp_path):
    """1 s at 25 fps, 160x120: the MP4 decodes to 25 frames that change while it moves."""
    iio = pytest.importorskip("imageio.v3")
    _scene(pitch_run, 16, 16)[1].close()  # skip cleanly without OpenGL
    out = tmp_path / "clip.mp4"
    code = main(
        [
            "render", str(pitch_run), "--size", "160x120", "--no-strip", "--camera", "side",
            "--start", str(PITCH_STEP_S), "--end", str(PITCH_STEP_S + 1.0), "--out", str(out),
            "--jobs", "2",
        ]
    )  # fmt: skip
    assert code == 0
    frames = iio.imread(out)
    assert frames.shape == (25, 120, 160, 3)
    frames = frames[:, 12:]  # below the time overlay, which changes in every frame
    diffs = [np.abs(frames[i + 1].astype(int) - frames[i]).mean() for i in range(24)]
    # the platform tilts by 3 deg during this second: the picture changes between frames
    # far above the codec's noise, and by much more from the first to the last frame
    assert np.median(diffs) > 0.05
    assert np.abs(frames[-1].astype(int) - frames[0]).mean() > 10 * np.median(diffs)


def test_plot_strip_cursor_moves(pitch_run, tmp_path):
    """With the strip: frames are taller by half a view and the red cursor moves right."""
    iio = pytest.importorskip("imageio.v3")
    _scene(pitch_run, 16, 16)[1].close()
    out = tmp_path / "strip.mp4"
    code = main(
        ["render", str(pitch_run), "--size", "160x120", "--fps", "2", "--out", str(out),
         "--jobs", "1"]
    )  # fmt: skip
    assert code == 0
    frames = iio.imread(out)
    assert frames.shape == (6, 180, 160, 3)  # 3 s at 2 fps; 120 + 60 rows of plots
    strip = frames[:, 120:].astype(int)
    red = (strip[..., 0] > 150) & (strip[..., 1] < 90) & (strip[..., 2] < 90)
    # left edge of the first panel's cursor (its anti-aliased width varies, 2-3 px)
    cursor_x = [np.nonzero(r.any(axis=0))[0][0] for r in red]
    assert all(b > a for a, b in zip(cursor_x, cursor_x[1:], strict=False))


def test_compare_folder_side_by_side(tmp_path):
    """A folder of runs is drawn side by side: twice as wide."""
    iio = pytest.importorskip("imageio.v3")
    for mode in ("joint_only", "task_space"):
        sc = load_scenario("step_pitch.yaml", ["duration_s=0.2", f"controller.mode={mode}"])
        execute(sc, tmp_path / "cmp" / mode, plots=False, quiet=True)
    code = main(
        ["render", str(tmp_path / "cmp"), "--size", "64x48", "--fps", "10", "--jobs", "1",
         "--no-strip"]
    )  # fmt: skip
    if code != 0:
        pytest.skip("no offscreen OpenGL")
    frames = iio.imread(tmp_path / "cmp" / "replay.mp4")
    assert frames.shape == (2, 48, 128, 3)
    # each view carries its run's name on a dark label in its top-left corner
    assert frames[0, :4, :8].mean() < 60 and frames[0, :4, 64:72].mean() < 60


# ---------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    "extra, needle",
    [
        (["--camera", "top"], "--camera"),
        (["--fps", "0"], "--fps"),
        (["--fps", "nan"], "--fps"),
        (["--size", "161x120"], "--size"),
        (["--speed", "-1"], "--speed"),
        (["--start", "5"], "--start"),
        (["--out", "clip.gif"], "--out"),
    ],
)
def test_bad_options_one_line_exit_2(pitch_run, extra, needle, capsys):
    assert main(["render", str(pitch_run), *extra]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: ") and needle in err
    assert not (pitch_run / "replay.mp4").exists()


def test_bad_folders_one_line_exit_2(tmp_path, capsys):
    assert main(["render", str(tmp_path / "missing")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no such folder" in err
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "timeseries.csv").write_text("time_s\n0\n")
    assert main(["render", str(tmp_path / "empty")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no recorded motion" in err


def test_batch_folder_of_many_runs_one_line_exit_2(pitch_run, tmp_path, capsys):
    import shutil

    for i in range(5):
        shutil.copytree(pitch_run, tmp_path / "batch" / f"v{i}")
    assert main(["render", str(tmp_path / "batch")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "too many runs" in err and "at most 4" in err


def test_unwritable_out_one_line_exit_2(pitch_run, tmp_path, capsys):
    blocker = tmp_path / "a_file"
    blocker.write_text("mine\n")
    assert main(["render", str(pitch_run), "--out", str(blocker / "clip.mp4")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--out" in err
    assert blocker.read_text() == "mine\n"  # the user's file untouched


def test_missing_video_extra_says_how_to_install(pitch_run, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # import fails
    assert main(["render", str(pitch_run)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "simpro-sim[video]" in err


# ---------------------------------------------------------------- run --video, view


def test_run_with_video_renders_at_the_end(tmp_path, capsys):
    iio = pytest.importorskip("imageio.v3")
    out = tmp_path / "run"
    code = main(["run", "step_pitch.yaml", "--set", "duration_s=0.2", "--no-plots", "--out",
                 str(out), "--video"])  # fmt: skip
    if code == 2 and "cannot render" in capsys.readouterr().err:
        pytest.skip("no offscreen OpenGL")
    # 0.2 s: the pose is still moving (not_settled, exit 1); the video is written all the same
    assert code == (0 if json.loads((out / "metrics.json").read_text())["status"] == "ok" else 1)
    assert iio.imread(out / "replay.mp4").shape == (5, 720, 640, 3)  # 0.2 s at 25 fps


def test_view_without_display_suggests_render(monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(sys, "platform", "linux")
    assert main(["view", "step_pitch.yaml"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no display" in err and "simpro-sim render" in err


class _FakeViewer:
    """What play() uses of a launch_passive handle, recording what it was shown."""

    def __init__(self, frames_open: int):
        import contextlib

        self.left, self.texts, self.qpos, self.mocap = frames_open, [], [], []
        self.opt = mujoco.MjvOption()
        self.lock = contextlib.nullcontext
        self.data = None

    def is_running(self):
        self.left -= 1
        return self.left >= 0

    def set_texts(self, texts):
        self.texts.append(texts[2])

    def sync(self):
        self.qpos.append(self.data.qpos.copy())
        self.mocap.append(self.data.mocap_quat[0].copy())


def test_view_plays_the_recording_paced_by_the_clock(pitch_run):
    """play(): row nearest to start + speed * elapsed, ghost posed, overlay with the pose."""
    from simpro_mj.report.recording import load_recording
    from simpro_mj.report.scene import replay_model
    from simpro_mj.report.viewer import play

    rec = load_recording(pitch_run)
    model, data = replay_model(rec.scenario)
    viewer = _FakeViewer(frames_open=40)
    viewer.data = data
    ticks = iter(np.arange(0.0, 10.0, 0.1))  # a clock advancing 0.1 s per call
    shown = play(viewer, model, data, rec, speed=0.5, start=0.5, clock=lambda: next(ticks),
                 sleep=lambda s: None)  # fmt: skip
    # 0.05 s of simulated time per clock tick: 0.55, 0.60, ... 2.50 s, one new row each
    assert shown == 40
    assert viewer.texts[0].startswith("t   0.550 s")
    assert viewer.texts[-1].startswith("t   2.500 s")
    assert viewer.qpos[0] == pytest.approx(rec.qpos[550], abs=0)
    assert viewer.qpos[-1] == pytest.approx(rec.qpos[2500], abs=0)
    assert "pitch" in viewer.texts[-1] and "(set +3.000)" in viewer.texts[-1]
    # the ghost follows the set-point: identity before the step, pitched 3 deg after it
    assert viewer.mocap[0] == pytest.approx([1, 0, 0, 0])
    assert 2 * math.degrees(math.asin(viewer.mocap[-1][2])) == pytest.approx(3.0, abs=1e-9)


def test_gl_backend_falls_back_and_names_what_is_missing(pitch_run, tmp_path, monkeypatch, capsys):
    """A backend that cannot start is skipped for the next; none working: one line, exit 2."""
    from simpro_mj.report import render

    _scene(pitch_run, 16, 16)[1].close()
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    monkeypatch.delenv("DISPLAY", raising=False)  # so glx cannot start, on any machine
    monkeypatch.setattr(render, "GL_BACKENDS", ("glx", "egl"))  # no X display here: glx fails
    info = render.render_video([pitch_run], tmp_path / "a.mp4", size=(32, 32), end=0.08,
                               plots=False, jobs=1, progress=False)  # fmt: skip
    assert info.gl == "egl" and info.frames == 2
    monkeypatch.setattr(render, "GL_BACKENDS", ("glx",))
    code = main(["render", str(pitch_run), "--size", "32x32", "--end", "0.08", "--jobs", "1",
                 "--out", str(tmp_path / "b.mp4")])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "MUJOCO_GL=glx" in err
    assert not (tmp_path / "b.mp4").exists()


def test_interrupted_render_leaves_no_file(pitch_run, tmp_path, monkeypatch):
    """Ctrl-C while frames arrive: KeyboardInterrupt, no video, no temporary file left."""
    import tempfile

    from simpro_mj.report import render

    _scene(pitch_run, 16, 16)[1].close()
    calls = []

    def drain_then_stop(future, writer, bar, cpu):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        for frame in future.result()[0]:
            writer.send(frame)

    monkeypatch.setattr(render, "_drain", drain_then_stop)
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))  # where the jobs file goes
    out = tmp_path / "v" / "clip.mp4"
    out.parent.mkdir()
    with pytest.raises(KeyboardInterrupt):
        render.render_video([pitch_run], out, size=(32, 32), fps=25, end=1.0, plots=False,
                            jobs=1, progress=False)  # fmt: skip
    assert calls == [1, 1]
    assert list(out.parent.iterdir()) == []  # neither clip.mp4 nor .clip.mp4.simpro-tmp-*.mp4
    assert not list(tmp_path.glob("simpro-render-*.pkl"))


def test_bench_video_reports_the_render(pitch_run, capsys):
    """`bench --video` (short run): frames, sizes and per-frame figures in its JSON."""
    import json

    _scene(pitch_run, 16, 16)[1].close()
    assert main(["bench", "--video", "--duration", "0.2", "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert (r["frames"], r["video_size"]) == (5, "640x720")
    assert r["workers"] == min(os.cpu_count() or 1, 5)
    assert r["worker_cpu_s_per_frame"] > 0 and r["render_s"] > 0

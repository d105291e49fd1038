"""Recorded drives into telemetry: a drive recorded by a device mounted at an unknown
angle comes back in the car's axes, a logger's named axes map exactly, and bad input
is one line with exit 2."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers.frames import GRAVITY
from simpro_mj.commands.main import main
from simpro_mj.config.telemetry import read_telemetry
from simpro_mj.config.telemetry_import import Recording, RecordingError, import_recording

RATE = 100.0


def _drive(seconds: float = 120.0):
    """A car at 20 m/s: brakings and accelerations on the straight (|f_x| up to 4 m/s^2)
    and turns whose lateral force is ``v r`` (up to 4 m/s^2), with small pitch and roll
    rates; vehicle frame, gravity included."""
    t = np.arange(0, seconds, 1 / RATE)
    v = 20.0
    r = 0.2 * np.sin(2 * math.pi * t / 15.0) * (np.sin(2 * math.pi * t / 40.0) > 0.3)
    fx = 4.0 * np.sin(2 * math.pi * t / 6.0) * (np.sin(2 * math.pi * t / 40.0) < -0.3)
    f = np.column_stack([fx, v * r, np.full_like(t, GRAVITY)])
    w = np.column_stack([0.02 * np.sin(2 * math.pi * t / 3.0), 0.01 * np.cos(t), r])
    return t, f, w


def _rot(roll, pitch, yaw):
    cr, sr, cp, sp, cy, sy = (np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch),
                              np.cos(yaw), np.sin(yaw))  # fmt: skip
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


@pytest.mark.parametrize("yaw_deg", [35.0, 130.0, -100.0])
def test_a_device_at_an_unknown_angle_gives_back_the_cars_axes(yaw_deg):
    """The device reads the drive turned by 20 deg of roll, -15 of pitch and ``yaw_deg``
    (a phone in a holder). Levelled by the mean force and headed by the principal axis
    of the straight-line force, with the sign from the lateral force following the yaw
    rate, every axis comes back: each force within 0.05 m/s^2 rms of the car's (the
    mean force the levelling removes is zero here) and the yaw rate's sign kept."""
    t, f, w = _drive()
    dev = _rot(math.radians(20), math.radians(-15), math.radians(yaw_deg))
    rec = Recording(ta=t, a=f @ dev, tg=t, g=w @ dev, source="synthetic")  # car -> device
    tel, rep = import_recording(rec, "device", rate_hz=RATE, bias_tau_s=0, vibration_hz=0)
    n = tel.t.size
    for k in range(3):
        rms = np.sqrt(np.mean((tel.f[:, k] - f[:n, k]) ** 2))
        assert rms < 0.05, (k, rms)
    assert np.corrcoef(tel.w[:, 2], w[:n, 2])[0, 1] > 0.999
    assert rep.lateral_yaw_corr > 0.9
    assert rep.straight_lateral_share < 0.01
    assert rep.tilt_deg == pytest.approx(math.degrees(math.acos(dev[2, 2])), abs=0.5)


def test_a_level_frame_whose_heading_drifts_is_followed():
    """Level data whose horizontal axes turn slowly against the car (30 deg over 120 s,
    a magnetometer's north disturbed by the car): the windowed heading follows it, so
    the braking stays on x (within 0.15 m/s^2 rms) where one fixed heading would
    leave up to sin(15 deg) of it on y."""
    t, f, w = _drive()
    drift = np.radians(60.0) + np.radians(30.0) * t / t[-1]
    c, s = np.cos(drift), np.sin(drift)
    a = np.column_stack([c * f[:, 0] - s * f[:, 1], s * f[:, 0] + c * f[:, 1], f[:, 2]])
    g = np.column_stack([c * w[:, 0] - s * w[:, 1], s * w[:, 0] + c * w[:, 1], w[:, 2]])
    rec = Recording(ta=t, a=a, tg=t, g=g, source="synthetic")
    tel, _ = import_recording(rec, "level", rate_hz=RATE, bias_tau_s=0, vibration_hz=0)
    n = tel.t.size
    assert np.sqrt(np.mean((tel.f[:, 0] - f[:n, 0]) ** 2)) < 0.15
    assert np.sqrt(np.mean((tel.f[:, 1] - f[:n, 1]) ** 2)) < 0.15


def test_a_loggers_named_axes_map_exactly():
    """Forward-right-down (comma2k19's IMU): ``x,-y,-z`` flips y and z and nothing else."""
    t, f, w = _drive(10.0)
    frd = np.array([1.0, -1.0, -1.0])
    rec = Recording(ta=t, a=f * frd, tg=t, g=w * frd, source="frd")
    tel, _ = import_recording(rec, "vehicle", axes="x,-y,-z", rate_hz=RATE, bias_tau_s=0,
                              vibration_hz=0)  # fmt: skip
    n = tel.t.size
    np.testing.assert_allclose(tel.f, f[:n], atol=1e-9)
    np.testing.assert_allclose(tel.w, w[:n], atol=1e-9)
    with pytest.raises(RecordingError, match="--axes"):
        import_recording(rec, "vehicle", axes="x,-x,z")


def test_the_cli_writes_a_file_the_chain_reads_and_refuses_a_wrong_column(tmp_path, capsys):
    """A CSV with the accelerometer in g (``--accel-scale``) and the gyroscope in its own
    columns is written as telemetry the cueing chain reads; a column the file lacks is
    one line naming it, exit 2."""
    t, f, w = _drive(30.0)
    src = tmp_path / "log.csv"
    rows = np.column_stack([t * 1e3, f / 9.80665, w])
    np.savetxt(src, rows, delimiter=",", header="t_ms,ax_g,ay_g,az_g,gx,gy,gz", comments="")
    out = tmp_path / "drive.csv"
    cmd = ["telemetry", "import", str(src),
           "--frame", "vehicle", "--time", "t_ms", "--time-scale", "0.001", "--accel",
           "ax_g,ay_g,az_g", "--accel-scale", "9.80665", "--gyro-columns", "gx,gy,gz",
           "--out", str(out)]  # fmt: skip
    assert main(cmd) == 0, capsys.readouterr().err
    tel = read_telemetry(out)
    assert tel.t[-1] == pytest.approx(29.99, abs=1e-6)
    assert np.abs(tel.f[:, 2] - GRAVITY).max() < 1e-6  # no bias, no vibration: g stays
    bad = cmd[:-2] + ["--out", str(tmp_path / "x.csv")]
    bad[bad.index("gx,gy,gz")] = "gx,gy,gyro_z"
    capsys.readouterr()
    assert main(bad) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert "missing column gyro_z" in err
    assert not (tmp_path / "x.csv").exists()


def _braking_file(path, seconds=8.0):
    """A 4 m/s^2 braking held 3 s, ramped in and out in 0.5 s, at rest otherwise."""
    from simpro_mj.config.telemetry import Telemetry, write_telemetry

    t = np.arange(0, seconds + 1e-9, 0.01)
    fx = -4.0 * np.clip(np.minimum((t - 1.0) / 0.5, (4.5 - t) / 0.5), 0, 1)
    f = np.column_stack([fx, np.zeros_like(t), np.full_like(t, GRAVITY)])
    write_telemetry(path, Telemetry(t=t, f=f, w=np.zeros((t.size, 3))))
    return path


def test_judge_plays_a_recording_through_the_shipped_law(tmp_path):
    """A braking judged through the shipped MPC and the loop's model: the surge is the
    one channel judged, felt in shape (correlation >= 0.9) at about the law's scale
    (``gain_x`` 0.3: the perceived gain 0.2-0.35), its onset found."""
    from simpro_mj.analysis.cue_corpus import judge, table

    rows = judge([_braking_file(tmp_path / "brake.csv")], shipped=(), bound=False)
    assert [r.channel for r in rows] == ["longitudinal_f"]
    r = rows[0]
    assert r.correlation >= 0.9
    assert 0.2 <= r.gain <= 0.35
    assert r.onsets >= 1 and r.onsets_missed == 0
    assert "| brake | longitudinal_f |" in table(rows)


def test_judge_refuses_a_parameter_the_law_does_not_take(tmp_path, capsys):
    """A law change out of range is one line naming it, exit 2."""
    path = _braking_file(tmp_path / "brake.csv", 3.0)
    assert main(["telemetry", "judge", str(path), "--no-shipped", "--law", "lead_x_s=0.9"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert "lead_x" in err


def test_a_real_highway_drive_is_felt_in_shape_at_the_laws_scale():
    """comma2k19's RAV4 (data/corpus, imported from the device's own axes) through the
    shipped law: both horizontal channels are judged (the car passes the otoliths'
    threshold on each), the surge is felt in shape (correlation >= 0.9; 0.92 measured)
    and the sway near it (>= 0.8; 0.86), at the law's scale 0.3 of the car (gain 0.2-0.35)
    although the platform could give 0.68-0.82 (docs/cueing.md), and the weak onsets a
    cue at 0.3 cannot lift over the threshold are missed."""
    from pathlib import Path

    from simpro_mj.analysis.cue_corpus import judge

    path = Path(__file__).resolve().parents[1] / "data" / "corpus" / "comma2k19_rav4_280.csv"
    rows = {r.channel: r for r in judge([path], shipped=(), bound=False)}
    assert set(rows) == {"longitudinal_f", "lateral_f"}
    assert rows["longitudinal_f"].correlation >= 0.9
    assert rows["lateral_f"].correlation >= 0.8
    for r in rows.values():
        assert 0.2 <= r.gain <= 0.35
    assert rows["longitudinal_f"].onsets_missed >= 1

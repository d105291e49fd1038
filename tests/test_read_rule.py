"""The read rule: every file simpro-sim reads is opened without blocking and read
only if it is a regular file within its size bound; a result folder read back
is validated as an input (the npz header before any allocation, the columns,
the sizes). Each refusal: exit 2, one line naming the file, well within 2 s.

Cases with a FIFO run in a child process with a timeout (a regression would
block the reader, not the test run); the rest in this process.
"""

from __future__ import annotations

import io
import os
import shutil
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

from simpro_mj.commands.main import main
from simpro_mj.config.telemetry import TelemetryError, read_telemetry
from simpro_mj.report.recording import load_recording

ROOT = Path(__file__).resolve().parents[1]
HEADER = "time_s,fx_mps2,fy_mps2,fz_mps2,wx_rad_s,wy_rad_s,wz_rad_s"


def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    return lines[0]


def test_fifos_and_devices_are_refused_at_once(tmp_path, recorded_run):
    fifo = tmp_path / "pipe.yaml"
    os.mkfifo(fifo)
    run = recorded_run(tmp_path / "r")
    (run / "timeseries.csv").unlink()
    os.mkfifo(run / "timeseries.csv")
    marker = tmp_path / "m"
    marker.mkdir()
    os.mkfifo(marker / ".simpro-result")
    tel = tmp_path / "tel.csv"
    os.mkfifo(tel)
    scen = tmp_path / "cue.yaml"
    scen.write_text(f"duration_s: 0.01\nsetpoint:\n  cueing: {{telemetry: {tel.name}}}\n")
    cases = [
        (["run", str(fifo)], "a FIFO"),
        (["run", "/dev/zero"], "a character device"),
        (["calibrate", "--targets", str(fifo)], "a FIFO"),
        (["calibrate", "--targets", "/dev/zero"], "a character device"),
        (["render", str(run), "--jobs", "1"], "a FIFO"),
        (["run", "step_pitch", "--out", str(marker), "--no-plots"], "not a simpro-sim result"),
        (["run", str(scen), "--out", str(tmp_path / "o")], "not a regular file"),
    ]
    # one child process runs every case in turn (a child: a refusal that blocked on a FIFO
    # would end at the timeout, not hang the suite); each case's stderr ends at a "--" line
    code = (
        "import sys\n"
        "from simpro_mj.commands.main import main\n"
        f"for argv in {[argv for argv, _ in cases]!r}:\n"
        "    rc = main(argv)\n"
        "    sys.stdout.flush()\n"
        "    print(f'rc={rc}', flush=True)\n"
        "    print('--', file=sys.stderr, flush=True)\n"
    )
    env = dict(os.environ, PYTHONPATH=str(ROOT), MPLBACKEND="Agg")
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env,
                       capture_output=True, text=True, timeout=300)  # fmt: skip
    codes = [line for line in r.stdout.splitlines() if line.startswith("rc=")]
    errors = r.stderr.split("--\n")
    assert len(codes) == len(cases) and len(errors) == len(cases) + 1, r.stdout + r.stderr
    assert errors[-1] == "", r.stderr
    for (argv, said), rc, err in zip(cases, codes, errors[:-1], strict=True):
        assert rc == "rc=2" and said in _one_line(err), (argv, err)
    assert not (tmp_path / "o").exists()


def _npz(members: dict, compress=zipfile.ZIP_STORED) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=compress) as zf:
        for name, data in members.items():
            zf.writestr(f"{name}.npy", data)
    return buf.getvalue()


def _npy(arr) -> bytes:
    b = io.BytesIO()
    np.lib.format.write_array(b, np.asarray(arr))
    return b.getvalue()


def _header_only(shape) -> bytes:
    b = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        b, {"descr": "<f8", "fortran_order": False, "shape": shape}
    )
    return b.getvalue() + b"\0" * 800


def test_a_corrupted_result_is_refused_naming_the_file(tmp_path, recorded_run):
    good = recorded_run(tmp_path / "good")
    rec = load_recording(good)
    t, q, names = rec.time_s, rec.qpos, np.array(rec.qpos_names)

    def bomb() -> bytes:  # 2.2 GB of zeros in 9.5 MB (deflate's fastest level)
        buf = io.BytesIO()
        with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=1) as zf:
            zf.writestr("time_s.npy", _npy(t))
            zf.writestr("qpos_names.npy", _npy(names))
            with zf.open("qpos.npy", "w", force_zip64=True) as m:
                m.write(_header_only((10**9 // 8 // 13, 13))[:128])
                zero = b"\0" * (1 << 24)
                for _ in range(130):
                    m.write(zero)
        return buf.getvalue()

    npz_cases = {
        "truncated": (good / "qpos.npz").read_bytes()[:300],
        "empty": b"",
        "rows 10^12": _npz(
            {"time_s": _npy(t), "qpos": _header_only((10**12, 13)), "qpos_names": _npy(names)}
        ),
        "object dtype": _npz(
            {
                "time_s": _npy(t),
                "qpos": _npy(q),
                "qpos_names": _npy(np.array(list(names), dtype=object)),
            }
        ),
        "5 of 13 joints": _npz(
            {"time_s": _npy(t), "qpos": _npy(q[:, :5]), "qpos_names": _npy(names[:5])}
        ),
        "rows differ": _npz({"time_s": _npy(t[:10]), "qpos": _npy(q), "qpos_names": _npy(names)}),
    }
    from simpro_mj.core.errors import UserInputError
    from simpro_mj.report.render import check_joints

    for what, data in {**npz_cases, "zip bomb": bomb()}.items():
        folder = tmp_path / what.replace(" ", "_")
        shutil.copytree(good, folder)
        (folder / "qpos.npz").write_bytes(data)
        t0 = time.process_time()  # CPU time: inflating the bomb would take seconds of it
        with pytest.raises(UserInputError) as info:
            check_joints(load_recording(folder))
        assert time.process_time() - t0 < 2.0, what
        msg = str(info.value)
        assert "\n" not in msg and str(folder / "qpos.npz") in msg, (what, msg)
    csv_cases = {
        "no set-points": "time_s,roll_rad\n0,0\n",
        "garbage": "time_s,roll_ref_rad\nabc,def\n",
    }
    for what, text in csv_cases.items():
        folder = tmp_path / what.replace(" ", "_")
        shutil.copytree(good, folder)
        (folder / "timeseries.csv").write_text(text)
        with pytest.raises(UserInputError, match="timeseries.csv"):
            load_recording(folder)
    folder = tmp_path / "deep"
    shutil.copytree(good, folder)
    (folder / "scenario.yaml").write_text("[" * 5000 + "]" * 5000)
    with pytest.raises(UserInputError, match="nesting deeper than 50"):
        load_recording(folder)


def test_render_of_a_corrupted_result_exits_2(tmp_path, capsys, recorded_run):
    folder = recorded_run(tmp_path / "r")
    (folder / "qpos.npz").write_bytes(b"PK\x03\x04 truncated")
    assert main(["render", str(folder), "--jobs", "1"]) == 2
    assert "qpos.npz" in _one_line(capsys.readouterr().err)


@pytest.mark.parametrize(
    "body, match",
    [
        (HEADER + "\n0,0,0,9.8,0,0,0\n0.01,1e300,0,9.8,0,0,0\n",
         r"column fx_mps2 row 3: 1e\+300; allowed: a finite number, \|value\| <= 100"),
        (HEADER + "\n0,0,0,9.8,0,0,0\n0.01,0,0,9.8,0,0,50\n", r"column wz_rad_s row 3: 50"),
        (HEADER + "\n0,0,0,9.8,0,0,0\n0.01,0,0,9.8,0," + "1" * 200_000 + ",0\n",
         r"column wy_rad_s row 3: inf; allowed: a finite number"),
        (HEADER + "\n0,0,0,9.8,0,0,0\n0.01,\"" + "x" * 140_000 + "\",0,9.8,0,0,0\n",
         r"row 3: a line of more than 10,000 characters"),
    ],
)  # fmt: skip
def test_implausible_or_huge_telemetry_is_one_line(tmp_path, body, match):
    p = tmp_path / "bad.csv"
    p.write_text(body)
    with pytest.raises(TelemetryError, match=match) as info:
        read_telemetry(p)
    assert "\n" not in str(info.value)


def test_telemetry_is_streamed_and_a_late_error_names_its_row(tmp_path):
    """Many blocks: the fast path parses them, a bad row deep in the file is named
    with its line number, and every value before it was checked."""
    n = 120_000
    t = np.arange(n) * 1e-3
    body = np.column_stack([t, *np.zeros((2, n)), np.full(n, 9.81), *np.zeros((3, n))])
    p = tmp_path / "long.csv"
    with open(p, "w") as fh:
        fh.write("# a comment\n" + HEADER + "\n")
        np.savetxt(fh, body, fmt="%.9g", delimiter=",")
    tel = read_telemetry(p)
    written = np.array([float(f"{x:.9g}") for x in t])  # what %.9g wrote
    assert len(tel.t) == n and np.array_equal(tel.t, written) and np.all(tel.f[:, 2] == 9.81)
    with open(p, "a") as fh:
        fh.write(f"{n * 1e-3},0,nan,9.81,0,0,0\n")
    with pytest.raises(TelemetryError, match=rf"column fy_mps2 row {n + 3}: nan"):
        read_telemetry(p)

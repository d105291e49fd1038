"""A HOME that is a file (or read-only) gives no matplotlib warnings: the CLI hands
matplotlib a private temporary folder (simpro_mj.core.environment.matplotlib_home)."""

from __future__ import annotations

import os
import subprocess
import sys

from simpro_mj.core.environment import matplotlib_home


def test_a_home_that_is_a_file_gets_a_private_folder_and_no_warning(tmp_path, monkeypatch):
    home = tmp_path / "home"
    home.write_text("not a folder")
    for var in ("MPLCONFIGDIR", "XDG_CONFIG_HOME", "XDG_CACHE_HOME"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("HOME", str(home))
    folder = matplotlib_home()
    assert folder is not None and os.path.isdir(folder)
    assert os.environ["MPLCONFIGDIR"] == folder
    proc = subprocess.run(
        [
            sys.executable,
            "-c",
            "import matplotlib; matplotlib.use('Agg'); "
            "import matplotlib.pyplot as plt; plt.figure()",
        ],  # fmt: skip
        env=dict(os.environ),
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0 and proc.stderr == ""


def test_a_usable_home_or_a_given_folder_is_left_alone(tmp_path, monkeypatch):
    monkeypatch.setenv("MPLCONFIGDIR", str(tmp_path))
    assert matplotlib_home() is None
    monkeypatch.delenv("MPLCONFIGDIR")
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "config"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    assert matplotlib_home() is None
    assert "MPLCONFIGDIR" not in os.environ

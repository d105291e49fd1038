"""A batch's worker: one variant run headless into its result folder.

:func:`run_variant` gets the resolved scenario (plain JSON data) and its
folder, builds its own MuJoCo model, runs, writes a normal result folder
(:func:`simpro_mj.report.runner.execute`, atomic) and returns a small dict. No
model is ever pickled; the function is top level so that it pickles by name
to a pool or Dask worker. A worker that may not share this file system writes
into a temporary folder and ships the files back (:func:`install` writes them here).
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Mapping
from pathlib import Path

from simpro_mj.batch.stability import stability_of_folder
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.messages import one_line
from simpro_mj.report.folders import install_folder
from simpro_mj.report.runner import execute

__all__ = ["install", "run_variant"]


def run_variant(task: Mapping) -> dict:
    """Run one variant (worker side; top level so that it pickles by name).

    Parameters
    ----------
    task : mapping
        ``scenario`` (resolved, plain data), ``out`` (its folder), ``plots``
        (bool), ``ship`` (bool: write into a temporary folder and return the
        files' bytes, for workers that may not share this file system).

    Returns
    -------
    dict
        ``status``, ``reason``, ``metrics`` (the ``metrics.json`` document,
        ``None`` if the run failed), ``stability`` (:func:`stability_of_folder`)
        and, when shipping, ``files`` (name -> bytes).
    """
    ship = bool(task.get("ship"))
    tmp = Path(tempfile.mkdtemp(prefix="simpro-batch-")) if ship else None
    try:
        folder = tmp / "variant" if tmp is not None else Path(task["out"])
        # warnings go to metrics.json only: many workers on one stderr would be noise
        res, doc = execute(
            task["scenario"],
            folder,
            plots=bool(task.get("plots", True)),
            quiet=True,
            stop=task.get("stop"),
        )
        folder = res.folder
        out = {
            "status": doc.get("status", "ok"),
            "reason": doc.get("reason"),
            "metrics": doc,
            "stability": stability_of_folder(folder, doc.get("status")),
        }
        if ship:
            out["files"] = {p.name: p.read_bytes() for p in sorted(folder.iterdir())}
        return out
    except UserInputError as exc:  # a value only the plant checks
        return {"status": "invalid", "reason": one_line(exc), "metrics": None}
    except Exception as exc:  # noqa: BLE001 - any failure is this variant's, not the batch's
        return {"status": "failed", "reason": one_line(exc, with_type=True), "metrics": None}
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)


def install(files: Mapping[str, bytes], out: Path) -> None:
    """Write shipped files as a result folder, atomically (as results.write_results)."""

    def fill(tmp: Path) -> None:
        for name, data in files.items():
            (tmp / Path(name).name).write_bytes(data)

    install_folder(out, fill)

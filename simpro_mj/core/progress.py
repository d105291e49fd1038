"""Feedback during long work: a progress bar on a terminal, nothing when piped.

Every command that can take more than a couple of seconds shows what it is doing on
stderr: the simulated seconds of a run, the variants of a batch (with the time
left), or the phase of an analysis (:class:`Phases`). Nothing is drawn with
``--quiet`` or ``--json``, or when stderr is not a terminal (a pipe, a file, CI).
"""

from __future__ import annotations

import sys


def show_progress(args) -> bool:
    """A command's progress bar is drawn on a terminal only: not with ``--quiet`` or
    ``--json``, nor when stderr is piped or redirected to a file."""
    quiet = getattr(args, "quiet", False) or getattr(args, "json", False)
    return not quiet and sys.stderr.isatty()


class Phases:
    """The named phases of a command as a tqdm bar (``desc: phase... 1/3 [elapsed]``).

    ``with Phases("analyze", ["loops", "plots"], enabled) as ph: ph.start("loops")``;
    disabled, every call does nothing.
    """

    def __init__(self, desc: str, names, enabled: bool):
        self.names = list(names)
        self.desc = desc
        self.bar = None
        if enabled:
            from tqdm import tqdm

            self.bar = tqdm(total=len(self.names), desc=desc, leave=False,
                            bar_format="{desc} {n}/{total} [{elapsed}]")  # fmt: skip

    def start(self, name: str) -> None:
        """Mark the phases before ``name`` done and show ``name`` as running."""
        if self.bar is None:
            return
        self.bar.n = self.names.index(name)
        self.bar.set_description_str(f"{self.desc}: {name}...", refresh=True)

    def __enter__(self) -> Phases:
        return self

    def __exit__(self, *exc) -> None:
        if self.bar is not None:
            self.bar.close()

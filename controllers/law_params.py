"""What a cueing law's frozen parameter record shares: its ranges checked, ``replace``.

:class:`controllers.washout.WashoutParams` and
:class:`controllers.cue_mpc_params.MpcParams` are frozen dataclasses of numbers; each
declares its ranges as ``{field: (test, allowed text)}`` and calls :meth:`LawParams._check`
from ``__post_init__``. A field that is not a finite real number (a bool is not one) or
fails its test raises the law's own error naming the field, its value and what is
allowed.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from typing import ClassVar, TypeVar

__all__ = ["LawParams"]

_P = TypeVar("_P", bound="LawParams")


class LawParams:
    """Mixin of a law's frozen parameter dataclass (no fields of its own)."""

    #: the law's name in messages ("washout", "mpc") and the error it raises
    _LABEL: ClassVar[str] = "law"
    _ERROR: ClassVar[type[ValueError]] = ValueError

    def _check(self, checks: Mapping[str, tuple[Callable[[float], bool], str]]) -> None:
        """Raise ``_ERROR`` for the first field that is not a finite number passing its test."""
        for name, (ok, allowed) in checks.items():
            v = getattr(self, name)
            bad = isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)
            if bad or not ok(v):
                raise self._ERROR(f"{self._LABEL} parameter {name}={v!r}: allowed {allowed}")

    @classmethod
    def field_names(cls) -> list[str]:
        """The record's fields, in order."""
        return [f.name for f in dataclasses.fields(cls)]  # type: ignore[arg-type]

    def replace(self: _P, **changes) -> _P:
        """A copy with some fields changed; an unknown name raises, listing the valid ones."""
        unknown = sorted(set(changes) - set(self.field_names()))
        if unknown:
            raise self._ERROR(
                f"unknown {self._LABEL} parameter {unknown[0]!r}; allowed: {self.field_names()}"
            )
        return dataclasses.replace(self, **changes)  # type: ignore[type-var]

"""What a cueing law's frozen parameter record shares: its ranges checked, ``replace``.

:class:`controllers.washout.WashoutParams` and
:class:`controllers.cue_mpc_params.MpcParams` are frozen dataclasses of numbers; each
field declares its default and its range with :func:`ranged`, and
``LawParams.__post_init__`` checks them in field order. A field that is not a finite
real number (a bool is not one) or fails its test raises the law's own error naming
the field, its value and what is allowed.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any, ClassVar, TypeVar

_P = TypeVar("_P", bound="LawParams")


def ranged(default: float, ok: Callable[[float], bool], allowed: str) -> Any:
    """A field with its ``default`` and its range: the test ``ok`` and its text."""
    return dataclasses.field(default=default, metadata={"range": (ok, allowed)})


class LawParams:
    """Mixin of a law's frozen parameter dataclass (no fields of its own)."""

    #: the law's name in messages ("washout", "mpc") and the error it raises
    _LABEL: ClassVar[str] = "law"
    _ERROR: ClassVar[type[ValueError]] = ValueError

    def __post_init__(self) -> None:
        """Raise ``_ERROR`` for the first field that is not a finite number passing its test."""
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            ok, allowed = f.metadata["range"]
            v = getattr(self, f.name)
            bad = isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)
            if bad or not ok(v):
                raise self._ERROR(f"{self._LABEL} parameter {f.name}={v!r}: allowed {allowed}")

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

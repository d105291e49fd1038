"""Named fields of a flat float64 array: one declaration, the offsets and the packing.

The 1 ms step keeps its memory in flat float64 arrays (numba compiles an index
into a load at a fixed offset; MuJoCo's callback receives the arrays as
pointers). A :func:`layout` declares such a block once, as its fields and their
sizes, in order::

    ACT = layout("ActuatorState", p=6, spool=3, rate=3, cell=12, ps=1, phi=3)

``ACT`` is a named tuple of offsets (``ACT.p == 0``, ``ACT.spool == 6``, ...,
``ACT.LEN == 28``, the block's length), so a step function reads
``ast[ACT.spool + i]``. numba takes a global named tuple as a constant: the
offset folds into the load exactly as a literal number would. The same
declaration packs a block (:meth:`Layout.pack`, every field named and its size
checked) and gives its fields back as views (:meth:`Layout.views`). A field
sized ``None`` (the last only) is an open tail: its offset is ``LEN`` and
:meth:`Layout.pack` takes any length for it.

Adding a field is one entry in the declaration: every offset after it, the
length and the packing follow. The helper imports numpy only: the
controllers (which import nothing of ``simpro_mj``), the plant's step
functions and the step (:mod:`simpro_mj.sim.step`) all declare their blocks
with it.
"""

from __future__ import annotations

from collections import namedtuple
from types import SimpleNamespace
from typing import TYPE_CHECKING

import numpy as np

__all__ = ["layout", "Layout"]

_RESERVED = {"LEN", "pack", "views", "sizes", "size", "count", "index", "name"}


class Layout(tuple):
    """A block's offsets (a named tuple made by :func:`layout`), with its packing.

    Attributes: one offset per field, ``LEN`` (the fixed part's length) and
    :attr:`sizes` (field -> size, ``None`` for an open tail).
    """

    __slots__ = ()
    sizes: dict = {}

    if TYPE_CHECKING:  # the fields are made by layout() at import: each one an offset
        LEN: int

        def __getattr__(self, name: str) -> int: ...

    def pack(self, out=None, **values) -> np.ndarray:
        """The block as a new float64 array (or into ``out``) from every field's value.

        Scalars fill a field of size 1, sequences (any shape, raveled) one of
        their size; a missing, unknown or wrongly sized field raises
        ``ValueError`` naming it.
        """
        unknown = sorted(set(values) - set(self.sizes))
        missing = [f for f in self.sizes if f not in values]
        if unknown or missing:
            raise ValueError(
                f"{type(self).__name__}.pack: unknown fields {unknown}, missing {missing}; "
                f"fields: {list(self.sizes)}"
            )
        flat = {f: np.ravel(np.asarray(v, dtype=float)) for f, v in values.items()}
        tail = [f for f, n in self.sizes.items() if n is None]
        n_tail = flat[tail[0]].size if tail else 0
        if out is None:
            out = np.zeros(self.LEN + n_tail)
        for f, n in self.sizes.items():
            v = flat[f]
            if n is not None and v.size != n:
                raise ValueError(f"{type(self).__name__}.{f}: {v.size} values, expected {n}")
            off = getattr(self, f)
            out[off : off + v.size] = v
        return out

    def views(self, arr) -> SimpleNamespace:
        """Each field of ``arr`` (a block of this layout) as a view, an attribute by name."""
        return SimpleNamespace(
            **{
                f: arr[getattr(self, f) :]
                if n is None
                else arr[getattr(self, f) : getattr(self, f) + n]
                for f, n in self.sizes.items()
            }
        )

    def size(self, field: str) -> int:
        """The declared size of ``field``."""
        return self.sizes[field]


def layout(name: str, **fields) -> Layout:
    """A block's :class:`Layout` from its fields' sizes, in order (module docstring)."""
    bad = sorted(_RESERVED & set(fields))
    if bad:
        raise ValueError(f"layout {name}: reserved field names {bad}")
    names, offsets, off = list(fields), [], 0
    for i, (f, n) in enumerate(fields.items()):
        if n is None and i != len(fields) - 1:
            raise ValueError(f"layout {name}: only the last field may be open, not {f!r}")
        if n is not None and not (isinstance(n, int) and n >= 1):
            raise ValueError(f"layout {name}.{f}: size {n!r}; allowed: an int >= 1 or None")
        offsets.append(off)
        off += n or 0
    base = namedtuple(name, [*names, "LEN"])  # type: ignore[misc]  # a name made at run time
    cls = type(name, (base, Layout), {"__slots__": (), "sizes": dict(fields)})
    return cls(*offsets, off)

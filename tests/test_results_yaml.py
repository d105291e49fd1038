"""A result folder's ``scenario.yaml`` is ``yaml.safe_dump``'s text, byte for byte.

:func:`simpro_mj.report.results.dump_yaml` writes it with libyaml's emitter where
that gives the same text (every string printable ASCII and non-empty) and with
PyYAML's pure-Python emitter otherwise. Checked on every shipped scenario and every
variant of the shipped sweeps (which must take the fast path), and on random trees:
of printable ASCII (the fast path) and of any text (either path).
"""

from __future__ import annotations

import io
from pathlib import Path

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from simpro_mj.batch.plan import plan
from simpro_mj.report.results import _plain_text, dump_yaml, jsonable

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = sorted((ROOT / "scenarios").glob("*.yaml"))


def _reference(data) -> str:
    return yaml.safe_dump(data, sort_keys=False, default_flow_style=None)


def _dumped(data) -> str:
    fh = io.StringIO()
    dump_yaml(data, fh)
    return fh.getvalue()


def test_the_shipped_scenarios_are_found():
    assert len(SHIPPED) >= 15


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_every_shipped_variant_is_written_as_safe_dump_writes_it(path):
    """Each resolved variant (a file without a sweep block is one) takes libyaml's
    emitter and gives safe_dump's text."""
    jobs = [job for job in plan([str(path)], []).jobs if job.scenario is not None]
    assert jobs, path
    for job in jobs:
        data = jsonable(job.scenario)
        assert not yaml.__with_libyaml__ or _plain_text(data), job.variant
        assert _dumped(data) == _reference(data), job.variant


_ascii = st.text(st.characters(min_codepoint=32, max_codepoint=126), min_size=1, max_size=120)
_leaf = st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | _ascii


def _trees(keys, leaves):
    return st.recursive(
        leaves,
        lambda inner: st.lists(inner, max_size=12) | st.dictionaries(keys, inner, max_size=5),
        max_leaves=20,
    )


@settings(max_examples=40)
@given(st.dictionaries(_ascii, _trees(_ascii, _leaf), min_size=1, max_size=6))
def test_plain_text_trees_are_written_as_safe_dump_writes_them(data):
    assert _plain_text(data)
    assert _dumped(data) == _reference(data)


@settings(max_examples=40)
@given(st.dictionaries(st.text(max_size=8), _trees(st.text(max_size=8), _leaf | st.text()),
                       min_size=1, max_size=6))  # fmt: skip
def test_any_text_is_written_as_safe_dump_writes_it(data):
    """Escapes, control characters, non-ASCII and empty keys, where the two emitters
    differ: the pure-Python one writes them."""
    assert _dumped(data) == _reference(data)


def test_text_the_emitters_quote_differently_takes_the_pure_python_one():
    """A case where libyaml folds a double-quoted string elsewhere than PyYAML."""
    data = {"note": "é" * 30 + " tail \t" + "x" * 60}
    c_text = yaml.dump(data, Dumper=yaml.CSafeDumper, sort_keys=False, default_flow_style=None)
    if yaml.__with_libyaml__:
        assert c_text != _reference(data)  # else this case shows nothing
    assert not _plain_text(data)
    assert _dumped(data) == _reference(data)

"""The scenario's error messages, word for word (issue 14: the typed scenario).

``tests/data/scenario_messages.json`` maps ``--set`` overrides of
``step_pitch`` (several joined by ``|``) to the one-line message the
hand-written validator gave on main ee6297d, before the pydantic models
(:mod:`simpro_mj.config.models`) replaced it; ``null``: accepted. A first
part without ``=`` names another shipped scenario to override instead
(``cue_braking|setpoint.cueing.algorithm=mpc``: the ``setpoint.cueing``
cases, recorded from the hand-written ``check_cueing`` on issue14h bae7616
before its models replaced it). Every type,
range, enumeration, unknown and missing key, tagged entry and cross-field rule
is there, so the models keep the contract of ``docs/robustness.md`` (one line,
dotted path, allowed values, the closest valid key) to the letter.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from simpro_mj.config.scenario import load_scenario
from simpro_mj.core.errors import UserInputError

CASES = json.loads((Path(__file__).parent / "data" / "scenario_messages.json").read_text())


def _load(sets: str) -> dict:
    """Load ``step_pitch`` (or the scenario a first part without ``=`` names) with the overrides."""
    parts = sets.split("|")
    base = parts.pop(0) if "=" not in parts[0] else "step_pitch"
    return load_scenario(base, parts)


@pytest.mark.parametrize("sets", sorted(CASES))
def test_message_word_for_word(sets):
    want = CASES[sets]
    if want is None:
        _load(sets)
        return
    with pytest.raises(UserInputError) as info:
        _load(sets)
    assert str(info.value) == want
    assert "\n" not in want

"""The scenario's error messages, word for word (issue 14: the typed scenario).

``tests/data/scenario_messages.json`` maps ``--set`` overrides of
``step_pitch`` (several joined by ``|``) to the one-line message the
hand-written validator gave on main ee6297d, before the pydantic models
(:mod:`simpro_mj.config.models`) replaced it; ``null``: accepted. Every type,
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


@pytest.mark.parametrize("sets", sorted(CASES))
def test_message_word_for_word(sets):
    want = CASES[sets]
    if want is None:
        load_scenario("step_pitch", sets.split("|"))
        return
    with pytest.raises(UserInputError) as info:
        load_scenario("step_pitch", sets.split("|"))
    assert str(info.value) == want
    assert "\n" not in want

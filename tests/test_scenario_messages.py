"""The scenario's refusals keep their contract, not their wording.

``tests/data/scenario_messages.json`` maps ``--set`` overrides of
``step_pitch`` (several joined by ``|``; a first part without ``=`` names
another shipped scenario, ``cue_braking|setpoint.cueing.algorithm=mpc``) to
what the refusal must say, or ``null``: accepted. Every type, range,
enumeration, unknown and missing key, tagged entry and cross-field rule of the
typed scenario (:mod:`simpro_mj.config.models`) is there.

What is checked is the contract of ``docs/robustness.md`` (exit 2 and one
line ``<what> at <dotted.path>: <what is allowed>``): a
:class:`~simpro_mj.core.errors.UserInputError`, one line, the kind of
refusal (``what``), the dotted path of the field (``at``), the allowed values
when the field has a list of them (``choices``: every one named), the
closest valid key or value (``closest``), and ``allowed`` said. The prose
around them is free to improve; the error catalogue of ``docs/robustness.md``
shows examples as printed.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from simpro_mj.config.scenario import load_scenario
from simpro_mj.core.errors import UserInputError

CASES = json.loads((Path(__file__).parent / "data" / "scenario_messages.json").read_text())

#: The kinds of refusal a scenario gets (the words before `` at ``).
KINDS = {
    "invalid value",
    "wrong type",
    "unknown key",
    "missing key",
    "unknown preset",
    "infeasible joint design",
    "unreachable set-point",
}
_HEAD = re.compile(r"^(?P<what>[a-z][a-z -]*?) at (?P<at>[^\s:;]+?)(:|;|\s|$)")


def _load(sets: str) -> dict:
    """Load ``step_pitch`` (or the scenario a first part without ``=`` names) with the overrides."""
    parts = sets.split("|")
    base = parts.pop(0) if "=" not in parts[0] else "step_pitch"
    return load_scenario(base, parts)


def test_the_cases_cover_every_kind_of_refusal():
    kinds = {want["what"] for want in CASES.values() if want}
    assert kinds == KINDS
    assert sum(want is None for want in CASES.values()) >= 5  # and valid input is accepted


@pytest.mark.parametrize("sets", sorted(CASES))
def test_message_contract(sets):
    want = CASES[sets]
    if want is None:
        _load(sets)
        return
    with pytest.raises(UserInputError) as info:
        _load(sets)
    text = str(info.value)
    assert "\n" not in text and len(text) <= 1000, text
    head = _HEAD.match(text)
    assert head, f"not '<what> at <dotted.path>: ...': {text}"
    assert (head["what"], head["at"]) == (want["what"], want["at"]), text
    for choice in want.get("choices", ()):
        assert f"'{choice}'" in text, f"{choice!r} not named: {text}"
    if "closest" in want:
        assert f"did you mean '{want['closest']}'" in text, text
    assert ("allowed" in text) == want["allowed"], text

"""The objective motion cueing test of a law: known answers of the washout's tilt
coordination and of the fidelity regions."""

from __future__ import annotations

import math

import pytest

from simpro_mj.analysis.omct import AMPLITUDES, fidelity, law_blocks, law_response
from simpro_mj.core.errors import UserInputError


def test_fidelity_regions_at_one_rad_s():
    assert fidelity(0.9, -5.0) == "high"
    assert fidelity(0.9, 355.0) == "high"  # the same phase on another branch
    assert fidelity(0.5, -25.0) == "medium"
    assert fidelity(0.3, 0.0) == "low"  # a tenth of the car's: low, however timely
    assert fidelity(0.9, 45.0) == "low"


def test_washout_surge_at_low_frequency_is_tilt_coordination_at_its_gain():
    """At 0.1 rad/s the washout's surge cue is all tilt coordination: the head feels
    gain_x (0.5) of the car's specific force, in phase; at 1 rad/s the tilt's rate limit
    and low-pass have taken some of it (medium fidelity at most)."""
    block = law_blocks(["classical_washout"])["classical_washout"]
    assert block["parameters"].get("gain_x", 0.5) == 0.5
    low = law_response(block, "fx", 0.1, AMPLITUDES["f"])["fx"]
    assert abs(low) == pytest.approx(0.5, abs=0.02)
    assert math.degrees(math.atan2(low.imag, low.real)) == pytest.approx(0.0, abs=6.0)
    one = law_response(block, "fx", 1.0, AMPLITUDES["f"])["fx"]
    assert 0.4 < abs(one) < 0.8
    assert fidelity(abs(one), math.degrees(math.atan2(one.imag, one.real))) != "high"


def test_an_unknown_law_is_named_with_the_valid_ones():
    with pytest.raises(UserInputError, match="--laws: 'nope'; allowed: \\['classical_washout'"):
        law_blocks(["nope"])


def test_a_law_block_alone_is_judged_against_its_bound():
    """The chain's metrics of a law block with no scenario around it (the OMCT's, the
    recordings' judge) carry the cue bound with the law's box: on a 2 m/s^2 braking
    step the best motion in that box gives the head more of the car's surge than the
    washout does, so the washout's share of it lies in (0, 1]."""
    import numpy as np

    from simpro_mj.analysis.omct import model_chain_metrics

    block = law_blocks(["classical_washout"])["classical_washout"]
    t = np.arange(0.0, 3.0, 0.01)
    f, w = np.zeros((t.size, 3)), np.zeros((t.size, 3))
    f[:, 2], f[t > 1.0, 0] = 9.80665, -2.0
    m = model_chain_metrics(block, t, f, w, bound=True)
    law, best = m["channels"]["longitudinal_f"], m["bound"]["channels"]["longitudinal_f"]
    assert 0.0 < law["gain"] < best["gain"]
    assert 0.0 < law["gain_share"] <= 1.0

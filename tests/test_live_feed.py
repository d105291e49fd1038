"""A game's feed as it arrives (``simpro-sim send`` with jitter, loss, duplicates,
reordering, a pause and a biased vertical force): the counts asked for, reproducible from
the seed, and bad values refused in one line."""

from __future__ import annotations

import numpy as np
import pytest

from simpro_mj.config.telemetry import Telemetry
from simpro_mj.core.errors import UserInputError
from simpro_mj.sim.live_feed import FeedImpairment, biased, impair

RATE = 60.0


def _feed(seconds: float = 60.0):
    t = np.arange(int(seconds * RATE)) / RATE
    return t, [i.to_bytes(4, "big") for i in range(t.size)]


def test_the_feed_the_issue_describes_has_its_shares():
    """60 Hz for 60 s, +-6 ms jitter, 3 % loss, 1 % duplicates, 1 % reordered, a 1.5 s
    pause at 20 s: 90 samples paused, about 3 % of the rest lost (a binomial draw: within
    four standard deviations), each send within 6 ms of its time, the pause a gap."""
    t, grams = _feed()
    imp = FeedImpairment(jitter_s=0.006, loss=0.03, duplicate=0.01, reorder=0.01,
                         pauses=((20.0, 1.5),), seed=3)  # fmt: skip
    ts, out, n = impair(t, grams, imp)
    assert n["paused"] == 90
    rest = t.size - 90
    for key, share in (("lost", 0.03), ("duplicated", 0.01), ("reordered", 0.01)):
        sd = np.sqrt(rest * share * (1 - share))
        assert abs(n[key] - rest * share) <= 4 * sd, (key, n[key])
    assert len(out) == rest - n["lost"] + n["duplicated"]
    assert np.all(np.diff(ts) >= 0)
    sample = {g: i for i, g in enumerate(grams)}
    # every datagram leaves within the jitter of its own time, or of its swapped neighbour's
    assert max(abs(ts[k] - t[sample[g]]) for k, g in enumerate(out)) <= 0.006 + 1.0 / RATE
    gap = np.diff(ts).max()
    assert 1.5 - 0.012 <= gap <= 1.5 + 1.0 / RATE + 0.012  # the pause
    again = impair(t, grams, imp)
    assert np.array_equal(again[0], ts) and again[1] == out  # one seed, one feed


def test_no_impairment_is_the_exact_feed():
    t, grams = _feed(2.0)
    ts, out, n = impair(t, grams, FeedImpairment())
    assert np.array_equal(ts, t) and out == grams
    assert n == {"paused": 0, "lost": 0, "reordered": 0, "duplicated": 0}


def test_a_bias_is_added_to_the_vertical_force_only():
    tel = Telemetry(t=np.arange(3.0), f=np.tile([1.0, 2.0, 9.81], (3, 1)), w=np.ones((3, 3)))
    b = biased(tel, -0.21)
    assert np.allclose(b.f[:, 2], 9.6) and np.array_equal(b.f[:, :2], tel.f[:, :2])
    assert np.array_equal(tel.f[:, 2], np.full(3, 9.81))  # the file's own is left alone


@pytest.mark.parametrize(
    "kwargs, key",
    [({"loss": 0.7}, "--loss"), ({"jitter_s": -0.001}, "--jitter-ms"),
     ({"reorder": float("nan")}, "--reorder"), ({"pauses": ((5.0, 0.0),)}, "--pause")],
)  # fmt: skip
def test_bad_impairments_are_refused_naming_the_option(kwargs, key):
    with pytest.raises(UserInputError, match=f"invalid value at {key}"):
        FeedImpairment(**kwargs)


def test_send_refuses_a_bad_pause_in_one_line(capsys):
    from simpro_mj.commands.main import main

    code = main(["send", "braking_100kmh.csv", "--to", "127.0.0.1:9", "--pause", "20"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "invalid value at --pause" in err[0]

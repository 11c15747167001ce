"""The chatter detector (csim.physics.events) on synthetic event sequences and the reference's events.

A sequence is fed one event at a time, as both drivers feed it, and the first event at
which the detector stops the run is compared with the rule worked out by hand: the last
n events lie within (n - 1) resolutions, resolution = max(min_step, 64 eps (1 + |t|)).
"""
from __future__ import annotations

import numpy as np
import pytest

from csim.physics.events import chattering_switches, check_chatter, event_resolution
from csim.physics.status import CHATTER, OK

MIN_STEP = 1e-10  # simulation.min_step's default [s]
N = 20  # simulation.chatter_events' default


def first_chatter(times, n=N, min_step=MIN_STEP):
    """Index (0-based) of the event at which the detector first reports CHATTER, or None; and its info."""
    ev_t = np.asarray(times, dtype=float)
    info = np.zeros(2)
    for n_ev in range(1, ev_t.size + 1):
        code = check_chatter(ev_t, n_ev, n, min_step, info)
        assert code in (OK, CHATTER)
        if code == CHATTER:
            return n_ev - 1, info
    return None, info


def test_events_at_one_instant_are_chatter_from_the_nth_on():
    # what the quick-return with loads.torque = 160000 gives: 23 regular events, then a pile at 2.19693 s
    regular = list(np.linspace(0.09, 1.76, 23))
    pile = [2.1969254309612922] * 30
    at, info = first_chatter(regular + pile)
    assert at == 23 + N - 1
    assert info[0] == 2.1969254309612922 and info[1] == 0.0


def test_fewer_than_n_events_at_one_instant_are_not_chatter():
    # e.g. a window bound and the velocity sign of several laws switching at one instant
    times = [0.5, 1.0] + [1.5] * (N - 1) + [2.0, 2.5]
    assert first_chatter(times)[0] is None


def test_the_quick_return_reference_events_do_not_trip_it(reference):
    # the independent minimal-coordinate model's 67 switching instants over 5 s (closest pair 0.0156 s apart)
    events = reference["events"]
    assert len(events) == 67
    assert first_chatter(events)[0] is None
    assert first_chatter(events, n=2)[0] is None  # not even two of them within min_step


@pytest.mark.parametrize("gap, chatters", [(0.0, True), (1.2e-11, True), (0.99 * MIN_STEP, True),
                                           (1.01 * MIN_STEP, False), (1e-6, False)])
def test_the_threshold_is_a_mean_gap_of_min_step(gap, chatters):
    # evenly spaced events: chatter exactly when the gap is at most min_step (1.2e-11 s: the widest
    # gap measured in a pile-up, RK4 with projection)
    times = 3.0 + gap * np.arange(2 * N)
    at, _ = first_chatter(times)
    assert (at == N - 1) if chatters else at is None


def test_one_wide_gap_among_many_zero_gaps_is_still_chatter():
    # a projection moved one event by 1e-9 s: the mean of the 19 gaps is 5.3e-11 s < min_step
    times = [1.0] * 10 + [1.0 + 1e-9] * 10
    assert first_chatter(times)[0] == N - 1


def test_an_accumulating_sequence_is_caught_once_its_mean_gap_drops_below_min_step():
    # Zeno-like: gaps halve from 1 ms; by hand, the first window of 20 events spanning at most
    # 19 min_step (the sum of 19 consecutive gaps 1e-3 2^-k, k = j .. j + 18) ends at event j + 19
    gaps = 1e-3 * 0.5 ** np.arange(60)
    times = np.concatenate(([1.0], 1.0 + np.cumsum(gaps)))
    spans = np.array([times[i + N - 1] - times[i] for i in range(times.size - N + 1)])
    expected = int(np.argmax(spans <= (N - 1) * MIN_STEP)) + N - 1
    at, info = first_chatter(times)
    assert at == expected and at < times.size - 1
    assert info[1] <= (N - 1) * MIN_STEP < times[at - 1] - times[at - N]


def test_far_from_t0_the_round_off_of_t_sets_the_resolution():
    # at t = 1e8 s consecutive doubles are 1.5e-8 s apart, more than min_step: events a few
    # ulps apart cannot be told apart, and count as one instant
    t0 = 1e8
    assert event_resolution(t0, MIN_STEP) == pytest.approx(64 * np.finfo(float).eps * (1 + t0))
    ulps = t0 + 3 * np.spacing(t0) * np.arange(2 * N)
    assert first_chatter(ulps)[0] == N - 1
    assert event_resolution(1.0, MIN_STEP) == MIN_STEP


def test_the_number_of_events_is_a_setting():
    times = [0.7] * 10
    assert first_chatter(times, n=5)[0] == 4
    assert first_chatter(times, n=11)[0] is None


def test_chattering_switches_are_those_of_the_last_n_events():
    # events: function 0, then 2 and 1 alternating at the pile; only the last n count
    ev_sw = np.zeros((8, 3), bool)
    ev_sw[0, 0] = True
    ev_sw[1::2, 2] = True
    ev_sw[2::2, 1] = True
    involved = np.ones(3, bool)
    chattering_switches(ev_sw, 8, 4, involved)
    np.testing.assert_array_equal(involved, [False, True, True])
    chattering_switches(ev_sw, 8, 8, involved)
    np.testing.assert_array_equal(involved, [True, True, True])
    chattering_switches(ev_sw, 3, 2, involved)  # only the recorded rows count
    np.testing.assert_array_equal(involved, [False, True, True])

"""Balanced Latin squares (Williams designs) for counterbalancing stimulus orders."""
from __future__ import annotations

from collections import Counter

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from laughlab_experiments.stimuli import participant_trials, williams


def _adjacent_pairs(rows):
    return Counter((a, b) for row in rows for a, b in zip(row, row[1:]))


@given(st.integers(min_value=1, max_value=16))
@settings(max_examples=40, deadline=None)
def test_each_condition_once_per_position(n):
    rows = williams(n)
    assert len(rows) == (n if n % 2 == 0 else 2 * n)
    for square in (rows[:n], rows[n:]) if n % 2 else (rows,):
        for row in square:
            assert sorted(row) == list(range(n))  # each row is an order of all conditions
        for pos in range(n):
            assert sorted(r[pos] for r in square) == list(range(n))  # each condition once per position


@given(st.integers(min_value=1, max_value=8).map(lambda k: 2 * k))
@settings(max_examples=20, deadline=None)
def test_even_n_every_ordered_pair_adjacent_exactly_once(n):
    pairs = _adjacent_pairs(williams(n))
    assert set(pairs) == {(a, b) for a in range(n) for b in range(n) if a != b}
    assert set(pairs.values()) == {1}


@given(st.integers(min_value=1, max_value=8).map(lambda k: 2 * k + 1))
@settings(max_examples=20, deadline=None)
def test_odd_n_two_squares_every_ordered_pair_adjacent_exactly_twice(n):
    pairs = _adjacent_pairs(williams(n))
    assert set(pairs) == {(a, b) for a in range(n) for b in range(n) if a != b}
    assert set(pairs.values()) == {2}


def test_known_square_of_four():
    assert williams(4) == [[0, 1, 3, 2], [1, 2, 0, 3], [2, 3, 1, 0], [3, 0, 2, 1]]


def test_bad_size():
    with pytest.raises(ValueError):
        williams(0)


@given(st.integers(min_value=1, max_value=7), st.integers(min_value=1, max_value=4),
       st.integers(min_value=1, max_value=30))
@settings(max_examples=40, deadline=None)
def test_participants_see_every_stimulus_once(n_cond, n_items, n_part):
    conds = [f"c{i}" for i in range(n_cond)]
    items = [f"a{i}" for i in range(n_items)]
    trials = participant_trials(conds, items, n_part, "all")
    assert len(trials) == n_part
    rows = williams(n_cond)
    for p, t in enumerate(trials):
        assert sorted(t) == sorted((c, a) for c in conds for a in items)
        # within every block of one item, the conditions follow the participant's Williams row
        for b in range(n_items):
            block = t[b * n_cond:(b + 1) * n_cond]
            assert len({a for _, a in block}) == 1
            assert [c for c, _ in block] == [conds[i] for i in rows[p % len(rows)]]


@given(st.integers(min_value=2, max_value=6), st.integers(min_value=1, max_value=6))
@settings(max_examples=30, deadline=None)
def test_one_per_condition_balances_positions_over_a_full_square(n_cond, n_items):
    conds = [f"c{i}" for i in range(n_cond)]
    items = [f"a{i}" for i in range(n_items)]
    rows = williams(n_cond)
    trials = participant_trials(conds, items, len(rows), "one_per_condition")
    for t in trials:
        assert sorted(c for c, _ in t) == sorted(conds)
    for pos in range(n_cond):
        counts = Counter(t[pos][0] for t in trials)
        assert set(counts.values()) == {len(rows) // n_cond}

"""Sweep plans: grid order, reproducible random and Latin-hypercube designs, checked values."""
from __future__ import annotations

import numpy as np
import pytest
from conftest import qr_case

from csim.errors import CaseError
from csim.study import make_plan, parse_variation


@pytest.fixture(scope="module")
def case():
    return qr_case("simulation.t_end=0.5")


def test_a_grid_is_every_combination_first_key_slowest(case):
    plan = make_plan(case, [parse_variation("stabilization.w=1,2"), parse_variation("stabilization.d=0.5,1,2")])
    assert plan.rows == [(1, 0.5), (1, 1), (1, 2), (2, 0.5), (2, 1), (2, 2)]
    assert plan.overrides(4) == ["stabilization.w=2", "stabilization.d=1"]
    assert plan.run_case(4).data["stabilization"]["d"] == 1


def test_values_with_units_are_planned_in_the_keys_unit(case):
    plan = make_plan(case, [parse_variation("initial.q.q1=170 deg,172 deg"),
                            parse_variation("simulation.t_end=lin:100 ms:200 ms:2")])
    assert plan.column("initial.q.q1") == pytest.approx([np.radians(170)] * 2 + [np.radians(172)] * 2)
    assert plan.column("simulation.t_end") == [0.1, 0.2, 0.1, 0.2]
    assert plan.run_case(3).data["simulation"]["t_end"] == 0.2
    with pytest.raises(CaseError) as info:
        make_plan(case, [parse_variation("loads.torque=1 kg,2 N*m")])
    assert "--vary 'loads.torque=1 kg,2 N*m': the value '1 kg': 'kg' is the unit of a mass" in str(info.value)


def test_random_designs_are_reproducible_and_stay_in_their_ranges(case):
    vs = [parse_variation("stabilization.w=log:1:1000"), parse_variation("stabilization.method=none,baumgarte")]
    a = make_plan(case, vs, sampling="random", samples=200, seed=7)
    b = make_plan(case, vs, sampling="random", samples=200, seed=7)
    assert a.rows == b.rows and a.seed == 7
    w = np.array(a.column("stabilization.w"))
    assert w.min() >= 1 and w.max() <= 1000
    # log-uniform: about half the draws below the geometric midpoint sqrt(1 * 1000)
    assert 0.35 < np.mean(w < np.sqrt(1000)) < 0.65
    assert set(a.column("stabilization.method")) == {"none", "baumgarte"}


def test_a_latin_hypercube_puts_one_run_in_each_stratum_of_each_key(case):
    n = 25
    plan = make_plan(case, [parse_variation("stabilization.w=lin:1:101"), parse_variation("stabilization.d=lin:1:2")],
                     sampling="lhs", samples=n, seed=3)
    for key, (a, b) in (("stabilization.w", (1, 101)), ("stabilization.d", (1, 2))):
        strata = np.floor((np.array(plan.column(key)) - a) / (b - a) * n).astype(int)
        assert sorted(strata) == list(range(n)), key


@pytest.mark.parametrize("vary, options, words", [
    (["stabilization.w=1,2", "stabilization.w=3"], {}, "varied twice"),
    (["stabilization.w=lin:1:2"], {}, "a grid needs N values"),
    (["stabilization.w=lin:1:2"], {"sampling": "random"}, "needs the number of runs"),
    (["stabilization.w=1,2"], {"samples": 5}, "only with --sample random"),
    (["stabilization.w=1,2"], {"sampling": "sobol"}, "valid: grid, random, lhs"),
    (["stabilization.w=1,-2"], {}, "--vary stabilization.w=-2: stabilization.w: got -2"),
    (["simulation.tend=1,2"], {}, "--vary simulation.tend=1: simulation.tend: unknown key"),
])
def test_bad_plans_are_rejected_naming_the_option(case, vary, options, words):
    with pytest.raises(CaseError) as info:
        make_plan(case, [parse_variation(v) for v in vary], **options)
    assert words in str(info.value)


def test_integer_keys_take_whole_numbers_in_ranges_and_random_draws(case):
    grid = make_plan(case, [parse_variation("simulation.max_steps=log:1000:100000:3")])
    assert grid.column("simulation.max_steps") == [1000, 10000, 100000]
    drawn = make_plan(case, [parse_variation("simulation.event_samples=lin:0:8")], sampling="random",
                      samples=20, seed=1).column("simulation.event_samples")
    assert all(isinstance(x, int) and 0 <= x <= 8 for x in drawn) and len(set(drawn)) > 3
    make_plan(case, [parse_variation("simulation.event_samples=lin:0:8")], sampling="random", samples=3, seed=1
              ).run_case(2)

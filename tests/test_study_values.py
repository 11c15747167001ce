"""--vary KEY=VALUES: lists, ranges, files, and the errors that name the option."""
from __future__ import annotations

import numpy as np
import pytest

from csim.errors import CaseError
from csim.study.values import parse_variation


def test_a_list_reads_values_as_a_case_file_would():
    v = parse_variation("stabilization.method=none, baumgarte,projection")
    assert v.key == "stabilization.method" and v.values == ("none", "baumgarte", "projection")
    assert not v.numeric
    w = parse_variation("simulation.rtol=1e-6,1e-8")
    assert w.values == (1e-6, 1e-8) and w.numeric


def test_a_yaml_list_of_lists_gives_vector_values():
    v = parse_variation("stabilization.w=[[20, 30], [40, 60]]")
    assert v.values == ([20, 30], [40, 60])


def test_ranges_include_both_ends_exactly():
    lin = parse_variation("stabilization.w=lin:0:1:11")
    assert len(lin.values) == 11 and lin.values[0] == 0.0 and lin.values[-1] == 1.0
    np.testing.assert_allclose(np.diff(lin.values), 0.1)
    log = parse_variation("simulation.step=log:1e-4:1e-1:13")
    assert len(log.values) == 13 and log.values[0] == 1e-4 and log.values[-1] == 1e-1
    np.testing.assert_allclose(np.diff(np.log10(log.values)), 0.25)


def test_a_range_of_whole_numbers_gives_integers_for_integer_keys():
    v = parse_variation("simulation.max_steps=lin:100000:200000:3")
    assert v.values == (100000, 150000, 200000) and all(isinstance(x, int) for x in v.values)
    assert all(isinstance(x, float) for x in parse_variation("stabilization.w=lin:1.0:3:3").values)


def test_a_range_without_n_is_a_distribution():
    v = parse_variation("simulation.step=log:1e-4:1e-2")
    assert v.values == () and v.bounds == (1e-4, 1e-2)
    x = v.sample(np.array([0.0, 0.5, 1.0]))
    np.testing.assert_allclose(x, [1e-4, 1e-3, 1e-2])


def test_values_from_a_file(tmp_path):
    (tmp_path / "w.txt").write_text("# gains\n10\n20  # the default\n\n40\n")
    assert parse_variation("stabilization.w=@w.txt", base=tmp_path).values == (10, 20, 40)
    (tmp_path / "m.yaml").write_text("[none, projection]\n")
    assert parse_variation("stabilization.method=@m.yaml", base=tmp_path).values == ("none", "projection")


def test_values_and_range_ends_with_units_are_converted_to_the_keys_unit():
    v = parse_variation("initial.q.q1=170 deg, 172 deg, 3.0")
    assert v.has_units and v.in_unit("rad").values == pytest.approx((np.radians(170), np.radians(172), 3.0))
    r = parse_variation("simulation.t_end=lin:100 ms:2 s:20")
    assert r.values == () and r.ends == ("100 ms", "2 s")
    s = r.in_unit("s")
    assert len(s.values) == 20 and s.values[0] == 0.1 and s.values[-1] == 2.0 and s.bounds == (0.1, 2.0)
    lhs = parse_variation("mechanism.parameters.l1=log:100 mm:1 m").in_unit("m")
    assert lhs.values == () and lhs.bounds == (0.1, 1.0)
    np.testing.assert_allclose(lhs.sample(np.array([0.5])), [10 ** -0.5])
    plain = parse_variation("simulation.t_end=1,2")
    assert not plain.has_units and plain.in_unit("s") is plain


@pytest.mark.parametrize("text, unit, words", [
    ("simulation.t_end=lin:100 kg:2 s:3", "s", "START '100 kg': 'kg' is the unit of a mass"),
    ("simulation.rtol=1e-6 s,1e-8", "", "the value '1e-6 s': this key has no unit"),
    ("simulation.t_end=log:-1 s:2 s:3", "s", "a log range needs positive START and STOP"),
    ("loads.x=lin:1 m:2 m:3", None, "csim does not know the unit of loads.x"),
])
def test_units_that_do_not_fit_the_key_name_the_option_and_the_value(text, unit, words):
    with pytest.raises(CaseError) as info:
        parse_variation(text).in_unit(unit)
    assert words in str(info.value) and "--vary" in str(info.value)


@pytest.mark.parametrize("text, words", [
    ("stabilization.w", "expected KEY=VALUES"),
    ("=1,2", "key is empty"),
    ("stabilization.w=lin:1:x:3", "STOP 'x' is not a number"),
    ("stabilization.w=log:0:1:3", "positive START and STOP"),
    ("stabilization.w=lin:0:1:0", "N must be from 1"),
    ("stabilization.w=lin:0:1:100000000000", "N must be from 1"),
    ("stabilization.w=lin:0:1:2.5", "not a whole number"),
    ("stabilization.w=1,,2", "empty one"),
    ("stabilization.w=@missing.txt", "cannot read the values file"),
])
def test_malformed_options_name_the_option(text, words):
    with pytest.raises(CaseError) as info:
        parse_variation(text)
    assert words in str(info.value) and "--vary" in str(info.value)

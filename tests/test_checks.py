"""clfd_bench.envs.checks: the verdict, margin and text of one criterion."""

import math

import pytest

from clfd_bench.envs.checks import Check, check_from_json, failed_checks


def test_at_most_bound_passes_on_the_bound_and_fails_just_past_it():
    assert Check("goal", 0.01, 0.01).passed
    over = Check("goal", 0.0112, 0.01, unit="m")
    assert not over.passed
    assert over.margin == pytest.approx(-0.0012)
    assert over.describe() == "goal 0.0112 m > 0.01 m"


def test_at_least_bound_and_flags():
    assert Check("coverage", 0.95, 0.9, ">=").margin == pytest.approx(0.05)
    assert not Check("coverage", 0.85, 0.9, ">=").passed
    assert Check.flag("held", True).passed and not Check.flag("held", False).passed


def test_missing_or_nonfinite_value_fails_with_minus_inf_margin():
    for value in (None, math.nan, math.inf):
        c = Check("dtw", value, 18.21)
        assert not c.passed and c.margin == -math.inf
    assert Check("dtw", math.inf, 18.21).to_json()["value"] is None


def test_bad_op_and_bound_are_refused():
    with pytest.raises(ValueError, match="op '<' is not one of"):
        Check("x", 1.0, 2.0, "<")
    with pytest.raises(ValueError, match="not finite"):
        Check("x", 1.0, math.nan)


def test_json_round_trip_and_failed_names():
    checks = [Check("a", 1.0, 2.0), Check("b", 3.0, 2.0), Check("c", 0.5, 0.9, ">=", "m", "n")]
    assert [check_from_json(c.to_json()) for c in checks] == checks
    assert failed_checks(checks) == ["b", "c"]

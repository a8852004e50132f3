"""eval/bound_audit.py whatif: the same executions scored under another success rule, against
hand-computed exec ACC and REM (docs/decisions.md's open decisions are read this way)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from clfd_bench.runs import RunDir


@pytest.fixture(scope="module")
def audit(eval_script):
    return eval_script("bound_audit")


def _check(name: str, value: float, bound: float, op: str = "<=") -> dict:
    passed = value <= bound if op == "<=" else value >= bound
    return {"name": name, "value": value, "bound": bound, "op": op, "unit": "m", "note": "",
            "passed": passed}


def _bottle(offset: float, on_shelf: float = 1.0) -> list[dict]:
    return [_check("release_offset", offset, 0.02), _check("on_shelf", on_shelf, 1.0, ">=")]


def _plate(offset: float, shift: float) -> list[dict]:
    return [_check("release_offset", offset, 0.0574), _check("rack_shift", shift, 0.02)]


@pytest.fixture
def lines(tmp_path) -> Path:
    """A two-task run (bottle2shelf, then platestandingtolying), two demos per cell:

    after 0, bottle:  1.0 cm (pass), 2.5 cm (fails by release_offset alone)
    after 1, bottle:  3.2 cm (fails), 2.5 cm but a reflex stopped it (fails, not by a check)
    after 1, plate:   offset 6 cm (fails, above its own 5.74 cm), rack shoved 3 cm (fails)
    """
    run = RunDir(tmp_path / "run")
    run.write_training_results({"tasks": [{"name": "bottle2shelf"},
                                          {"name": "platestandingtolying"}],
                                "config": {"dataset": "robotasks"}, "tasks_done": 2,
                                "complete": True})
    rows = [(0, "bottle2shelf", 0, _bottle(0.010), None),
            (0, "bottle2shelf", 1, _bottle(0.025), "task"),
            (1, "bottle2shelf", 0, _bottle(0.032), "task"),
            (1, "bottle2shelf", 1, _bottle(0.025), "reflex"),
            (1, "platestandingtolying", 0, _plate(0.060, 0.001), "task"),
            (1, "platestandingtolying", 1, _plate(0.010, 0.030), "task")]
    path = tmp_path / "audit.jsonl"
    with path.open("w") as f:
        for after, task, demo, checks, kind in rows:
            success = kind is None and all(c["passed"] for c in checks)
            f.write(json.dumps({"method": "chn", "run": str(run.path), "after": after,
                                "task": task, "demo": demo, "success": success, "kind": kind,
                                "checks": checks}) + "\n")
    return path


def _acc_rem(audit, lines: Path, rules) -> tuple[float, float]:
    from clfd_bench.metrics.cl import acc, rem

    ((_, _, then, recorded),) = audit._matrices([lines], rules).values()
    assert recorded is None  # the fixture's results.json has no execution
    return acc(then), rem(then)


def test_today_equals_the_recorded_verdicts(audit, lines):
    # R = [[1/2, -], [0/2, 0/2]]: ACC = (0.5 + 0 + 0) / 3, BWT = 0 - 0.5
    assert _acc_rem(audit, lines, []) == (pytest.approx(0.5 / 3), pytest.approx(0.5))


def test_a_floor_passes_only_what_failed_by_that_check_alone(audit, lines):
    rules = [audit.parse_rule("floor", "release_offset=0.03")]
    # after 0: both bottles pass (2.5 cm < 3 cm); after 1: 3.2 cm still fails, the reflex
    # still fails; the plate's own 5.74 cm bound is not lowered (6 cm fails), the rack fails
    assert _acc_rem(audit, lines, rules) == (pytest.approx(1.0 / 3), pytest.approx(0.0))


def test_drop_and_bound_apply_to_the_task_named_only(audit, lines):
    drop_bottle = [audit.parse_rule("drop", "bottle2shelf:release_offset")]
    # bottles: after 0 2/2, after 1 1/2 (the reflex stays a failure); plates 0/2
    assert _acc_rem(audit, lines, drop_bottle) == (pytest.approx(1.5 / 3), pytest.approx(0.5))
    rack = [audit.parse_rule("bound", "platestandingtolying:rack_shift=0.05")]
    assert _acc_rem(audit, lines, rack)[0] == pytest.approx((0.5 + 0 + 0.5) / 3)
    both = drop_bottle + rack + [audit.parse_rule("drop", "platestandingtolying:release_offset")]
    assert _acc_rem(audit, lines, both)[0] == pytest.approx((1.0 + 0.5 + 1.0) / 3)


def test_the_decisions_table_and_bad_rules(audit, lines, capsys):
    assert audit.main(["whatif", str(lines), "--decisions"]) == 0
    out = capsys.readouterr().out
    # 1a floor 3 cm, 1b no end point in placing scenes, 2 rack 5 cm, 1b and 2 (hand-computed
    # from the fixture's six executions)
    assert "| chn | 1 | 0.17 | 0.33 (+0.17) | 0.67 (+0.50) | 0.33 (+0.17) | 0.83 (+0.67) |" \
        in out, out
    assert "ranking today: chn 0.17" in out
    with pytest.raises(SystemExit):
        audit.main(["whatif", str(lines), "--bound", "release_offset"])
    assert "expected [TASK:]CHECK=VALUE" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        audit.main(["whatif", str(lines)])
    assert "needs --drop, --bound, --floor or --decisions" in capsys.readouterr().err

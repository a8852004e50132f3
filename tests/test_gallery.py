"""The borderline gallery: which executions it picks (nearest each bound, on both sides, the
decisive ones preferred), what the execution layer stores for it (checks in the summary, the
cache schema, failure reasons naming failed checks), and the CLI's refusal of a folder
without runs."""

from __future__ import annotations

import json

import pytest

from clfd_bench.envs.checks import Check, checks_json
from clfd_bench.execution.borderline import (
    Execution,
    is_flag,
    numeric_check_names,
    select_borderline,
)
from clfd_bench.execution.execute import ExecResult, failure_reason
from clfd_bench.runs import RunDir

BOUND = 0.01


def _ex(key: str, goal: float | None, hausdorff: float = 0.02, held: bool = True,
        complete: bool = True, env: str = "clfd/Fake-v0") -> Execution:
    checks = (Check("goal", goal, BOUND, "<=", "m"),
              Check("hausdorff", hausdorff, 0.025, "<=", "m"), Check.flag("held", held))
    return Execution(env, key, checks, complete=complete,
                     success=all(c.passed for c in checks), label={"name": key})


@pytest.fixture()
def executions() -> list[Execution]:
    return [
        _ex("A", 0.0095),                    # passes by 0.0005, every check passes
        _ex("B", 0.0099, hausdorff=0.03),    # passes by 0.0001, but hausdorff fails
        _ex("C", 0.0102, hausdorff=0.03),    # fails by 0.0002, hausdorff fails too
        _ex("D", 0.0110),                    # fails by 0.001, the only failed check
        _ex("D", 0.0110),                    # the same execution again (another point)
        _ex("E", 0.0300),                    # fails by 0.02, the only failed check
        _ex("F", None),                      # not measured: no distance to the bound
        _ex("G", 0.01001, complete=False),   # the episode ended early: left out
    ]


def test_nearest_on_each_side_failures_of_only_this_check_first(executions):
    (goal, hausdorff) = select_borderline(executions, per_side=1)
    assert (goal.env_id, goal.check) == ("clfd/Fake-v0", "goal")
    # The nearest pass, whatever else failed (B: hausdorff), which the pick names.
    assert [p.execution.key for p in goal.passing] == ["B"]
    assert goal.passing[0].side == "pass" and goal.passing[0].also_failed == ("hausdorff",)
    assert not goal.passing[0].decisive and goal.passing[0].margin == pytest.approx(0.0001)
    # C is nearer but fails hausdorff too: D, failing only the goal, comes first.
    assert [p.execution.key for p in goal.failing] == ["D"]
    assert goal.failing[0].decisive and goal.failing[0].also_failed == ()
    # Distinct executions: A, B, C, D, E pass or fail the goal (F unmeasured, G incomplete).
    assert goal.candidates == (2, 3)
    assert hausdorff.check == "hausdorff"
    assert [p.execution.key for p in hausdorff.failing] == ["B"]  # B's hausdorff alone fails


def test_more_per_side_fill_with_the_others_and_say_what_else_failed(executions):
    goal = select_borderline(executions, per_side=3)[0]
    assert [p.execution.key for p in goal.passing] == ["B", "A"]
    assert goal.passing[1].also_failed == () and goal.passing[1].decisive
    assert [p.execution.key for p in goal.failing] == ["D", "E", "C"]
    assert goal.failing[2].also_failed == ("hausdorff",)
    assert goal.failing[1].margin == pytest.approx(-0.02)


def test_flags_are_not_numeric_checks(executions):
    assert is_flag(Check.flag("held", False)) and not is_flag(Check("beans", 1.0, 3.0, ">="))
    assert numeric_check_names(executions) == {"clfd/Fake-v0": ["goal", "hausdorff"]}
    assert [b.check for b in select_borderline(executions)] == ["goal", "hausdorff"]
    with pytest.raises(ValueError, match="per_side must be >= 1"):
        select_borderline(executions, per_side=0)


def test_envs_are_kept_apart():
    picks = select_borderline([_ex("a", 0.009, env="clfd/X-v0"), _ex("b", 0.0099, env="clfd/Y-v0")])
    assert [(b.env_id, [p.execution.key for p in b.passing]) for b in picks
            if b.check == "goal"] == [("clfd/X-v0", ["a"]), ("clfd/Y-v0", ["b"])]


def test_failure_reason_names_failed_checks_first():
    info = {"is_success": False, "checks": checks_json([
        Check("goal", 0.0112, 0.01, "<=", "m"), Check("dwell", 0.1, 0.5, "<=")]), "dtw": 9.5}
    assert failure_reason(False, info) == "task not achieved: goal 11.2 mm > 10 mm allowed"
    no_checks = {k: v for k, v in info.items() if k != "checks"}
    assert failure_reason(False, no_checks) == "task not achieved (dtw=9.5)"
    assert failure_reason(False, dict(info, failure_reason="reflex: x")) == "reflex: x"
    assert failure_reason(True, info) is None


def test_failure_reason_says_every_failed_check_in_words():
    checks = [
        Check("goal", 0.0106, 0.01, "<=", "m", "last ink point to the task's end point"),
        Check("turn", 33.38, 47.45, ">=", "deg"),
        Check("beans_in_scoop", 0.0, 3.0, ">="),
        Check.flag("held", False, "the scoop never slipped"),
        Check("coverage", None, 0.9, ">=", "", "no ink"),
        Check("drag", 0.25, 0.3, "<=", "m"),  # passed: not named
        Check("stray_ink", 0.35, 0.2, "<=", "m"),
    ]
    info = {"is_success": False, "checks": checks_json(checks), "held": False}
    assert failure_reason(False, info) == (
        "task not achieved: goal 10.6 mm > 10 mm allowed (last ink point to the task's end "
        "point); turn 33.4° < 47.5° needed; beans_in_scoop 0 < 3 needed; held not met (the "
        "scoop never slipped); coverage not measured (no ink); stray_ink 35 cm > 20 cm allowed")


def test_summary_keeps_checks_and_says_whether_the_rollout_stopped_early():
    raw = checks_json([Check("goal", 0.0112, 0.01, "<=", "m")])
    res = ExecResult(demo=2, success=False, mean_tracking_error=0.001, max_tracking_error=0.002,
                     mean_rotation_error=0.0, failure_reason="task not achieved: goal ...",
                     failure_kind="task", steps=1060, wall_s=1.0, info={"checks": raw})
    summary = res.summary()
    assert summary["checks"] == raw and summary["stopped_early"] is False
    assert json.loads(json.dumps(summary)) == summary
    assert res.checks() == [Check("goal", 0.0112, 0.01, "<=", "m")]
    early = ExecResult(2, False, 0.0, 0.0, 0.0, "task failed", "task", 300, 0.1,
                       info={"stopped_early": {"stopped_at": 300}})
    assert early.summary()["stopped_early"] is True and early.summary()["checks"] is None


def test_a_cache_without_checks_is_not_read(tmp_path):
    run = RunDir(tmp_path / "run")
    run.path.mkdir()
    run.save_cache("fp", {"k": {"success": True, "checks": []}})
    assert run.load_cache("fp") == {"k": {"success": True, "checks": []}}
    # A cache of schema 2 (summaries without checks) reads as empty: it is executed again.
    doc = json.loads(run.cache_path.read_text())
    run.cache_path.write_text(json.dumps(dict(doc, schema=2)))
    assert run.load_cache("fp") == {}


def test_cli_refuses_a_folder_without_runs(tmp_path, capsys):
    from clfd_bench.cli.main import main

    empty = tmp_path / "results"
    empty.mkdir()
    out = tmp_path / "gallery"
    assert main(["gallery", str(empty), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0
    assert err.startswith("clfd-bench gallery: error:") and "holds no run" in err
    assert not out.exists()


def test_contact_sheet_rows_take_the_nearest_over_a_datasets_envs():
    from clfd_bench.viz.gallery import pick_caption, sheet_picks

    exs = [_ex("x1", 0.0090, env="clfd/X-v0"), _ex("y1", 0.0098, env="clfd/Y-v0"),
           _ex("x2", 0.0105, env="clfd/X-v0"), _ex("y2", 0.0120, env="clfd/Y-v0")]
    rows = sheet_picks(select_borderline(exs), {"clfd/X-v0": "ds", "clfd/Y-v0": "ds"})
    goal = next(r for r in rows["ds"] if r[0] == "goal [m]")
    assert goal[1].execution.key == "y1" and goal[2].execution.key == "x2"
    hausdorff = next(r for r in rows["ds"] if r[0] == "hausdorff [m]")
    assert hausdorff[2] is None  # no execution fails it
    lines = pick_caption(goal[2])
    assert lines[1].startswith("goal 0.0105 m > 0.01 m → fails")
    assert lines[2] == "only this check fails: it alone fails the execution"

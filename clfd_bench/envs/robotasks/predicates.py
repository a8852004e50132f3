"""The success checks several RoboTasks tasks share, as pure functions: measured quantities and
the spec's `[success]` bounds in, `clfd_bench.envs.checks.Check`s out (no simulator). Each
task's `success.py` composes them with its own."""

from __future__ import annotations

from typing import Any

from clfd_bench.envs.checks import Check

__all__ = ["knock_checks", "release_checks", "rest_checks"]


def knock_checks(name: str, shift: float, tilt: float, cfg: dict[str, Any]) -> list[Check]:
    """A rack or tray that must not be knocked (`placing.KnockWatch`).

    Args:
        name: what it is ("rack", "tray"): the checks are `<name>_shift`, `<name>_tilt`.
        shift: its largest shift (m) from where it was put, at any step.
        tilt: its largest tilt (deg), at any step.
        cfg: the spec's `[success]`: `max_<name>_shift` (m), `max_<name>_tilt_deg`.
    """
    return [Check(f"{name}_shift", float(shift), float(cfg[f"max_{name}_shift"]), "<=", "m",
                  f"the {name}'s largest shift at any step"),
            Check(f"{name}_tilt", float(tilt), float(cfg[f"max_{name}_tilt_deg"]), "<=", "deg",
                  f"the {name}'s largest tilt at any step")]


def release_checks(release_reason: str | None, held: bool, release_height: float | None,
                   release_offset: float | None, cfg: dict[str, Any]) -> list[Check]:
    """A held prop let go onto a support: by the gripper, low, near demo j's release point.

    Args:
        release_reason: how the prop left the fingers: "opened", "slipped", None (never).
        held: the gripper holds the prop now.
        release_height: the prop's lowest point above the support's top when the gripper
            opened (m), None if it never did.
        release_offset: horizontal distance (m) from where demo j lets the prop go, then.
        cfg: the spec's `[success]`: `max_release_height`, `place_radius` (m); a provisional
            spec without them (while deriving) fails those checks.

    Returns:
        `let_go` (flag), `release_height` <= `max_release_height`, `release_offset` <=
        `place_radius`.
    """
    checks = [
        Check.flag("let_go", release_reason == "opened" and not held,
                   "the gripper opened (the prop did not slip out) and holds nothing")]
    for name, value, key, note in (
            ("release_height", release_height, "max_release_height",
             "the prop's lowest point above the support's top when the gripper opens"),
            ("release_offset", release_offset, "place_radius",
             "horizontal distance from where demo j lets the prop go")):
        if key in cfg:
            checks.append(Check(name, value, float(cfg[key]), "<=", "m", note))
        else:  # a provisional spec while deriving (the prop is never let go there)
            checks.append(Check.flag(name, False, f"the spec has no [success] {key}"))
    return checks


def rest_checks(support: str, on_top: bool, tilt: float, tilt_note: str, height: float,
                height_note: str, cfg: dict[str, Any]) -> list[Check]:
    """A prop at rest on a support at the end.

    Args:
        support: the support's name ("shelf"): the first check is `on_<support>`.
        on_top: the prop's reference point is over the support's top.
        tilt: the prop's tilt from how it should rest (deg); tilt_note says what it is.
        height: the reference point above the support's top (m); height_note says what it is.
        cfg: the spec's `[success]`: `max_tilt_deg`, `min_height`, `max_height`.

    Returns:
        `on_<support>` (flag), `tilt` <= `max_tilt_deg`, `rest_height_min` >= `min_height`,
        `rest_height_max` <= `max_height`.
    """
    return [
        Check.flag(f"on_{support}", on_top, f"over the {support}'s top"),
        Check("tilt", tilt, float(cfg["max_tilt_deg"]), "<=", "deg", tilt_note),
        Check("rest_height_min", height, float(cfg["min_height"]), ">=", "m", height_note),
        Check("rest_height_max", height, float(cfg["max_height"]), "<=", "m", height_note),
    ]

"""Derives the RoboTasks task specs (`tasks/<task>.toml`) from the demonstrations.

`derive_spec(task)` recomputes every data-derived number of a scene, its success thresholds and
the per-demo start configurations; `eval/make_task_specs.py` writes the results, with each
number's procedure as a comment next to it. What is derived:

- openbox: the hinge (a horizontal axis fitted to the arcs the grasp points trace,
  `clfd_bench.sim.scene_fit.fit_hinge`), placed as the box's hinge frame; how far the lid's
  edge slides and turns in the fingers in the demos (`scene_fit.grip_slips`), + margins: the
  grasp's slip bounds; the opening angle the grasp must reach;
- bottle2shelf: the shelf top 1 cm under the lowest point the held bottle reaches at the
  demos' end poses, centred under the bottles' end positions; the release height and place
  radius bounds;
- platestandingtolying: the table 3 mm under the lowest point the plate reaches in the first
  fifth of the demos (where it stands in the rack), the rack's pegs 1.5 cm clear of where the
  plate's rim passes in that fifth, the platform top 1 cm under the lowest point of the plate
  in the last fifth of the demos, centred under the plates' end positions; the release height
  and place radius bounds;
- pouring: the container centred on the median of where the beans first reach the table when
  the demos are replayed over a flat tray, wide enough for 95 % of them (+ a bean radius +
  1 cm), its rim 2 cm under the lowest point the cup reaches in the demos; the bean-count
  thresholds from the demos replayed into that container;
- wineglass (RoboTasks9): the stand's top (the drying tray's base) 1.5 cm under the lowest
  point the glass reaches in the first fifth of the demos; the tray's walls 1.5 cm clear of where
  the demos move the glass below the walls' top (2.4 cm up the glass) in that fifth; the shelf
  as the bottle's, under the glass's foot at the demos' ends; the release height and place
  radius bounds;
- pan2stove (RoboTasks9): the table 1.5 cm + the rack's base under the lowest point the pan
  reaches in the first fifth of the demos; the rack's walls as the glass tray's; the stove as
  the bottle's shelf, under the pan at the demos' ends; the release height and place radius
  bounds;
- matfolding (RoboTasks9): the table 1.5 cm under the lowest start grasp point, lowered until
  every demo's hand clears it by 1.5 cm; the bound of the pinched edge's turn in the fingers
  (the demos' largest + 10 deg); from the demos replayed, where each lets the edge go in the
  room (its radius from how much replaying the demos 2x slower and 1.5x faster moves it), the
  strips they turn over and how far they drag the mat (the largest + the demos' spread);
- obstaclerotate (RoboTasks9): the table as the bottle's; the obstacle's faces moved in until
  every demo's box and arm clear it by 1.5 cm (replayed with the obstacle a ghost); the shelf as
  the bottle's; the turn the demos make and undo;
- scoop (RoboTasks9): the beans' level 3.5 cm over the highest of the demos' lowest points of
  the bowl's lip; the bin's floor 1.5 cm under the scoop's lowest point, its walls 1.5 cm
  outside the scoop below the rim, moved out until every demo's scoop and arm clear them by
  1.5 cm (replayed with the bin a ghost); from the demos replayed (as they are, 2x slower,
  1.5x faster) the beans they end with, the beans they spill and how level the bowl ends;
- every task: start configurations by backward IK tracking from the common end pose
  (`clfd_bench.sim.start_configs.backward_start_configs`), each checked by kinematic forward
  tracking; a demo whose backward start does not track gets the IK solution of its first pose
  from `home` instead, if that tracks; a camera framing the demos' workspace.

Margins (design constants, `POSITION_MARGIN`, `TURN_MARGIN_DEG`): a bound taken from the demos
is widened by what good-but-imperfect executions add: 1 cm (the smooth noise and start offsets
an execution must survive) + 5 mm (servo lag and IK error). Design constants (not data-derived)
sit in the `DESIGN` table below and in the task MJCF.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np

from clfd_bench.data import load_dataset
from clfd_bench.envs.robotask_specs import TASK_DATASETS, load_task_spec
from clfd_bench.envs.robotasks import RoboTaskEnv
from clfd_bench.resources import resource_path
from clfd_bench.sim.robot import ROBOT_BODIES, robot_model
from clfd_bench.sim.scene_fit import (
    fit_hinge,
    grasp_points,
    grip_slips,
    hinge_angles,
    lowest_point,
    prop_pose,
)
from clfd_bench.sim.start_configs import (
    backward_start_configs,
    solve_configuration,
    tracking_errors,
)

#: A start configuration "tracks" when forward IK stays within these of the demo.
TRACK_TOL_POS = 1e-3
TRACK_TOL_ROT = 1e-2
#: Added to a position bound measured on the demos: 1 cm of noise / offset an execution must
#: survive + 5 mm of servo lag and IK error (m).
POSITION_MARGIN = 0.015
#: Added to an orientation bound measured on the demos (deg): the 1.5 cm position margin moves
#: the lid's angle by up to 4 deg at the demos' smallest grasp radius (0.21 m), + 6 deg.
TURN_MARGIN_DEG = 10.0

#: How far (m) a rack or tray a prop is taken out of may move before it counts as knocked: the
#: 1.5 cm position margin + 5 mm, the distance a placed prop may be off too (`PLACE_RADIUS`).
#: Argued in `_knock_argument`: the rack's walls / pegs stand 1.5 cm clear of the demos' prop,
#: so a good execution that far off the demos' path touches them and pushes the rack up to that.
KNOCK_SHIFT = POSITION_MARGIN + 0.005

IDENTITY = [1.0, 0.0, 0.0, 0.0]
#: The cup's axis (its z) along minus the hand's x axis: a -90 deg turn about the hand's y.
CUP_IN_GRASP = [float(np.sqrt(0.5)), 0.0, -float(np.sqrt(0.5)), 0.0]

#: The Franka Hand's grip, shared by every task (clfd_bench.sim.grasp): 70 N continuous grasp
#: force (datasheet), friction coefficient 0.5 (stock fingertips on PET/ceramic/wood), 17 x 17
#: mm pads; the load ratio is averaged over 6 control steps (0.1 s) before it breaks the grasp.
GRIP = {"grip_force": 70.0, "mu": 0.5, "filter_steps": 6}

#: The tray / rack a held prop is taken out of (wineglass, pan2stove): its walls derived from
#: the first `tray_fraction` of the demos, `tray_clearance` clear of the prop below their top,
#: which is `tray_rise` up the prop from its lowest start point; base and wall thickness (m).
TRAY = {"tray_fraction": 0.2, "tray_clearance": POSITION_MARGIN, "tray_base_thickness": 0.005,
        "tray_wall_thickness": 0.008, "tray_rise": 0.024}

#: Design constants per task (documented choices, not derived from the data). Physics steps
#: of 2 ms (8 per 60 Hz control step): the arm's stiff position servos, at their torque limits
#: while a held prop swings, track the demos only as well as the step lets them. Worst hand
#: position error over the replays (eval/measure_limits.py; PlateStacking demo 0 2x slower /
#: Pouring demo 7 1.5x faster) with 4, 5, 6, 8, 12 physics steps per control step: 23.8 /
#: 21.1, 11.6 / 8.2, 8.3 / 7.4, 3.8 / 1.4, 1.3 / 1.2 mm. 4 ms steps (tried for speed) made
#: tracking errors a simulation artefact; 2 ms is within ~2.5 mm of the finest step, at ~80 %
#: of 4 ms's speed.
DESIGN: dict[str, dict[str, Any]] = {
    "openbox": {
        "task": {"physics_dt": 0.002},
        "grasp": {"kind": "weld", "body": "lid_handle", "exclude": ["lid"], **GRIP,
                  "contact": "patch", "max_slip": 0.03, "max_slip_angle_deg": 30.0,
                  "closed_opening": 0.006, "prop_pos": [0.0, 0.0, 0.0], "prop_quat": IDENTITY},
        "success": {"stay_open_tolerance_deg": 3.0},
        "camera": {"distance": 1.2, "azimuth": 125.0, "elevation": -22.0},
    },
    "bottle2shelf": {
        "task": {"physics_dt": 0.002},
        "grasp": {"kind": "weld", "body": "bottle", **GRIP, "contact": "line_z",
                  "contact_radius": 0.0135, "max_slip": 0.03, "max_slip_angle_deg": 30.0,
                  "closed_opening": 0.0135, "prop_pos": [0.0, 0.0, 0.0],
                  "prop_quat": IDENTITY},
        "scene": {"shelf_half_size": [0.12, 0.09], "clearance": POSITION_MARGIN,
                  "table_fraction": 0.2,
                  "table_clearance": POSITION_MARGIN},
        "success": {"max_tilt_deg": 20.0, "min_height": 0.0, "max_height": 0.045},
        "camera": {"distance": 1.15, "azimuth": 140.0, "elevation": -24.0},
    },
    "platestandingtolying": {
        "task": {"physics_dt": 0.002},
        "grasp": {"kind": "weld", "body": "plate", **GRIP, "contact": "patch",
                  "max_slip": 0.03, "max_slip_angle_deg": 30.0, "closed_opening": 0.005,
                  "prop_pos": [0.0, 0.0, 0.0], "prop_quat": IDENTITY},
        "scene": {"platform_half_size": [0.13, 0.08], "clearance": POSITION_MARGIN,
                  "place_fraction": 0.2, "table_clearance": POSITION_MARGIN,
                  "block_clearance": POSITION_MARGIN, "block_x": 0.045, "block_rise": 0.024,
                  "rack_base_thickness": 0.005,
                  "rack_fraction": 0.2},
        "success": {"max_tilt_deg": 25.0, "min_height": 0.0, "max_height": 0.03,
                    "max_rack_shift": KNOCK_SHIFT, "max_rack_tilt_deg": 10.0},
        "camera": {"distance": 1.25, "azimuth": 140.0, "elevation": -24.0},
    },
    "wineglass": {
        "task": {"physics_dt": 0.002},
        "grasp": {"kind": "weld", "body": "glass", **GRIP, "contact": "line_x",
                  "contact_radius": 0.0045, "max_slip": 0.03, "max_slip_angle_deg": 30.0,
                  "closed_opening": 0.0045, "prop_pos": [0.0, 0.0, 0.0],
                  "prop_quat": IDENTITY},
        "scene": {"shelf_half_size": [0.1, 0.1], "clearance": POSITION_MARGIN, **TRAY,
                  "stand_margin": 0.02},
        "success": {"max_tilt_deg": 10.0, "min_height": -0.005, "max_height": 0.01,
                    "max_tray_shift": KNOCK_SHIFT, "max_tray_tilt_deg": 10.0},
        "camera": {"distance": 1.2, "azimuth": 150.0, "elevation": -22.0},
    },
    "pan2stove": {
        "task": {"physics_dt": 0.002},
        "grasp": {"kind": "weld", "body": "pan", **GRIP, "contact": "patch",
                  "max_slip": 0.03, "max_slip_angle_deg": 30.0, "closed_opening": 0.004,
                  "prop_pos": [0.0, 0.0, 0.0], "prop_quat": IDENTITY},
        "scene": {"stove_half_size": [0.15, 0.15], "clearance": POSITION_MARGIN, **TRAY},
        "success": {"max_tilt_deg": 15.0, "min_height": -0.005, "max_height": 0.01,
                    "max_rack_shift": KNOCK_SHIFT, "max_rack_tilt_deg": 10.0},
        "camera": {"distance": 1.3, "azimuth": 150.0, "elevation": -24.0},
    },
    "obstaclerotate": {
        "task": {"physics_dt": 0.002},
        "grasp": {"kind": "weld", "body": "object", **GRIP, "contact": "patch",
                  "max_slip": 0.03, "max_slip_angle_deg": 30.0, "closed_opening": 0.03,
                  "prop_pos": [0.0, 0.0, 0.0], "prop_quat": IDENTITY},
        "scene": {"shelf_half_size": [0.12, 0.12], "clearance": POSITION_MARGIN,
                  "table_fraction": 0.2, "table_clearance": POSITION_MARGIN,
                  "obstacle_xy": [0.20, 0.43, -0.24, 0.00], "obstacle_top": 0.30},
        "success": {"max_tilt_deg": 15.0, "min_height": -0.005, "max_height": 0.01},
        "camera": {"distance": 1.35, "azimuth": 160.0, "elevation": -30.0},
    },
    "matfolding": {
        "task": {"physics_dt": 0.002},
        "grasp": {"kind": "weld", "body": "mat_pinch", **GRIP, "contact": "patch",
                  "max_slip": 0.03, "max_slip_angle_deg": 30.0, "closed_opening": 0.0015,
                  "exclude": ["mat10", "mat9", "mat8"], "prop_pos": [0.0, 0.0, 0.0],
                  "prop_quat": IDENTITY},
        "scene": {"table_clearance": POSITION_MARGIN, "table_xy": [-0.3, 0.9, -1.0, 0.6],
                  "jitter_factor": 1.3},
        "success": {"max_layer_height": 0.01},
        "camera": {"distance": 1.3, "azimuth": 60.0, "elevation": -30.0},
    },
    "scoop": {
        "task": {"physics_dt": 0.002, "release_after": False},
        "grasp": {"kind": "weld", "body": "scoop", **GRIP, "contact": "line_x",
                  "contact_radius": 0.008, "max_slip": 0.03, "max_slip_angle_deg": 30.0,
                  "closed_opening": 0.008, "prop_pos": [0.0, 0.0, 0.0],
                  "prop_quat": IDENTITY},
        "scene": {"n_beans": 6, "bean_radius": 0.012, "bean_mass": 0.002, "grain_spacing": 0.01,
                  # the bowl of tasks/scoop.xml in the scoop's frame: inside its walls and
                  # floor, from the opening (low z) up; and its outside
                  "bowl_cavity": [[0.214, -0.031, -0.02], [0.286, 0.031, 0.016]],
                  "bowl_outer": [[0.21, -0.035, -0.02], [0.29, 0.035, 0.02]],
                  "dip": 0.035, "rim_above": 0.0, "clearance": POSITION_MARGIN,
                  "bin_wall_thickness": 0.008},
        "solver": {"solver": "newton", "iterations": 20, "ls_iterations": 10,
                   "tolerance": 1e-8, "cone": "pyramidal"},
        "success": {},
        "camera": {"distance": 1.1, "azimuth": 145.0, "elevation": -26.0},
    },
    "pouring": {
        "task": {"physics_dt": 0.002, "release_after": False},
        "grasp": {"kind": "weld", "body": "cup", **GRIP, "contact": "line_x",
                  "contact_radius": 0.04, "max_slip": 0.03, "max_slip_angle_deg": 30.0,
                  "closed_opening": 0.04, "prop_pos": [0.0, 0.0, 0.0],
                  "prop_quat": CUP_IN_GRASP},
        "scene": {"n_beans": 9, "bean_radius": 0.011, "bean_mass": 0.0025,
                  "cup_inner_radius": 0.036, "cup_floor": -0.042,
                  "rim_clearance": 0.02, "landing_quantile": 0.95, "margin": 0.01,
                  "min_half_size": 0.05, "jitter_factor": 1.3},
        "solver": {"solver": "newton", "iterations": 20, "ls_iterations": 10,
                   "tolerance": 1e-8, "cone": "pyramidal"},
        "success": {},
        "camera": {"distance": 1.0, "azimuth": 135.0, "elevation": -28.0},
    },
}


#: Where the observer arguments' measurements come from.
_REPLAYED = "in every must-succeed replay of `clfd-bench replay --perturb all` (2026-12-05)"


def _knock_argument(what: str, replayed: str, hit: str, size: str) -> str:
    return (f"observer: the {what} is not knocked. It may move at most this far (m) from where "
            "it was put, at any step. Design: the 1.5 cm position margin + 5 mm (the distance "
            "a placed prop may be off too). The walls stand 1.5 cm clear of where the demos "
            "move the prop, so a good execution up to 1.5 cm off the demos' path may touch "
            "them and push the rack that far; what an observer sees as a knock is the rack "
            f"shoved out of place or tipped. Why an observer signs it: {replayed}; executions "
            f"that run into it {hit}; {size}")


#: The observer's argument for every design constant of a success criterion (issue 38): why an
#: observer would sign the verdicts at that bound, with what the demos and the perturbation
#: families measure on either side of it (docs/execution.md, "Where every bound comes from").
#: Written next to the value in tasks/<task>.toml.
OBSERVER: dict[str, dict[str, dict[str, str]]] = {
    "openbox": {"success": {
        "stay_open_tolerance_deg": (
            "observer: the lid stays open. After the gripper lets go the lid may settle this "
            "far (deg) below min_open_angle_deg. Design. Why an observer signs it: the friction "
            f"hinges hold the lid where it is left ({_REPLAYED} it settles at most 0.6 deg); "
            "3 deg is 1.2-1.4 cm of the edge's travel at the demos' 0.23-0.26 m grasp radii, "
            "less than the 1.5 cm of arc min_open_angle_deg already concedes, so a lid within "
            "it is as open as demo j leaves it; the must-fail executions that let the lid go "
            "end 4.8 deg (stop-early) to 101 deg short of min_open_angle_deg"),
    }},
    "bottle2shelf": {"success": {
        "max_tilt_deg": (
            "observer: lying on the shelf. The bottle's axis at most this far (deg) from "
            "horizontal at the end. Design. Why an observer signs it: on the flat board the "
            f"axis is horizontal (0.04 deg {_REPLAYED}); it rests tilted only on something "
            "else, and 20 deg lifts one end of the 14.5 cm bottle 5 cm off the board: propped, "
            "not lying; a standing bottle is at 90 deg"),
        "min_height": (
            "observer: resting on the board. The bottle's centre must be at least this high "
            "(m) above the shelf's top at the end: below it, it has sunk into the board (a "
            "physics failure)"),
        "max_height": (
            "the bottle's centre at most this high (m) above the shelf's top at the end. "
            f"Design. Why an observer signs it: lying on the board its centre is its radius, "
            f"2.8 cm, above it ({_REPLAYED}); 4.5 cm is 1.7 cm more, resting on something "
            "else, and below the 7 cm of a standing bottle"),
    }},
    "platestandingtolying": {"success": {
        "max_tilt_deg": (
            "observer: lying on the platform. The plate's face at most this far (deg) from "
            "horizontal at the end. Design. Why an observer signs it: lying on the flat "
            f"platform it is level (0.01 deg {_REPLAYED}); 25 deg lifts the far rim of the "
            "14 cm plate 5.9 cm: propped (on the rack, a finger), not lying; standing is 90 deg"),
        "min_height": (
            "observer: resting on the platform. The plate's centre must be at least this high "
            "(m) above the platform's top at the end: below it, it has sunk into the board (a "
            "physics failure)"),
        "max_height": (
            "the plate's centre at most this high (m) above the platform's top at the end. "
            "Design. Why an observer signs it: lying on the board its centre is half its 1 cm "
            f"thickness above it (0.49 cm {_REPLAYED}); 3 cm is 2.5 cm more, resting on "
            "something else, and below the 7 cm of a plate standing on its rim"),
        "max_rack_shift": _knock_argument(
            "dish rack", f"{_REPLAYED} the rack moves at most 0.2 mm (settling)",
            "(shortcut, rush-wait) move it 7-24 cm", "2 cm is 15 % of the 13 x 14.5 cm rack; "
            "learned executions (the RoboTasks fast grid) that bump it 1.2-1.9 cm while "
            "laying the plate flat leave it in place in the closing frame (FT after task 2, "
            "demo 2: 1.23 cm) and pass; from 2.3 cm it is pushed aside and they fail "
            "(docs/execution.md, 'Learned executions nearest the bounds')"),
        "max_rack_tilt_deg": (
            "observer: the rack is not tipped. It may tilt at most this far (deg) at any step. "
            f"Design. Why an observer signs it: it stays level ({_REPLAYED} 0.0 deg); 10 deg "
            "lifts one side of its 13 cm base 2.3 cm off the table; executions that run into "
            "it tilt it 10-90 deg"),
    }},
    "wineglass": {"success": {
        "max_tilt_deg": (
            "observer: standing upright. The glass's axis at most this far (deg) from "
            "vertical at the end. Design. Why an observer signs it: standing on its foot on "
            f"the flat shelf it is upright (0.02 deg {_REPLAYED}); it leans only against "
            "something, and 10 deg moves the rim of the 20 cm glass 3.5 cm sideways; "
            "must-fail executions that let it go leave it 16-146 deg from upright"),
        "min_height": (
            "observer: standing on the shelf. The foot's bottom at least this far (m) above "
            "the shelf's top at the end (negative: the contact's give; deeper, it has sunk "
            "into the board: a physics failure)"),
        "max_height": (
            "the foot's bottom at most this high (m) above the shelf's top at the end. Design. "
            f"Why an observer signs it: standing on the board it touches it (-0.07 mm "
            f"{_REPLAYED}); 1 cm up, the foot rests on something else"),
        "max_tray_shift": _knock_argument(
            "drying tray", f"{_REPLAYED} the tray moves at most 0.1 mm (settling)",
            "(shortcut, rush-wait) move it 6.8-11 cm", "2 cm is 8 % of the 25 x 13 cm tray; "
            "the nearest must-fail rollout moved it 1.03 cm (mirror), and fails because it "
            "hits the tray's wall"),
        "max_tray_tilt_deg": (
            "observer: the tray is not tipped. It may tilt at most this far (deg) at any step. "
            f"Design. Why an observer signs it: it stays level ({_REPLAYED} 0.0 deg); 10 deg "
            "lifts one side of its 13 cm base 2.3 cm off the stand"),
    }},
    "pan2stove": {"success": {
        "max_tilt_deg": (
            "observer: lying flat, bottom down. The pan's bottom at most this far (deg) from "
            "facing down at the end. Design. Why an observer signs it: flat on the stove it is "
            f"level (0.02 deg {_REPLAYED}); 15 deg lifts the far side of the 16 cm bottom "
            "4.1 cm: resting on its rim or handle, not flat; must-fail executions that let it "
            "go leave it 19-90 deg"),
        "min_height": (
            "observer: on the stove. The bottom's outer centre at least this far (m) above the "
            "stove's top at the end (negative: the contact's give; deeper, it has sunk in: a "
            "physics failure)"),
        "max_height": (
            "the bottom's outer centre at most this high (m) above the stove's top at the end. "
            f"Design. Why an observer signs it: flat on the stove it touches it (-0.07 mm "
            f"{_REPLAYED}); 1 cm up, the pan rests on something else"),
        "max_rack_shift": _knock_argument(
            "pan rack", "the demos drag the pan 9-26 cm along the rack's floor and move the "
            "rack at most 0.7 mm; 1 cm noise and start offsets rub the pan along a wall and "
            "nudge it up to 8.4 mm (0.1 deg): the one knock bound a good execution comes "
            "within 1.2 cm of", "(shortcut, rush-wait) move it 2.8-35 cm",
            "2 cm is 5 % of the 26 x 39 cm rack: a nudge, not a knock, up to it; the mirror "
            "rollouts that move it 1.3 cm fail by their collision"),
        "max_rack_tilt_deg": (
            "observer: the rack is not tipped. It may tilt at most this far (deg) at any step. "
            f"Design. Why an observer signs it: it stays level (0.1 deg at most {_REPLAYED}); "
            "10 deg lifts one side of its 26 cm base 4.5 cm off the table; executions that run "
            "into it tilt it up to 32 deg"),
    }},
    "obstaclerotate": {"success": {
        "max_tilt_deg": (
            "observer: lying on the shelf. The box's top face at most this far (deg) from "
            "level at the end. Design. Why an observer signs it: on the flat shelf it is level "
            f"(0.0 deg {_REPLAYED}); 15 deg lifts one end of the 20 cm box 5.2 cm: propped, "
            "not lying"),
        "min_height": (
            "observer: on the shelf. The box's lowest point at least this far (m) above the "
            "shelf's top at the end (negative: the contact's give; deeper, it has sunk in: a "
            "physics failure)"),
        "max_height": (
            "the box's lowest point at most this high (m) above the shelf's top at the end. "
            f"Design. Why an observer signs it: lying on the board it touches it (-0.07 mm "
            f"{_REPLAYED}); 1 cm up, the box rests on something else"),
    }},
}

def _task_model(task: str) -> tuple[mujoco.MjModel, mujoco.MjData]:
    model = mujoco.MjModel.from_xml_path(str(resource_path("tasks", f"{task}.xml")))
    return model, mujoco.MjData(model)


def _place(model: mujoco.MjModel, data: mujoco.MjData, body: str, pos: np.ndarray,
           quat: np.ndarray) -> None:
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
    adr = model.jnt_qposadr[model.body_jntadr[bid]]
    data.qpos[adr:adr + 3] = pos
    data.qpos[adr + 3:adr + 7] = quat
    mujoco.mj_kinematics(model, data)


def _held_prop_lows(task: str, body: str, positions: np.ndarray, quaternions: np.ndarray,
                    grasp: dict[str, Any], geom: str | None = None
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Lowest z [...] and centre of mass [..., 3] (with `geom`: that geom's centre) of a held
    prop at hand poses [..., 3|4] (held at `grasp["prop_pos"]`, `grasp["prop_quat"]` in the
    grasp-site frame)."""
    model, data = _task_model(task)
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
    gid = None if geom is None else mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, geom)
    shape = positions.shape[:-1]
    pos = positions.reshape(-1, 3)
    quat = quaternions.reshape(-1, 4)
    lows = np.empty(len(pos))
    coms = np.empty((len(pos), 3))
    sites = grasp_points(pos, quat)
    for i in range(len(pos)):
        p, q = prop_pose(sites[i], quat[i], grasp["prop_pos"], grasp["prop_quat"])
        _place(model, data, body, p, q)
        lows[i] = lowest_point(model, data, body)
        coms[i] = data.xipos[bid] if gid is None else data.geom_xpos[gid]
    return lows.reshape(shape), coms.reshape(shape + (3,))


def _path_clearance(task, doc: dict[str, Any], body: str, support_geoms: tuple[str, ...],
                    every: int = 3) -> np.ndarray:
    """[N] the smallest distance (m) between the held prop's geoms and `support_geoms` along
    each demo (every `every`-th sample), in the scene of the provisional spec `doc`."""
    env = RoboTaskEnv(doc["task"]["name"], spec=doc, limits=None)
    m, d = env.model, env.data
    bid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, body)
    mine = [g for g in range(m.ngeom) if m.geom_bodyid[g] == bid and m.geom_contype[g]]
    theirs = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, n) for n in support_geoms]
    grasp = doc["grasp"]
    out = np.full(len(task.positions), np.inf)
    fromto = np.zeros(6)
    for n in range(len(task.positions)):
        env.reset(options={"demo": n})
        g = grasp_points(task.positions[n], task.quaternions[n])
        for t in range(0, task.positions.shape[1], every):
            p, q = prop_pose(g[t], task.quaternions[n, t], grasp["prop_pos"], grasp["prop_quat"])
            _place(m, d, body, p, q)
            for a in mine:
                for b in theirs:
                    out[n] = min(out[n], mujoco.mj_geomDistance(m, d, a, b, 0.1, fromto))
    env.close()
    return out


def _lower_until_clear(task, doc: dict[str, Any], body: str, key: str,
                       support_geoms: tuple[str, ...], clearance: float
                       ) -> tuple[float, np.ndarray]:
    """Lowers the support top `doc["scene"][key]` (its z) until every demo's held prop stays
    `clearance` away from it along its whole path. Returns (top z, clearance per demo [N])."""
    for _ in range(4):
        gaps = _path_clearance(task, doc, body, support_geoms)
        deficit = clearance - float(gaps.min())
        if deficit <= 5e-4:
            break
        top = list(doc["scene"][key])
        top[2] -= deficit
        doc["scene"][key] = top
    return float(doc["scene"][key][2]), gaps


def start_configurations(positions: np.ndarray, quaternions: np.ndarray
                         ) -> tuple[np.ndarray, list[str], np.ndarray]:
    """Per-demo start configurations [N, 7], how each was found ("backward" or "home"), and
    the max kinematic forward-tracking position error [N] (m) from each."""
    model = robot_model()
    starts = backward_start_configs(model, positions, quaternions)
    methods, errors = [], np.empty(len(starts))
    for n in range(len(starts)):
        pe, re = tracking_errors(model, starts[n], positions[n], quaternions[n])
        method = "backward"
        if pe.max() > TRACK_TOL_POS or re.max() > TRACK_TOL_ROT:
            q, _, _ = solve_configuration(model, positions[n, 0], quaternions[n, 0])
            pe2, re2 = tracking_errors(model, q, positions[n], quaternions[n])
            if pe2.max() < pe.max():
                starts[n], pe, method = q, pe2, "home"
        methods.append(method)
        errors[n] = pe.max()
    return starts, methods, errors


def _camera(task, design) -> dict[str, Any]:
    """A camera looking at the middle of the demos' grasp points (design angles/distance)."""
    g = grasp_points(task.positions, task.quaternions).reshape(-1, 3)
    centre = (g.min(0) + g.max(0)) / 2
    return {"lookat": [float(v) for v in centre], **design["camera"]}


def _derive_openbox(task, design, starts) -> dict[str, Any]:
    g = grasp_points(task.positions, task.quaternions)
    fit = fit_hinge(g)
    ang = np.degrees(hinge_angles(g, fit))
    half = ang.shape[1] // 2
    radial, axial, turn = grip_slips(task.positions, task.quaternions, fit)
    m, mt = POSITION_MARGIN, TURN_MARGIN_DEG
    slip = [["handle_radial", float(radial.min() - m), float(radial.max() + m)],
            ["handle_axial", float(axial.min() - m), float(axial.max() + m)],
            ["handle_turn", 0.0, float(np.radians(np.degrees(turn.max()) + mt))]]
    # Open as far as another demo leaves the lid: the least of the demos' end angles, each less
    # what the 1.5 cm position margin turns the lid by at that demo's radius; never below the
    # angle any demo has reached at half time.
    margin_deg = np.degrees(POSITION_MARGIN / fit.radii)
    need = float(max((ang[:, -1] - margin_deg).min(), ang[:, half].max() + 1.0))
    return {
        "scene": {"hinge_pos": fit.point, "hinge_yaw_deg": float(np.degrees(fit.yaw))},
        "grasp": {"slip_joints": slip},
        "success": {"min_open_angle_deg": need},
        "derived": {
            "hinge_axis": fit.axis, "grasp_radii": fit.radii, "grasp_axial_offsets": fit.axial,
            "radial_residual_max": fit.radial_residual,
            "axial_residual_max": fit.axial_residual,
            "grasp_angle_start_deg": ang[:, 0], "grasp_angle_half_deg": ang[:, half],
            "grasp_angle_end_deg": ang[:, -1],
            "edge_radial_slip_range": [radial.min(1), radial.max(1)],
            "edge_axial_slip_range": [axial.min(1), axial.max(1)],
            "edge_turn_max_deg": np.degrees(turn.max(1)),
        },
        "comments": {
            "grasp": {"slip_joints": (
                "how far the lid's edge may move in the fingers from where it was grasped "
                "before it slips out: [joint, lower, upper] (m; handle_turn: rad, the angle the "
                "hand turns relative to the lid). Procedure: the demos' grasp points about the "
                "fitted hinge give the edge's radial and axial slide and the hand's turn "
                "relative to the lid at each sample (scene_fit.grip_slips; [derived] "
                "edge_*); bound = the demos' min / max, widened by 1.5 cm (turn: by 10 deg)")},
            "success": {"min_open_angle_deg": (
                "the lid angle the grasp must have opened the lid to while holding it: as far "
                "as another demo opens it. Procedure: each demo's final grasp angle ([derived] "
                "grasp_angle_end_deg) less the angle 1.5 cm of arc make at its grasp radius "
                "([derived] grasp_radii); the least of them over the demos, at least 1 deg "
                "more than any demo has reached at half time (grasp_angle_half_deg, max). A "
                "must-fail execution that opens the lid that far is within the demos' own "
                "spread: `clfd-bench replay` counts such a drift n/a "
                "(clfd_bench.execution.replay.within_demo_spread)")},
        },
    }


#: The least radius (m) around where demo j lets the prop go within which an execution may let
#: it go: the 1.5 cm position margin + 5 mm for the prop's swing while the gripper opens. The
#: radius itself is derived (`_place_bounds`): at least this, or as far as two demos' release
#: points lie apart.
PLACE_RADIUS = POSITION_MARGIN + 0.005


def _largest_gap(points: np.ndarray) -> float:
    """The largest distance between two of `points` [N, k]."""
    points = np.asarray(points, dtype=float)
    return float(np.linalg.norm(points[:, None] - points[None], axis=-1).max())


def _release_points(task, doc: dict[str, Any]) -> np.ndarray:
    """[N, 2] where each demo, replayed in the scene of the provisional spec `doc`, lets its
    prop go (the prop's centre (x, y) when the gripper opens; the scene's `release_point`)."""
    _, recs = _replay_demos(task, doc, records=True)
    missing = [j for j, r in enumerate(recs) if r.get("release_point") is None]
    if missing:
        raise RuntimeError(f"{doc['task']['name']}: demos {missing} never let the prop go when "
                           "replayed; the scene cannot derive its place radius (check the "
                           "scene's support and grasp)")
    return np.array([r["release_point"] for r in recs], dtype=float)


def _place_bounds(lows: np.ndarray, coms: np.ndarray, top: float,
                  released: np.ndarray) -> dict[str, Any]:
    """Release-height and place bounds from the held prop at the demos' end poses (lowest
    points [N], centres [N, 3]) and where the demos, replayed, let it go ([N, 2]:
    `_release_points`)."""
    drop = lows - top
    spread = _largest_gap(released)
    return {
        "success": {"max_release_height": float(drop.max() + POSITION_MARGIN),
                    "place_radius": float(max(PLACE_RADIUS, spread))},
        "place_centre": coms[:, :2],
        "derived": {"release_height_demos": drop, "release_point_demos": released,
                    "release_spread": spread},
        "comments": {
            "max_release_height": (
                "the prop's lowest point may be at most this high above the support's top when "
                "the gripper opens. Procedure: the held prop at each demo's last pose "
                "([derived] release_height_demos), max + 1.5 cm"),
            "place_radius": (
                "when the gripper opens, the prop must be within this horizontal distance (m) "
                "of where demo j lets it go ([scene] place_centre[j]): let go as far from demo "
                "j's point as another demo lets it go, and no further. Procedure: the demos "
                "replayed in this scene, where each lets the prop go ([derived] "
                "release_point_demos); the largest distance between two of them ([derived] "
                "release_spread), at least 2 cm (the 1.5 cm position margin + 5 mm for the "
                "prop's swing as the fingers open). A must-fail execution that lets go within "
                "it is within the demos' own spread: `clfd-bench replay` counts such a drift "
                "n/a (clfd_bench.execution.replay.within_demo_spread)"),
        },
    }


_PLACE_CENTRE_COMMENT = ("per demo j: where the prop's centre (x, y) is when demo j lets it go "
                         "(the held prop at demo j's last pose)")


def _table_below(task, name: str, body: str, grasp: dict[str, Any], fraction: float,
                 clearance: float) -> tuple[float, np.ndarray]:
    """The table height: `clearance` under the lowest point the held prop reaches in the first
    `fraction` of the demos (where it starts, near the table), at most 0 (the robot's base).
    Returns (table_z, lowest point per demo [N])."""
    n = int(task.positions.shape[1] * fraction)
    lows, _ = _held_prop_lows(name, body, task.positions[:, :n], task.quaternions[:, :n], grasp)
    return float(min(0.0, lows.min() - clearance)), lows.min(1)


_TABLE_COMMENT = (
    "the table top (m, robot base frame). Procedure: the lowest point the held prop reaches in "
    "the first fifth of the demos ([derived] start_lowest_z), less a clearance of 1.5 cm (a 1 cm "
    "start offset in any direction must not push the prop into the table; plate: + the rack's "
    "base), at most 0 (lower: the robot stands on a mount)")


def _derive_bottle(task, design, starts) -> dict[str, Any]:
    d = design["scene"]
    grasp = design["grasp"]
    table_z, start_lows = _table_below(task, "bottle2shelf", "bottle", grasp,
                                       d["table_fraction"], d["table_clearance"])
    lows, coms = _held_prop_lows("bottle2shelf", "bottle", task.positions[:, -1],
                                 task.quaternions[:, -1], grasp)
    centre = coms[:, :2].mean(0)
    scene = {"table_z": table_z,
             "shelf_top": [float(centre[0]), float(centre[1]), float(lows.min() - d["clearance"])],
             "shelf_half_size": d["shelf_half_size"], "shelf_yaw_deg": 0.0,
             "place_centre": coms[:, :2]}
    top, gaps = _lower_until_clear(task, _doc("bottle2shelf", design, scene, {}, starts),
                                   "bottle", "shelf_top", ("shelf_board", "shelf_support"),
                                   d["clearance"])
    released = _release_points(task, _doc("bottle2shelf", design, scene, {}, starts))
    place = _place_bounds(lows, coms, top, released)
    return {
        "scene": scene,
        "success": place["success"],
        "derived": {"start_lowest_z": start_lows, "bottle_end_lowest_z": lows,
                    "bottle_end_com": coms, "shelf_path_clearance": gaps, **place["derived"]},
        "comments": {"success": place["comments"], "scene": {
            "table_z": _TABLE_COMMENT,
            "shelf_top": "centre of the shelf's top: under the mean of the bottle's centres at "
                         "the demos' last poses, 1.5 cm under the lowest point the bottle "
                         "reaches there, and lower if needed until every demo's bottle stays "
                         "1.5 cm clear of the shelf on its way ([derived] "
                         "shelf_path_clearance)",
            "place_centre": _PLACE_CENTRE_COMMENT}},
    }


def _derive_plate(task, design, starts) -> dict[str, Any]:
    d = design["scene"]
    grasp = design["grasp"]
    n_rack = int(task.positions.shape[1] * d["rack_fraction"])
    # The plate stands 1.5 cm above the rack's base, the base on the table.
    table_z, rack_lows = _table_below(task, "platestandingtolying", "plate", grasp,
                                      d["rack_fraction"],
                                      d["table_clearance"] + d["rack_base_thickness"])
    n_place = int(task.positions.shape[1] * d["place_fraction"])
    lows_end, coms_end = _held_prop_lows("platestandingtolying", "plate",
                                         task.positions[:, -n_place:],
                                         task.quaternions[:, -n_place:], grasp)
    top = float(lows_end.min() - d["clearance"])
    centre = coms_end[:, -1, :2].mean(0)
    provisional = {"table_z": table_z, "block_offsets": [[0.0, 9.0]] * 4, "block_height": 0.02,
                   "platform_top": [float(centre[0]), float(centre[1]), top],
                   "platform_half_size": d["platform_half_size"], "platform_yaw_deg": 0.0,
                   "place_centre": coms_end[:, -1, :2]}
    top, gaps = _lower_until_clear(task, _doc("platestandingtolying", design, provisional, {},
                                              starts),
                                   "plate", "platform_top", ("platform_top", "platform_support"),
                                   d["clearance"])
    end_lows, coms_end, lows_end = lows_end[:, -1], coms_end[:, -1], lows_end.min(1)
    model, _ = _task_model("platestandingtolying")
    block_half = model.geom_size[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM,
                                                   "rack_peg1")]
    bx = d["block_x"]
    # The blocks reach `block_rise` up the plate from its lowest point at the start.
    block_height = float(rack_lows.max() + d["block_rise"] - table_z)
    extent = _rack_gap(task, grasp, table_z + block_height, n_rack, bx + block_half[0])
    by_lo = extent[0] - d["block_clearance"] - block_half[1]
    by_hi = extent[1] + d["block_clearance"] + block_half[1]
    offsets = [[-bx, by_lo], [bx, by_lo], [-bx, by_hi], [bx, by_hi]]
    scene = {"table_z": table_z, "block_offsets": offsets, "block_height": block_height,
             "rack_base_thickness": d["rack_base_thickness"],
             "platform_top": [float(centre[0]), float(centre[1]), top],
             "platform_half_size": d["platform_half_size"], "platform_yaw_deg": 0.0,
             "place_centre": coms_end[:, :2]}
    released = _release_points(task, _doc("platestandingtolying", design, scene, {}, starts))
    place = _place_bounds(end_lows, coms_end, top, released)
    return {
        "scene": scene,
        "success": place["success"],
        "derived": {"start_lowest_z": rack_lows, "plate_end_lowest_z": lows_end,
                    "plate_end_centre": coms_end, "platform_path_clearance": gaps,
                    "rack_plate_extent_y": extent,
                    **place["derived"]},
        "comments": {"scene": {
            "table_z": _TABLE_COMMENT,
            "block_height": "the rack's pegs reach 2.4 cm (design) up every demo's plate "
                            "from its lowest point at the start ([derived] start_lowest_z, "
                            "max): the demos lift the rim ~3 cm before they move it sideways",
            "block_offsets": "the rack's pegs (rack frame: x along the plate, y across it, "
                             "origin under the plate's start centre): 1.5 cm clear of where the "
                             "demos move the plate's rim below the blocks' top in their first "
                             "fifth ([derived] rack_plate_extent_y)",
            "platform_top": "under the mean of the plate's final centres, 1.5 cm under the "
                            "lowest point of the plate in the demos' last fifth, and lower if "
                            "needed until every demo's plate stays 1.5 cm clear of the "
                            "platform on its way ([derived] platform_path_clearance)",
            "place_centre": _PLACE_CENTRE_COMMENT},
            "success": place["comments"]},
    }


def _rack_gap(task, grasp: dict[str, Any], top: float, n_samples: int,
              x_half: float) -> np.ndarray:
    """[2] the extent (min, max) along the rack's y axis (the plate normal's horizontal
    direction, origin under the plate's start centre) of the plate's rim below the blocks' top
    and within `x_half` of the rack's middle, over the first `n_samples` of every demo: where
    the blocks must not be."""
    model, data = _task_model("platestandingtolying")
    disc = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "plate_disc")
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "plate")
    radius, half_t = model.geom_size[disc][:2]
    ang = np.linspace(0, 2 * np.pi, 72, endpoint=False)
    rim = np.concatenate([np.stack([radius * np.cos(ang), np.full_like(ang, side),
                                    radius * np.sin(ang)], axis=1) for side in (-half_t, half_t)])
    lo, hi = np.inf, -np.inf
    g = grasp_points(task.positions[:, :n_samples], task.quaternions[:, :n_samples])
    for n in range(len(g)):
        rack_origin, ex, ey = None, None, None
        for t in range(0, n_samples, 2):
            p, q = prop_pose(g[n, t], task.quaternions[n, t], grasp["prop_pos"],
                             grasp["prop_quat"])
            _place(model, data, "plate", p, q)
            rot = data.xmat[bid].reshape(3, 3)
            centre = data.geom_xpos[disc]
            if rack_origin is None:  # the rack is set up around the plate's start pose
                yaw = np.arctan2(rot[1, 0], rot[0, 0])
                ex = np.array([np.cos(yaw), np.sin(yaw), 0.0])
                ey = np.array([-np.sin(yaw), np.cos(yaw), 0.0])
                rack_origin = centre.copy()
            # rim points in plate-local coordinates are offsets from the disc centre
            pts = centre + rim @ rot.T
            near = pts[(pts[:, 2] <= top) & (np.abs((pts - rack_origin) @ ex) <= x_half)]
            if len(near):
                proj = (near - rack_origin) @ ey
                lo, hi = min(lo, proj.min()), max(hi, proj.max())
    return np.array([lo, hi])


def _derive_pouring(task, design, starts) -> dict[str, Any]:
    d = design["scene"]
    grasp = design["grasp"]
    lows, _ = _held_prop_lows("pouring", "cup", task.positions, task.quaternions, grasp)
    rim = float(lows.min() - d["rim_clearance"])
    scene = {"container_floor": [0.0, 0.0, 0.0], "container_half_size": 0.3,
             "container_height": 0.003, "container_yaw_deg": 0.0, "n_beans": d["n_beans"],
             "bean_radius": d["bean_radius"], "bean_mass": d["bean_mass"],
             "cup_inner_radius": d["cup_inner_radius"], "cup_floor": d["cup_floor"]}
    doc = _doc("pouring", design, scene, {"min_fraction": 0.0, "max_spilled_fraction": 1.0},
               starts)
    landing = _bean_landing(task, doc)
    ok = np.isfinite(landing[..., 0])
    centre = np.median(landing[ok][:, :2], axis=0)
    spread = np.abs(landing[ok][:, :2] - centre).max(1)
    half = float(np.quantile(spread, d["landing_quantile"]) + d["bean_radius"] + d["margin"])
    half = float(np.ceil(max(half, d["min_half_size"]) / 0.005) * 0.005)
    scene.update({"container_floor": [float(centre[0]), float(centre[1]), 0.0],
                  "container_half_size": half, "container_height": rim})
    # The demos poured into that container: where the beans come down through the rim's
    # height, how many end inside, how many land outside.
    doc = _doc("pouring", design, scene, {"min_fraction": 0.0, "max_spilled_fraction": 1.0},
               starts)
    infos, records = _replay_demos(task, doc, records=True)
    n = int(d["n_beans"])
    inside = np.array([round(i["bean_fraction"] * n) for i in infos])
    spilled = np.array([round(i["spilled_fraction"] * n) for i in infos])
    def poured_at(rec):
        return rec["pour_sum"] / max(rec["pour_count"], 1)

    pour = np.array([poured_at(r) for r in records])
    scene["pour_centre"] = pour
    # Replayed 2x slower and 1.5x faster (the same path): how much that moves it.
    jitter = []
    for factor in (2.0, 1.0 / 1.5):
        _, recs = _replay_demos(task, doc, records=True, time_scale=factor)
        jitter.append([float(np.linalg.norm(poured_at(r) - c))
                       for r, c in zip(recs, pour, strict=True)])
    jitter = np.asarray(jitter)
    pour_spread = _largest_gap(pour)
    radius = max(POSITION_MARGIN, d["jitter_factor"] * float(jitter.max()), pour_spread)
    return {
        "scene": scene,
        "success": {"min_fraction": float((inside.min() - 1) / n),
                    "max_spilled_fraction": float((spilled.max() + 1) / n),
                    "pour_radius": radius},
        "derived": {"cup_lowest_z": lows.min(1), "bean_landing_median": centre,
                    "bean_landing_spread_quantiles": np.quantile(spread, [0.5, 0.9, 0.95, 1.0]),
                    "beans_landed": ok.sum(1), "beans_inside_demos": inside,
                    "beans_spilled_demos": spilled, "pour_jitter_slower": jitter[0],
                    "pour_jitter_faster": jitter[1], "pour_spread": pour_spread},
        "comments": {
            "scene": {"container_floor": (
                "the container's centre on the table. Procedure: the demos replayed over a flat "
                "tray; the median of where each bean first comes within 3 cm of the table "
                "([derived] bean_landing_median)"),
                "container_half_size": (
                    "the 95 % quantile of the beans' landing distance from that centre "
                    "(Chebyshev) + a bean radius + 1 cm, at least 5 cm, rounded up to 5 mm"),
                "container_height": "its rim: 2 cm under the lowest point the cup reaches",
                "pour_centre": "per demo j: where the cup's mouth is (world, m), on average, "
                               "when demo j's beans leave the cup (the demos replayed into the "
                               "container)"},
            "success": {"min_fraction": (
                "fraction of the beans that must be in the container at the end. Procedure: "
                "the demos replayed into the container ([derived] beans_inside_demos): one "
                "bean fewer than the worst demo"),
                "max_spilled_fraction": (
                    "fraction of the beans that may ever land outside the container (on the "
                    "table, its rim, ...). Procedure: the demos replayed ([derived] "
                    "beans_spilled_demos): one bean more than the worst demo"),
                "pour_radius": (
                    "the cup must be emptied within this distance (m) of where demo j empties "
                    "it ([scene] pour_centre): as far from it as another demo empties the cup, "
                    "and no further. Procedure: the largest distance between two demos' pour "
                    "points ([derived] pour_spread); at least the 1.5 cm position margin and "
                    "1.3 x the largest shift the demos replayed 2x slower and 1.5x faster (same "
                    "path, the beans leave a little earlier or later) show ([derived] "
                    "pour_jitter_*). What an observer judges is the beans' counts below; this "
                    "bound only rejects a cup emptied farther from demo j's point than any demo "
                    "empties it. A must-fail execution within it is within the demos' own "
                    "spread: `clfd-bench replay` counts such a drift n/a "
                    "(clfd_bench.execution.replay.within_demo_spread)")},
        },
    }


def _surface_points(model: mujoco.MjModel, body: str, n: int = 24) -> np.ndarray:
    """[P, 3] points on the surface of `body`'s cylinder, capsule and box geoms (rings at the
    ends of cylinders and capsules, capsules' hemispheres in rings too; boxes' corners, edge
    midpoints and face centres), in the body's frame."""
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
    ang = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    ring = np.stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)], axis=1)
    out = []
    for g in np.flatnonzero(model.geom_bodyid == bid):
        r, h = model.geom_size[g][:2]
        kind = model.geom_type[g]
        if kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
            local = [r * ring + [0.0, 0.0, z] for z in (-h, h)]
        elif kind == mujoco.mjtGeom.mjGEOM_BOX:
            grid = np.stack(np.meshgrid(*[[-1.0, 0.0, 1.0]] * 3, indexing="ij"), -1)
            grid = grid.reshape(-1, 3)
            local = [grid[np.abs(grid).max(1) == 1.0] * model.geom_size[g]]
        elif kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
            local = []
            for phi in np.linspace(0.0, np.pi / 2, 5):
                for side in (-1.0, 1.0):
                    local.append(r * np.cos(phi) * ring
                                 + [0.0, 0.0, side * (h + r * np.sin(phi))])
        else:
            raise ValueError(f"_surface_points supports cylinders, capsules and boxes; {body!r} "
                             f"has geom type {mujoco.mjtGeom(kind).name}")
        rot = np.empty(9)
        mujoco.mju_quat2Mat(rot, model.geom_quat[g])
        out.append(np.concatenate(local) @ rot.reshape(3, 3).T + model.geom_pos[g])
    return np.concatenate(out)


def _tray_extent(task, name: str, body: str, axis: int, grasp: dict[str, Any], top: float,
                 n_samples: int) -> np.ndarray:
    """[4] the extent (x_lo, x_hi, y_lo, y_hi) in the tray frame (origin under the grasp point
    at the start, x along the held prop's axis `axis`, horizontal) of the surface of `body`
    (task `name`'s held prop) below `top` (world z) over the first `n_samples` of every demo:
    where the tray's walls must not be."""
    model, _ = _task_model(name)
    pos, quat = task.positions[:, :n_samples], task.quaternions[:, :n_samples]
    pts = _prop_points(pos, quat, grasp, _surface_points(model, body))
    g = grasp_points(pos, quat)
    lo, hi = np.full(2, np.inf), np.full(2, -np.inf)
    rot = np.empty(9)
    for n in range(len(g)):
        _, q = prop_pose(g[n, 0], quat[n, 0], grasp["prop_pos"], grasp["prop_quat"])
        mujoco.mju_quat2Mat(rot, q)
        yaw = np.arctan2(rot[3 + axis], rot[axis])  # the prop's axis at the start, seen from above
        ex = np.array([np.cos(yaw), np.sin(yaw), 0.0])
        ey = np.array([-np.sin(yaw), np.cos(yaw), 0.0])
        near = pts[n][pts[n][..., 2] <= top] - g[n, 0]
        if len(near):
            xy = np.stack([near @ ex, near @ ey], axis=1)
            lo, hi = np.minimum(lo, xy.min(0)), np.maximum(hi, xy.max(0))
    return np.array([lo[0], hi[0], lo[1], hi[1]])


def _tray_walls(task, name: str, body: str, axis: int, grasp: dict[str, Any],
                d: dict[str, Any], floor: Callable[[float], float]
                ) -> tuple[np.ndarray, float, float, np.ndarray, list[float]]:
    """The tray (or rack) a held prop is taken out of, from the first `d["tray_fraction"]` of
    the demos: the prop's lowest point per demo there [N]; what the tray stands on (`floor`
    of the height `d["tray_clearance"]` + the base under the lowest of them); the walls' height
    above the base (`d["tray_rise"]` up the prop from its highest lowest point); the prop's
    extent below the walls' top in the tray frame [4] (`_tray_extent`, the prop's axis `axis`)
    and the walls' inner faces, `d["tray_clearance"]` outside it."""
    n = int(task.positions.shape[1] * d["tray_fraction"])
    lows, _ = _held_prop_lows(name, body, task.positions[:, :n], task.quaternions[:, :n], grasp)
    lows = lows.min(1)
    base, c = float(d["tray_base_thickness"]), float(d["tray_clearance"])
    floor_z = floor(float(lows.min() - c - base))
    wall_height = float(lows.max() + d["tray_rise"] - (floor_z + base))
    extent = _tray_extent(task, name, body, axis, grasp, floor_z + base + wall_height, n)
    walls = [float(extent[0] - c), float(extent[1] + c), float(extent[2] - c),
             float(extent[3] + c)]
    return lows, floor_z, wall_height, extent, walls


def _derive_glass(task, design, starts) -> dict[str, Any]:
    d = design["scene"]
    grasp = design["grasp"]
    base = float(d["tray_base_thickness"])
    start_lows, stand_z, wall_height, extent, walls = _tray_walls(
        task, "wineglass", "glass", 0, grasp, d, lambda z: z)  # the tray on a stand
    # The stand: under every demo's tray (each lies under its own start grasp point, turned
    # with its glass), `stand_margin` beyond the farthest wall.
    g0 = grasp_points(task.positions[:, 0], task.quaternions[:, 0])
    axes = np.stack([_hand_x(q) for q in task.quaternions[:, 0]])
    yaws = np.arctan2(axes[:, 1], axes[:, 0])
    yaw = float(np.arctan2(np.sin(yaws).mean(), np.cos(yaws).mean()))
    centre = g0[:, :2].mean(0)
    corners = np.array([[x, y] for x in walls[:2] for y in walls[2:]])
    ex, ey = np.array([np.cos(yaw), np.sin(yaw)]), np.array([-np.sin(yaw), np.cos(yaw)])
    reach = []
    for n in range(len(g0)):
        e1 = np.array([np.cos(yaws[n]), np.sin(yaws[n])])
        e2 = np.array([-np.sin(yaws[n]), np.cos(yaws[n])])
        world = g0[n, :2] + corners[:, :1] * e1 + corners[:, 1:] * e2 - centre
        reach.append(np.stack([world @ ex, world @ ey], axis=1))
    reach = np.concatenate(reach)
    margin = float(d["tray_wall_thickness"] + d["stand_margin"])
    lo, hi = reach.min(0) - margin, reach.max(0) + margin
    mid = centre + (lo[0] + hi[0]) / 2 * ex + (lo[1] + hi[1]) / 2 * ey
    # The shelf: under the feet at the demos' last poses, like the bottle's.
    lows, feet = _held_prop_lows("wineglass", "glass", task.positions[:, -1],
                                 task.quaternions[:, -1], grasp, geom="glass_foot")
    fcentre = feet[:, :2].mean(0)
    scene = {"table_z": 0.0,
             "stand_top": [float(mid[0]), float(mid[1]), stand_z],
             "stand_half_size": [float(hi[0] - lo[0]) / 2, float(hi[1] - lo[1]) / 2],
             "stand_yaw_deg": float(np.degrees(yaw)),
             "tray_walls": walls, "tray_wall_height": wall_height,
             "tray_base_thickness": base, "tray_wall_thickness": d["tray_wall_thickness"],
             "shelf_top": [float(fcentre[0]), float(fcentre[1]),
                           float(lows.min() - d["clearance"])],
             "shelf_half_size": d["shelf_half_size"], "shelf_yaw_deg": 0.0,
             "place_centre": feet[:, :2]}
    top, gaps = _lower_until_clear(task, _doc("wineglass", design, scene, {}, starts), "glass",
                                   "shelf_top", ("shelf_board", "shelf_support"),
                                   d["clearance"])
    released = _release_points(task, _doc("wineglass", design, scene, {}, starts))
    place = _place_bounds(lows, feet, top, released)
    return {
        "scene": scene,
        "success": place["success"],
        "derived": {"start_lowest_z": start_lows, "glass_end_lowest_z": lows,
                    "glass_end_foot_centre": feet, "shelf_path_clearance": gaps,
                    "tray_glass_extent": extent, **place["derived"]},
        "comments": {"scene": {
            "table_z": "the table top: at the robot's base (0); the glass lies and ends higher, "
                       "on the stand and the shelf",
            "stand_top": "the top of the stand the tray lies on: the tray's base 1.5 cm under "
                         "the lowest point the glass reaches in the first fifth of the demos "
                         "([derived] start_lowest_z, min); centred under the demos' trays",
            "stand_half_size": "the stand reaches 2 cm (design) beyond every demo's tray "
                               "(each under its own start grasp point, turned with its glass)",
            "tray_walls": "the inner faces of the tray's walls (tray frame: origin on the "
                          "stand under the glass's grasp point at the start, x along the "
                          "glass's axis; x_lo, x_hi, y_lo, y_hi): 1.5 cm clear of where the "
                          "demos move the glass below the walls' top in their first fifth "
                          "([derived] tray_glass_extent)",
            "tray_wall_height": "the walls' top above the tray's base: 2.4 cm (design) up "
                                "every demo's glass from its lowest point at the start (the "
                                "demos lift the glass ~2 cm before they move it sideways)",
            "shelf_top": "centre of the shelf's top: under the mean of the glass's foot at the "
                         "demos' last poses, 1.5 cm under the lowest point the glass reaches "
                         "there, and lower if needed until every demo's glass stays 1.5 cm "
                         "clear of the shelf on its way ([derived] shelf_path_clearance)",
            "place_centre": "per demo j: where the glass's foot centre (x, y) is when demo j "
                            "lets it go (the held glass at demo j's last pose)"},
            "success": place["comments"]},
    }


def _derive_pan(task, design, starts) -> dict[str, Any]:
    d = design["scene"]
    grasp = design["grasp"]
    base = float(d["tray_base_thickness"])
    # the rack on the table, at most at the robot's base (lower: the robot on a mount)
    start_lows, table_z, wall_height, extent, walls = _tray_walls(
        task, "pan2stove", "pan", 1, grasp, d, lambda z: min(0.0, z))
    lows, bottoms = _held_prop_lows("pan2stove", "pan", task.positions[:, -1],
                                    task.quaternions[:, -1], grasp, geom="pan_bottom")
    centre = bottoms[:, :2].mean(0)
    scene = {"table_z": table_z, "tray_walls": walls, "tray_wall_height": wall_height,
             "tray_base_thickness": base, "tray_wall_thickness": d["tray_wall_thickness"],
             "stove_top": [float(centre[0]), float(centre[1]),
                           float(lows.min() - d["clearance"])],
             "stove_half_size": d["stove_half_size"], "stove_yaw_deg": 0.0,
             "place_centre": bottoms[:, :2]}
    top, gaps = _lower_until_clear(task, _doc("pan2stove", design, scene, {}, starts), "pan",
                                   "stove_top", ("stove_top", "stove_support"), d["clearance"])
    released = _release_points(task, _doc("pan2stove", design, scene, {}, starts))
    place = _place_bounds(lows, bottoms, top, released)
    return {
        "scene": scene,
        "success": place["success"],
        "derived": {"start_lowest_z": start_lows, "pan_end_lowest_z": lows,
                    "pan_end_bottom_centre": bottoms, "stove_path_clearance": gaps,
                    "rack_pan_extent": extent, **place["derived"]},
        "comments": {"scene": {
            "table_z": _TABLE_COMMENT,
            "tray_walls": "the inner faces of the pan rack's walls (rack frame: origin on the "
                          "table under the grasp point at the start, x along the pan's y axis, "
                          "horizontal in its plane; x_lo, x_hi, y_lo, y_hi): 1.5 cm clear of "
                          "where the demos move the pan below the walls' top in their first "
                          "fifth ([derived] rack_pan_extent)",
            "tray_wall_height": "the walls' top above the rack's base: 2.4 cm (design) up "
                                "every demo's pan from its lowest point at the start",
            "stove_top": "centre of the stove's top: under the mean of the pan's bottom centre "
                         "at the demos' last poses, 1.5 cm under the lowest point the pan "
                         "reaches there, and lower if needed until every demo's pan stays "
                         "1.5 cm clear of the stove on its way ([derived] "
                         "stove_path_clearance)",
            "place_centre": "per demo j: where the pan's bottom centre (x, y) is when demo j "
                            "lets it go (the held pan at demo j's last pose)"},
            "success": place["comments"]},
    }


def _ghost_clearance(task, doc: dict[str, Any], geoms: tuple[str, ...], every: int = 3
                     ) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Each demo replayed (no motion-limit checks) in the scene of `doc` with its geoms `geoms`
    made ghosts (no contacts): the smallest distance (m, negative: into it) between any of them
    and the held prop or any robot geom [N], the point of the ghost's surface where it is
    smallest [N, 3], and which ghost that is [N]."""
    env = RoboTaskEnv(doc["task"]["name"], spec=doc, limits=None)
    m, d = env.model, env.data
    ghosts = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, g) for g in geoms]
    for g in ghosts:  # the demos follow their own paths; the distance says how far in they go
        m.geom_contype[g] = m.geom_conaffinity[g] = 0
    robot = {mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, n) for n in ROBOT_BODIES}
    prop = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, doc["grasp"]["body"])
    solid = [g for g in range(m.ngeom) if m.geom_contype[g] or m.geom_conaffinity[g]]
    movers = [g for g in solid if m.geom_bodyid[g] in robot or m.geom_bodyid[g] == prop]
    n = len(task.positions)
    gaps, where, which = np.full(n, np.inf), np.zeros((n, 3)), [geoms[0]] * n
    fromto = np.zeros(6)
    for j in range(n):
        actions = _demo_actions(env, task, j, settle_steps=0)
        env.reset(options={"demo": j, "horizon": len(actions)})
        for k, a in enumerate(actions):
            env.step(a)
            if k % every:
                continue
            for ghost, name in zip(ghosts, geoms, strict=True):
                for g in movers:
                    dist = mujoco.mj_geomDistance(m, d, ghost, g, 0.1, fromto)
                    if dist < gaps[j]:
                        gaps[j], where[j], which[j] = dist, fromto[:3], name
    env.close()
    return gaps, where, which


def _derive_obstacle(task, design, starts) -> dict[str, Any]:
    d = design["scene"]
    grasp = design["grasp"]
    turns = np.array([_turn_deg(q) for q in task.quaternions])  # [N, T] about world z
    peak = turns[np.arange(len(turns)), np.abs(turns).argmax(1)]
    sign = float(np.sign(np.median(peak)))
    turn = {"turn_sign": sign, "min_turn_deg": float(np.min(sign * peak) - TURN_MARGIN_DEG),
            "max_end_turn_deg": float(np.abs(turns[:, -1]).max() + TURN_MARGIN_DEG)}
    table_z, start_lows = _table_below(task, "obstaclerotate", "object", grasp,
                                       d["table_fraction"], d["table_clearance"])
    lows, coms = _held_prop_lows("obstaclerotate", "object", task.positions[:, -1],
                                 task.quaternions[:, -1], grasp)
    centre = coms[:, :2].mean(0)
    scene = {"table_z": table_z,
             "obstacle_xy": list(d["obstacle_xy"]), "obstacle_top": float(d["obstacle_top"]),
             "shelf_top": [float(centre[0]), float(centre[1]), float(lows.min() - d["clearance"])],
             "shelf_half_size": d["shelf_half_size"], "shelf_yaw_deg": 0.0,
             "place_centre": coms[:, :2]}
    top, shelf_gaps = _lower_until_clear(task, _doc("obstaclerotate", design, scene, turn,
                                                    starts),
                                         "object", "shelf_top",
                                         ("shelf_board", "shelf_support"), d["clearance"])
    # The obstacle: shrunk (the face nearest to where the demos come closest moved in) until
    # every demo keeps the box and the arm `clearance` away from it.
    c = float(d["clearance"])
    for _ in range(12):
        gaps, where, _ = _ghost_clearance(task, _doc("obstaclerotate", design, scene, {
            **turn, "max_release_height": 1.0, "place_radius": 1.0}, starts), ("obstacle_box",))
        j = int(np.argmin(gaps))
        deficit = c - float(gaps[j])
        if deficit <= 5e-4:
            break
        x0, x1, y0, y1 = scene["obstacle_xy"]
        p = where[j]
        faces = {"x0": abs(p[0] - x0), "x1": abs(p[0] - x1), "y0": abs(p[1] - y0),
                 "y1": abs(p[1] - y1), "top": abs(p[2] - scene["obstacle_top"])}
        # a witness on the top's edge counts as the top: something passes over the obstacle
        face = "top" if faces["top"] < 1e-3 else min(faces, key=faces.get)
        step = deficit + 1e-3
        if face == "top":
            scene["obstacle_top"] = float(scene["obstacle_top"] - step)
        else:
            box = dict(zip(("x0", "x1", "y0", "y1"), (x0, x1, y0, y1), strict=True))
            box[face] += step if face in ("x0", "y0") else -step
            scene["obstacle_xy"] = [float(box[k]) for k in ("x0", "x1", "y0", "y1")]
    else:
        raise RuntimeError("obstaclerotate: the obstacle did not clear the demos in 12 steps")
    released = _release_points(task, _doc("obstaclerotate", design, scene, turn, starts))
    place = _place_bounds(lows, coms, top, released)
    return {
        "scene": scene,
        "success": {**place["success"], **turn},
        "derived": {"demo_peak_turn_deg": peak, "demo_end_turn_deg": turns[:, -1],
                    "start_lowest_z": start_lows, "object_end_lowest_z": lows,
                    "object_end_com": coms, "shelf_path_clearance": shelf_gaps,
                    "obstacle_clearance": gaps, **place["derived"]},
        "comments": {"scene": {
            "table_z": _TABLE_COMMENT,
            "obstacle_xy": "the obstacle's footprint (x0, x1, y0, y1). Procedure: the largest "
                           "box inside the demos' bend that no grasp point comes within 6.5 cm "
                           "of, x [0.20, 0.43] x y [-0.24, 0.00] (docs/design/robotasks9, "
                           "derive_sketch.py), its faces then moved in where a demo's box or "
                           "arm came within 1.5 cm of it ([derived] obstacle_clearance)",
            "obstacle_top": "the obstacle's top: 0.30 m (design: the demos' paths go around "
                            "the footprint, never over it, up to that height), lowered where a "
                            "demo's arm passes over it closer than 1.5 cm",
            "shelf_top": "centre of the shelf's top: under the mean of the box's centres at "
                         "the demos' last poses, 1.5 cm under the lowest point the box "
                         "reaches there, and lower if needed until every demo's box stays "
                         "1.5 cm clear of the shelf on its way ([derived] "
                         "shelf_path_clearance)",
            "place_centre": _PLACE_CENTRE_COMMENT},
            "success": {**place["comments"],
                        "turn_sign": "the direction the demos turn the box about the world's "
                                     "z axis (-1: clockwise seen from above): the sign of the "
                                     "demos' largest turns ([derived] demo_peak_turn_deg)",
                        "min_turn_deg": "while held, the box must have turned at least this "
                                        "far in that direction (its long axis' heading seen "
                                        "from above). Procedure: the demos' smallest largest "
                                        "turn less 10 deg",
                        "max_end_turn_deg": "when let go, the box's heading must be back "
                                            "within this of its start heading. Procedure: the "
                                            "demos' largest end turn ([derived] "
                                            "demo_end_turn_deg) + 10 deg"}},
    }


def _prop_points(positions: np.ndarray, quaternions: np.ndarray, grasp: dict[str, Any],
                 local: np.ndarray, every: int = 1) -> np.ndarray:
    """[N, T', P, 3] the held prop's points `local` [P, 3] (prop frame) in the world at the hand
    poses [N, T, 3|4] (every `every`-th sample), the prop held at `grasp["prop_pos"]`,
    `grasp["prop_quat"]` in the grasp-site frame."""
    g = grasp_points(positions, quaternions)
    steps = range(0, g.shape[1], every)
    out = np.empty((len(g), len(steps), len(local), 3))
    rot = np.empty(9)
    for n in range(len(g)):
        for i, t in enumerate(steps):
            p, q = prop_pose(g[n, t], quaternions[n, t], grasp["prop_pos"], grasp["prop_quat"])
            mujoco.mju_quat2Mat(rot, q)
            out[n, i] = p + local @ rot.reshape(3, 3).T
    return out


def _extent_below(name: str, body: str, positions: np.ndarray, quaternions: np.ndarray,
                  grasp: dict[str, Any], top: float, every: int = 2) -> np.ndarray:
    """[4] the world extent (x_lo, x_hi, y_lo, y_hi) of the surface of `body` (task `name`'s
    held prop) below `top` (world z) at the hand poses [N, T, 3|4] (every `every`-th sample);
    NaN where nothing is below."""
    model, _ = _task_model(name)
    pts = _prop_points(positions, quaternions, grasp, _surface_points(model, body), every)
    near = pts[pts[..., 2] <= top]
    if not len(near):
        return np.full(4, np.nan)
    lo, hi = near[:, :2].min(0), near[:, :2].max(0)
    return np.array([lo[0], hi[0], lo[1], hi[1]])


_BIN_GEOMS = ("bin_floor", "bin_wall_back", "bin_wall_front", "bin_wall_right", "bin_wall_left")


def _derive_scoop(task, design, starts) -> dict[str, Any]:
    d = design["scene"]
    grasp = design["grasp"]
    c = float(d["clearance"])
    lows, _ = _held_prop_lows("scoop", "scoop", task.positions, task.quaternions, grasp)
    dips = lows.min(1)  # the scoop's lowest point per demo
    # the bowl's lip (the edge of its opening) at its lowest per demo: beans flow in over it
    lo, hi = np.asarray(d["bowl_cavity"], dtype=float)
    lip = np.array([[x, y, lo[2]] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])])
    lips = _prop_points(task.positions, task.quaternions, grasp, lip)[..., 2].min((1, 2))
    surface = float(lips.max() + d["dip"])
    rim = surface + float(d["rim_above"])
    floor = float(dips.min() - c)
    ext = _extent_below("scoop", "scoop", task.positions, task.quaternions, grasp, rim)
    walls = [float(ext[0] - c), float(ext[1] + c), float(ext[2] - c), float(ext[3] + c)]
    scene = {"bin_walls": walls, "bin_floor_z": floor, "bin_rim_z": rim, "surface_z": surface,
             **{k: d[k] for k in ("n_beans", "bean_radius", "bean_mass", "grain_spacing",
                                  "bowl_cavity",
                                  "bowl_outer", "bin_wall_thickness")}}
    loose = {"min_beans": 0, "max_spilled": 10 ** 6, "max_tilt_deg": 180.0}
    # The bin's walls and floor moved out until every demo's scoop and arm stay `clearance`
    # away from them (replayed, the bin a ghost): the hand may come down lower than the scoop.
    for _ in range(12):
        gaps, where, which = _ghost_clearance(task, _doc("scoop", design, scene, loose, starts),
                                              _BIN_GEOMS)
        j = int(np.argmin(gaps))
        deficit = c - float(gaps[j])
        if deficit <= 5e-4:
            break
        step = deficit + 1e-3
        if which[j] == "bin_floor":
            scene["bin_floor_z"] = float(scene["bin_floor_z"] - step)
        else:  # against a wall, or over its top: that wall goes out
            k = _BIN_GEOMS.index(which[j]) - 1
            scene["bin_walls"][k] += -step if k in (0, 2) else step
    else:
        raise RuntimeError("scoop: the bin did not clear the demos in 12 steps")
    doc = _doc("scoop", design, scene, loose, starts)
    infos = _replay_demos(task, doc)
    beans = np.array([i["beans_in_scoop"] for i in infos])
    spilled = np.array([i["beans_spilled"] for i in infos])
    scooped = np.array([i["beans_scooped"] for i in infos])
    # Replayed 2x slower and 1.5x faster (the same path): how much that changes the scoopful.
    timed = [_replay_demos(task, doc, time_scale=f) for f in (2.0, 1.0 / 1.5)]
    timed_beans = np.array([[i["beans_in_scoop"] for i in infos_f] for infos_f in timed])
    tilts = np.array([i["bowl_tilt_deg"] for i in infos])
    return {
        "scene": scene,
        "success": {"min_beans": int(max(1, min(beans.min(), timed_beans.min()) - 1)),
                    "max_spilled": int(spilled.max() + 1),
                    "max_tilt_deg": float(tilts.max() + TURN_MARGIN_DEG)},
        "derived": {"scoop_lowest_z": dips, "lip_lowest_z": lips, "bin_clearance": gaps,
                    "beans_scooped_demos": scooped, "beans_in_scoop_demos": beans,
                    "beans_spilled_demos": spilled, "beans_in_scoop_slower": timed_beans[0],
                    "beans_in_scoop_faster": timed_beans[1], "end_bowl_tilt_deg": tilts},
        "comments": {
            "scene": {
                "bin_walls": "the bin's inner faces (x0, x1, y0, y1). Procedure: the extent of "
                             "the scoop's surface below the rim over the demos, 1.5 cm out, then "
                             "moved out where a demo's scoop or arm came within 1.5 cm of a wall "
                             "(the demos replayed with the bin a ghost; [derived] "
                             "bin_clearance)",
                "bin_floor_z": "the bin's inner floor: 1.5 cm under the lowest point the scoop "
                               "reaches in the demos ([derived] scoop_lowest_z)",
                "surface_z": "the level of the beans: `dip` (design, 3.5 cm) over the highest of "
                             "the demos' lowest lip points (the edge of the bowl's opening; "
                             "[derived] lip_lowest_z), so that in every demo the beans flow "
                             "into the bowl over its lip",

                "n_beans": "design: the pool of beans the scoop can hold at once (free "
                           "spheres; the bin's contents are grain sites, see "
                           "clfd_bench.envs.robotask_scenes.ScoopScene)"},
            "success": {
                "min_beans": "beans that must be in the scoop at the end (after 1 s holding "
                             "still). Procedure: the demos replayed as they are, 2x slower and "
                             "1.5x faster ([derived] beans_in_scoop_*): one fewer than the "
                             "fewest, at least 1",
                "max_spilled": "beans that may land outside the bin (table, stand, rim). "
                               "Procedure: the demos replayed ([derived] beans_spilled_demos): "
                               "one more than the worst demo",
                "max_tilt_deg": "at the end the bowl's opening must face up within this "
                                "(deg). Procedure: the demos replayed ([derived] "
                                "end_bowl_tilt_deg): the largest + 10 deg. Where the scoop "
                                "ends is not judged: nothing in the scene marks demo j's end "
                                "(no container)"},
        },
    }


def _turn_deg(quaternions: np.ndarray) -> np.ndarray:
    """[T] how far the hand's x axis has turned about the world's z axis since the first of
    the hand quaternions [T, 4] (its heading seen from above, unwrapped), degrees."""
    heading = np.array([_hand_x(q)[:2] for q in quaternions])
    angle = np.unwrap(np.arctan2(heading[:, 1], heading[:, 0]))
    return np.degrees(angle - angle[0])


def _mat_replays(task, doc: dict[str, Any], time_scale: float = 1.0) -> dict[str, np.ndarray]:
    """Each demo replayed (+ 1 s settling, no motion-limit checks) in the scene of `doc`, its
    duration scaled by `time_scale` (as `_replay_demos`), [N] or [N, 3] per quantity:
    `turn`, the largest turn of the pinched edge between the pads while held (rad);
    `release_edge`, where the near edge's middle is in the world when the gripper lets it go
    (NaN: never let go); after the settling `turned`, the strips turned over onto the far half
    (`MatScene.turned_strips`), `root_shift`, the far plate's largest shift on the table (m)
    and `success`."""
    env = RoboTaskEnv("matfolding", spec=doc, limits=None)
    n = len(task.positions)
    out = {"turn": np.zeros(n), "release_edge": np.full((n, 3), np.nan),
           "turned": np.zeros(n, dtype=int), "root_shift": np.zeros(n),
           "success": np.zeros(n, dtype=bool)}
    for j in range(n):
        actions = _demo_actions(env, task, j, time_scale=time_scale)
        env.reset(options={"demo": j, "horizon": len(actions)})
        for a in actions:
            env.step(a)
            if env.grasp.held(env.data):
                out["turn"][j] = max(out["turn"][j],
                                     env.grasp.slips(env.data).get("pinch_turn", 0.0))
        rec, scene = env.scene.record, env.scene
        if rec["release_edge"] is not None:
            out["release_edge"][j] = rec["release_edge"]
        out["turned"][j] = scene.turned_strips(env.data)
        info = env.evaluate()
        out["root_shift"][j] = info["max_root_shift"]
        out["success"][j] = info["is_success"]
    env.close()
    return out


def _derive_mat(task, design, starts) -> dict[str, Any]:
    d = design["scene"]
    grasp = dict(design["grasp"])
    g0 = grasp_points(task.positions[:, 0], task.quaternions[:, 0])
    table_z = float(min(0.0, g0[:, 2].min() - d["table_clearance"]))
    n = len(task.positions)
    scene = {"table_z": table_z, "table_xy": d["table_xy"], "release_edge": np.zeros((n, 3))}
    # nothing judged while deriving
    lenient = {"place_radius": 1.0, "min_turned_strips": 0, "max_drag": 10.0}
    # the pinch's turn with no bound
    free = {**grasp, "slip_joints": [["pinch_turn", 0.0, float(np.pi)]]}
    provisional = {"task": {"name": "matfolding", **design["task"]}, "grasp": free,
                   "scene": scene, "success": {**design["success"], **lenient},
                   "start": {"qpos": starts}}
    # lower the table until the hand clears it by 1.5 cm in every demo (the hand is tilted
    # 35-60 deg at the end: it comes lower than the fingertips)
    hand_gaps, _, _ = _ghost_clearance(task, provisional, ("floor",))
    deficit = float(d["table_clearance"] - hand_gaps.min())
    if deficit > 0:
        scene["table_z"] = table_z = table_z - deficit
    free_runs = _mat_replays(task, provisional)
    bound = float(np.radians(np.degrees(free_runs["turn"].max()) + TURN_MARGIN_DEG))
    slip = {"slip_joints": [["pinch_turn", 0.0, bound]]}
    # where each demo lets the edge go and how it leaves the mat, in the scene with that bound;
    # and how much replaying the same paths 2x slower and 1.5x faster moves it
    doc = {**provisional, "grasp": {**grasp, **slip}}
    runs = _mat_replays(task, doc)
    if not np.isfinite(runs["release_edge"]).all():
        raise RuntimeError("matfolding: a demo replay never let the mat go")
    timed = [_mat_replays(task, doc, time_scale=f) for f in (2.0, 1.0 / 1.5)]
    jitter = [np.linalg.norm(r["release_edge"] - runs["release_edge"], axis=1) for r in timed]
    if not all(np.isfinite(v).all() for v in jitter):
        raise RuntimeError("matfolding: a slower / faster demo replay never let the mat go")
    k = float(d["jitter_factor"])
    scene["release_edge"] = runs["release_edge"]
    drags = runs["root_shift"]
    success = {
        "place_radius": max(POSITION_MARGIN, k * float(np.max(jitter))),
        "min_turned_strips": int(min(r.min() for r in [runs["turned"]] + [t["turned"]
                                                                          for t in timed]) - 1),
        # the demos' largest drag + the demos' own spread of drag (largest - smallest)
        "max_drag": float(2.0 * drags.max() - drags.min())}
    return {
        "scene": scene,
        "grasp": slip,
        "success": success,
        "derived": {"start_grasp_z": g0[:, 2], "hand_table_gap": hand_gaps,
                    "pinch_turn_max_deg": np.degrees(free_runs["turn"]),
                    "root_shift_max": drags,
                    "root_shift_max_slower": timed[0]["root_shift"],
                    "root_shift_max_faster": timed[1]["root_shift"],
                    "turned_strips": runs["turned"],
                    "turned_strips_slower": timed[0]["turned"],
                    "turned_strips_faster": timed[1]["turned"],
                    "release_edge_jitter_slower": jitter[0],
                    "release_edge_jitter_faster": jitter[1]},
        "comments": {
            "scene": {
                "table_z": "the table top: the lowest grasp point at the demos' starts "
                           "([derived] start_grasp_z) less 1.5 cm, lowered until the hand "
                           "clears it by 1.5 cm in every demo ([derived] hand_table_gap, at "
                           "the table before lowering); the mat lies on it and its last strips "
                           "ramp up to each demo's start grasp",
                "release_edge": "per demo j: where the middle of the mat's near edge is in the "
                                "world when the gripper lets it go in demo j's replay (where "
                                "the trajectory ends: it does not depend on how far the mat "
                                "was dragged)"},
            "grasp": {"slip_joints": (
                "how far the pinched edge may turn between the pads (the ball joint "
                "pinch_turn's angle since the grasp, rad) before it slips out. Procedure: the "
                "demos replayed with no bound ([derived] pinch_turn_max_deg), max + 10 deg")},
            "success": {
                "place_radius": (
                    "when the gripper opens, the near edge's middle must be within this "
                    "distance (3-D, world) of where demo j lets it go ([scene] release_edge). "
                    "Procedure: the 1.5 cm position margin (1 cm of noise and start offset an "
                    "execution must survive + 5 mm of servo lag and IK error), or 1.3 x the "
                    "largest shift the demos replayed 2x slower and 1.5x faster show "
                    "([derived] release_edge_jitter_*) if that is larger"),
                "min_turned_strips": (
                    "after the settling, at least this many strips of the near half must lie "
                    "turned over on the far half, in one layer (upside down within 25 deg, "
                    "over the far plate, at most max_layer_height above it): the mat folded in "
                    "half. Procedure: the fewest in the demos' replays, 2x slower and 1.5x "
                    "faster ([derived] turned_strips*), less one (in some demos the last "
                    "strips fold back at the near edge: the edge strip flips back when the "
                    "hand, tilted 35-60 deg back, lets it go 5-8 cm above the mat)"),
                "max_drag": (
                    "the far half's largest shift on the table over the episode (m) must be at "
                    "most this. Procedure: the largest in the demos' replays ([derived] "
                    "root_shift_max) + a margin of the demos' own spread (their largest less "
                    "their smallest). Argument for the margin: a mat lifted by one edge slides "
                    "towards the hand, and how far depends on the path (the strip chain "
                    "exaggerates it: 8-14 cm on the demos' paths where a flexcomp cloth "
                    "slides 1-3 cm; raising the demo's arc 5 cm mid-way drags the chain up to "
                    "6 cm further), so a valid path may drag it as much further as the demos' own "
                    "paths differ among themselves; more is a mat pulled across the table"),
                "max_layer_height": (
                    "observer: lying, not in the air. The far plate's middle plane at most "
                    "this high (m) above the table, a turned-over strip's hinge at most this "
                    "high above the far plate's. Design. Why an observer signs it: the mat is "
                    "3 mm thick, so a strip folded onto the far half lies 3 mm up and one "
                    "folded over another 6 mm; in every must-succeed replay (demo, 2x slower, "
                    "1.5x faster, noise, start offset; 45 rollouts, 2026-12-06) each counted "
                    "strip lies at most 6.0 mm up and the far plate at most 3.5 mm, while the "
                    "upside-down strips a stop-early leaves over the far half arch 1.1-2.0 cm "
                    "above it: in the air, not folded onto it")}},
    }


def _hand_x(quat: np.ndarray) -> np.ndarray:
    """[3] the hand's x axis in the world for a hand quaternion [4] (w, x, y, z)."""
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, np.asarray(quat, dtype=float) / np.linalg.norm(quat))
    return rot.reshape(3, 3)[:, 0]


def _doc(task_name: str, design: dict[str, Any], scene: dict[str, Any],
         success: dict[str, Any], starts: np.ndarray) -> dict[str, Any]:
    """A provisional spec (for replaying the demos while deriving)."""
    doc = {"task": {"name": task_name, **design["task"]}, "grasp": dict(design["grasp"]),
           "scene": scene, "success": {**design["success"], **success},
           "start": {"qpos": starts}}
    if "solver" in design:
        doc["solver"] = dict(design["solver"])
    return doc


def _demo_actions(env: RoboTaskEnv, task, j: int, settle_steps: int = 60,
                  time_scale: float = 1.0) -> np.ndarray:
    """Demo j's actions [T, 8] (its duration scaled by `time_scale`: positions interpolated,
    orientations slerped), then `settle_steps` of `env.settle_actions`."""
    from clfd_bench.data.resample import resample

    traj = np.concatenate([task.positions[j], task.quaternions[j]], axis=1)
    if time_scale != 1.0:
        traj = resample(traj, int(round((len(traj) - 1) * time_scale)) + 1)
    actions = env.trajectory_to_actions(traj)
    return np.concatenate([actions, env.settle_actions(actions[-1], settle_steps)])


def _bean_landing(task, doc: dict[str, Any]) -> np.ndarray:
    """[N, n_beans, 3] where each bean first comes within 3 cm of the table when the demos are
    replayed (NaN: never)."""
    env = RoboTaskEnv("pouring", spec=doc, limits=None)
    n = len(task.positions)
    landing = np.full((n, env.scene.n_beans, 3), np.nan)
    for j in range(n):
        actions = _demo_actions(env, task, j)
        env.reset(options={"demo": j, "horizon": len(actions)})
        for a in actions:
            env.step(a)
            p = env.data.xpos[env.scene.bean_ids]
            new = (p[:, 2] < 0.03) & np.isnan(landing[j, :, 0])
            landing[j, new] = p[new]
    env.close()
    return landing


def _replay_demos(task, doc: dict[str, Any], records: bool = False, time_scale: float = 1.0):
    """The env's final info of each demo replayed (trajectory + 1 s of settling) in the scene
    of `doc` (no motion-limit checks: the scene alone), the demos' durations scaled by
    `time_scale` (positions interpolated, orientations slerped). With `records`, also the
    scene's episode records: (infos, records)."""
    env = RoboTaskEnv(doc["task"]["name"], spec=doc, limits=None)
    infos, recs = [], []
    for j in range(len(task.positions)):
        actions = _demo_actions(env, task, j, time_scale=time_scale)
        env.reset(options={"demo": j, "horizon": len(actions)})
        for a in actions:
            env.step(a)
        infos.append(env.evaluate())
        recs.append(env.scene.scene_state()["record"])
    env.close()
    return (infos, recs) if records else infos


_DERIVE = {"openbox": _derive_openbox, "bottle2shelf": _derive_bottle,
           "platestandingtolying": _derive_plate, "pouring": _derive_pouring,
           "wineglass": _derive_glass, "pan2stove": _derive_pan,
           "obstaclerotate": _derive_obstacle, "matfolding": _derive_mat, "scoop": _derive_scoop}

#: Comments on design entries every spec has.
_COMMON_COMMENTS = {
    "grasp": {
        "contact": "grip model (clfd_bench.sim.grasp): the contact the pads make with the prop; "
                   "the grip breaks when the wrench on the prop exceeds its capacity",
        "mu": "design: fingertip friction coefficient (stock Franka fingertips, 0.3-0.7 on "
              "PET / ceramic / wood)",
        "grip_force": "Franka Hand continuous grasp force, N (datasheet; 140 N peak)",
        "filter_steps": "control steps (60 Hz) the grip's load ratio is averaged over",
    },
    "camera": {"lookat": "the middle of the demos' grasp points (bounding box)"},
}


def derive_spec(task_name: str, with_starts: bool = True,
                comments: dict[str, dict[str, str]] | None = None
                ) -> dict[str, dict[str, Any]]:
    """The spec of a RoboTasks task as {table: {key: value}}, from the dataset.

    Args:
        task_name: a task of `robotask_specs.TASKS` ("openbox", ..., "wineglass").
        with_starts: compute the start configurations (~20 s per task); False keeps those of
            the existing `tasks/<task>.toml`.
        comments: if given, filled with {table: {key: how the value was derived}} for
            `robotask_specs.dumps_task_spec`.
    """
    if task_name not in DESIGN:
        raise KeyError(f"no RoboTasks task {task_name!r}; valid: {sorted(DESIGN)}")
    dataset = TASK_DATASETS[task_name]
    ds = load_dataset(dataset)
    task = ds.tasks[ds.task_names.index(task_name)]
    design = DESIGN[task_name]
    if with_starts:
        starts, methods, errors = start_configurations(task.positions, task.quaternions)
        # as the spec will hold them (10 decimals), so that a run with `with_starts=False`
        # derives from the very same starts
        starts = np.array([[round(float(v), 10) for v in row] for row in starts])
    else:
        old = load_task_spec(task_name)
        starts = np.asarray(old["start"]["qpos"], dtype=float)
        methods = old["derived"]["start_method"]
        errors = old["derived"]["start_forward_tracking_error_max"]
    derived = _DERIVE[task_name](task, design, starts)
    doc: dict[str, dict[str, Any]] = {
        "task": {"name": task_name, "dataset": dataset, **design["task"]},
        "grasp": {**design["grasp"], **derived.get("grasp", {})},
        "scene": dict(derived["scene"]),
        "success": {**design["success"], **derived.get("success", {})},
    }
    if "solver" in design:
        doc["solver"] = dict(design["solver"])
    doc["camera"] = _camera(task, design)
    doc["derived"] = dict(derived["derived"])
    # How the derived scene executes the demos (no motion-limit checks), for the record.
    infos = _replay_demos(task, {**doc, "start": {"qpos": starts}})
    doc["derived"]["demo_replay_success"] = [bool(i["is_success"]) for i in infos]
    doc["derived"]["demo_replay_grip_load_max"] = [float(i["grip_load_max"]) for i in infos]
    doc["derived"]["start_method"] = methods
    doc["derived"]["start_forward_tracking_error_max"] = errors
    doc["start"] = {"qpos": starts}
    if comments is not None:
        for table, entries in _COMMON_COMMENTS.items():
            comments.setdefault(table, {}).update(entries)
        for table, entries in derived.get("comments", {}).items():
            comments.setdefault(table, {}).update(entries)
        for table, entries in OBSERVER.get(task_name, {}).items():
            comments.setdefault(table, {}).update(entries)
        comments.setdefault("derived", {}).update({
            "demo_replay_success": "each demo replayed in this scene (+ 1 s settling, no "
                                   "motion-limit checks): success",
            "demo_replay_grip_load_max": "largest filtered load of the grip over that replay "
                                         "(1 = its capacity)"})
    return doc

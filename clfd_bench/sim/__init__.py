"""Simulation: the Panda (Menagerie + project MJCF), mink IK tracking, start configurations,
rollouts, offscreen rendering and the speed benchmark.

Modules (import what you need; nothing heavy is imported here):

- `clfd_bench.sim.robot`: `panda_spec(tool)`, `robot_model(tool)`, names and constants.
- `clfd_bench.sim.ik`: `PoseTracker`.
- `clfd_bench.sim.start_configs`: `backward_start_configs`, `solve_configuration`.
- `clfd_bench.sim.rollout`: `rollout(env, trajectory, ...) -> RolloutResult` (the function
  lives in the module of the same name: `from clfd_bench.sim.rollout import rollout`).
- `clfd_bench.sim.replay`: replay dataset demos (optionally perturbed) through an env.
- `clfd_bench.sim.render`: `OffscreenRenderer`, `CameraSpec`, `write_video`.
- `clfd_bench.sim.bench`: the `clfd-bench bench sim` measurement.
- `clfd_bench.sim.grasp`: the grasp model of the RoboTasks props (attached by an equality
  constraint, released when the gripper opens).
- `clfd_bench.sim.scene_fit`: geometry fitted to the demonstrations (e.g. the box lid's hinge).
"""

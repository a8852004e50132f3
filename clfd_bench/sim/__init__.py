"""Simulation, below the envs: the Panda (Menagerie + project MJCF), mink IK tracking, the
Panda's motion limits, start configurations, grasps, offscreen rendering. Rollouts, replays and
the speed benchmark are the execution layer's (`clfd_bench.execution`), above the envs.

Modules (import what you need; nothing heavy is imported here):

- `clfd_bench.sim.robot`: `panda_spec(tool)`, `robot_model(tool)`, names and constants.
- `clfd_bench.sim.ik`: `PoseTracker`.
- `clfd_bench.sim.start_configs`: `backward_start_configs`, `solve_configuration`.
- `clfd_bench.sim.limits`: the Panda's published motion limits and the per-step monitor.
- `clfd_bench.sim.render`: `OffscreenRenderer`, `CameraSpec`, `write_video`.
- `clfd_bench.sim.grasp`: the grasp model of the RoboTasks props (attached by an equality
  constraint, released when the gripper opens).
- `clfd_bench.sim.scene_fit`: geometry fitted to the demonstrations (e.g. the box lid's hinge).
"""

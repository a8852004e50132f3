"""The execution layer: predicted or perturbed trajectories run on the simulated Panda, above
the envs (`clfd_bench.envs`) and the simulator (`clfd_bench.sim`), which never import it.

One concept per module (import what you need; nothing heavy is imported here):

- `rollout`: `rollout(env, trajectory, ...) -> RolloutResult`, one trajectory through an env.
- `perturb`: perturbation families that must succeed or must fail.
- `replay`: demos (perturbed) through envs, and the env × family confusion table.
- `bench`: the `clfd-bench bench sim` speed measurement.
- `env_pool`: `get_env`, one env per process and id, reused.
- `trace`: `Trace`, `FrameHook`, `tracer`, `tool_site`, `tool_path`.
- `execute`: `execute`, `execute_predictions`, `ExecResult`, failure kinds.
- `scoring`: `sim_fields` (success matrix, its CL metrics), `failure_counts`.
- `cache`: keys and summaries of the rollout cache (the file: `clfd_bench.runs.RunDir`).
- `borderline`: the executions nearest each check's bound, both sides (pure selection).
- `final_checks`: `gather_executions`, saved runs' executions with their final checks.
- `fingerprint`: `sim_fingerprint`, `sim_provenance`.
- `saved_run`: a run's learned tasks and saved predictions (read through `clfd_bench.runs`).
- `evaluate`: `evaluate_run`, a saved run scored by execution (`clfd-bench evaluate`).
- `limit_calibration`: the measurement behind `clfd_bench.sim.limits`' bounds
  (`python eval/measure_limits.py`).
- `limit_derivation`: what that measurement derives (`Calibration.derive`), and `compare` with
  the constants of `clfd_bench.sim.limits`.
"""

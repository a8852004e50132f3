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
- `cache`: the rollout cache of a run directory.
- `fingerprint`: `sim_fingerprint`, `sim_provenance`.
- `saved_run`: reading a run's `results.json` and saved predictions.
- `evaluate`: `evaluate_run`, a saved run scored by execution (`clfd-bench evaluate`).
"""

"""The RoboTasks task `openbox` (env `clfd/BoxOpening`): its scene, success predicate,
docs and derivation (`clfd_bench.envs.robotasks.registry` says what each module holds)."""

"""The RoboTasks task `scoop` (env `clfd/Scoop`): its scene, success predicate,
docs and derivation (`clfd_bench.envs.robotasks.registry` says what each module holds)."""

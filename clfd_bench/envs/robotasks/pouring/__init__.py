"""The RoboTasks task `pouring` (env `clfd/Pouring`): its scene, success predicate,
docs and derivation (`clfd_bench.envs.robotasks.registry` says what each module holds)."""

"""The RoboTasks task `pan2stove` (env `clfd/PanToStove`): its scene, success predicate,
docs and derivation (`clfd_bench.envs.robotasks.registry` says what each module holds)."""

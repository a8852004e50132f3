"""The RoboTasks task `matfolding` (env `clfd/MatFolding`): its scene, success predicate,
docs and derivation (`clfd_bench.envs.robotasks.registry` says what each module holds)."""

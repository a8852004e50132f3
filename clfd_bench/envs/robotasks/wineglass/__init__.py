"""The RoboTasks task `wineglass` (env `clfd/WineGlass`): its scene, success predicate,
docs and derivation (`clfd_bench.envs.robotasks.registry` says what each module holds)."""

"""The RoboTasks task `bottle2shelf` (env `clfd/BottleShelving`): its scene, success predicate,
docs and derivation (`clfd_bench.envs.robotasks.registry` says what each module holds)."""

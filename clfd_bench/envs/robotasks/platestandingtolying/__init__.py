"""The RoboTasks task `platestandingtolying` (env `clfd/PlateStacking`): its scene, success
predicate, docs and derivation (`clfd_bench.envs.robotasks.registry` says what each module
holds)."""

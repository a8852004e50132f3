"""The RoboTasks task `obstaclerotate` (env `clfd/ObstacleRotate`): its scene, success predicate,
docs and derivation (`clfd_bench.envs.robotasks.registry` says what each module holds)."""

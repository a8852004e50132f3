"""Execution speed: where a control step's time goes, measured inside real rollouts.

A rollout (`clfd_bench.execution.rollout.rollout`, the harness's lean path) times its own parts:
the IK of the whole command stream (`CommandPlan.ik_s`) and MuJoCo's physics steps as they run
in the rollout, contacts included (`PlanRun.physics_s`). The rest is everything else: the
command checks, the servo references, the blow-up, collision and tracking checks, the task's
per-step hook (ink, grasp slips, records), the final judgement. The target (issue 40, a team
decision that holds on any machine, unlike x real time, which moves 3x on shared VMs): a control
step costs at most `RATIO_TARGET` x its physics + IK. Single process, single thread (MuJoCo and
mink run on one core; no torch).
"""

from __future__ import annotations

import os
import time
from typing import Any

import gymnasium as gym

from clfd_bench.envs.registration import env_id_for
from clfd_bench.envs.robotasks.registry import TASKS as ROBOTASKS
from clfd_bench.execution.rollout import DEFAULT_SETTLE_S, rollout

#: The envs `clfd-bench bench sim` measures by default: one per kind of scene (a letter, a LASA
#: shape, every RoboTasks task of `clfd_bench.envs.robotasks.registry`).
DEFAULT_ENVS = ("clfd/HelloWorld-h-v3", "clfd/LASA-Angle-v3",
                *(env_id_for(t.dataset, t.name) for t in ROBOTASKS))
#: The most a control step may cost, as a multiple of its physics + IK (issue 40): the rest
#: stays within 40 % of what MuJoCo and the IK must do.
RATIO_TARGET = 1.4


def bench_env(env_id: str, demo: int = 0, settle_s: float = DEFAULT_SETTLE_S,
              repeats: int = 1) -> dict[str, Any]:
    """Measures one env on demo `demo`'s trajectory (the fastest of `repeats` rollouts).

    Returns:
        {env, steps, sim_s, wall_s, cpu_s, x_realtime (sim / wall), x_realtime_cpu (sim / CPU
         time of this process: the one-core figure when the machine is shared), per control
         step in microseconds: step_us, physics_us (MuJoCo's steps inside the rollout),
         ik_us, rest_us (step - physics - IK); ratio (step / (physics + IK)), ratio_target,
         meets_target, physics_substeps, success}.
    """
    import clfd_bench.envs  # noqa: F401 - registers the ids

    env = gym.make(env_id)
    try:
        base = env.unwrapped
        traj = base.demo_trajectory(demo)
        rollout(env, traj[:5] if not isinstance(traj, list) else [t[:5] for t in traj],
                demo=demo, settle_s=0.0)  # warm-up: caches, start configuration
        best = None
        for _ in range(max(1, repeats)):
            t0, c0 = time.perf_counter(), time.process_time()
            result = rollout(env, traj, demo=demo, settle_s=settle_s, lean=True)
            wall, cpu = time.perf_counter() - t0, time.process_time() - c0
            best = (wall, cpu, result) if best is None or wall < best[0] else best
        wall, cpu, result = best
        n = result.steps
        sim = n * base.control_dt
        physics, ik = result.timing["physics_s"], result.timing["ik_s"]
        ratio = wall / (physics + ik)
        return {
            "env": env_id, "steps": n, "sim_s": sim, "wall_s": wall, "cpu_s": cpu,
            "x_realtime": sim / wall, "x_realtime_cpu": sim / cpu if cpu > 0 else float("inf"),
            "step_us": wall / n * 1e6, "physics_us": physics / n * 1e6, "ik_us": ik / n * 1e6,
            "rest_us": (wall - physics - ik) / n * 1e6, "ratio": ratio,
            "ratio_target": RATIO_TARGET, "meets_target": ratio <= RATIO_TARGET,
            "physics_substeps": base.n_substeps, "success": result.success,
        }
    finally:
        env.close()


def machine_note() -> str:
    """CPU count and load, to read the figures against."""
    try:
        load = os.getloadavg()[0]
    except OSError:
        load = float("nan")
    return f"{os.cpu_count()} CPUs, 1-min load average {load:.2f} at the start"

"""Every clfd-bench task as a `dm_env.Environment`, its physics a `dm_control.mujoco.Physics`.

```python
from clfd_bench import dm

env = dm.load("PlateStacking-v3", options={"demo": 3})   # or "clfd/PlateStacking-v3"
timestep = env.reset()                                   # StepType.FIRST
while not timestep.last():
    timestep = env.step(policy(timestep.observation))    # action [8]: hand pose + gripper
timestep.reward, env.last_info["is_success"], env.last_info["failure_reason"]
env.physics.named.data.qpos                              # the scene's state, by joint name
```

Needs the optional extra: `pip install 'clfd-bench[dm]'` (dm-control, which brings dm-env).

**One implementation.** `DmEnv` adapts the registered Gymnasium env (`gymnasium.make("clfd/...")`,
a `clfd_bench.envs.base.PandaEnv`): its scene, step (IK, servos, the Panda's motion limits),
success criterion, observations and actions are the Gymnasium env's, called as they are. Its
`physics` is a `dm_control.mujoco.Physics` over the very `MjModel` and `MjData` the Gymnasium
env steps (`Physics(wrapper.MjData(env.data))` shares them, it does not copy), so it always
shows the env's current state; use it to read state (`physics.named.data`, `physics.render`).
The env steps the physics itself: calling `physics.step()` or writing to `physics.data`
changes the episode behind the env's back, like writing to the Gymnasium env's `data`.
(dm-control's own `rl.control.Environment` + `Task` cannot host this loop: its step applies one
control for `n_sub_steps` physics steps, while the Panda env changes the servo reference at every
substep and checks the controller's limits between IK and physics.)

**Specs.** `action_spec()`: a `BoundedArray` with the Gymnasium action `Box`'s shape, dtype and
bounds (RoboTasks [8]: position m, quaternion w x y z, gripper 1 = closed; writing [2]: pen
point on the board; `HelloWorld-v3` [3]). `observation_spec()`: a dict with one spec per
entry of the Gymnasium `Dict` observation (`ee_pos` [3], `ee_quat` [4], `qpos` [7], `qvel` [7]
and the task's entries): a `BoundedArray` with the `Box`'s bounds when it has a finite one, an
`Array` when it is unbounded. `reward_spec()`: a scalar in [0, 1] (the envs' sparse reward:
1.0 while the task is accomplished). `discount_spec()`: dm_env's default, a scalar in [0, 1].

**Episodes.** `reset()` resets the Gymnasium env with the options given to `load` (`demo`:
which demo's start and scene, default drawn with the seed; `horizon`: episode length in steps,
default the task's) and returns `StepType.FIRST`. `step(action)` returns `MID`, or `LAST`
when the episode ends: a failure (a limit of the real Panda broken, a collision, a physics
blow-up: the Gymnasium env's `terminated`) ends it with discount 0.0; reaching the horizon
(the Gymnasium env's `truncated`) ends it with discount 1.0, dm_env's convention for a time
limit. The step after `LAST` (and the first `step` of a new env) starts a new episode, ignores
its action and returns `FIRST`. Success is the reward of the last step (1.0: the criterion
holds at the episode's end), and `last_info` holds the Gymnasium env's info dict of the last
`reset`/`step` (`is_success`, `failure_reason`, `failure`, the task's measures).

**Seeding.** `seed` seeds the Gymnasium env at the first reset; later resets continue its
random stream, as `gymnasium` resets without a seed do. The only randomness is the demo drawn
when `options` has no `demo`; the simulation itself is deterministic.

`DmEnv` pickles (mid-episode too) as the Gymnasium envs do.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces
from gymnasium.envs.registration import parse_env_id

try:
    import dm_env
    from dm_control import mujoco as dm_mujoco
    from dm_control.mujoco import wrapper as dm_wrapper
    from dm_env import specs
except ImportError as exc:  # the optional extra is missing
    raise ImportError(
        f"clfd_bench.dm needs dm-control and dm-env ({exc.name or exc} is missing); install "
        "them with: pip install 'clfd-bench[dm]'") from exc

from clfd_bench.envs.base import PandaEnv
from clfd_bench.envs.registration import NAMESPACE, register_envs, registered_env_ids

__all__ = ["DmEnv", "UnknownEnvError", "box_spec", "load", "names"]


class UnknownEnvError(KeyError):
    """`load` got a name that is no clfd-bench env; the message lists the valid names."""

    def __str__(self) -> str:  # KeyError would print the message in quotes
        return str(self.args[0])


def names() -> list[str]:
    """The names `load` accepts, without the namespace (e.g. "PlateStacking-v3"), sorted; the
    same with "clfd/" in front are accepted too."""
    register_envs()
    return [env_id.split("/", 1)[1] for env_id in registered_env_ids()]


def _resolve(name: str) -> str:
    """The registered id of `name` ("PlateStacking-v3", "clfd/PlateStacking-v3", or without the
    version for the current one). Raises `UnknownEnvError` with the registry's own reason (e.g.
    Gymnasium's "version v0 ... is deprecated. Please use `clfd/PlateStacking-v3`") and the
    valid names."""
    register_envs()
    ids = registered_env_ids()
    env_id = name if "/" in name else f"{NAMESPACE}/{name}"
    if env_id in ids:
        return env_id
    try:
        namespace, base, version = parse_env_id(env_id)
    except gym.error.Error as exc:  # not an id at all
        raise _unknown(name, str(exc)) from None
    if namespace != NAMESPACE:
        raise _unknown(name, f"clfd-bench envs are in the namespace {NAMESPACE!r}, not "
                             f"{namespace!r}")
    if version is None:
        versions = [i for i in ids if parse_env_id(i)[1] == base]
        if versions:
            return max(versions, key=lambda i: parse_env_id(i)[2])
    try:
        gym.spec(env_id)
    except gym.error.Error as exc:  # the registry's reason: no such name, version, ...
        raise _unknown(name, str(exc)) from None
    raise _unknown(name, "registered, but not by clfd-bench")


def _unknown(name: str, reason: str) -> UnknownEnvError:
    return UnknownEnvError(f"no clfd-bench env {name!r} ({reason}); valid names (with or "
                           f"without '{NAMESPACE}/'): {', '.join(names())}")


def box_spec(space: spaces.Space, name: str) -> specs.Array:
    """The dm_env spec of a Gymnasium `Box` (shape and dtype exact): a `BoundedArray` with its
    bounds when it has a finite bound, else an `Array`. Other spaces raise TypeError."""
    if not isinstance(space, spaces.Box):
        raise TypeError(f"{name!r}: only Box spaces have a dm_env spec here, got "
                        f"{type(space).__name__}")
    if not (np.isfinite(space.low).any() or np.isfinite(space.high).any()):
        return specs.Array(space.shape, space.dtype, name=name)
    return specs.BoundedArray(space.shape, space.dtype, space.low.copy(), space.high.copy(),
                              name=name)


class DmEnv(dm_env.Environment):
    """A clfd-bench task as a `dm_env.Environment` (see the module docstring).

    Args:
        env: the Gymnasium env (a `PandaEnv`, e.g. `gymnasium.make("clfd/...").unwrapped`);
            the adapter steps it and owns it from now on.
        seed: seed of the first reset (None: fresh entropy).
        options: the Gymnasium env's reset options used at every reset: `demo` (int),
            `horizon` (int steps). Kept in `reset_options`, which may be changed between
            episodes.
    """

    def __init__(self, env: PandaEnv, *, seed: int | None = None,
                 options: Mapping[str, Any] | None = None):
        if not isinstance(env, PandaEnv):
            raise TypeError(f"DmEnv adapts a clfd-bench env (PandaEnv), got {type(env).__name__}")
        self._env = env
        self.seed = seed
        self.reset_options: dict[str, Any] = dict(options or {})
        self.last_info: dict[str, Any] = {}
        self._seeded = False
        self._reset_next = True
        self._action_spec = box_spec(env.action_space, "action")
        self._observation_spec = {key: box_spec(space, key)
                                  for key, space in env.observation_space.spaces.items()}
        self._reward_spec = specs.BoundedArray((), np.float64, 0.0, 1.0, name="reward")
        self._physics = self._make_physics()

    def _make_physics(self) -> dm_mujoco.Physics:
        physics = dm_mujoco.Physics(dm_wrapper.MjData(self._env.data))
        # Physics runs a forward pass with actuation disabled when it is made; redo it with
        # actuation so the derived quantities (actuator forces, qacc) are the env's again.
        mujoco.mj_forward(self._env.model, self._env.data)
        return physics

    # ------------------------------------------------------------------ dm_env API
    def reset(self) -> dm_env.TimeStep:
        """Starts an episode: `StepType.FIRST` with the first observation."""
        seed = None if self._seeded else self.seed
        obs, self.last_info = self._env.reset(seed=seed, options=dict(self.reset_options))
        self._seeded = True
        self._reset_next = False
        return dm_env.restart(obs)

    def step(self, action: np.ndarray) -> dm_env.TimeStep:
        """One control step (1/60 s) with `action` [A] (see `action_spec()`); on a new env or
        after `LAST`, starts an episode instead (the action is ignored)."""
        if self._reset_next:
            return self.reset()
        obs, reward, terminated, truncated, self.last_info = self._env.step(action)
        reward = float(reward)
        if terminated:
            self._reset_next = True
            return dm_env.termination(reward, obs)
        if truncated:
            self._reset_next = True
            return dm_env.truncation(reward, obs)
        return dm_env.transition(reward, obs)

    def action_spec(self) -> specs.BoundedArray:
        return self._action_spec

    def observation_spec(self) -> dict[str, specs.Array]:
        return dict(self._observation_spec)

    def reward_spec(self) -> specs.BoundedArray:
        return self._reward_spec

    def close(self) -> None:
        """Closes the Gymnasium env (its renderer) and frees the Physics' rendering contexts;
        the env is not to be used afterwards."""
        self._env.close()
        self._physics.free()

    # ------------------------------------------------------------------ beyond dm_env
    @property
    def physics(self) -> dm_mujoco.Physics:
        """The scene as a `dm_control.mujoco.Physics`, sharing the env's MjModel and MjData."""
        return self._physics

    @property
    def gym_env(self) -> PandaEnv:
        """The Gymnasium env this adapter steps (for `trajectory_to_actions`,
        `demo_trajectory`, `settle_actions`, `render`, `evaluate`)."""
        return self._env

    def __getstate__(self) -> dict[str, Any]:
        state = dict(self.__dict__)
        del state["_physics"]  # rebuilt over the unpickled env's model and data
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._physics = self._make_physics()


def load(name: str, *, seed: int | None = None, options: Mapping[str, Any] | None = None,
         **env_kwargs: Any) -> DmEnv:
    """A clfd-bench task as a `dm_env.Environment`.

    Args:
        name: an env id with or without the namespace ("PlateStacking-v3",
            "clfd/PlateStacking-v3"; without a version, the current one); `names()` lists them.
        seed: seed of the first reset (only the demo drawn when `options` has no `demo`
            depends on it).
        options: reset options used at every reset: `demo` (int), `horizon` (int steps).
        **env_kwargs: the Gymnasium env's arguments (`limits`, `physics_dt`, `render_mode`,
            `width`, `height`, ...; see the env's class docstring).

    Raises:
        UnknownEnvError: `name` is no clfd-bench env; the message says why and lists the names.
    """
    env_id = _resolve(name)
    env = gym.make(env_id, disable_env_checker=True, **env_kwargs).unwrapped
    return DmEnv(env, seed=seed, options=options)

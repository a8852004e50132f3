"""One env per process, id and arguments, reused across rollouts (building a scene and its IK
takes a while; resetting it is cheap)."""

from __future__ import annotations

import collections
from typing import Any

__all__ = ["ENV_CACHE_SIZE", "clear_env_cache", "get_env"]

_ENV_CACHE: collections.OrderedDict[tuple, Any] = collections.OrderedDict()
ENV_CACHE_SIZE = 8
"""Most envs :func:`get_env` keeps (least recently used are closed): a writing env holds
~40 MB, so all 26 LASA shapes at once would take > 1 GB."""


def get_env(env_id: str, render: bool = False, **kwargs: Any):
    """The env ``env_id`` made with ``gymnasium.make`` (``render_mode="rgb_array"`` when
    ``render``), cached per process, id, render flag and ``kwargs`` (up to
    :data:`ENV_CACHE_SIZE`): building a scene and its IK takes a while, resetting it is cheap.

    Raises:
        gymnasium.error.Error: ``env_id`` is not registered (the message lists close ids).
    """
    import gymnasium as gym

    import clfd_bench.envs  # noqa: F401 - registers the ids (importing the package does)

    key = (env_id, bool(render), tuple(sorted(kwargs.items())))
    env = _ENV_CACHE.get(key)
    if env is None:
        env = gym.make(env_id, render_mode="rgb_array" if render else None,
                       disable_env_checker=True, **kwargs)
        _ENV_CACHE[key] = env
        while len(_ENV_CACHE) > max(1, ENV_CACHE_SIZE):
            _ENV_CACHE.popitem(last=False)[1].close()
    _ENV_CACHE.move_to_end(key)
    return env


def clear_env_cache() -> None:
    """Closes and forgets every env made by :func:`get_env` (frees renderers and memory)."""
    for env in _ENV_CACHE.values():
        env.close()
    _ENV_CACHE.clear()

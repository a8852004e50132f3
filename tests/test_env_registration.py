"""Env ids carry each env's own version: one env can move on while the others stay, and an
outdated id is refused with a message naming the current one."""

from __future__ import annotations

import gymnasium as gym
import pytest

import clfd_bench  # noqa: F401  (registers the envs)
from clfd_bench.envs import registration
from clfd_bench.envs.registration import env_id_for, env_specs, env_version
from clfd_bench.envs.robotasks.registry import TASKS as ROBOTASKS


def test_every_id_has_its_envs_version():
    specs = env_specs()
    # RoboTasks (the registry's: 4 + 5 of RoboTasks9 today), letters, text, LASA
    assert len(specs) == len(ROBOTASKS) + 7 + 1 + 26
    assert {t.name for t in ROBOTASKS} >= {"openbox", "bottle2shelf", "platestandingtolying",
                                           "pouring", "wineglass", "pan2stove",
                                           "obstaclerotate", "matfolding", "scoop"}
    for env_id in specs:
        name, version = env_id.split("/")[1].rsplit("-v", 1)
        assert int(version) == env_version(name)
        assert gym.spec(env_id).version == int(version)
    assert env_id_for("robotasks", "openbox") == (
        f"clfd/BoxOpening-v{registration.FAMILY_VERSIONS['robotasks']}")


def test_one_env_can_move_on_alone(monkeypatch):
    monkeypatch.setitem(registration.ENV_VERSIONS, "Pouring", 7)
    specs = env_specs()
    assert "clfd/Pouring-v7" in specs
    others = [i for i in specs if i.startswith("clfd/BoxOpening-")]
    assert others == [f"clfd/BoxOpening-v{registration.FAMILY_VERSIONS['robotasks']}"]
    with pytest.raises(KeyError, match="no clfd-bench env named 'Nope'"):
        env_version("Nope")


@pytest.mark.skipif(registration.FAMILY_VERSIONS["letters"] < 1, reason="no older version")
def test_outdated_id_is_refused_naming_the_current_one():
    current = env_id_for("helloworld", "h")
    stem, version = current.rsplit("-v", 1)
    for old in range(int(version)):  # every older version, e.g. -v0 and -v1 for -v2
        with pytest.raises(gym.error.Error, match=current.split("/")[1]):
            gym.make(f"{stem}-v{old}")

"""Where the paper is silent the `paper` profile does what the released code does
(docs/studies/paper.md): RoboTasks orientation tangent vectors x100 (`tangent_scale`) and
LASA's first-demo time axis (`time_axis`)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import scipy.io
import torch

from clfd_bench.cli.main import main as cli_main
from clfd_bench.data import load_dataset
from clfd_bench.harness.config import ConfigError, PartConfig, resolve_config
from clfd_bench.harness.learner import Learner, PartLearner
from clfd_bench.harness.protocol import _config_without_tasks, _diff

pytestmark = pytest.mark.usefixtures("data_dir")

ROBOTASKS_METHODS = ("sg", "ft", "rep", "hn", "chn")
ALL_METHODS = ("sg", "ft", "rep", "si", "mas", "hn", "chn")


@pytest.fixture
def data_dir(monkeypatch):
    import os
    from pathlib import Path

    shared = Path(__file__).resolve().parents[2] / "shared" / "datasets"
    if "CLFD_DATA_DIR" not in os.environ and shared.is_dir():
        monkeypatch.setenv("CLFD_DATA_DIR", str(shared))


@pytest.fixture(scope="module")
def robotask():
    return load_dataset("robotasks")[0]


@pytest.fixture(scope="module")
def heee():
    return load_dataset("lasa").task("heee")


def _orientation_part(scale: float, normalize: bool = False) -> PartLearner:
    config = resolve_config("sg", "robotasks", "smoke", overrides=(
        f"orientation.tangent_scale={scale}", f"orientation.normalize={str(normalize).lower()}"))
    torch.manual_seed(0)
    return Learner.from_config(config, 7).parts["orientation"]


def _same_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``|q_a . q_b|``: 1 where two unit quaternions are the same rotation (q and -q)."""
    return np.abs(np.sum(a * b, axis=-1))


# ------------------------------------------------------------------------- tangent scale
def test_tangent_scale_round_trip_and_targets(robotask):
    """Data -> NODE -> data gives the demos back; the NODE-space targets are 100x."""
    one, hundred = _orientation_part(1.0), _orientation_part(100.0)
    data_1, data_100 = one.add_task(robotask), hundred.add_task(robotask)
    np.testing.assert_allclose(data_100.demos.numpy(), 100.0 * data_1.demos.numpy(),
                               rtol=1e-6, atol=1e-6)
    assert float(data_1.demos.abs().max()) < np.pi / 2 < float(data_100.demos.abs().max())

    quats, goals = robotask.quaternions, robotask.demo_goals[:, 3:]  # [N, T, 4], [N, 4]
    node_1 = one.node_states(0, quats, goals)  # [N, T, 3] float64
    node_100 = hundred.node_states(0, quats, goals)
    np.testing.assert_allclose(node_100, 100.0 * node_1, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(node_100[:, -1], 0.0, atol=1e-9)  # each demo ends at its goal
    back = hundred.data_states(0, node_100, goals)
    np.testing.assert_allclose(_same_rotation(back, quats), 1.0, atol=1e-9)
    np.testing.assert_allclose(np.abs(back), np.abs(quats), atol=1e-9)
    # not dividing by the scale would be a different rotation
    wrong = one.data_states(0, node_100, goals)
    assert _same_rotation(wrong, quats).min() < 0.5


def test_predictions_are_divided_by_the_scale(robotask):
    """Prediction starts where the demos start, in quaternions, whatever the scale."""
    part = _orientation_part(100.0)
    part.add_task(robotask)
    starts, goals = robotask.quaternions[:, 0], robotask.demo_goals[:, 3:]
    pred = part.predict(0, starts, robotask.times[:3], goals)  # [N, 3, 4]
    np.testing.assert_allclose(_same_rotation(pred[:, 0], starts), 1.0, atol=1e-6)


def test_tangent_scale_cancels_with_normalisation(robotask):
    one, hundred = _orientation_part(1.0, True), _orientation_part(100.0, True)
    np.testing.assert_allclose(hundred.add_task(robotask).demos.numpy(),
                               one.add_task(robotask).demos.numpy(), rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("value", [0, -1.0, float("nan"), float("inf")])
def test_invalid_tangent_scale_is_rejected(value):
    with pytest.raises(ConfigError, match=r"tangent_scale must be a finite number > 0"):
        PartConfig(iterations=1, lr=1e-3, node_hidden=(4,), tangent_scale=value)


def test_invalid_tangent_scale_override_names_the_key():
    with pytest.raises(ConfigError) as err:
        resolve_config("hn", "robotasks", "paper", overrides=("orientation.tangent_scale=0",))
    assert str(err.value).startswith("--set orientation.tangent_scale=0: tangent_scale must be "
                                     "a finite number > 0")
    assert "the paper profile uses orientation.tangent_scale=100" in str(err.value)
    with pytest.raises(ConfigError, match="tangent_scale must be a number, got 'big'"):
        resolve_config("sg", "robotasks", "fast", overrides=("orientation.tangent_scale=big",))


def test_tangent_scale_on_a_position_model_is_refused():
    with pytest.raises(ConfigError, match=r"--set tangent_scale=100: tangent_scale = 100\.0 "
                       r"scales orientation tangent vectors.*use --set "
                       r"orientation\.tangent_scale=100\.0"):
        resolve_config("sg", "robotasks", "fast", overrides=("tangent_scale=100",))
    with pytest.raises(ConfigError, match=r"drop it \(lasa has no orientations\)"):
        resolve_config("sg", "lasa", "fast", overrides=("tangent_scale=2",))
    cfg = PartConfig(iterations=1, lr=1e-3, node_hidden=(4,), tangent_scale=2.0)
    with pytest.raises(ValueError, match="tangent_scale = 2 is for orientation models"):
        PartLearner("position", object(), cfg)


@pytest.mark.parametrize("method", ROBOTASKS_METHODS)
def test_paper_orientation_uses_the_released_scale(method):
    for dataset in ("robotasks", "robotasks9"):
        paper = resolve_config(method, dataset, "paper")
        assert paper.part("orientation").tangent_scale == 100.0
        assert paper.part("position").tangent_scale == 1.0
        for profile in ("fast", "smoke"):
            cfg = resolve_config(method, dataset, profile)
            assert cfg.part("orientation").tangent_scale == 1.0


def test_show_config_prints_the_scale(capsys):
    assert cli_main(["train", "--method", "chn", "--dataset", "robotasks", "--profile", "paper",
                     "--show-config"]) == 0
    parts = json.loads(capsys.readouterr().out)["parts"]
    assert parts["orientation"]["tangent_scale"] == 100.0
    assert parts["position"]["tangent_scale"] == 1.0
    assert cli_main(["train", "--method", "chn", "--dataset", "robotasks", "--profile", "fast",
                     "--set", "orientation.tangent_scale=10", "--show-config"]) == 0
    parts = json.loads(capsys.readouterr().out)["parts"]
    assert parts["orientation"]["tangent_scale"] == 10.0


# ----------------------------------------------------------------------------- time axis
def test_lasa_keeps_every_demos_time_stamps(heee):
    mat = scipy.io.loadmat(heee.source, squeeze_me=True, struct_as_record=False)
    expected = np.stack([np.asarray(d.t, dtype=np.float64) for d in mat["demos"]])
    assert heee.demo_times.shape == (7, 1000)
    np.testing.assert_array_equal(heee.demo_times, expected)
    np.testing.assert_allclose(heee.times, np.arange(1000) * float(mat["dt"]))
    # heee: demo 0 lasts 3.91 s, the file's mean period gives 5.10 s (30 % longer)
    assert heee.demo_times[0, -1] == pytest.approx(3.910, abs=5e-4)
    assert heee.times[-1] == pytest.approx(5.096, abs=5e-4)
    assert heee.times[-1] / heee.demo_times[0, -1] - 1 == pytest.approx(0.303, abs=1e-3)
    # the file's dt is the mean of the seven demos' periods
    assert heee.times[-1] == pytest.approx(heee.demo_times[:, -1].mean(), rel=1e-6)


def test_sixty_hertz_data_has_one_time_axis(robotask):
    np.testing.assert_array_equal(robotask.demo_times,
                                  np.broadcast_to(robotask.times, robotask.demo_times.shape))
    assert not robotask.demo_times.flags.writeable


def _lasa_part(time_axis: str) -> PartLearner:
    config = resolve_config("sg", "lasa", "smoke", overrides=(f"time_axis={time_axis}",))
    torch.manual_seed(0)
    return Learner.from_config(config, 2).parts["position"]


def test_first_demo_axis_trains_and_predicts_on_demo_zeros_stamps(heee):
    first, uniform = _lasa_part("first_demo"), _lasa_part("uniform")
    t_first, t_uniform = first.add_task(heee).times, uniform.add_task(heee).times
    np.testing.assert_allclose(t_first.numpy(), heee.demo_times[0], rtol=1e-6)
    np.testing.assert_allclose(t_uniform.numpy(), heee.times, rtol=1e-6)
    assert first.time_factors == [pytest.approx(3.910 / 5.096, abs=2e-4)]
    assert uniform.time_factors == [1.0]
    # predictions are asked for on the data's axis and land on the NODE's
    np.testing.assert_allclose(first.node_times(0, heee.times), heee.demo_times[0],
                               rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(uniform.node_times(0, heee.times), heee.times)
    # the factor travels with the checkpoint header; old headers mean the data's axis
    header = first.header()
    restored = _lasa_part("first_demo")
    restored.restore(header, first.method.state_dict())
    assert restored.time_factors == first.time_factors
    del header["time_factors"]
    restored.restore(header, first.method.state_dict())
    assert restored.time_factors == [1.0]


def test_first_demo_needs_evenly_scaled_stamps(heee):
    import dataclasses

    bent = heee.demo_times.copy()
    bent[0, 500:] += 0.01
    task = dataclasses.replace(heee, demo_times=bent)
    with pytest.raises(ValueError, match="first demo's time stamps are not the task's times "
                       "scaled by one factor.*use time_axis = uniform"):
        _lasa_part("first_demo").add_task(task)


@pytest.mark.parametrize("method", ALL_METHODS)
def test_paper_lasa_uses_the_first_demo_axis(method):
    assert resolve_config(method, "lasa", "paper").part("position").time_axis == "first_demo"
    assert resolve_config(method, "lasa", "fast").part("position").time_axis == "uniform"
    assert resolve_config(method, "helloworld", "paper").part("position").time_axis == "uniform"


def test_invalid_time_axis_is_rejected():
    with pytest.raises(ConfigError, match=r"--set time_axis=demo0: time_axis must be one of "
                       r"uniform, first_demo, got 'demo0'"):
        resolve_config("sg", "lasa", "paper", overrides=("time_axis=demo0",))


def test_runs_saved_before_the_new_keys_still_resume():
    """A config saved without tangent_scale / time_axis equals today's with their defaults."""
    now = resolve_config("hn", "robotasks", "fast").to_dict()
    saved = json.loads(json.dumps(now))
    for part in saved["parts"].values():
        del part["tangent_scale"], part["time_axis"]
    assert _diff(_config_without_tasks(saved), _config_without_tasks(now)) == []
    now["parts"]["orientation"]["tangent_scale"] = 100.0
    assert _diff(_config_without_tasks(saved), _config_without_tasks(now)) == [
        "parts.orientation.tangent_scale: 1.0 -> 100.0"]

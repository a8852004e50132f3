"""Videos: frames with the paths drawn in, mp4 files that decode with the expected frame
counts, for one rollout and for a tiny trained run (tasks, all tasks, the HelloWorld text)."""

from __future__ import annotations

import argparse

import imageio.v3 as iio
import numpy as np
import pytest

from clfd_bench.data import load_dataset
from clfd_bench.execution.env_pool import get_env
from clfd_bench.viz.video import (
    VideoStyle,
    VideoWriter,
    render_rollout,
    render_run_videos,
    text_for_letters,
)

#: Small and sparse: software rendering is slow, the checks do not need pixels.
STYLE = VideoStyle(width=160, height=120, fps=3.0, hold_s=1.0, max_segments=40)


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """SG on HelloWorld's first two letters, smoke profile."""
    from clfd_bench.harness.config import resolve_config
    from clfd_bench.harness.protocol import run_training

    out = tmp_path_factory.mktemp("run") / "sg_smoke"
    run_training(resolve_config("sg", "helloworld", "smoke", seed=0, tasks=2), out, threads=1,
                 log=None)
    return out


def test_rollout_video_decodes_with_expected_frames(tmp_path):
    demos = np.asarray(load_dataset("helloworld").tasks[1].demos)  # 'e'
    writer = VideoWriter(tmp_path / "e.mp4", STYLE.fps)
    frames: list[np.ndarray] = []
    result, count = render_rollout(get_env("clfd/HelloWorld-e-v2"), demos[0], 0,
                                   [writer.append, frames.append], demonstration=demos[0],
                                   caption="e", style=STYLE)
    path = writer.close()
    assert result.success
    assert count == STYLE.frames_for(result.steps) == len(frames)
    video = iio.imread(path)
    assert video.shape == (count, STYLE.height, STYLE.width, 3)
    # The closing frames carry the green success border.
    border = frames[-1][0, STYLE.width // 2].astype(int)
    assert border[1] > 150 and border[0] < 100
    # The prediction (orange) is drawn onto the white board.
    orange = (frames[0][..., 0] > 200) & (frames[0][..., 1] > 90) & (frames[0][..., 1] < 190) \
        & (frames[0][..., 2] < 80)
    assert orange.sum() > 10


def test_text_for_letters():
    assert text_for_letters("hello world") == "hello world"
    assert text_for_letters(["h", "e", "l", "o", "w", "r", "d"]) == "hello world"
    assert text_for_letters(["h", "e"]) == "he"
    assert text_for_letters(["o", "w"]) == "o wo"
    assert text_for_letters([]) == ""


def test_run_videos(tiny_run, tmp_path):
    out = tmp_path / "videos"
    paths = render_run_videos(tiny_run, task="all", demo=0, out_dir=out, style=STYLE)
    names = [p.name for p in paths]
    run = tiny_run.name
    assert names == [f"{run}_task0_h_demo0.mp4", f"{run}_task1_e_demo0.mp4",
                     f"{run}_all_tasks_demo0.mp4", f"{run}_text_demo0.mp4"]
    per_task = STYLE.frames_for(1000 + 60)  # 1000-sample letters, 1 s settling
    assert len(iio.imread(paths[0])) == per_task
    assert len(iio.imread(paths[1])) == per_task
    assert len(iio.imread(paths[2])) == 2 * per_task
    text_env = get_env("clfd/HelloWorld-v2", text="he").unwrapped
    steps = len(text_env.trajectory_to_actions([np.zeros((1000, 2))] * 2)) + 60
    assert len(iio.imread(paths[3])) == STYLE.frames_for(steps)
    assert not list(out.glob(".*"))  # no temporary files left


def test_video_cli_one_task_by_name(tiny_run, tmp_path, capsys):
    from clfd_bench.cli import video

    parser = argparse.ArgumentParser()
    video.register(parser.add_subparsers())
    args = parser.parse_args(["video", str(tiny_run), "--task", "e", "--out", str(tmp_path),
                              "--fps", "5", "--size", "96x72"])
    assert args.func(args) == 0
    printed = capsys.readouterr().out.split()
    assert printed == [str(tmp_path / f"{tiny_run.name}_task1_e_demo0.mp4")]
    assert iio.imread(printed[0]).shape[1:] == (72, 96, 3)

    args = parser.parse_args(["video", str(tiny_run), "--task", "q", "--out", str(tmp_path)])
    assert args.func(args) == 2
    assert "valid: an index 0..1, a name (h, e) or 'all'" in capsys.readouterr().err

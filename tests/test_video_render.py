"""Videos: frames with the paths drawn in, mp4 files that decode with the expected frame
counts, for one rollout and for a tiny trained run (tasks, all tasks, the HelloWorld text);
captions that name the run's method and the outcome; the comparison of several runs on one
task, a grid of tiles rendered at tile size."""

from __future__ import annotations

import argparse

import imageio.v3 as iio
import numpy as np
import pytest

from clfd_bench.data import load_dataset
from clfd_bench.execution.env_pool import get_env
from clfd_bench.execution.saved_run import load_run
from clfd_bench.viz import compare as compare_mod
from clfd_bench.viz.video import (
    FAILURE_RGB,
    SUCCESS_RGB,
    VideoStyle,
    VideoWriter,
    comparison_grid,
    frame_camera,
    outcome_caption,
    render_comparison_video,
    render_rollout,
    render_run_videos,
    run_caption,
    text_for_letters,
)

#: Small and sparse: software rendering is slow, the checks do not need pixels.
STYLE = VideoStyle(width=160, height=120, fps=3.0, hold_s=1.0, max_segments=40)


def _train_two_letters(tmp_path_factory, method: str):
    """``method`` on HelloWorld's first two letters, smoke profile, seed 0."""
    from clfd_bench.harness.config import resolve_config
    from clfd_bench.harness.protocol import run_training

    out = tmp_path_factory.mktemp("run") / f"{method}_smoke"
    run_training(resolve_config(method, "helloworld", "smoke", seed=0, tasks=2), out,
                 threads=1, log=None)
    return out


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """SG on HelloWorld's first two letters, smoke profile."""
    return _train_two_letters(tmp_path_factory, "sg")


@pytest.fixture(scope="module")
def tiny_ft_run(tmp_path_factory):
    """FT on HelloWorld's first two letters (a second method to compare)."""
    return _train_two_letters(tmp_path_factory, "ft")


def test_default_size_is_1280x720_and_stays_an_option():
    from clfd_bench.cli.main import build_parser

    assert (VideoStyle().width, VideoStyle().height) == (1280, 720)
    parser = build_parser()
    assert parser.parse_args(["video", "r"]).size == (1280, 720)
    assert parser.parse_args(["video", "r", "--size", "640x360"]).size == (640, 360)


def test_frame_camera_fills_a_wide_frame_sideways():
    """A row of points wider than tall: at 16:9 the camera comes closer than at 4:3 (it fits
    the horizontal field of view, not the points' bounding sphere in the vertical one), and
    every point projects inside the frame."""
    pts = np.array([[0.5, -0.6, 0.2], [0.5, 0.6, 0.2], [0.5, 0.0, 0.4]])
    wide, square = (frame_camera(pts, 180.0, -20.0, aspect=a, margin=1.0)
                    for a in (16 / 9, 4 / 3))
    assert wide.distance < square.distance
    az, el = np.radians(180.0), np.radians(-20.0)
    fwd = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    right = np.cross(fwd, [0, 0, 1])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    eye = np.array(wide.lookat) - wide.distance * fwd
    rel = pts - eye
    depth = rel @ fwd
    tan_y = np.tan(np.radians(45.0) / 2)
    assert np.all(np.abs(rel @ right) / depth <= tan_y * 16 / 9 + 1e-9)
    assert np.all(np.abs(rel @ up) / depth <= tan_y + 1e-9)


def test_caption_names_the_method_task_and_outcome(tiny_run):
    """The caption comes from the run's config (SG); a rollout that fails (the letter 'e'
    written in the 'h' env) closes on a red border with "failed (<kind>)" and the env's
    reason, a success on a green one."""
    run = load_run(tiny_run)
    caption = run_caption(run, "task 0 'h'", 0)
    assert caption == "SG · task 0 'h' · demo 0"
    demos = load_dataset("helloworld").tasks
    env = get_env("clfd/HelloWorld-h-v3")
    frames: list[np.ndarray] = []
    wrong = np.asarray(demos[1].demos)[0]  # an 'e'
    result, count = render_rollout(env, wrong, 0, [frames.append], caption=caption, style=STYLE)
    assert not result.success and count == len(frames)
    text, border = outcome_caption(caption, result)
    assert border == FAILURE_RGB
    first, reason = text.split("\n")
    assert first == f"SG · task 0 'h' · demo 0 · failed ({result.failure_kind})"
    assert reason == result.failure_reason and reason
    red = frames[-1][0, STYLE.width // 2].astype(int)
    assert red[0] > 150 and red[1] < 100  # the held closing frames: red border
    good = render_rollout(env, np.asarray(demos[0].demos)[0], 0, [], style=STYLE)[0]
    assert outcome_caption(caption, good) == (f"{caption} · success", SUCCESS_RGB)


def test_comparison_video_is_a_grid_of_tiles_one_per_run(tiny_run, tiny_ft_run, tmp_path,
                                                         monkeypatch):
    style = VideoStyle(width=192, height=108, fps=3.0, hold_s=1.0, max_segments=40)
    rows, cols, tw, th = comparison_grid(3, style)
    assert (rows, cols, tw, th) == (2, 2, 96, 54)
    rendered: list[tuple[int, int, str]] = []
    real = compare_mod.render_rollout

    def spy(env, trajectory, demo, sinks, **kw):
        rendered.append((kw["style"].width, kw["style"].height, kw["caption"]))
        return real(env, trajectory, demo, sinks, **kw)

    monkeypatch.setattr(compare_mod, "render_rollout", spy)
    out = render_comparison_video([tiny_run, tiny_ft_run, tiny_run], task="e", demo=1,
                                  out_path=tmp_path / "cmp.mp4", style=style)
    # Each tile rendered at tile size (not the whole frame's, then shrunk), one per run.
    assert rendered == [(96, 54, "SG · 'e'"), (96, 54, "FT · 'e'"), (96, 54, "SG · 'e'")]
    video = iio.imread(out)
    assert video.shape == (style.frames_for(1000 + 60), 108, 192, 3)
    last = video[-1].astype(int)
    for k in range(3):  # three tiles with the scene, each with its outcome border
        r, c = divmod(k, cols)
        cell = last[r * th:(r + 1) * th, c * tw:(c + 1) * tw]
        assert cell.mean() > 40
        edge = cell[1, tw // 2]
        assert max(edge[0], edge[1]) > 150 and min(edge[0], edge[1]) < 110  # red or green
    legend = last[th:, tw:]  # the empty cell: white text on black
    assert legend.mean() < 40 and (legend > 200).all(axis=-1).sum() > 20
    assert not list(tmp_path.glob(".*"))  # no tile videos left behind


def test_comparison_refuses_runs_that_did_not_learn_the_task(tiny_run, tmp_path):
    with pytest.raises(ValueError, match=r"learned no task 'l'; valid: an index 0\.\.1"):
        render_comparison_video([tiny_run], task="l", out_path=tmp_path / "x.mp4",
                                style=STYLE)


def test_rollout_video_decodes_with_expected_frames(tmp_path):
    demos = np.asarray(load_dataset("helloworld").tasks[1].demos)  # 'e'
    writer = VideoWriter(tmp_path / "e.mp4", STYLE.fps)
    frames: list[np.ndarray] = []
    result, count = render_rollout(get_env("clfd/HelloWorld-e-v3"), demos[0], 0,
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
    text_env = get_env("clfd/HelloWorld-v3", text="he").unwrapped
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

    args = parser.parse_args(["video", "--compare", str(tiny_run), "--out", str(tmp_path)])
    assert args.func(args) == 2
    assert "--compare shows one task: give --task" in capsys.readouterr().err


def _line_box(frame: np.ndarray) -> tuple[float, float]:
    """The share of the frame's width and height spanned by the prediction (orange) and the
    demonstration (green) lines drawn into it."""
    r, g, b = (frame[..., k].astype(int) for k in range(3))
    orange = (r > 200) & (g > 90) & (g < 190) & (b < 80)
    green = (g > 120) & (r < 110) & (b < 110) & (g - r > 60)
    ys, xs = np.nonzero(orange | green)
    assert len(xs) > 20, "no prediction or demonstration line in the frame"
    h, w = frame.shape[:2]
    (x0, x1), (y0, y1) = np.percentile(xs, [1, 99]), np.percentile(ys, [1, 99])  # stray pixels
    return (x1 - x0 + 1) / w, (y1 - y0 + 1) / h


@pytest.mark.parametrize("size", [(240, 180), (320, 180)])
def test_a_letter_fills_the_frame(size):
    """The writing camera frames the letter, not the robot: at the wall's 4:3 and a 16:9
    frame, the letter's lines span at least half of the frame's width or height (whichever
    its shape fills first; the old camera, framing the arm, gave the letter 'h' ~12 % x 15 %
    of a 240x180 tile) and lie inside it; the robot is drawn see-through over it."""
    from clfd_bench.viz.framing import see_through_bodies
    from clfd_bench.viz.video import closing_frame

    demos = np.asarray(load_dataset("helloworld").tasks[0].demos)  # 'h'
    env = get_env("clfd/HelloWorld-h-v3")
    style = VideoStyle(width=size[0], height=size[1], max_segments=40)
    result, frame = closing_frame(env, demos[0], 0, demonstration=demos[0], style=style)
    assert result.success
    width, height = _line_box(frame)
    assert max(width, height) >= 0.5, (width, height)
    print(f"letter spans {width:.0%} x {height:.0%} of {size}")
    assert min(width, height) >= 0.2, (width, height)
    assert max(width, height) < 0.95  # a margin: the whole letter is in the frame
    assert len(see_through_bodies(env.unwrapped)) >= 9  # the arm's links, hand and fingers


def test_a_closing_caption_without_the_reason_leaves_the_frame_visible():
    """``caption_reason=False`` (the site's wall tiles, whose page prints the reason) keeps the
    failed rollout's closing caption to one line: less of the frame under its dark veil."""
    import dataclasses

    wrong = np.asarray(load_dataset("helloworld").tasks[1].demos)[0]  # an 'e' in the 'h' env
    env = get_env("clfd/HelloWorld-h-v3")
    dark = []
    for reason in (True, False):
        frames: list[np.ndarray] = []
        style = dataclasses.replace(STYLE, hold_s=1.0, caption_reason=reason)
        result, _ = render_rollout(env, wrong, 0, [frames.append], caption="SG · 'h'",
                                   style=style)
        assert not result.success
        dark.append(int((frames[-1].max(axis=-1) < 120).sum()))  # the veil: the board x 0.35
    assert dark[1] < dark[0] / 2, dark

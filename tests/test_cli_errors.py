"""Mistakes at the command line end in one line (``clfd-bench <cmd>: error: ...``), exit 2,
nothing written; an interrupted run says how to resume."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

CLI = [sys.executable, "-m", "clfd_bench.cli.main"]
_CONSOLE = "import sys; from clfd_bench.cli.main import main; sys.exit(main())"
SMOKE = ["train", "--method", "sg", "--dataset", "helloworld", "--profile", "smoke", "--no-sim"]


def _main(args: list[str], capsys) -> tuple[int, str]:
    """``clfd-bench ARGS`` in this process (no interpreter start-up): exit code and stderr."""
    from clfd_bench.cli.main import main

    capsys.readouterr()
    code = main(args)
    return code, capsys.readouterr().err


def _one_error_line(code: int, err: str, command: str) -> str:
    assert code == 2, (code, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"clfd-bench {command}: error: "), err
    return lines[0]


def test_a_truncated_checkpoint_is_one_line_and_names_the_fix(tmp_path, capsys):
    out = tmp_path / "run"
    assert _main(SMOKE + ["--tasks", "1", "--quiet", "--out", str(out)], capsys)[0] == 0
    ckpt = out / "checkpoint.pt"
    ckpt.write_bytes(ckpt.read_bytes()[:1000])
    line = _one_error_line(*_main(SMOKE + ["--tasks", "2", "--out", str(out)], capsys), "train")
    assert str(ckpt) in line and "delete it" in line


def test_a_folder_that_is_not_a_run_is_not_written_into(tmp_path, capsys):
    folder = tmp_path / "docs"
    folder.mkdir()
    (folder / "notes.md").write_text("mine\n")
    line = _one_error_line(*_main(SMOKE + ["--tasks", "1", "--out", str(folder)], capsys),
                           "train")
    assert "'notes.md'" in line and "not a run directory" in line
    assert sorted(p.name for p in folder.iterdir()) == ["notes.md"]


def test_replay_names_the_closest_env_and_takes_ids_without_namespace(capsys):
    line = _one_error_line(*_main(["replay", "--env", "PlateStaking-v3"], capsys), "replay")
    assert "did you mean 'PlateStacking-v3'" in line
    line = _one_error_line(
        *_main(["replay", "--env", "PlateStacking-v3", "--perturb", "revers"], capsys), "replay")
    assert "did you mean 'reverse'" in line  # the env id itself was accepted


def test_ctrl_c_says_how_to_resume(tmp_path):
    out = tmp_path / "run"
    # the console script, as a user runs it: under `python -m`, runpy sometimes reports a
    # handled Ctrl-C as an unhandled one and the process ends by SIGINT (-2) after the line
    script = Path(sys.executable).with_name("clfd-bench")
    cmd = [str(script)] if script.exists() else [sys.executable, "-c", _CONSOLE]
    proc = subprocess.Popen(
        cmd + ["train", "--method", "sg", "--dataset", "helloworld", "--profile", "fast",
               "--tasks", "1", "--no-sim", "--out", str(out)],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "CLFD_NO_PROGRESS": "1"},
        # a background job inherits SIGINT ignored; a user's terminal delivers it
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    deadline = time.monotonic() + 120
    while not (out / ".lock").exists() and time.monotonic() < deadline:
        time.sleep(0.1)
    time.sleep(2.0)  # training has started (fast's first letter takes tens of seconds)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert err.strip().splitlines()[-1] == (
        "clfd-bench train: interrupted; finished work is kept: run the same command again, "
        "it resumes after the last finished task")

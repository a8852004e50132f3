"""The command line is the top floor: no module of the library below it imports
``clfd_bench.cli`` (read from the source, every import statement, also inside functions), and
a grid starts its workers on the library's entry point, not on ``clfd-bench train``."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import clfd_bench
from clfd_bench.harness.worker import ENTRY_POINT, Job
from clfd_bench.leaderboard.grid import RunSpec

PACKAGE = Path(clfd_bench.__file__).parent


def _imported(path: Path) -> list[tuple[int, str]]:
    """``(line, module)`` of every import in ``path``, relative ones made absolute."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    package = ".".join(("clfd_bench", *path.relative_to(PACKAGE).parent.parts))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*parent, base] if base else parent)
            found.append((node.lineno, base))
            found += [(node.lineno, f"{base}.{alias.name}") for alias in node.names]
    return found


def test_no_library_module_imports_the_cli():
    offenders = []
    for path in sorted(PACKAGE.rglob("*.py")):
        if path.relative_to(PACKAGE).parts[0] == "cli":
            continue
        for line, module in _imported(path):
            if module == "clfd_bench.cli" or module.startswith("clfd_bench.cli."):
                offenders.append(f"{path.relative_to(PACKAGE.parent)}:{line} imports {module}")
    assert not offenders, "the library imports the command line:\n" + "\n".join(offenders)


def test_the_scan_sees_every_kind_of_import(tmp_path, monkeypatch):
    """The scan itself: absolute, from-, relative and function-level imports are all seen."""
    folder = tmp_path / "clfd_bench" / "studies"
    folder.mkdir(parents=True)
    module = folder / "probe.py"
    module.write_text("import clfd_bench.cli.main\n"
                      "def f():\n"
                      "    from clfd_bench.cli import train\n"
                      "    from ..cli.common import names\n"
                      "    from .. import cli\n", encoding="utf-8")
    monkeypatch.setattr(sys.modules[__name__], "PACKAGE", tmp_path / "clfd_bench")
    modules = [m for _, m in _imported(module)]
    assert "clfd_bench.cli.main" in modules
    assert "clfd_bench.cli" in modules and "clfd_bench.cli.train" in modules
    assert "clfd_bench.cli.common" in modules
    assert "clfd_bench.cli" in [m for ln, m in _imported(module) if ln == 5]


def test_a_grid_worker_runs_the_library_entry_point(tmp_path):
    spec = RunSpec("helloworld", "hn", "smoke", 1, order=0, node="s", tasks=2, sim=False,
                   overrides=(("beta", "0.01"),))
    argv = spec.worker_argv(tmp_path)
    assert argv[:3] == [sys.executable, "-m", ENTRY_POINT] and len(argv) == 4
    assert not any("clfd_bench.cli" in a or a == "train" for a in argv)
    job = Job.from_json(argv[3])
    assert job == spec.job(tmp_path)
    assert job.out == str(spec.run_dir(tmp_path)) and job.sim is False
    assert job.train.config() == spec.config()  # the worker trains what the grid planned

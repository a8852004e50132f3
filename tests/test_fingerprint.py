"""The simulator's fingerprint follows what the envs run: a comment or docstring reworded
leaves every execution result current; any change to the code makes them stale."""

from __future__ import annotations

from pathlib import Path

import pytest

from clfd_bench.execution import fingerprint
from clfd_bench.execution.fingerprint import _hashed_bytes

CODE = '''"""Module doc."""

LIMIT = 0.01  # metres


class Check:
    """Class doc, with a non-ASCII bound: ≤ 1 cm."""

    def passed(self, d: float) -> bool:
        """Doc of a method."""
        # the bound
        return d <= LIMIT and "label # not a comment" != ""
'''


def _hash(tmp_path: Path, text: str) -> bytes:
    path = tmp_path / "module.py"
    path.write_text(text)
    return _hashed_bytes(path)


@pytest.mark.parametrize("edit", [
    lambda s: s.replace("# metres", "# metres, from the demos"),
    lambda s: s.replace('"""Module doc."""', '"""Module doc,\nnow on two lines."""'),
    lambda s: s.replace("≤ 1 cm", "at most 1 cm (see the gallery)"),
    lambda s: s.replace('"""Doc of a method."""', "'''Doc — reworded.'''"),
    lambda s: s.replace("        # the bound\n", "\n\n"),
    lambda s: s.replace("# metres", "   "),
])
def test_comments_docstrings_and_blank_lines_do_not_count(tmp_path, edit):
    assert edit(CODE) != CODE
    assert _hash(tmp_path, edit(CODE)) == _hash(tmp_path, CODE)


@pytest.mark.parametrize("edit", [
    lambda s: s.replace("0.01", "0.011"),
    lambda s: s.replace("d <= LIMIT", "d < LIMIT"),
    lambda s: s.replace("label # not a comment", "label # changed"),
    lambda s: s.replace("        return", "        d = -d\n        return"),
    lambda s: s.replace("        # the bound\n", "        'not a docstring'\n"),
])
def test_a_change_to_the_code_counts(tmp_path, edit):
    assert _hash(tmp_path, edit(CODE)) != _hash(tmp_path, CODE)


def test_a_file_that_does_not_parse_counts_whole(tmp_path):
    assert _hash(tmp_path, "version 1 # x") == b"version 1 # x"


def test_a_reworded_comment_in_the_simulator_keeps_the_fingerprint(tmp_path, monkeypatch):
    """End to end: the fingerprint of a simulator file edited in a comment is unchanged."""
    source = tmp_path / "sim.py"
    source.write_text(CODE)
    monkeypatch.setattr(fingerprint, "_sim_files", lambda: iter([("sim.py", source)]))
    fingerprint.sim_fingerprint.cache_clear()
    try:
        before = fingerprint.sim_fingerprint()
        source.write_text(CODE.replace("# the bound", "# the bound (observer's argument)"))
        fingerprint.sim_fingerprint.cache_clear()
        assert fingerprint.sim_fingerprint() == before
        source.write_text(CODE.replace("0.01", "0.02"))
        fingerprint.sim_fingerprint.cache_clear()
        assert fingerprint.sim_fingerprint() != before
    finally:
        fingerprint.sim_fingerprint.cache_clear()


def test_the_modules_the_envs_import_count_and_the_rest_do_not():
    """Beyond sim/ and envs/, the fingerprint hashes what they import, transitively and lazily
    imported included: the demos' loading (data/), the writing judges' DTW (metrics/trajectory.py
    imports metrics/warping.py inside a function). Training code, which no env runs, stays out
    (a change there leaves every execution result current)."""
    names = {name for name, _ in fingerprint._sim_files()}
    for needed in ("envs/writing/judge.py", "execution/rollout.py", "metrics/trajectory.py",
                   "metrics/warping.py", "data/resample.py", "envs/robotasks/scoop/kernels.py"):
        assert needed in names, needed
    for other in ("harness/loop.py", "learning/node.py", "methods/hn.py", "execution/evaluate.py",
                  "envs/robotasks/scoop/doc.py"):
        assert other not in names, other

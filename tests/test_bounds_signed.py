"""Every success bound in tasks/*.toml is signed (issue 38): next to its value stands either the
procedure that derives it from the demonstrations or an observer's argument for it. A bound
added without one fails here, naming the file and the key."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

TASKS = Path(__file__).resolve().parents[1] / "tasks"
#: the tables that hold success bounds (a scene's [success]; writing's [success] and the
#: constants of its derivation, [tolerances]).
SECTIONS = ("success", "tolerances")
#: what a signature says: a derivation from the demos (a procedure, or the [derived] value
#: it is read from), the paper's own threshold, or an
#: observer's argument (a design value with why an observer signs it; a floor below which
#: the state is a physics failure rather than a judgement).
SIGNED = re.compile(r"Procedure:|DERIVED|\[derived\]|Why an\s+observer signs it|"
                    r"the paper's own|a\s+physics failure")
KEY = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)\s*=\s*(.*)$")
#: a table header, not a row of a multi-line array (which also starts with "[").
HEADER = re.compile(r"^\[[A-Za-z_][A-Za-z0-9_.]*\]$")


def signatures(path: Path) -> dict[str, str]:
    """``{"section.key": the comment that stands for it}`` for the numeric keys of
    :data:`SECTIONS`. A key's comment is the block of comment lines right above it plus its
    inline comment; keys that follow one another with no blank line or comment between share
    the block above the first of them (writing.toml's [tolerances])."""
    out: dict[str, str] = {}
    section, block, group = "", [], ""
    for line in path.read_text(encoding="utf-8").splitlines():
        stripped = line.strip()
        if HEADER.match(stripped):
            section, block, group = stripped.strip("[]"), [], ""
        elif stripped.startswith("#"):
            block.append(stripped.lstrip("# "))
        elif not stripped:
            block, group = [], ""
        elif (m := KEY.match(stripped)) and section in SECTIONS:
            if block:
                group, block = " ".join(block), []
            value, _, inline = m.group(2).partition("#")
            if re.fullmatch(r"\s*-?[0-9.e+-]+\s*|\s*\"paper\"\s*", value):
                out[f"{section}.{m.group(1)}"] = f"{group} {inline}"
        else:  # a key of another table, or a row of a multi-line array
            block = []
    return out


@pytest.mark.parametrize("path", sorted(TASKS.glob("*.toml")), ids=lambda p: p.name)
def test_every_bound_has_a_procedure_or_an_argument(path):
    found = signatures(path)
    unsigned = [key for key, text in found.items() if not SIGNED.search(text)]
    assert not unsigned, (f"{path.name}: {unsigned} carry neither a procedure nor an "
                          "observer's argument (issue 38); write one next to the value")


def test_the_parser_sees_the_bounds():
    """The check above cannot pass by finding nothing: every scene has success bounds and
    writing has its derivation constants."""
    assert {"success.max_rack_shift", "success.max_release_height"} <= set(
        signatures(TASKS / "platestandingtolying.toml"))
    assert {"success.min_ink_fraction", "tolerances.goal_size_fraction",
            "tolerances.hausdorff_floor"} <= set(signatures(TASKS / "writing.toml"))
    assert not SIGNED.search("design: a constant")
